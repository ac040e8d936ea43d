"""Random small rigs for exactness soaks: a bent tube of two to five capsules on an anisotropic grid, skeletonized,
bound rigidly or smoothly, and random poses in every mode, proximity and sampling. `mismatch(seed)` compares the
Deformer's frames with the thesis' brute-force scatter (volrig.deform_reference) voxel for voxel,
`collide_mismatch(seed)` volrig.collide of two such tubes with their brute-force frames intersected (and
volrig.self_collide of one with its brute force); it is what
tests/python/test_deform_soak.py runs for a few seeds and scripts/soak_deform.py for thousands."""
from typing import Optional

import numpy as np

import volrig


def capsules(shape, spacing, origin, joints, r_out, r_in, values):
    """A uint8 volume (z, y, x) of capsules between consecutive joints (world): each one's flesh (within r_out of its
    axis, where no earlier capsule is) and core (within r_in) take its pair of `values`."""
    z, y, x = np.indices(shape)
    world = np.stack([x, y, z], -1) * np.asarray(spacing) + np.asarray(origin)
    vol = np.zeros(shape, np.uint8)
    for a, b, (flesh, core) in zip(joints[:-1], joints[1:], values):
        ab = b - a
        t = np.clip(((world - a) @ ab) / max(ab @ ab, 1e-9), 0, 1)
        d = np.linalg.norm(world - (a + t[..., None] * ab), axis=-1)
        vol[(d < r_out) & (vol == 0)] = flesh
        vol[d < r_in] = core
    return vol


def tube(rng, grid=None):
    """A random bent tube (capsules with a brighter core) and a chain rig along it; None when a bone has no length.
    `grid`: (shape, spacing, origin) to make it on, else a random one."""
    if grid is None:
        shape = tuple(int(v) for v in rng.integers(24, 48, 3))  # z, y, x
        spacing = tuple(float(v) for v in rng.uniform(0.6, 1.5, 3))
        origin = tuple(float(v) for v in rng.uniform(-5, 5, 3))
    else:
        shape, spacing, origin = grid
    sp, org = np.asarray(spacing), np.asarray(origin)
    ext = np.array(shape[::-1]) * sp
    bones = int(rng.integers(2, 5))
    joints = [org + ext * (0.2 + 0.6 * rng.random(3))]
    for _ in range(bones):
        step = rng.normal(size=3)
        joints.append(np.clip(joints[-1] + rng.uniform(5, 12) * step / np.linalg.norm(step), org + 0.15 * ext,
                              org + 0.85 * ext))
    if any(np.allclose(a, b) for a, b in zip(joints[:-1], joints[1:])):
        return None
    r_out, r_in = rng.uniform(2.5, 6), rng.uniform(1, 2.4)
    values = [(rng.integers(40, 120), rng.integers(150, 255)) for _ in range(bones)]  # (flesh, core) per capsule
    vol = capsules(shape, sp, org, joints, r_out, r_in, values)
    rig = volrig.Rig(joints=np.array(joints), bones=[[i, i + 1] for i in range(bones)],
                     names=[f"b{i}" for i in range(bones)])
    return volrig.Volume(vol, spacing, origin), rig


def random_pose(rig, rng, degrees=35.0, shift=2.0):
    """Each bone turned about its head by up to `degrees` and shifted by about `shift` (bones come apart and
    overlap)."""
    M = volrig.rest_pose(len(rig))
    for b in range(len(rig)):
        M[b] = volrig.rotation_about(rng.normal(size=3), rng.uniform(-degrees, degrees), rig.heads()[b])
        M[b][:3, 3] += rng.normal(size=3) * shift
    return M


def mismatch(seed: int, frames: int = 3, extended: bool = False) -> Optional[str]:
    """None when `frames` random frames of rig `seed` equal the brute-force scatter voxel for voxel (or the seed
    makes no rig), else what differed; each frame is drawn twice, with the bones' lattice tables
    (`Deformer(lattice_after=0)`) and without them (-1). `extended` also draws, from a second stream (the first stays
    the seed's): the bright core as rigid tissue (the rigid layer), per-point radius scales, and frames in 8³
    bricks."""
    rng = np.random.default_rng(seed)
    extra = np.random.default_rng([seed, 7]) if extended else None
    made = tube(rng)
    if made is None:
        return None
    volume, rig = made
    mask = volrig.segment(volume, lo=1)
    count, bind = int(rng.integers(30, 1500)), str(rng.choice(["rigid", "smooth"]))
    points = volrig.skeletonize(mask).top(count)
    rigid = volume.array >= 150 if extra is not None and extra.random() < 0.3 else None
    binding = volrig.bind(points, rig, mask, mode=bind, rigid=rigid)
    proximity = str(rng.choice(["power", "nearest"]))
    d = volrig.Deformer(volume, points, binding, proximity=proximity, lattice_after=0)
    balls = volrig.Deformer(volume, points, binding, proximity=proximity, lattice_after=-1)
    scale = extra.uniform(0.5, 1.5, len(points)) if extra is not None and extra.random() < 0.3 else None
    for k in range(frames):
        mode = str(rng.choice(["rigid", "linear", "dual_quaternion"]))
        sampling = str(rng.choice(["trilinear", "nearest"]))
        keep = bool(rng.integers(0, 2))
        M = random_pose(rig, rng, degrees=float(rng.uniform(5, 90)), shift=float(rng.uniform(0, 4)))
        bricks = extra is not None and extra.random() < 0.3
        ref = None
        for tables, deformer in (("lattice tables", d), ("balls", balls)):
            fast = deformer.frame(M, mode=mode, sampling=sampling, keep_volume=keep, radius_scale=scale, bricks=bricks)
            fast = fast.dense() if bricks else fast
            if ref is None:
                ref = volrig.deform_reference(volume, points, binding, M, mode=mode, proximity=proximity,
                                              sampling=sampling, like=fast, keep_volume=keep, radius_scale=scale)
            if tuple(fast.offset) != tuple(ref.offset) or fast.bone.dims != ref.bone.dims:
                return f"seed {seed} frame {k}, {tables}: the frame's box differs from the lattice tables' frame"
            bone = int((fast.bone.array != ref.bone.array).sum())
            values = int((fast.values.array != ref.values.array).sum())
            if bone or values:
                extras = (f", rigid tissue {rigid is not None}, radius scales {scale is not None}, bricks {bricks}"
                          if extended else "")
                return (f"seed {seed} frame {k}, {tables}: {bind} binding of {len(points)} points, {proximity} "
                        f"proximity, {mode}, {sampling} sampling, keep_volume {keep}{extras}: {bone} bone labels and "
                        f"{values} values differ")
    return None


def collide_mismatch(seed: int) -> Optional[str]:
    """None when `volrig.collide` of two random tubes on one grid, in random poses and modes, counts exactly the
    lattice points covered by both of their brute-force frames (and agrees with its own brute force), else what
    differed."""
    rng = np.random.default_rng([seed, 11])
    made_a = tube(rng)
    if made_a is None:
        return None
    vol_a, rig_a = made_a
    made_b = tube(rng, (vol_a.array.shape, vol_a.spacing, vol_a.origin))
    if made_b is None:
        return None
    vol_b, rig_b = made_b
    bodies = []
    for vol, rig in ((vol_a, rig_a), (vol_b, rig_b)):
        mask = volrig.segment(vol, lo=1)
        points = volrig.skeletonize(mask).top(int(rng.integers(30, 1000)))
        binding = volrig.bind(points, rig, mask, mode=str(rng.choice(["rigid", "smooth"])))
        pose = random_pose(rig, rng, degrees=float(rng.uniform(5, 60)), shift=float(rng.uniform(0, 6)))
        mode = str(rng.choice(["rigid", "linear", "dual_quaternion"]))
        bodies.append((vol, rig, points, binding, pose, mode))
    keep = bool(rng.integers(0, 2))
    (va, ra, pa, ba, ma, mode_a), (vb, rb, pb, bb, mb, mode_b) = bodies
    shape = va.array.shape
    a, b = volrig.Collider(pa, ba, ra, shape=shape), volrig.Collider(pb, bb, rb, shape=shape)
    fast = volrig.collide(a, ma, b, mb, mode=mode_a, mode_b=mode_b, keep_volume=keep)
    brute = volrig.collide(a, ma, b, mb, mode=mode_a, mode_b=mode_b, keep_volume=keep, reference=True)
    fa = volrig.deform_reference(va, pa, ba, ma, mode=mode_a, keep_volume=keep)
    fb = volrig.deform_reference(vb, pb, bb, mb, mode=mode_b, keep_volume=keep)
    lo = np.maximum(fa.offset, fb.offset)  # (x, y, z) on the shared lattice
    hi = np.minimum(np.add(fa.offset, fa.bone.dims), np.add(fb.offset, fb.bone.dims))
    both = 0
    if (hi > lo).all():
        def part(f):
            o = lo - np.asarray(f.offset)
            e = o + (hi - lo)
            return f.bone.array[o[2]:e[2], o[1]:e[1], o[0]:e[0]] > 0
        both = int((part(fa) & part(fb)).sum())
    if fast.voxels != both or brute.voxels != both:
        return (f"collide seed {seed}: {mode_a} / {mode_b}, keep_volume {keep}, {len(pa)} / {len(pb)} points: "
                f"collide {fast.voxels}, its brute force {brute.voxels}, the frames intersected {both}")
    # A against itself: bones at least 1 or 2 apart, balls joined at rest ignored or not, against its brute force
    apart, rest = int(rng.integers(1, 3)), bool(rng.integers(0, 2))
    own = [volrig.self_collide(a, ma, min_bone_distance=apart, ignore_rest_contact=rest, mode=mode_a,
                               keep_volume=keep, reference=ref) for ref in (False, True)]
    if own[0].voxels != own[1].voxels or sorted(own[0].bone_pairs) != sorted(own[1].bone_pairs):
        return (f"self_collide seed {seed}: {mode_a}, bones {apart} apart, rest contact ignored {rest}: "
                f"{own[0].voxels} voxels {own[0].bone_pairs}, its brute force {own[1].voxels} {own[1].bone_pairs}")
    return None

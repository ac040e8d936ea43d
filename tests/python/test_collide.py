"""Collision detection (issue 19): the phantom walking into a ball (equal to two Deformer frames intersected voxel
for voxel), self-contact of the phantom (a walk: none; a forearm swung into the thigh: found with hand.R/thigh.R),
contacts over a clip, and bad input. The brute-force equality on random limbs is in tests/native/test_collide.cpp."""
import numpy as np
import pytest

import volrig
from volrig.walk import walk_matrices


@pytest.fixture(scope="module")
def body(phantom_half):
    vol = phantom_half.volume
    mask = volrig.segment(vol)
    pts = volrig.skeletonize(mask).top(5000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask)
    rigid = volrig.bind(pts, rig, mask)
    smooth = volrig.bind(pts, rig, mask, mode="smooth")
    return vol, pts, rig, rigid, smooth


@pytest.fixture(scope="module")
def ball(body):
    """A ball of radius 12 voxels on the phantom's own grid (so both deform on one lattice), one bone."""
    vol = body[0]
    z, y, x = np.indices(vol.array.shape)
    centre = np.array([98.0, 72.0, 60.0])  # x, y, z: in front of the left shin
    inside = (x - centre[0]) ** 2 + (y - centre[1]) ** 2 + (z - centre[2]) ** 2 < 12.0 ** 2
    bv = vol.like(np.where(inside, 200, 0).astype(np.uint8))
    mask = volrig.segment(bv)
    pts = volrig.skeletonize(mask).top(400)
    world = np.array(vol.origin) + np.array(vol.spacing) * centre
    rig = volrig.Rig([world, world + [0, 0, 10.0]], [[0, 1]], ["ball"])
    return bv, pts, rig, volrig.bind(pts, rig, mask)


def shift(dy):
    """The ball moved along y (towards the shin for dy < 0)."""
    m = np.eye(4)[None].copy()
    m[0, 1, 3] = dy
    return m


@pytest.mark.parametrize("mode", ["rigid", "linear", "dual_quaternion"])
def test_the_phantom_walking_into_a_ball_equals_two_deformed_frames_intersected(body, ball, mode):
    vol, pts, rig, rigid, smooth = body
    bv, bpts, brig, bbind = ball
    binding = rigid if mode == "rigid" else smooth
    a = volrig.Collider(pts, binding, rig, shape=vol.array.shape)
    b = volrig.Collider(bpts, bbind, brig, shape=bv.array.shape)
    da, db = volrig.Deformer(vol, pts, binding), volrig.Deformer(bv, bpts, bbind)
    clip = walk_matrices(rig, 8)
    hits = 0
    k = rig.index("shin.L")
    rest_mid = np.append((rig.heads()[k] + rig.tails()[k]) / 2, 1.0)
    ball_centre = brig.heads()[0]
    for f, gap in zip(range(0, 8, 2), (20.0, 14.0, 8.0, 70.0)):  # the ball in front of the walking left shin
        target = (clip[f][k] @ rest_mid)[:3] + [0.0, gap, 0.0]
        mb = shift(target[1] - ball_centre[1])
        mb[0, 0, 3], mb[0, 2, 3] = target[0] - ball_centre[0], target[2] - ball_centre[2]
        c = volrig.collide(a, clip[f], b, mb, mode=mode, mode_b="rigid")
        want = da.frame(clip[f], mode=mode, values=False).shared_voxels(db.frame(mb, values=False))
        assert c.voxels == want, (f, gap)
        assert c.hit == (want > 0)
        hits += c.hit
        if c.hit:
            with_points = volrig.collide(a, clip[f], b, mb, mode=mode, mode_b="rigid", points=True)
            assert with_points.points.shape == (c.voxels, 3) and c.points is None
            assert (with_points.points >= c.box[0]).all() and (with_points.points <= c.box[1]).all()
            assert c.bones_b == ["ball"]
            assert c.bones_a == ["shin.L"], c.bones_a
            assert all(pair[1] == "ball" for pair in c.bone_pairs)
            assert (c.box[0] <= c.box[1]).all()
    assert hits == 3  # all but the ball 70 voxels away
    fa = da.frame(clip[0], mode=mode, values=False)
    assert fa.shared_voxels(fa) == fa.stats["covered"]
    assert not volrig.collide(a, clip[0], b, shift(200.0), mode=mode, mode_b="rigid").hit


def test_self_contact_of_the_phantom(body):
    vol, pts, rig, rigid, smooth = body
    c = volrig.Collider(pts, rigid, rig, shape=vol.array.shape)
    cs = volrig.Collider(pts, smooth, rig, shape=vol.array.shape)
    clip = walk_matrices(rig, 24)
    for collider, mode in ((c, "rigid"), (cs, "linear")):  # a walk: nothing passes through anything
        found = volrig.collisions(collider, clip, mode=mode)
        assert found.hit_frames == [] and found.contacts == []
    rest = np.repeat(np.eye(4)[None], len(rig), axis=0)
    assert not volrig.self_collide(c, rest)
    # without skipping bones joined at rest, the trunk and the thighs touch at rest
    assert ("hips", "thigh.L") in volrig.self_collide(c, rest, ignore_rest_contact=False).bone_pairs
    # the right forearm swung in about the front-back axis: the hand goes into the right thigh, and only there
    hand = volrig.self_collide(c, rig.pose({"upper_arm.R": ([0, 1, 0], 8), "forearm.R": ([0, 1, 0], -20)}))
    assert hand.hit and hand.bone_pairs == [("hand.R", "thigh.R")]
    assert hand.bones_a == hand.bones_b == ["hand.R", "thigh.R"]
    heads = rig.heads()
    assert heads[rig.index("hand.R")][0] - 5 < hand.box[0][0] < heads[rig.index("thigh.R")][0]
    deeper = volrig.self_collide(c, rig.pose({"upper_arm.R": ([0, 1, 0], 8), "forearm.R": ([0, 1, 0], -30)}))
    assert deeper.voxels > 10 * hand.voxels and ("hand.R", "thigh.R") in deeper.bone_pairs
    # swung outwards instead: nothing
    assert not volrig.self_collide(c, rig.pose({"forearm.R": ([0, 1, 0], 30)}))


def test_contacts_over_a_clip_come_in_runs_with_their_bones(body, ball):
    vol, pts, rig, rigid, _ = body
    bv, bpts, brig, bbind = ball
    a = volrig.Collider(pts, rigid, rig, shape=vol.array.shape)
    b = volrig.Collider(bpts, bbind, brig, shape=bv.array.shape)
    still = np.repeat(np.eye(4)[None], len(rig), axis=0)
    ys = np.linspace(20.0, -70.0, 13)  # the ball passes through the left shin, then out the back
    clip_b = np.array([shift(y) for y in ys])
    ticks = []
    found = volrig.collisions(a, np.repeat(still[None], len(ys), axis=0), b, clip_b, frames=range(1, 14),
                              progress=lambda f: ticks.append(f) or True)
    assert ticks[-1] == 1.0 and len(ticks) == 13
    hit = found.hit_frames
    assert hit and hit == list(range(hit[0], hit[-1] + 1))  # one run of consecutive frames
    (run,) = found.contacts
    assert (run.first, run.last) == (hit[0], hit[-1])
    assert run.voxels == max(r.voxels for r in found.results) and run.first <= run.peak_frame <= run.last
    assert run.bone_pairs == [("shin.L", "ball")] and run.name == "shin.L/ball"
    many = volrig.Contact(1, 2, [("forearm.R", "pelvis.L"), ("forearm.R", "thigh.R"), ("hand.R", "thigh.R")], 9, 1)
    assert many.name == "forearm.R hand.R pelvis.L thigh.R (3 pairs)"
    with pytest.raises(volrig.Cancelled):
        volrig.collisions(a, np.repeat(still[None], 3, axis=0), b, clip_b[:3], progress=lambda f: False)


def test_bad_input_gets_clear_errors(body, ball):
    vol, pts, rig, rigid, _ = body
    bv, bpts, brig, bbind = ball
    a = volrig.Collider(pts, rigid, rig, shape=vol.array.shape)
    b = volrig.Collider(bpts, bbind)  # no rig: two-body tests only
    still = np.repeat(np.eye(4)[None], len(rig), axis=0)
    with pytest.raises(volrig.VolrigError, match="needs the rig's bone parents"):
        volrig.self_collide(b, np.eye(4)[None])
    with pytest.raises(volrig.VolrigError, match="bone matrices"):
        volrig.collide(a, still[:3], b, np.eye(4)[None])
    scaled = np.eye(4)[None].copy()
    scaled[0, :3, :3] *= 2
    with pytest.raises(volrig.VolrigError, match="not a rotation"):
        volrig.collide(a, still, b, scaled)
    with pytest.raises(volrig.VolrigError, match="min_bone_distance"):
        volrig.self_collide(a, still, min_bone_distance=-1)
    with pytest.raises(volrig.VolrigError, match="clip_b"):
        volrig.collisions(a, still[None], b, np.eye(4)[None, None].repeat(3, axis=0))
    with pytest.raises(TypeError, match="Collider"):
        volrig.collide(a, still, "ball", np.eye(4)[None])
    with pytest.raises(volrig.VolrigError, match="rig has 1 bones but the binding 21"):
        volrig.Collider(pts, rigid, brig)


def test_cli_contacts(tmp_path, body, ball):
    from conftest import shared
    from test_cli import run
    vol, pts, rig, rigid, _ = body
    bv, bpts, brig, bbind = ball
    a, b = tmp_path / "phantom.vrig", tmp_path / "ball.vrig"
    volrig.save_rig(a, pts, rig=rig, binding=rigid)
    # the ball 14 voxels nearer the left shin, at rest against it
    moved = volrig.SkeletonPoints(bpts.ijk - [0, 14, 0], bpts.centers - [0, 14, 0], bpts.radii, bpts.dt, bpts.scores,
                                  bpts.metric, bpts.spacing, bpts.origin)
    volrig.save_rig(b, moved, rig=brig, binding=bbind)
    r = run("contacts", a, b)
    assert r.returncode == 0, r.stderr
    want = volrig.collide(volrig.Collider(pts, rigid, rig), volrig.rest_pose(len(rig)),
                          volrig.Collider(moved, bbind, brig), volrig.rest_pose(1))
    assert want.hit and f"frame 1: shin.L/ball (most {want.voxels:,} voxels" in r.stdout
    assert "1 of 1 frames in contact" in r.stdout
    clip = shared("bvh/131_01.bvh")
    r = run("contacts", a, clip, "--frames", "1-97", "--step", 48)  # self-contact over a mocap walk: 3 frames
    assert r.returncode == 0, r.stderr
    assert "of 3 frames in contact" in r.stdout and "against itself" in r.stdout
    for bad, words in [((a, b, b), "one or two rig files"), ((a, tmp_path / "x.txt"), "not understood"),
                       ((tmp_path / "none.vrig",), "none.vrig")]:
        r = run("contacts", *bad)
        assert r.returncode == 2 and words in r.stderr and "Traceback" not in r.stderr, r.stderr

"""Autorig and binding: synthetic shapes with known structure, brute-force references, the phantom (the
skeleton-tree's own tests are in test_tree.py)."""
import numpy as np
import pytest

import volrig
from volrig import _volrig
from volrig.rig import Rig, autorig, bind
from volrig.tree import skeleton_tree

from test_tree import points_at, segment_sampled_inside


def capsule_mask(shape, segments, radius):
    """Union of capsules (segments given as ((z, y, x), (z, y, x))) on a grid."""
    zz, yy, xx = np.indices(shape)
    q = np.stack([zz, yy, xx], -1).astype(float)
    out = np.zeros(shape, bool)
    for a, b in segments:
        a, b = np.asarray(a, float), np.asarray(b, float)
        d = b - a
        t = np.clip(((q - a) @ d) / (d @ d), 0, 1)[..., None]
        out |= np.linalg.norm(q - (a + t * d), axis=-1) <= radius
    return out


# ---- rigs ------------------------------------------------------------------------------------------------------

def test_rest_matrices_follow_blenders_convention():
    r = Rig([[0, 0, 0], [0, 2, 0], [3, 2, 4]], [[0, 1], [1, 2]], ["a", "b"])
    m = r.rest_matrices
    np.testing.assert_allclose(m[0], [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose(m[1][:3, 1], [0.6, 0, 0.8])  # Y runs head -> tail
    np.testing.assert_allclose(m[1][:3, 3], [0, 2, 0])
    rng = np.random.default_rng(1)
    for _ in range(200):
        d = rng.normal(size=3)
        R = _volrig.rest_matrix((0.0, 0.0, 0.0), tuple(d))[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-4)  # Blender's series near -Y is approximate
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-4)
        np.testing.assert_allclose(R[:, 1], d / np.linalg.norm(d), atol=1e-12)
    # Blender's own matrix for a bone along +X with roll 0: X axis (0, -1, 0), Z axis (0, 0, 1)
    np.testing.assert_allclose(_volrig.rest_matrix((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))[:3, :3],
                               [[0, 1, 0], [-1, 0, 0], [0, 0, 1]], atol=1e-12)


def test_rig_validation():
    with pytest.raises(volrig.VolrigError, match="used twice"):
        Rig([[0, 0, 0], [0, 1, 0], [0, 2, 0]], [[0, 1], [1, 2]], ["a", "a"])
    with pytest.raises(volrig.VolrigError, match="refers to joint 5"):
        Rig([[0, 0, 0], [0, 1, 0]], [[0, 5]], ["a"])
    with pytest.raises(volrig.VolrigError, match="zero length"):
        Rig([[0, 0, 0], [0, 0, 0]], [[0, 1]], ["a"])
    with pytest.raises(volrig.VolrigError, match="cycle"):
        Rig([[0, 0, 0], [0, 1, 0], [0, 2, 0]], [[0, 1], [1, 2]], ["a", "b"], parents=[1, 0])
    r = Rig([[0, 0, 0], [0, 1, 0], [0, 2, 0]], [[0, 1], [1, 2]], ["a", "b"])
    assert list(r.parents) == [-1, 0]  # default parents follow connected joints
    with pytest.raises(KeyError, match="bones: a, b"):
        r.index("c")


def test_y_shape_autorigs_into_three_chains_meeting_at_the_fork():
    fork = (40, 30, 30)
    mask = capsule_mask((100, 60, 60), [((5, 30, 30), fork), (fork, (90, 30, 8)), (fork, (90, 30, 52))], 6)
    sk = volrig.skeletonize(mask)
    pts = sk.at(0.3)
    tree = skeleton_tree(pts, mask)
    for i, j in tree.edges:
        assert segment_sampled_inside(mask, pts.ijk[i], pts.ijk[j])
    rig = autorig(pts, tree, mask)
    assert rig.kind == "chains"
    # three branches: three end joints, and a joint with three bones near the fork
    heads, tails = rig.bones[:, 0], rig.bones[:, 1]
    ends = [j for j in range(len(rig.joints)) if (heads == j).sum() + (tails == j).sum() == 1]
    assert len(ends) == 3
    fork_xyz = np.array(fork[::-1], float)
    branching = [j for j in range(len(rig.joints)) if (heads == j).sum() + (tails == j).sum() >= 3]
    assert branching and min(np.linalg.norm(rig.joints[j] - fork_xyz) for j in branching) <= 1.5 * 6
    tips = np.array([[30, 30, 5], [8, 30, 90], [52, 30, 90]], float)
    for t in tips:
        assert np.linalg.norm(rig.joints[ends] - t, axis=1).min() <= 8.0


def test_bind_is_geodesic_a_hand_near_a_thigh_binds_to_the_arm():
    # "thigh": a tall cylinder at x = 10; "arm": a parallel cylinder at x = 24 (a 4-voxel gap), whose bone only
    # covers its upper part, so that its lower points are nearer the thigh's bone in a straight line.
    mask = capsule_mask((70, 20, 36), [((4, 10, 10), (64, 10, 10)), ((4, 10, 24), (64, 10, 24))], 4.5)
    rig = Rig([[10, 10, 2], [10, 10, 64], [24, 10, 45], [24, 10, 64]], [[0, 1], [2, 3]], ["thigh", "arm"])
    ijk = np.array([[z, 10, x] for z in range(6, 63, 2) for x in (10, 24)])
    pts = points_at(ijk, 4.0)
    b = bind(pts, rig, mask)
    on_arm = ijk[:, 2] == 24
    assert (b.bone[on_arm] == 1).all() and (b.bone[~on_arm] == 0).all()
    assert not b.unreachable.any()
    # the lower arm points are indeed nearer the thigh's bone in a straight line
    low = on_arm & (ijk[:, 0] < 20)
    assert (np.abs(pts.centers[low, 2] - 45) > 14).all()


def test_smooth_weights_blend_across_joints_and_sum_to_one():
    mask = capsule_mask((80, 20, 20), [((4, 10, 10), (76, 10, 10))], 6)
    rig = Rig([[10, 10, 4], [10, 10, 40], [10, 10, 76]], [[0, 1], [1, 2]], ["upper", "lower"])
    ijk = np.array([[z, 10, 10] for z in range(4, 77)])
    pts = points_at(ijk, 5.0)
    b = bind(pts, rig, mask, mode="smooth")
    w = b.weights.toarray()
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-6)
    z = ijk[:, 0]
    np.testing.assert_allclose(w[z == 40], [[0.5, 0.5]], atol=1e-6)  # at the joint plane: half and half
    assert (w[np.abs(z - 40) >= 5].max(axis=1) == 1.0).all()          # beyond one radius: one bone
    assert (w[(np.abs(z - 40) > 0) & (np.abs(z - 40) < 5)].min(axis=1) > 0).all()
    rigid = bind(pts, rig, mask)
    assert rigid.weights.nnz == len(pts)
    moved = rigid.reassign(np.flatnonzero(z < 10), "lower")
    assert (moved.bone[z < 10] == 1).all() and (moved.bone[(z >= 10) & (z < 40)] == 0).all()
    np.testing.assert_allclose(moved.weights.toarray().sum(axis=1), 1.0)
    assert rigid.bone[0] == 0  # the original is unchanged


def test_rigid_tissue_moves_with_one_bone_and_only_soft_tissue_blends():
    mask = capsule_mask((80, 20, 20), [((4, 10, 10), (76, 10, 10))], 6)
    rig = Rig([[10, 10, 4], [10, 10, 40], [10, 10, 76]], [[0, 1], [1, 2]], ["upper", "lower"])
    ijk = np.array([[z, 10, 10] for z in range(4, 77)])
    pts = points_at(ijk, 5.0)
    z = ijk[:, 0]
    # Two bones with a soft gap at the joint (z 38..42): the bones' points take one bone, the gap still blends.
    labels = np.zeros(mask.shape, dtype=np.uint8)
    labels[6:38, 8:13, 8:13] = 84
    labels[43:75, 8:13, 8:13] = 92
    source = volrig.Volume(labels)
    rigid = volrig.rigid_tissue(source, labels=[84, 92])
    assert rigid.array.dtype == np.bool_ and rigid.array.sum() == 2 * 32 * 25
    b = bind(pts, rig, mask, mode="smooth", rigid=rigid)
    w = b.weights.toarray()
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-6)
    on_bone = ((z >= 6) & (z < 38)) | ((z >= 43) & (z < 75))
    assert (w[on_bone].max(axis=1) == 1.0).all()
    assert (b.bone[(z >= 6) & (z < 38)] == 0).all() and (b.bone[(z >= 43) & (z < 75)] == 1).all()
    np.testing.assert_allclose(w[z == 40], [[0.5, 0.5]], atol=1e-6)
    # One bone across the joint (a coarse label map where they touch): each point keeps its own bone, unblended.
    labels[38:43, 8:13, 8:13] = 84
    b = bind(pts, rig, mask, mode="smooth", rigid=volrig.rigid_tissue(volrig.Volume(labels), value_range=(80, 95)))
    w = b.weights.toarray()
    assert (w.max(axis=1) == 1.0)[(z >= 6) & (z < 75)].all()
    assert (b.bone[(z >= 6) & (z < 40)] == 0).all() and (b.bone[(z > 40) & (z < 75)] == 1).all()
    # A bone mostly on one side of the joint goes wholly with that bone.
    labels[:] = 0
    labels[6:44, 8:13, 8:13] = 84
    b = bind(pts, rig, mask, mode="smooth", rigid=volrig.rigid_tissue(volrig.Volume(labels), labels=[84]))
    assert (b.bone[(z >= 6) & (z < 44)] == 0).all()
    with pytest.raises(volrig.VolrigError, match="labels or value_range"):
        volrig.rigid_tissue(source)
    with pytest.raises(volrig.VolrigError, match="grid"):
        bind(pts, rig, mask, rigid=np.zeros((10, 10, 10), dtype=bool))


def test_snap_moves_joints_onto_skeleton_points():
    pts = points_at([[5, 5, 5], [5, 5, 9], [5, 9, 9]], 1.0)
    r = Rig([[5.2, 4.9, 5.1], [8.6, 5.3, 5.0]], [[0, 1]], ["a"]).snap(pts)
    np.testing.assert_allclose(r.joints, [[5, 5, 5], [9, 5, 5]])
    assert list(r.joint_points) == [0, 1]


# ---- the phantom -----------------------------------------------------------------------------------------------

ROLE_BONES = {"hips", "spine", "chest", "neck", "head"} | {
    f"{b}.{s}" for s in "LR" for b in ("shoulder", "upper_arm", "forearm", "hand", "pelvis", "thigh", "shin", "foot")}


@pytest.fixture(scope="module")
def phantom_rig(phantom_half):
    mask = volrig.segment(phantom_half.volume)
    pts = volrig.skeletonize(mask).top(15000)
    tree = skeleton_tree(pts, mask)
    rig = autorig(pts, tree, mask)
    return phantom_half, mask, pts, tree, rig, bind(pts, rig, mask)


def test_phantom_autorig_is_a_role_named_humanoid(phantom_rig):
    ph, mask, pts, tree, rig, _ = phantom_rig
    assert rig.kind == "humanoid"
    assert set(rig.names) == ROLE_BONES
    assert rig.names[rig.parents.tolist().index(-1)] == "hips" and (rig.parents == -1).sum() == 1
    # .L is the character's left: +x on the phantom
    for b in ("upper_arm", "thigh", "hand", "foot"):
        assert rig.tails()[rig.index(f"{b}.L")][0] > 72 > rig.tails()[rig.index(f"{b}.R")][0]
    assert rig.joints[rig.bones[rig.index("head"), 1]][2] > rig.joints[rig.bones[rig.index("neck"), 0]][2]


def test_phantom_elbows_and_knees_are_where_the_phantom_bends(phantom_rig):
    ph, mask, pts, tree, rig, _ = phantom_rig
    radius = {s.name: s.radius_a for s in ph.segments}
    for side in "LR":
        for joint, bone, seg in (("elbow", "upper_arm", "forearm"), ("knee", "thigh", "shin")):
            got = rig.tails()[rig.index(f"{bone}.{side}")]
            err = np.linalg.norm(got - ph.joints[f"{joint}.{side}"])
            assert err <= 1.5 * radius[f"{seg}.{side}"], (joint, side, err)


def test_phantom_limb_points_bind_to_their_limb(phantom_rig):
    ph, mask, pts, tree, rig, binding = phantom_rig
    c = pts.centers
    inside_torso = np.zeros(len(c), bool)
    for e in ph.ellipsoids:
        if e.name != "head":
            inside_torso |= (((c - e.centre) / np.asarray(e.radii)) ** 2).sum(1) <= 1
    segs = {s.name: s for s in ph.segments}

    def in_capsule(s):
        a, b = ph.joints[s.joint_a], ph.joints[s.joint_b]
        d = b - a
        t = np.clip((c - a) @ d / (d @ d), 0, 1)
        return np.linalg.norm(c - (a + t[:, None] * d), axis=1) <= s.radius_a + t * (s.radius_b - s.radius_a)

    for side in "LR":
        for limb, parts, bones in (("arm", ("upper_arm", "forearm", "hand"), ("shoulder", "upper_arm", "forearm", "hand")),
                                   ("leg", ("thigh", "shin", "foot"), ("pelvis", "thigh", "shin", "foot"))):
            inside = np.zeros(len(c), bool)
            for p in parts:
                inside |= in_capsule(segs[f"{p}.{side}"])
            inside &= ~inside_torso
            own = np.isin(binding.bone, [rig.index(f"{b}.{side}") for b in bones])
            assert inside.sum() > 100
            assert own[inside].mean() >= 0.99, (limb, side, own[inside].mean())
    assert not binding.unreachable.any()


# ---- the rig file ----------------------------------------------------------------------------------------------

def test_rig_file_round_trip(phantom_rig, tmp_path):
    ph, mask, pts, tree, rig, binding = phantom_rig
    smooth = bind(pts, rig, mask, mode="smooth")
    path = tmp_path / "phantom.vrig"
    volrig.save_rig(path, pts, tree, rig, smooth, source="phantom.nrrd")
    r = volrig.load_rig(path)
    for f in ("ijk", "centers", "radii", "dt", "scores"):
        np.testing.assert_array_equal(getattr(r.points, f), getattr(pts, f))
    assert (r.points.metric, r.points.spacing, r.points.origin) == (pts.metric, pts.spacing, pts.origin)
    np.testing.assert_array_equal(r.tree.edges, tree.edges)
    np.testing.assert_array_equal(r.tree.weights, tree.weights)
    assert r.tree.component_count == tree.component_count and r.tree.alpha == tree.alpha
    np.testing.assert_array_equal(r.rig.joints, rig.joints)
    np.testing.assert_array_equal(r.rig.bones, rig.bones)
    assert r.rig.names == rig.names and r.rig.kind == "humanoid"
    np.testing.assert_array_equal(r.rig.parents, rig.parents)
    assert (r.binding.weights != smooth.weights).nnz == 0 and r.binding.mode == "smooth"
    np.testing.assert_array_equal(r.binding.bone, smooth.bone)
    assert r.source == str(tmp_path / "phantom.nrrd")
    # only the points
    volrig.save_rig(path, pts)
    r = volrig.load_rig(path)
    assert r.tree is None and r.rig is None and r.binding is None and len(r.points) == len(pts)


def test_rig_file_errors(phantom_rig, tmp_path):
    ph, mask, pts, tree, rig, binding = phantom_rig
    good = tmp_path / "good.vrig"
    rigid = np.asarray(mask.array).copy()
    rigid[:rigid.shape[0] // 2] = False  # rigid tissue in the file too (the damage below reaches its bits)
    volrig.save_rig(good, pts, tree, rig, bind(pts, rig, mask, rigid=rigid))
    with pytest.raises(FileNotFoundError):
        volrig.load_rig(tmp_path / "absent.vrig")
    # a newer version says so
    with np.load(good) as z:
        a = {k: z[k] for k in z.files}
    newer = tmp_path / "newer.vrig"
    with open(newer, "wb") as f:
        np.savez(f, **{**a, "version": np.array(2)})
    with pytest.raises(volrig.FileFormatError, match="newer volrig"):
        volrig.load_rig(newer)
    # lying shapes, out-of-range indices, wrong types
    for key, value, message in (("radii", a["radii"][:-1], "shape"), ("tree_edges", a["tree_edges"] + len(pts), "outside"),
                                ("rig_bones", a["rig_bones"] * 100, "inconsistent rig"),
                                ("binding_bone", a["binding_bone"] + 99, "outside"),
                                ("centers", np.full_like(a["centers"], np.nan), "non-finite"),
                                ("ijk", a["ijk"].astype(np.float32), "type"), ("format", np.array("other"), "format"),
                                ("binding_rigid_bits", a["binding_rigid_bits"][:-1], "shape"),
                                ("binding_rigid_shape", np.array([-1, 2, 3]), "impossible shape"),
                                ("binding_rigid_shape", a["binding_rigid_shape"].astype(np.float64), "type")):
        p = tmp_path / f"bad_{key}.vrig"
        with open(p, "wb") as f:
            np.savez(f, **{**a, key: value})
        with pytest.raises(volrig.FileFormatError, match=message):
            volrig.load_rig(p)
    # truncation and random damage: always a FileFormatError, never another exception
    data = good.read_bytes()
    rng = np.random.default_rng(5)
    bad = tmp_path / "damaged.vrig"
    for k in range(120):
        if k % 3 == 0:
            blob = data[:int(rng.integers(0, len(data)))]
        else:
            b = bytearray(data)
            for pos in rng.integers(0, len(b), size=int(rng.integers(1, 8))):
                b[pos] = int(rng.integers(0, 256))
            blob = bytes(b)
        bad.write_bytes(blob)
        try:
            volrig.load_rig(bad)
        except volrig.FileFormatError:
            pass
    # the writer never leaves a partial file behind
    with pytest.raises(ValueError):
        volrig.save_rig(tmp_path / "x.vrig", pts, tree, None, binding)
    assert not list(tmp_path.glob(".x.vrig*")) and not (tmp_path / "x.vrig").exists()

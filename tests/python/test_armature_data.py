"""What the Blender add-on stores and reads back, without Blender: rigs from armature bones, bindings as vertex
groups and back, and VDB volumes returned to their original grid."""
import numpy as np
import pytest

import volrig


@pytest.fixture(scope="module")
def rigged():
    ph = volrig.phantom.humanoid(scale=0.3)
    mask = volrig.segment(ph.volume)
    pts = volrig.skeletonize(mask).top(4000)
    tree = volrig.skeleton_tree(pts, mask)
    rig = volrig.autorig(pts, tree, mask)
    binding = volrig.bind(pts, rig, mask, mode="smooth")
    return ph, mask, pts, rig, binding


def test_rig_from_bones_shares_joints_of_connected_bones(rigged):
    _, _, _, rig, _ = rigged
    again = volrig.Rig.from_bones(rig.heads(), rig.tails(), rig.names, rig.parents)
    np.testing.assert_allclose(again.heads(), rig.heads())
    np.testing.assert_allclose(again.tails(), rig.tails())
    assert again.names == rig.names
    np.testing.assert_array_equal(again.parents, rig.parents)
    # autorig's joints are shared by the bones that meet there, and so are the rebuilt ones
    assert len(again.joints) == len(np.unique(rig.joints[np.unique(rig.bones)], axis=0))
    np.testing.assert_allclose(again.rest_matrices, rig.rest_matrices, atol=1e-12)


def test_rig_from_bones_checks_its_input():
    with pytest.raises(ValueError, match="heads but"):
        volrig.Rig.from_bones([[0, 0, 0]], [[0, 0, 1], [0, 0, 2]], ["a"], [-1])
    with pytest.raises(ValueError, match="finite"):
        volrig.Rig.from_bones([[0, 0, np.nan]], [[0, 0, 1]], ["a"], [-1])
    with pytest.raises(volrig.VolrigError, match="zero length"):
        volrig.Rig.from_bones([[0, 0, 0]], [[0, 0, 0]], ["a"], [-1])


def test_binding_groups_round_trip(rigged):
    _, _, pts, rig, binding = rigged
    groups = binding.groups()
    assert len(groups) == len(rig)
    assert sum(len(i) for i, _ in groups) == binding.weights.nnz
    for b, (idx, w) in enumerate(groups):
        np.testing.assert_allclose(w, binding.weights.toarray()[idx, b])
    named = {rig.names[b]: g for b, g in enumerate(groups)}
    back = volrig.Binding.from_groups(named, rig.names, len(pts))
    assert back.mode == "smooth"
    dense = binding.weights.toarray()
    top2 = np.sort(dense, axis=1)[:, -2:]
    clear = top2[:, 1] > top2[:, 0] + 1e-6  # owner = heaviest bone; at the joint plane (0.5/0.5) either one
    assert clear.mean() > 0.9
    np.testing.assert_array_equal(back.bone[clear], binding.bone[clear])
    np.testing.assert_allclose(back.weights.toarray(), dense, atol=1e-6)


def test_binding_from_painted_groups(rigged):
    _, _, pts, rig, binding = rigged
    groups = {rig.names[b]: g for b, g in enumerate(binding.groups())}
    hand = rig.index("hand.L")
    moved = binding.points_of("forearm.L")[:25]
    # paint: take the points out of every group, give them to the hand at weight 0.5 (normalised to 1)
    painted = {}
    for name, (idx, w) in groups.items():
        keep = ~np.isin(idx, moved)
        painted[name] = (idx[keep], w[keep])
    idx, w = painted["hand.L"]
    painted["hand.L"] = (np.concatenate([idx, moved]), np.concatenate([w, np.full(len(moved), 0.5)]))
    painted["not a bone"] = (np.arange(5), np.ones(5))  # ignored
    back = volrig.Binding.from_groups(painted, rig.names, len(pts))
    assert (back.bone[moved] == hand).all()
    np.testing.assert_allclose(back.weights.toarray()[moved, hand], 1.0)
    np.testing.assert_allclose(np.asarray(back.weights.sum(axis=1)).ravel(), 1.0, atol=1e-6)


def test_binding_from_groups_falls_back_for_unweighted_points(rigged):
    _, _, pts, rig, binding = rigged
    groups = {rig.names[b]: g for b, g in enumerate(binding.groups())}
    del groups["head"]
    with pytest.raises(ValueError, match="have no weight"):
        volrig.Binding.from_groups(groups, rig.names, len(pts))
    back = volrig.Binding.from_groups(groups, rig.names, len(pts), fallback=binding)
    head_only = np.flatnonzero(np.asarray((binding.weights[:, rig.index("head")] == 1).todense()).ravel())
    assert len(head_only) > 0
    assert (back.bone[head_only] == rig.index("head")).all()
    with pytest.raises(IndexError):
        volrig.Binding.from_groups({"head": ([len(pts)], [1.0])}, rig.names, len(pts), fallback=binding)
    with pytest.raises(ValueError, match="non-finite"):
        volrig.Binding.from_groups({"head": ([0], [np.nan])}, rig.names, len(pts), fallback=binding)


def test_vdb_read_back_returns_to_its_grid(tmp_path):
    a = np.zeros((10, 12, 14), np.float32)
    a[3:6, 4:8, 5:9] = np.arange(48, dtype=np.float32).reshape(3, 4, 4) + 1
    v = volrig.Volume(a, (0.5, 1.0, 2.0), (10.0, 20.0, 30.0))
    volrig.write_vdb(tmp_path / "v.vdb", {"density": v})
    back = volrig.load(tmp_path / "v.vdb")
    assert back.array.shape != a.shape  # the file holds the non-zero bounding box only
    placed = back.on_grid(v.origin, v.dims)
    assert placed.origin == v.origin and placed.shape == a.shape
    np.testing.assert_array_equal(placed.array, a)
    # a smaller grid crops, a disjoint one is empty, a fractional shift is refused
    crop = back.on_grid((12.0, 24.0, 36.0), (2, 2, 2))
    np.testing.assert_array_equal(crop.array, a[3:5, 4:6, 4:6])
    assert not back.on_grid((1000.0, 0.0, 0.0), (3, 3, 3)).array.any()
    with pytest.raises(ValueError, match="whole number"):
        back.on_grid((10.25, 20.0, 30.0), v.dims)


def test_walk_cycle_swings_the_legs_in_opposition(rigged):
    from volrig.walk import walk_cycle
    _, _, _, rig, _ = rigged
    axis, angles = walk_cycle(rig, frames=24, period=24)
    np.testing.assert_allclose(axis, [1.0, 0.0, 0.0], atol=0.05)  # the phantom's left is on +x
    assert {"thigh.L", "thigh.R", "shin.L", "shin.R", "upper_arm.L"} <= set(angles)
    left, right = angles["thigh.L"], angles["thigh.R"]
    assert left.shape == (24,)
    np.testing.assert_allclose(left[:12], right[12:], atol=1e-12)  # half a stride apart
    assert np.degrees(np.ptp(left)) == pytest.approx(56.0, abs=1.0)
    assert (np.degrees(angles["shin.L"]) >= -1e-9).all()  # knees bend one way only
    np.testing.assert_allclose(walk_cycle(rig, 24, amplitude=0.0)[1]["thigh.L"], 0.0)


def test_walk_cycle_needs_a_humanoid():
    from volrig.walk import walk_cycle
    chain = volrig.Rig([[0, 0, 0], [0, 0, 1], [0, 0, 2]], [[0, 1], [1, 2]], ["a", "b"])
    with pytest.raises(ValueError, match="humanoid"):
        walk_cycle(chain, 10)

"""Parts of a rig (bone groups), their grids, and exploded views through the Deformer."""
import numpy as np
import pytest

import volrig
from volrig import pipeline


@pytest.fixture(scope="module")
def rigged():
    ph = volrig.phantom.humanoid(scale=0.3)
    mask = ph.volume.like(ph.volume.array > 0)
    pts = volrig.skeletonize(mask).at(0.3)
    r = pipeline.rig_skeleton(pts, mask, bind_mode="rigid")
    return ph.volume, r


def test_humanoid_parts_from_rigify_names(rigged):
    _, r = rigged
    parts = volrig.bone_parts(r.rig.names, r.rig.parents)
    by_name = {p.name: [r.rig.names[b] for b in p.bones] for p in parts}
    assert set(by_name) == {"spine", "head", "left arm", "right arm", "left leg", "right leg"}
    assert by_name["left arm"] == ["shoulder.L", "upper_arm.L", "forearm.L", "hand.L"]
    assert by_name["right leg"] == ["pelvis.R", "thigh.R", "shin.R", "foot.R"]
    assert by_name["head"] == ["neck", "head"]
    assert sorted(b for p in parts for b in p.bones) == list(range(len(r.rig)))
    assert {p.key for p in parts} >= {"left_arm", "right_leg", "spine"}


def test_other_names_make_one_part_per_chain():
    # a root with two chains: a (root) -> b -> c, and a -> d -> e
    parts = volrig.bone_parts(["a", "b", "c", "d", "e"], [-1, 0, 1, 0, 3])
    assert [(p.name, p.bones) for p in parts] == [("a", [0]), ("b", [1, 2]), ("d", [3, 4])]
    # a hand's unsided names: one part per finger chain
    parts = volrig.bone_parts(["palm", "f_index.01", "f_index.02", "thumb.01"], [-1, 0, 1, 0])
    assert [p.name for p in parts] == ["palm", "f_index.01", "thumb.01"]


def test_part_grids_split_values_exactly():
    labels = volrig.Volume(np.array([[[0, 1, 2, 3, 3]]], dtype=np.int16), (2.0, 1.0, 1.0), (10.0, 0.0, 0.0))
    values = labels.like(np.array([[[5.0, 1.0, 2.0, 3.0, 4.0]]], dtype=np.float32))
    parts = [volrig.Part("a", "a", [0, 1]), volrig.Part("b", "b", [2])]
    g = volrig.part_grids(values, labels, parts)
    # each cropped to its part's voxels, placed on the same lattice
    assert g["density_a"].array.tolist() == [[[1, 2]]] and g["density_a"].origin == (12.0, 0.0, 0.0)
    assert g["density_b"].array.tolist() == [[[3, 4]]] and g["density_b"].origin == (16.0, 0.0, 0.0)
    assert g["mask_a"].array.tolist() == [[[1, 1]]] and g["mask_b"].array.tolist() == [[[1, 1]]]
    assert "density_outside" not in g
    outside = volrig.part_grids(values, labels, parts, outside=True)["density_outside"]
    assert outside.array.tolist() == [[[5, 0, 0, 0, 0]]] and outside.origin == values.origin
    with pytest.raises(volrig.VolrigError, match="shape"):
        volrig.part_grids(values.like(values.array[..., :2]), labels, parts)


def test_rest_labels_cover_the_object(rigged):
    vol, r = rigged
    labels = pipeline.rest_labels(vol, r.points, r.binding)
    assert labels.dims == vol.dims
    inside = vol.array > 0
    # the binding's spheres cover the object at rest; nothing outside it is labelled
    assert np.count_nonzero(labels.array[inside]) > 0.97 * np.count_nonzero(inside)
    assert not labels.array[~inside].any()
    # with the object's mask, every object voxel has a bone (the nearest covered voxel's)
    filled = pipeline.rest_labels(vol, r.points, r.binding, vol.like(inside))
    assert filled.array[inside].all() and not filled.array[~inside].any()
    covered = labels.array > 0
    assert np.array_equal(filled.array[covered], labels.array[covered])


def _voxels(frame, bone_count):
    """Each bone's voxels (x, y, z source-lattice indices) in a frame."""
    idx = np.argwhere(frame.bone.array > 0)
    lab = frame.bone.array[tuple(idx.T)] - 1
    world = idx[:, ::-1] + np.array(frame.offset)
    return [world[lab == b] for b in range(bone_count)]


def test_explode_and_reassemble_voxel_for_voxel(rigged):
    vol, r = rigged
    deformer = volrig.Deformer(vol, r.points, r.binding)
    rest = deformer.frame(volrig.rest_pose(len(r.rig)), mode="rigid")
    rest_values, rest_bone, rest_offset = np.array(rest.values.array), np.array(rest.bone.array), rest.offset
    del rest
    apart = deformer.frame(volrig.explode_matrices(r.rig, 1.0), mode="rigid")
    assert apart.bone.dims != tuple(rest_bone.shape[::-1]) or not np.array_equal(apart.bone.array, rest_bone)
    del apart
    back = deformer.frame(volrig.explode_matrices(r.rig, 0.0), mode="rigid")
    assert back.offset == rest_offset
    assert np.array_equal(back.bone.array, rest_bone)
    assert np.array_equal(back.values.array, rest_values)


def test_factor_one_moves_every_part_away_from_its_parent(rigged):
    from scipy.spatial import cKDTree
    vol, r = rigged
    rig = r.rig
    deformer = volrig.Deformer(vol, r.points, r.binding)
    rest = _voxels(deformer.frame(volrig.rest_pose(len(rig)), mode="rigid"), len(rig))
    apart = _voxels(deformer.frame(volrig.explode_matrices(rig, 1.0), mode="rigid"), len(rig))
    heads, tails = rig.heads(), rig.tails()
    children = [b for b in range(len(rig)) if rig.parents[b] >= 0]
    separated = 0
    for b in children:
        p = rig.parents[b]
        own = np.linalg.norm(tails[b] - heads[b])
        away = 0.5 * (heads[b] + tails[b]) - heads[p]
        away /= np.linalg.norm(away)
        # the part's voxels, seen from its parent's, moved along the direction away from the parent by about its
        # length (at least half of it: apart, the voxels at the joint its parent won at rest become its own)
        moved = (apart[b].mean(0) - apart[p].mean(0)) - (rest[b].mean(0) - rest[p].mean(0))
        assert np.dot(moved, away) > 0.5 * own, rig.names[b]
        # touching at rest; apart, a gap between the voxels of the limbs (the torso's thick parts overlap by
        # more than their bones' length: factor 1 moves them apart without a gap yet)
        assert cKDTree(rest[p]).query(rest[b])[0].min() == 1.0
        separated += cKDTree(apart[p]).query(apart[b])[0].min() > 2.0
    assert separated >= 0.6 * len(children)


def test_explode_of_a_pose_starts_from_the_pose(rigged):
    _, r = rigged
    rig = r.rig
    pose = rig.pose({"forearm.L": ((0, 1, 0), 60)})
    assert np.array_equal(volrig.explode_matrices(rig, 0.0, pose), pose)
    m = volrig.explode_matrices(rig, 0.5, pose)
    assert np.allclose(m[:, :3, :3], pose[:, :3, :3])
    hand, forearm = rig.index("hand.L"), rig.index("forearm.L")
    posed_dir = pose[forearm, :3, :3] @ (rig.tails()[forearm] - rig.heads()[forearm])
    moved = (m[hand, :3, 3] - pose[hand, :3, 3]) - (m[forearm, :3, 3] - pose[forearm, :3, 3])
    assert np.dot(moved, posed_dir) > 0
    with pytest.raises(volrig.VolrigError, match="pose"):
        volrig.explode_matrices(rig, 1.0, pose[:3])


def test_write_rest_looks(rigged, tmp_path):
    vol, r = rigged
    parts = volrig.bone_parts(r.rig.names, r.rig.parents)
    path = str(tmp_path / "rest.vdb")
    pipeline.write_rest_looks(path, vol, r.points, r.binding, parts, vol.like(vol.array > 0))
    names = {g["name"]: g["active_voxels"] for g in volrig._volrig.vdb_grids(path)}
    assert set(names) == {"density", "bone", "density_outside"} | {f"{kind}_{p.key}" for p in parts
                                                                    for kind in ("density", "mask")}
    # every object voxel is in one part: the part masks add up to the object, nothing is outside
    assert sum(names[f"mask_{p.key}"] for p in parts) == names["density"] == np.count_nonzero(vol.array)
    assert names["density_outside"] == 0


def _posed(rig):
    """The left elbow bent 70 degrees and the right knee 40: a pose moving parts with more than one bone."""
    return rig.pose({"forearm.L": ([0, 1, 0], 70.0), "shin.R": ([1, 0, 0], 40.0)})


def test_a_part_substituted_by_its_own_source_is_the_rigid_frame(rigged):
    vol, r = rigged
    M = _posed(r.rig)
    frame = volrig.Deformer(vol, r.points, r.binding).frame(M, mode="rigid")
    arm = next(p for p in volrig.bone_parts(r.rig.names, r.rig.parents) if p.name == "left arm")
    g = volrig.parts.substitute_grid(frame.bone, M, arm.bones, vol)
    # on the source's lattice, covering the arm's voxels: there it equals the rigid frame's values, 0 elsewhere
    assert g.spacing == frame.values.spacing
    o = np.rint((np.array(g.origin) - np.array(frame.values.origin)) / np.array(g.spacing)).astype(int)[::-1]
    window = tuple(slice(a, a + n) for a, n in zip(o, g.array.shape))
    labels, values = frame.bone.array[window], frame.values.array[window]
    on_arm = np.isin(labels, np.asarray(arm.bones) + 1)
    assert on_arm.sum() == np.isin(frame.bone.array, np.asarray(arm.bones) + 1).sum() > 100
    np.testing.assert_allclose(g.array[on_arm], values[on_arm], rtol=1e-5, atol=1e-4)
    assert not g.array[~on_arm].any()


def test_a_part_from_a_finer_volume_lies_on_its_lattice(rigged):
    """Detail: the source at half resolution, the arm from the full-resolution volume (co-registered)."""
    vol, r = rigged
    fine = volrig.phantom.humanoid(scale=0.6).volume  # the same phantom on a grid twice as fine ...
    fine = volrig.Volume(fine.array, (0.5, 0.5, 0.5), vol.origin)  # ... in the same world frame
    assert np.allclose(np.array(fine.dims) * fine.spacing, np.array(vol.dims) * vol.spacing, rtol=0.05)
    M = _posed(r.rig)
    frame = volrig.Deformer(vol, r.points, r.binding).frame(M, mode="rigid")
    arm = next(p for p in volrig.bone_parts(r.rig.names, r.rig.parents) if p.name == "left arm")
    g = volrig.parts.substitute_grid(frame.bone, M, arm.bones, fine, sampling="nearest")
    assert g.spacing == fine.spacing
    # every value is the fine volume's nearest sample through one of the arm's bones' matrices
    nz = np.argwhere(g.array > 0)
    assert len(nz) > 8 * 100
    world = np.array(g.origin) + nz[:, ::-1] * np.array(g.spacing)
    got = g.array[tuple(nz.T)]
    match = np.zeros(len(nz), bool)
    for b in arm.bones:
        src = np.linalg.solve(M[b], np.c_[world, np.ones(len(world))].T).T[:, :3]
        ijk = np.rint((src - np.array(fine.origin)) / np.array(fine.spacing)).astype(int)[:, ::-1]
        ok = np.all((ijk >= 0) & (ijk < fine.array.shape), axis=1)
        near = np.zeros(len(nz))
        near[ok] = fine.array[tuple(ijk[ok].T)]
        match |= near == got
    assert match.mean() > 0.98, match.mean()
    # the grid's voxels are 8 per coarse arm voxel, about
    coarse = np.isin(frame.bone.array, np.asarray(arm.bones) + 1).sum()
    assert 5 * coarse < len(nz) < 11 * coarse


def test_folder_bake_writes_substituted_parts(rigged, tmp_path):
    vol, r = rigged
    parts = volrig.bone_parts(r.rig.names, r.rig.parents)
    doubled = vol.like(vol.array.astype(np.float32) * 2)
    with pytest.raises(volrig.VolrigError, match="no such part"):
        pipeline.FolderBake(vol, r.points, r.binding, str(tmp_path), "f", parts=parts, substitutes={"tail": doubled})
    bake = pipeline.FolderBake(vol, r.points, r.binding, str(tmp_path), "f", mode="rigid", parts=parts,
                               substitutes={"left_arm": doubled})
    M = _posed(r.rig)
    bake.bake(1, M)
    bake.finish()
    arm = volrig.load(bake.path(1), grid="density_left_arm")
    leg = volrig.load(bake.path(1), grid="density_right_leg")
    frame = volrig.Deformer(vol, r.points, r.binding).frame(M, mode="rigid")
    g = volrig.part_grids(frame.values, frame.bone, parts)
    assert arm.array.max() == pytest.approx(2 * g["density_left_arm"].array.max(), rel=1e-3)
    np.testing.assert_allclose(leg.array, g["density_right_leg"].array, rtol=1e-3)  # (half floats)
    rest = str(tmp_path / "rest.vdb")
    pipeline.write_rest_looks(rest, vol, r.points, r.binding, parts, vol.like(vol.array > 0),
                              substitutes={"left_arm": doubled})
    assert volrig.load(rest, grid="density_left_arm").array.max() == pytest.approx(2 * vol.array.max())

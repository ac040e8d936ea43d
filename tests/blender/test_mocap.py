"""Motion capture in Blender: "Drive with BVH" keys the phantom's armature with CMU 131's walk, the evaluated pose
equals volrig.animate's headless matrices, the bone map is kept on the Volume object and edits are used, and a
driven frame bakes."""
import os

import numpy as np
import pytest

import bpy
import volrig
from conftest import run_op
from volrig_support import data_root

WALK = str(data_root() / "bvh" / "131_01.bvh")


@pytest.fixture
def walk():
    if not os.path.exists(WALK):
        pytest.skip(f"real data not available: {WALK} (the ../shared/data folder sits beside the checkout)")
    return volrig.read_bvh(WALK)


def _members(vol):
    from volrig_addon.objects import members
    return members(vol)


def _evaluated_matrices(rig_obj, names):
    """Rest-to-pose matrices of the evaluated armature at the current frame (as the bake computes them)."""
    arm = rig_obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    return np.array([np.array(arm.pose.bones[n].matrix @ arm.pose.bones[n].bone.matrix_local.inverted())
                     for n in names])


def test_drive_with_bvh_matches_headless_animate_and_bakes(rigged, walk):
    from volrig_addon import bake
    from volrig_addon.objects import armature_rig
    vol = rigged
    rig_obj = _members(vol)["RIG"]
    rig = armature_rig(rig_obj)
    assert "thigh.L" in rig.names
    scene = bpy.context.scene
    run_op(bpy.ops.volrig.drive_with_bvh, filepath=WALK, first=1, last=61, step=5, frame_start=10,
           root_motion="travel")
    assert (scene.frame_start, scene.frame_end) == (10, 22)  # BVH frames 1, 6, ..., 61
    assert scene.render.fps == 24 and scene.render.fps / scene.render.fps_base == pytest.approx(walk.fps / 5, rel=1e-6)
    # the bone map is on the Volume object, one line per BVH joint, the automatic map's bones
    pairs = {p.joint: p.bone for p in vol.volrig.bone_map}
    assert sorted(pairs) == sorted(walk.names)
    auto = volrig.default_bone_map(walk, rig)
    assert {j: b for j, b in pairs.items() if b} == auto
    assert vol.volrig.bvh_file == WALK
    # the panel lists the map, each line a joint and a bone search over the armature's bones
    from test_addon import _Layout
    from volrig_addon import mocap
    drawn = []
    mocap.VOLRIG_PT_mocap.draw(type("PanelStub", (), {"layout": _Layout(drawn)})(), bpy.context)
    assert "bone_map" in drawn and f"Bone map: {len(auto)} of {len(walk.names)} joints drive a bone" in drawn
    line = []
    mocap.VOLRIG_UL_bone_map.draw_item(None, bpy.context, _Layout(line), vol.volrig, vol.volrig.bone_map[0], 0,
                                        None, "")
    assert line == [walk.names[0], "bone"]

    size = float(np.ptp(rig.joints, axis=0).max())
    frames = np.arange(0, 61, 5)
    expected = volrig.animate(rig, walk, frames=frames, bone_map=auto, root_motion="travel")
    moved = 0.0
    for k in (0, 3, 7, 12):
        scene.frame_set(10 + k)
        got = _evaluated_matrices(rig_obj, rig.names)
        np.testing.assert_allclose(got[:, :3, :3], expected[k, :, :3, :3], atol=1e-5)
        np.testing.assert_allclose(got[:, :3, 3] / size, expected[k, :, :3, 3] / size, atol=1e-5)
        moved = max(moved, float(np.abs(expected[k] - np.eye(4)).max()))
    assert moved > 0.1  # the walk does move the bones

    # an edited map is used by the next drive: without the left thigh mapped, it follows its parent
    thigh_joint = next(j for j, b in auto.items() if b == "thigh.L")
    next(p for p in vol.volrig.bone_map if p.joint == thigh_joint).bone = ""
    run_op(bpy.ops.volrig.drive_with_bvh, filepath=WALK, first=31, last=31, frame_start=1)
    assert (scene.frame_start, scene.frame_end) == (1, 1)
    edited = {j: b for j, b in auto.items() if j != thigh_joint}
    scene.frame_set(1)
    got = _evaluated_matrices(rig_obj, rig.names)
    want = volrig.animate(rig, walk, frames=[30], bone_map=edited)[0]
    np.testing.assert_allclose(got[:, :3, :3], want[:, :3, :3], atol=1e-5)
    np.testing.assert_allclose(got[:, :3, 3] / size, want[:, :3, 3] / size, atol=1e-5)
    parent = rig.parents[rig.index("thigh.L")]
    np.testing.assert_allclose(got[rig.index("thigh.L"), :3, :3], got[parent, :3, :3], atol=1e-5)
    # "Map by Names" restores the automatic map
    run_op(bpy.ops.volrig.reset_bone_map)
    assert {p.joint: p.bone for p in vol.volrig.bone_map if p.bone} == auto

    # the usual bake follows the keys: frame 1 (BVH frame 31) is the headless Deformer's frame of animate's matrices
    run_op(bpy.ops.volrig.drive_with_bvh, filepath=WALK, first=31, last=31, frame_start=1)
    vol.volrig.bake_frames = "1"
    run_op(bpy.ops.volrig.bake)
    path = bake.frame_path(vol, 1)
    baked = volrig.load(path, grid="bone")
    from volrig_addon import scans
    saved = volrig.load_rig(scans.rig_path(vol))
    deformer = volrig.Deformer(scans.source(vol), saved.points, saved.binding)
    rest = deformer.frame(volrig.rest_pose(len(saved.rig)), mode="linear").bone.array
    headless = deformer.frame(volrig.animate(rig, walk, frames=[30])[0], mode="linear").bone.array
    count, rest_count = int(np.count_nonzero(baked.array)), int(np.count_nonzero(rest))
    # Blender's single-precision pose (its matrices agree to 1e-5 above) flips only voxels on a tie: between two
    # bones' spheres or at a sphere's edge (0.13% of them with autorig's rig of the phantom at TP 0.5)
    assert baked.array.shape == headless.shape
    assert np.count_nonzero(baked.array != headless) <= 2e-3 * count
    # the hips swing the pelvis bones out of the spheres they overlap at rest: a few % more voxels
    assert abs(count - rest_count) <= 0.05 * rest_count, (count, rest_count)
    assert baked.array.shape != rest.shape or not np.array_equal(baked.array, rest)


def test_drive_with_bvh_reports_errors(rigged, walk, tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_text(open(WALK).read().replace("Frame Time:", "Frame Tim:", 1))
    with pytest.raises(RuntimeError, match="bad.bvh: line"):
        bpy.ops.volrig.drive_with_bvh(filepath=str(bad))
    with pytest.raises(RuntimeError, match="missing.bvh: no such file"):
        bpy.ops.volrig.drive_with_bvh(filepath=str(tmp_path / "missing.bvh"))
    with pytest.raises(RuntimeError, match="has frames 1-994; asked for 5-3"):
        bpy.ops.volrig.drive_with_bvh(filepath=WALK, first=5, last=3)
    # a map naming a bone the armature lacks: the error names it, the map stays for the user to fix
    run_op(bpy.ops.volrig.drive_with_bvh, filepath=WALK, first=1, last=1)
    rigged.volrig.bone_map[0].bone = "no_such_bone"
    with pytest.raises(RuntimeError, match="no_such_bone"):
        bpy.ops.volrig.drive_with_bvh(filepath=WALK, first=1, last=1)
    assert rigged.volrig.bone_map[0].bone == "no_such_bone"

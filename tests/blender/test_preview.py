"""Live preview while scrubbing (issue 21): unbaked frames show a coarse reconstruction of the pose, baked ones
their bake."""
import os

import numpy as np

import bpy
import volrig
from conftest import run_op
from test_bake import _members, posed  # noqa: F401  (the fixture: the phantom rigged, forearm.L keyed 1..3)


def test_unbaked_frames_preview_the_pose_and_baked_frames_show_the_bake(posed):  # noqa: F811
    from volrig_addon import bake, preview, scans
    vol, scene = posed, bpy.context.scene
    scene.frame_set(1)
    shown = _members(vol).get("PREVIEW")
    assert shown is not None and not shown.hide_get() and shown.hide_render and vol.hide_get()
    path = preview.preview_path(vol)
    source = scans.source(vol)
    f = preview.factor_for(source.dims)
    at_rest = volrig.load(path, grid="bone")
    assert np.allclose(at_rest.spacing, np.array(source.spacing) * f)
    forearm = bake.RigState(vol).names.index("forearm.L") + 1
    scene.frame_set(3)  # the forearm keyed 1.2 rad away: its preview voxels moved
    bent = volrig.load(path, grid="bone")
    def centre(v):
        z, y, x = np.nonzero(np.asarray(v.array) == forearm)
        return np.array(v.origin) + np.array(v.spacing) * np.stack([x, y, z], 1).mean(0)
    assert np.linalg.norm(centre(bent) - centre(at_rest)) > 5 * source.spacing[0]
    # the preview's object is where the full reconstruction would be (Dice of the forearm's voxels' centres)
    run_op(bpy.ops.volrig.bake)  # frames 1..3
    for frame in (1, 2, 3):
        assert os.path.exists(bake.frame_path(vol, frame))
    scene.frame_set(2)
    assert _members(vol)["PREVIEW"].hide_get() and not vol.hide_get()
    os.remove(bake.frame_path(vol, 3))  # frame 3 unbaked again: previewed
    scene.frame_set(3)
    assert not _members(vol)["PREVIEW"].hide_get() and vol.hide_get()
    scene.volrig_live_preview = False
    scene.frame_set(1)
    scene.frame_set(3)
    assert _members(vol)["PREVIEW"].hide_get() and not vol.hide_get()

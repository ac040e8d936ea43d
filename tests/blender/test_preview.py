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
    vol.select_set(True)
    scene.frame_set(1)
    path = preview.preview_path(vol)
    assert preview.showing_preview(vol) and not vol.hide_get() and vol.select_get()  # never hidden or deselected
    source = scans.source(vol)
    f = preview.factor_for(source.dims)
    at_rest = volrig.load(path, grid="bone")
    assert np.allclose(at_rest.spacing, np.array(source.spacing) * f)
    forearm = bake.RigState(vol).names.index("forearm.L") + 1
    scene.frame_set(3)  # the forearm keyed 1.2 rad away: its preview voxels moved

    def centre(v):
        z, y, x = np.nonzero(np.asarray(v.array) == forearm)
        return np.array(v.origin) + np.array(v.spacing) * np.stack([x, y, z], 1).mean(0)
    assert np.linalg.norm(centre(volrig.load(path, grid="bone")) - centre(at_rest)) > 5 * source.spacing[0]
    bent = centre(volrig.load(path, grid="bone"))
    vol.volrig.explode = 1.0  # the preview takes the pose apart as the bake would
    scene.frame_set(3)
    assert np.linalg.norm(centre(volrig.load(path, grid="bone")) - bent) > 5 * source.spacing[0]
    vol.volrig.explode = 0.0
    scene.frame_set(3)
    run_op(bpy.ops.volrig.bake)  # frames 1..3: the object plays them
    for frame in (1, 2, 3):
        assert os.path.exists(bake.frame_path(vol, frame))
    scene.frame_set(2)
    assert vol.data.is_sequence and not preview.showing_preview(vol)
    os.remove(bake.frame_path(vol, 3))  # frame 3 unbaked again: previewed
    scene.frame_set(3)
    assert preview.showing_preview(vol)
    scene.frame_set(2)  # baked: the sequence again
    assert vol.data.is_sequence and bpy.path.abspath(vol.data.filepath) == bake.frame_path(vol, 1)
    scene.volrig_live_preview = False
    scene.frame_set(3)
    assert vol.data.is_sequence and not preview.showing_preview(vol)
    scene.volrig_live_preview = True
    scene.frame_set(3)
    preview._render_started(scene)  # a render starting: the bake state back, no preview during it
    try:
        assert vol.data.is_sequence
        scene.frame_set(3)
        assert not preview.showing_preview(vol)
    finally:
        preview._render_ended()


def test_the_preview_follows_weight_changes_without_reading_weights_each_frame(posed):  # noqa: F811
    from volrig_addon import bake, objects, preview, scans
    vol, scene = posed, bpy.context.scene
    scene.frame_set(3)
    first = scans._entry(vol)["preview"][1]
    scene.frame_set(2)
    assert scans._entry(vol)["preview"][1] is first  # nothing changed: the same coarse rig
    forearm = bake.RigState(vol).names.index("forearm.L") + 1
    assert (volrig.load(preview.preview_path(vol), grid="bone").array == forearm).any()
    # "weight painting": every forearm sphere given to the upper arm (a geometry edit of the sphere mesh)
    spheres = _members(vol)["SPHERES"]
    fore, upper = spheres.vertex_groups["forearm.L"], spheres.vertex_groups["upper_arm.L"]
    moved = [v.index for v in spheres.data.vertices if any(g.group == fore.index and g.weight > 0 for g in v.groups)]
    assert moved
    fore.remove(moved)
    upper.add(moved, 1.0, "REPLACE")
    bpy.context.view_layer.update()  # the depsgraph reports the mesh's edit
    scene.frame_set(3)
    assert scans._entry(vol)["preview"][1] is not first  # rebuilt for the new weights
    assert not (volrig.load(preview.preview_path(vol), grid="bone").array == forearm).any()

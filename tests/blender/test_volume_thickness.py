"""Thickness editing on a rigged volume (issue 23): a pose bone's ``volrig_thickness`` (keyframable) thickens that
bone's part of the baked frames."""
import numpy as np

import bpy
import volrig
from test_bake import _members, posed  # noqa: F401  (the fixture: the phantom rigged, forearm.L keyed 1..3)


def test_keyed_thickness_thickens_the_baked_frames(posed):  # noqa: F811
    from volrig_addon import bake
    vol, scene = posed, bpy.context.scene
    pb = _members(vol)["RIG"].pose.bones["thigh.L"]
    pb[bake.THICKNESS] = 1.0
    pb.keyframe_insert(f'["{bake.THICKNESS}"]', frame=1)
    pb[bake.THICKNESS] = 1.6
    pb.keyframe_insert(f'["{bake.THICKNESS}"]', frame=3)
    baker = bake.Baker(vol, "linear")
    for frame in (1, 3):
        assert baker.bake_frame(scene, frame)
    baker.finish()
    thigh = baker.names.index("thigh.L") + 1
    counts = [np.count_nonzero(np.asarray(volrig.load(bake.frame_path(vol, f), grid="bone").array) == thigh)
              for f in (1, 3)]
    assert counts[1] > 1.5 * counts[0]  # a radius 1.6 times as large: about 2.5 times the voxels
    # the thickness is part of the pose: unchanged frames stay baked, a new factor re-bakes
    baker = bake.Baker(vol, "linear")
    assert [baker.bake_frame(scene, f) for f in (1, 3)] == [False, False]
    scene.frame_set(3)
    pb[bake.THICKNESS] = 1.3
    pb.keyframe_insert(f'["{bake.THICKNESS}"]', frame=3)
    assert baker.bake_frame(scene, 3)
    baker.finish()


def test_thickness_per_bone_gives_every_bone_the_property(posed):  # noqa: F811
    from conftest import run_op
    from volrig_addon import objects
    vol = posed
    bpy.context.view_layer.objects.active = vol
    run_op(bpy.ops.volrig.thickness)
    rig = _members(vol)["RIG"]
    assert all(pb[objects.THICKNESS] == 1.0 for pb in rig.pose.bones)
    assert rig.pose.bones[0].id_properties_ui(objects.THICKNESS).as_dict()["max"] == 4.0

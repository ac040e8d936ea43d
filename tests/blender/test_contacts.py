"""Find Contacts in the add-on (issue 19): self-contact of the rigged phantom over keyed poses, and two rigged
volumes, as timeline markers named with the bones."""
import pytest
from conftest import PHANTOM_SCALE, run_op  # noqa: F401  (the phantom the fixtures build)

bpy = pytest.importorskip("bpy")

from mathutils import Euler  # noqa: E402


def _markers(scene):
    return {m.frame: m.name for m in scene.timeline_markers if m.name.startswith("contact: ")}


def _rig_obj(vol):
    from volrig_addon.objects import members
    return members(vol)["RIG"]


def test_self_contact_markers_name_the_bones(rigged):
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 5
    pb = _rig_obj(rigged).pose.bones["upper_arm.R"]
    pb.rotation_mode = "XYZ"
    for frame, euler in [(1, (0, 0, 0)), (2, (1.0, 0, 0)), (3, (-1.0, 0, 0)), (4, (0, 0, 1.0)), (5, (0, 0, -1.0))]:
        pb.rotation_euler = Euler(euler)
        pb.keyframe_insert("rotation_euler", frame=frame)
    fc = _rig_obj(rigged).animation_data.action.fcurves
    for curve in fc:
        for k in curve.keyframe_points:
            k.interpolation = "CONSTANT"
    scene.frame_set(3)
    bpy.context.view_layer.objects.active = rigged
    run_op(bpy.ops.volrig.find_contacts)
    assert scene.frame_current == 3  # put back
    marks = _markers(scene)
    assert 1 not in marks  # the rest pose touches nothing
    assert marks and all("arm.R" in name or "hand.R" in name for name in marks.values()), marks
    # a second run replaces the markers instead of piling them up
    run_op(bpy.ops.volrig.find_contacts)
    assert _markers(scene) == marks


def test_two_volumes_touch_where_they_overlap(rigged, phantom_file):
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 3
    path, _ = phantom_file
    run_op(bpy.ops.volrig.import_volume, filepath=path, unit="MM")
    other = bpy.context.active_object
    other.volrig.low = 1.0
    run_op(bpy.ops.volrig.skeletonize)
    other.volrig.thinness = 0.3
    run_op(bpy.ops.volrig.rig)
    arm = _rig_obj(other)
    for frame, x in [(1, 0.0), (3, 1.0)]:  # the second phantom walks away (1 m) from the first
        arm.location = (x, 0.0, 0.0)
        arm.keyframe_insert("location", frame=frame)
    for o in bpy.context.selected_objects:
        o.select_set(False)
    other.select_set(True)
    rigged.select_set(True)
    bpy.context.view_layer.objects.active = rigged
    run_op(bpy.ops.volrig.find_contacts)
    marks = _markers(scene)
    assert list(marks) == [1], marks  # one contact, in frame 1 only (at frame 2 they are half a metre apart)
    # two whole phantoms overlap: many pairs, so the sorted bone list is cut ("…") before thigh.L (Contact.name)
    assert "pairs)" in marks[1] and len(marks[1]) <= 63 and ("thigh.L" in marks[1] or "…" in marks[1])
    # scaled differently: a clear error, no markers touched
    arm.scale = (2.0, 2.0, 2.0)
    with pytest.raises(RuntimeError, match="scaled differently"):
        bpy.ops.volrig.find_contacts()
    assert _markers(scene) == marks

"""Find Contacts in the add-on (issue 19): self-contact of the rigged phantom over keyed poses, and two rigged
volumes, as timeline markers named with the bones."""
import pytest
from conftest import import_and_rig, run_op

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
    from volrig_addon import compat
    fc = compat.fcurves(_rig_obj(rigged), create=False)
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


def test_two_volumes_touch_where_they_overlap(rigged, phantom_file, capfd):
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 3
    other = import_and_rig(phantom_file[0])
    arm = _rig_obj(other)
    for frame, x in [(1, 0.0), (3, 1.0)]:  # the second phantom walks away (1 m) from the first
        arm.location = (x, 0.0, 0.0)
        arm.keyframe_insert("location", frame=frame)
    for o in bpy.context.selected_objects:
        o.select_set(False)
    other.select_set(True)
    rigged.select_set(True)
    bpy.context.view_layer.objects.active = rigged
    capfd.readouterr()
    run_op(bpy.ops.volrig.find_contacts)
    report = capfd.readouterr().out
    marks = _markers(scene)
    assert list(marks) == [1], marks  # one contact, in frame 1 only (at frame 2 they are half a metre apart)
    assert marks[1].endswith("pairs)") and len(marks[1]) <= 63  # every bone touches its twin: many pairs
    assert "1 contact(s) of phantom and phantom.001 over frames 1-3: 1-1 " in report, report  # ends at frame 1
    # scaled differently: a clear error, no markers touched
    arm.scale = (2.0, 2.0, 2.0)
    with pytest.raises(RuntimeError, match="scaled differently"):
        bpy.ops.volrig.find_contacts()
    assert _markers(scene) == marks

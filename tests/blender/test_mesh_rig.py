"""Rig Mesh (issue 23): a Blender mesh rigged and skinned through its volume; Blender's Armature modifier with the
volrig weights moves the vertices exactly as volrig's own skinning (linear blend; dual quaternions for Preserve
Volume); thickness shape keys driven by the pose bones' volrig_thickness; bad meshes reported."""
import math

import numpy as np
import pytest

from conftest import run_op
from volrig_support import data_root

bpy = pytest.importorskip("bpy")

SHARED_DATA = data_root()
KNIGHT = SHARED_DATA / "meshes" / "decimated-knight.off"
RIGIFY = ["hips", "spine", "chest", "neck", "head"] + [f"{b}.{s}" for s in "LR" for b in (
    "shoulder", "upper_arm", "forearm", "hand", "pelvis", "thigh", "shin", "foot")]


def mesh_object(name, vertices, faces):
    from volrig_addon import mesh_rig
    return mesh_rig.new_mesh_object(bpy.context, name, vertices, faces)


def knight():
    """The shared knight as a Blender mesh, its +Y up turned to Blender's +Z (x, y, z) -> (x, -z, y)."""
    if not KNIGHT.exists():
        pytest.skip(f"real data not available: {KNIGHT} (the ../shared/data folder sits beside the checkout)")
    import volrig
    v, f = volrig.read_mesh(str(KNIGHT))
    v = np.asarray(v, float)
    return mesh_object("knight", np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1), f)


def bar(name="bar", cuts=8):
    """A bar 4 x 0.5 x 0.5 along x, subdivided (no data needed), placed off the origin, turned and scaled."""
    import bmesh
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    bmesh.ops.scale(bm, vec=(4.0, 0.5, 0.5), verts=bm.verts)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=cuts, use_grid_fill=True)
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
    me = bpy.data.meshes.new(name)
    bm.to_mesh(me)
    bm.free()
    obj = mesh_object(name, [], [])
    obj.data = me
    obj.location = (1.0, 2.0, 0.5)
    obj.rotation_euler = (0.0, 0.0, 0.3)
    obj.scale = (1.5, 1.5, 1.5)
    bpy.context.view_layer.update()
    return obj


def group_weights(obj, names):
    """(V, B) the weights the vertex groups hold (B in ``names`` order); checks nothing else is there."""
    col = {obj.vertex_groups[n].index: b for b, n in enumerate(names)}
    out = np.zeros((len(obj.data.vertices), len(names)))
    for v in obj.data.vertices:
        for g in v.groups:
            out[v.index, col[g.group]] = g.weight
    return out


def evaluated(obj):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    depsgraph.update()
    ev = obj.evaluated_get(depsgraph)
    co = np.empty(3 * len(ev.data.vertices), dtype=np.float32)
    ev.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def pose_matrices(arm, names):
    """(B, 4, 4) rest-to-pose matrices in the armature's frame (= the mesh's local frame after Rig Mesh)."""
    bpy.context.view_layer.update()
    return np.array([np.array(arm.pose.bones[n].matrix @ arm.data.bones[n].matrix_local.inverted()) for n in names])


def expected_rig(obj, **kw):
    """What volrig.rig_mesh makes of the object's own vertices and triangles (up: the scene's +Z)."""
    import volrig
    from volrig_addon import mesh_rig, objects
    v, f = mesh_rig._mesh_arrays(obj.data)
    return volrig.rig_mesh(v, f, up=objects.scene_up(obj), **kw)


def check_rigged(obj, mr):
    from volrig_addon import mesh_rig
    arm = bpy.context.active_object
    assert arm.type == "ARMATURE" and mesh_rig.armature_of(obj) == arm and mesh_rig.rigged_mesh(arm) == obj
    assert sorted(b.name for b in arm.data.bones) == sorted(mr.rig.names)  # (Blender orders them by hierarchy)
    assert obj.parent == arm and obj.modifiers[0].name == "volrig" and obj.modifiers[0].type == "ARMATURE"
    w = group_weights(obj, mr.rig.names)
    assert np.abs(w - mr.weights.toarray()).max() <= 1e-6  # the very float32 weights
    assert np.allclose(w.sum(axis=1), 1.0, atol=1e-5) and ((w > 0).sum(axis=1) <= 4).all()
    return arm


def check_pose(obj, arm, mr, height, bone, degrees):
    """Bends ``bone`` in pose mode; Blender's deformation equals MeshRig.pose (linear; Preserve Volume: dual
    quaternions). Returns the largest differences (linear, dual quaternion) relative to ``height``."""
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode="POSE")
    pb = arm.pose.bones[bone]
    pb.rotation_mode = "XYZ"
    pb.rotation_euler = (math.radians(degrees), 0.0, 0.0)
    M = pose_matrices(arm, mr.rig.names)
    linear = np.abs(evaluated(obj) - mr.pose(M)).max() / height
    moved = np.abs(mr.pose(M) - mr.vertices).max() / height
    assert moved > 0.05  # the bone did move a part of the mesh
    obj.modifiers["volrig"].use_deform_preserve_volume = True
    dq = np.abs(evaluated(obj) - mr.pose(M, "dual_quaternion")).max() / height
    obj.modifiers["volrig"].use_deform_preserve_volume = False
    pb.rotation_euler = (0.0, 0.0, 0.0)
    bpy.ops.object.mode_set(mode="OBJECT")
    print(f"\n{obj.name}: {bone} {degrees} degrees: Blender vs volrig {linear:.2e} (linear), {dq:.2e} (dual "
          "quaternion) of the height")
    return linear, dq


def check_thickness(obj, arm, mr, bone):
    from volrig.skin import thickness_offsets
    key = obj.data.shape_keys.key_blocks["thickness." + bone]
    assert key.slider_min == -1.0 and key.slider_max == 3.0
    pb = arm.pose.bones[bone]
    assert pb["volrig_thickness"] == 1.0
    rest = evaluated(obj)
    assert np.allclose(rest, mr.vertices, atol=1e-5)
    for factor in (2.0, 0.5):
        pb["volrig_thickness"] = factor
        arm.update_tag()
        got = evaluated(obj)
        want = mr.vertices + thickness_offsets(mr.rig, mr.weights, mr.vertices, {bone: factor})
        assert abs(key.value - (factor - 1)) < 1e-6
        assert np.abs(got - want).max() <= 1e-5 * np.ptp(mr.vertices, axis=0).max()
        assert np.abs(got - rest).max() > 1e-3 * np.ptp(mr.vertices, axis=0).max()
    pb["volrig_thickness"] = 1.0
    arm.update_tag()


def test_rig_mesh_knight(empty_scene):
    obj = knight()
    world = obj.matrix_world.copy()
    run_op(bpy.ops.volrig.rig_mesh)
    mr = expected_rig(obj)
    arm = check_rigged(obj, mr)
    assert obj["volrig_rig_found"].startswith("humanoid")
    assert set(RIGIFY) <= set(mr.rig.names)
    assert np.allclose(np.array(obj.matrix_world), np.array(world))
    heads = {b.name: b.head_local for b in arm.data.bones}
    assert heads["head"].z > heads["hips"].z > heads["foot.L"].z
    height = float(np.ptp(mr.vertices[:, 2]))
    linear, dq = check_pose(obj, arm, mr, height, "forearm.L", 90.0)
    assert linear <= 1e-4
    assert dq <= 1e-4
    check_thickness(obj, arm, mr, "upper_arm.L")


def test_rig_mesh_bar(empty_scene):
    obj = bar()
    world = obj.matrix_world.copy()
    run_op(bpy.ops.volrig.rig_mesh, body_plan="chains", voxels=80)
    mr = expected_rig(obj, voxels=80, kind="chains")
    arm = check_rigged(obj, mr)
    assert len(mr.rig.names) >= 2
    assert np.allclose(np.array(obj.matrix_world), np.array(world), atol=1e-6)
    assert np.allclose(np.array(arm.matrix_world), np.array(world), atol=1e-6)
    height = float(np.ptp(mr.vertices, axis=0).max())
    last = mr.rig.names[-1]
    linear, dq = check_pose(obj, arm, mr, height, last, 60.0)
    assert linear <= 1e-4 and dq <= 1e-4
    check_thickness(obj, arm, mr, mr.rig.names[0])
    # again: the earlier rig is replaced (one armature, one modifier, the same groups)
    bpy.context.view_layer.objects.active = obj
    run_op(bpy.ops.volrig.rig_mesh, body_plan="chains", voxels=80, thickness_keys="OFF")
    assert [o.type for o in bpy.data.objects].count("ARMATURE") == 1
    assert [m.type for m in obj.modifiers] == ["ARMATURE"]
    assert obj.data.shape_keys is None or not any(k.name.startswith("thickness.") for k in
                                                  obj.data.shape_keys.key_blocks)
    check_rigged(obj, mr)


def test_rig_mesh_under_a_subdivision(empty_scene):
    """The subdivided surface is voxelized, the original vertices skinned; the Armature modifier comes first."""
    import volrig
    from volrig_addon import mesh_rig, objects
    obj = bar(cuts=3)
    sub = obj.modifiers.new("Subdivision", "SUBSURF")
    sub.levels = 1
    run_op(bpy.ops.volrig.rig_mesh, body_plan="chains", voxels=80)
    assert [m.type for m in obj.modifiers] == ["ARMATURE", "SUBSURF"]
    sub.show_viewport = False
    arm = mesh_rig.armature_of(obj)
    sub.show_viewport = True
    names = [b.name for b in arm.data.bones]
    w = group_weights(obj, names)
    assert w.shape[0] == len(obj.data.vertices) and np.allclose(w.sum(axis=1), 1.0, atol=1e-5)
    mod = obj.modifiers["volrig"]
    mod.show_viewport = False
    v, f = mesh_rig.evaluated_triangles(bpy.context, obj)
    mod.show_viewport = True
    assert len(v) > len(obj.data.vertices)
    mr = volrig.rig_mesh(v, f, kind="chains", voxels=80, up=objects.scene_up(obj),
                         skin_points=mesh_rig.vertex_positions(obj))
    assert np.abs(w - mr.weights.toarray()).max() <= 1e-6


def test_rig_mesh_reports_meshes_without_volume(empty_scene):
    import bmesh
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=4, y_segments=4, size=1.0)
    me = bpy.data.meshes.new("plane")
    bm.to_mesh(me)
    mesh_object("plane", [], []).data = me
    with pytest.raises(RuntimeError, match="encloses no"):
        bpy.ops.volrig.rig_mesh()
    mesh_object("points", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [])
    with pytest.raises(RuntimeError, match="no faces"):
        bpy.ops.volrig.rig_mesh()
    from volrig_addon import objects
    group, _, out = objects._geometry_group("a cube")  # a surface made by geometry nodes only
    group.links.new(group.nodes.new("GeometryNodeMeshCube").outputs["Mesh"], out.inputs[0])
    made = mesh_object("made", [], [])
    made.modifiers.new("cube", "NODES").node_group = group
    with pytest.raises(RuntimeError, match="no vertices of its own"):
        bpy.ops.volrig.rig_mesh()
    assert not any(o.type == "ARMATURE" for o in bpy.data.objects)


def test_thickness_keys_operator_follows_painted_weights(empty_scene):
    """Thickness Keys remakes the keys from the armature and the vertex groups as they are now."""
    from volrig.skin import thickness_offsets
    from volrig_addon import mesh_rig, objects
    obj = bar(cuts=4)
    run_op(bpy.ops.volrig.rig_mesh, body_plan="chains", voxels=60, thickness_keys="OFF")
    arm = bpy.context.active_object
    assert obj.data.shape_keys is None
    names = [b.name for b in arm.data.bones]
    obj.vertex_groups[names[0]].add([0, 1, 2], 0.25, "REPLACE")  # painted
    run_op(bpy.ops.volrig.thickness_keys)
    keys = [k.name for k in obj.data.shape_keys.key_blocks]
    assert keys[0] == "Basis" and set(keys[1:]) == {"thickness." + n for n in names}
    w = mesh_rig.read_weights(obj, names)
    v = mesh_rig.vertex_positions(obj)
    arm.pose.bones[names[0]]["volrig_thickness"] = 3.0
    arm.update_tag()
    want = v + thickness_offsets(objects.armature_rig(arm), w, v, {0: 3.0})
    assert np.abs(evaluated(obj) - want).max() <= 1e-5 * np.ptp(v, axis=0).max()


def test_undo_removes_the_rig(empty_scene):
    """Rig Mesh is one undo step. Blender's undo needs a window, so this runs only in Blender with its UI, e.g.
    under Xvfb: DISPLAY=:97 blender --factory-startup --python-exit-code 1 --python tests/blender/run.py -- -k undo
    (skipped in background mode)."""
    wm = bpy.context.window_manager
    if bpy.app.background or not wm.windows:  # (in background, undo_push with a window override crashes Blender)
        pytest.skip("undo needs Blender with a window (background mode has none): run under Xvfb, see the docstring")
    win = wm.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    with bpy.context.temp_override(window=win, screen=win.screen, area=area,
                                   region=next(r for r in area.regions if r.type == "WINDOW")):
        obj = bar(cuts=3)
        bpy.ops.ed.undo_push(message="bar")
        # as from the UI: an undo step pushed (bpy.ops' positional undo flag)
        assert bpy.ops.volrig.rig_mesh("EXEC_DEFAULT", True, body_plan="chains", voxels=60) == {"FINISHED"}
        assert any(o.type == "ARMATURE" for o in bpy.data.objects)
        assert bpy.data.objects["bar"].vertex_groups
        bpy.ops.ed.undo()
    assert not any(o.type == "ARMATURE" for o in bpy.data.objects)
    obj = bpy.data.objects["bar"]
    assert not obj.modifiers and not obj.vertex_groups and obj.parent is None and obj.data.shape_keys is None


def test_markers_on_a_mesh_place_its_joints(empty_scene):
    """The Mesh panel's Markers: markers parented to the mesh (a click's ray: half-way between where it enters
    and leaves the surface) go to rig_mesh; the marked joint sits on its marker."""
    from mathutils import Vector
    from volrig_addon import markers
    obj = knight()
    bpy.context.view_layer.objects.active = obj
    # a ray from the front (-Y) through the knight's middle: the marker lies inside, between its two surfaces
    box = np.array([tuple(c) for c in obj.bound_box])
    centre = box.mean(0)
    p = markers.mesh_ray_marker(obj, (centre[0], box[:, 1].min() - 1.0, centre[2]), (0.0, 1.0, 0.0))
    assert p is not None and box[:, 1].min() < p[1] < box[:, 1].max()
    assert markers.mesh_ray_marker(obj, (centre[0], box[:, 1].min() - 1.0, centre[2]), (0.0, -1.0, 0.0)) is None
    run_op(bpy.ops.volrig.rig_mesh)
    knee = {b.name: b.head_local for b in obj.parent.data.bones}["shin.L"]
    target = Vector(knee) + Vector((0.0, 0.0, 0.05 * float(np.ptp(box[:, 2]))))  # the knee 5% higher
    obj.volrig.marker_name = "knee.L"
    run_op(bpy.ops.volrig.place_marker, location=tuple(obj.matrix_world @ target))
    assert set(markers.markers_of(obj)) == {"knee.L"}
    bpy.context.view_layer.objects.active = obj
    run_op(bpy.ops.volrig.rig_mesh)
    moved = {b.name: b.head_local for b in obj.parent.data.bones}["shin.L"]
    assert (moved - target).length < 1e-4


def test_a_rigs_note_is_wrapped_to_the_sidebar_so_none_of_it_is_cut_off():
    """The Mesh and Rig panels draw what autorig found a line a part, each part wrapped at words to the sidebar's
    width (a long warning, such as an overruled up, was cut off mid-word before)."""
    from volrig_addon.ops_base import found_lines, sidebar_chars
    found = ("humanoid, fit 0.97 (runner-up chains 0.00); given up overruled; no body plan stands along it; "
             "rigged standing along (-0.02, -0.99, 0.03); check the up axis, or choose a plan")
    whole = found_lines(found)
    assert [t for t, _ in whole][:3] == ["humanoid, fit 0.97", "runner-up chains 0.00", "given up overruled"]
    assert whole[2][1] == "ERROR" and len(whole) == 6
    narrow = found_lines(found, 20)
    assert all(len(t) <= 20 for t, _ in narrow[2:]) and len(narrow) > len(whole)
    # Every word kept, in order; only a warning's first line carries the warning icon.
    assert " ".join(t for t, _ in narrow[2:]).split() == " ".join(t for t, _ in whole[2:]).split()
    assert [i for _, i in narrow[2:]].count("ERROR") == 1
    assert sidebar_chars(bpy.context) == 0  # no region in the background: not wrapped

    class Region:
        width = 300

    class Context:
        region = Region()
        preferences = bpy.context.preferences

    chars = sidebar_chars(Context())
    assert 16 <= chars <= 45


def test_the_panels_hints_are_wrapped_to_the_sidebar_so_none_of_it_is_cut_off():
    """The Markers box's hint ("optional: chin, wrists, groin, knees", "missing: ...") and the Mesh panel's
    "Select a bone: its thickness shows here" are drawn by draw_wrapped, at words to the sidebar's width: Blender
    3.4's sidebar showed "optional: c...groin, knees". Whole without a region (in the background)."""
    from volrig_addon.ops_base import draw_wrapped

    class Layout:
        def __init__(self):
            self.labels = []

        def column(self, align=False):
            return self

        def label(self, text="", icon="NONE"):
            self.labels.append((text, icon))

    class Region:
        width = 200

    class Context:
        region = Region()
        preferences = bpy.context.preferences

    hint = "optional: chin, wrists, groin, knees"
    narrow, whole = Layout(), Layout()
    draw_wrapped(narrow, hint, Context(), icon="INFO")
    draw_wrapped(whole, hint, None, icon="INFO")
    assert whole.labels == [(hint, "INFO")]
    assert len(narrow.labels) >= 2 and all(len(t) <= 23 for t, _ in narrow.labels)
    assert " ".join(t for t, _ in narrow.labels) == hint  # every word, in order
    assert [i for _, i in narrow.labels] == ["INFO"] + ["BLANK1"] * (len(narrow.labels) - 1)

"""The add-on's operators on the humanoid phantom, inside headless Blender."""
import hashlib
import os

import numpy as np
import pytest

import bpy
import volrig
from conftest import run_op
from mathutils import Euler


def _sha(path):
    with open(path, "rb") as f:
        return hashlib.sha1(f.read()).hexdigest()


def _members(vol):
    from volrig_addon.objects import members
    return members(vol)


def test_import_places_the_volume_and_keeps_the_source(empty_scene, phantom_file):
    path, ph = phantom_file
    before = (_sha(path), os.path.getmtime(path))
    run_op(bpy.ops.volrig.import_volume, filepath=path, unit="MM")
    vol = bpy.context.active_object
    assert vol.type == "VOLUME" and vol.volrig.role == "VOLUME" and vol.name == "phantom"
    s = vol.volrig
    assert tuple(s.dims) == ph.volume.dims and tuple(s.spacing) == ph.volume.spacing
    np.testing.assert_allclose(np.array(vol.matrix_world), np.diag([0.001, 0.001, 0.001, 1.0]))
    cached = bpy.path.abspath(vol.data.filepath)
    assert os.path.exists(cached) and os.path.dirname(cached) == bpy.path.abspath(s.cache_dir).rstrip("/")
    # the cached samples, back on their grid, are the source's
    back = volrig.load(cached).on_grid(s.origin, s.dims)
    np.testing.assert_array_equal(back.array, ph.volume.array.astype(np.float32))
    # Blender sees the grid where the volume is: its bounding box spans the object's voxels (in mm)
    vol.data.grids.load()
    assert [g.name for g in vol.data.grids] == ["density"]
    corners = np.array([tuple(c) for c in vol.bound_box])
    nz = np.argwhere(ph.volume.array)
    lo, hi = nz.min(axis=0)[::-1] * s.spacing, nz.max(axis=0)[::-1] * s.spacing
    # (OpenVDB keeps 8-voxel leaves: the box may reach up to a leaf beyond the object's voxels)
    assert np.all(corners.min(axis=0) <= lo + 1e-3) and np.all(corners.min(axis=0) >= lo - 8)
    assert np.all(corners.max(axis=0) >= hi - 1e-3) and np.all(corners.max(axis=0) <= hi + 8)
    assert len(vol.data.materials) == 1 and vol.data.materials[0].node_tree.nodes.get("volrig ramp")
    assert (_sha(path), os.path.getmtime(path)) == before  # never touched


def test_mask_preview_shows_the_segmentation(empty_scene, phantom_file):
    path, ph = phantom_file
    run_op(bpy.ops.volrig.import_volume, filepath=path)
    vol = bpy.context.active_object
    s = vol.volrig
    s.low, s.high, s.largest = 150, 255, False  # all the bone
    run_op(bpy.ops.volrig.preview_mask)
    preview = _members(vol)["MASK"]
    assert preview.name == "phantom_mask" and preview.type == "VOLUME" and preview.parent == vol
    first = bpy.path.abspath(preview.data.filepath)
    grids = {g["name"]: g for g in volrig._volrig.vdb_grids(first)}
    assert grids["density"]["active_voxels"] == s.mask_count == np.count_nonzero(ph.volume.array >= 150)
    s.low = 1  # a new segmentation: a new file, the old one gone
    run_op(bpy.ops.volrig.preview_mask)
    second = bpy.path.abspath(_members(vol)["MASK"].data.filepath)
    assert second != first and not os.path.exists(first)
    assert volrig._volrig.vdb_grids(second)[0]["active_voxels"] == np.count_nonzero(ph.volume.array)
    s.low, s.high = 230, 250  # nothing in range: reported, not raised
    with pytest.raises(RuntimeError, match="segmentation is empty"):
        bpy.ops.volrig.preview_mask()


def test_show_thickness_colours_the_object_by_its_thickness(empty_scene, phantom_file):
    path, ph = phantom_file
    run_op(bpy.ops.volrig.import_volume, filepath=path)
    vol = bpy.context.active_object
    s = vol.volrig
    s.low, s.high, s.largest = 150, 255, False  # the bone
    run_op(bpy.ops.volrig.show_thickness)
    obj = _members(vol)["THICKNESS"]
    assert obj.name == "phantom_thickness" and obj.type == "VOLUME" and obj.parent == vol
    file = bpy.path.abspath(obj.data.filepath)
    grids = {g["name"]: g for g in volrig._volrig.vdb_grids(file)}
    assert set(grids) == {"density", "thickness"}
    mask = ph.volume.array >= 150
    assert grids["thickness"]["active_voxels"] == np.count_nonzero(mask)
    # the grid is volrig.local_thickness of the mask, on the scan's grid
    want = volrig.local_thickness(volrig.Volume(mask, ph.volume.spacing))
    got = volrig.load(file, grid="thickness").on_grid(s.origin, s.dims)
    np.testing.assert_allclose(got.array, want.array, rtol=1e-6)
    # the ramp spans the thickness values: From Max at their 99th percentile
    nodes = obj.active_material.node_tree.nodes
    top = nodes["volrig thickness span"].inputs["From Max"].default_value
    assert top == pytest.approx(np.percentile(want.array[mask], 99), rel=1e-5)
    assert nodes["volrig thickness volume"].inputs["Density"].default_value > 0
    run_op(bpy.ops.volrig.show_thickness)  # again: the same object, the cached file
    assert bpy.path.abspath(_members(vol)["THICKNESS"].data.filepath) == file
    assert len([o for o in bpy.data.objects if o.volrig.role == "THICKNESS"]) == 1


def test_import_reports_bad_files_without_raising(empty_scene, tmp_path):
    bad = tmp_path / "broken.nrrd"
    bad.write_bytes(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 100 100 100\nencoding: raw\n\n" + b"\0" * 100)
    n = len(bpy.data.objects)
    # an operator's error report reaches a Python caller as RuntimeError("Error: <the report>"); in the UI it is
    # a message in the status bar
    with pytest.raises(RuntimeError, match="header says 100x100x100 uint8 = 1,000,000 bytes but the file holds 100"):
        bpy.ops.volrig.import_volume(filepath=str(bad))
    with pytest.raises(RuntimeError, match="missing.nrrd: no such file"):
        bpy.ops.volrig.import_volume(filepath=str(tmp_path / "missing.nrrd"))
    (tmp_path / "x.raw").write_bytes(b"\0" * 64)
    with pytest.raises(RuntimeError, match="raw file needs its size"):
        bpy.ops.volrig.import_volume(filepath=str(tmp_path / "x.raw"))
    with pytest.raises(RuntimeError, match="4 x 4 x 4 float32 = 256 bytes but the file holds 64|holds 64"):
        bpy.ops.volrig.import_volume(filepath=str(tmp_path / "x.raw"), raw_dims=(4, 4, 4), raw_dtype="float32")
    assert len(bpy.data.objects) == n
    assert bad.read_bytes().startswith(b"NRRD0004")


def test_segment_count_follows_the_settings(empty_scene, phantom_file):
    path, ph = phantom_file
    run_op(bpy.ops.volrig.import_volume, filepath=path)
    s = bpy.context.active_object.volrig
    a = ph.volume.array
    s.low, s.high = 150, 255
    assert s.mask_count == np.count_nonzero(a >= 150)  # bone only
    s.low = 1
    assert s.mask_count == np.count_nonzero(a)
    s.segment_by, s.labels = "LABELS", "80 220"
    assert s.mask_count == np.count_nonzero((a == 80) | (a == 220))
    s.labels = "eighty"
    assert s.mask_count == -1
    with pytest.raises(RuntimeError, match="'eighty' is not a number"):
        bpy.ops.volrig.skeletonize()


def test_thinness_rethresholds_the_preview(empty_scene, phantom_file):
    path, ph = phantom_file
    run_op(bpy.ops.volrig.import_volume, filepath=path)
    vol = bpy.context.active_object
    vol.volrig.low = 1
    run_op(bpy.ops.volrig.skeletonize)
    sk = volrig.skeletonize(volrig.segment(ph.volume, lo=1, largest_component=True))
    preview = _members(vol)["SKELETON"]
    for tp in (0.2, 0.5, 0.9):
        vol.volrig.thinness = tp
        assert vol.volrig.point_count == sk.count(tp) == len(preview.data.vertices)
        radius = np.zeros(len(preview.data.vertices), np.float32)
        preview.data.attributes["radius"].data.foreach_get("value", radius)
        np.testing.assert_allclose(radius, sk.at(tp).radii)
    assert preview.modifiers["volrig spheres"].node_group.name == "volrig spheres"


def test_rig_builds_the_armature_and_the_spheres(rigged):
    vol = rigged
    parts = _members(vol)
    rig_obj, spheres = parts["RIG"], parts["SPHERES"]
    assert rig_obj.name == "phantom_rig" and spheres.name == "phantom_spheres"
    saved = volrig.load_rig(os.path.join(bpy.path.abspath(vol.volrig.cache_dir), vol.volrig.rig_file))
    rig, pts, binding = saved.rig, saved.points, saved.binding
    # the armature: the rig's bones with its names, parents and Blender rest matrices
    bones = rig_obj.data.bones
    assert rig.kind == "humanoid"
    assert [b.name for b in bones] == rig.names
    for role in ("hips", "spine", "chest", "neck", "head", "upper_arm.L", "forearm.R", "hand.L", "thigh.R",
                 "shin.L", "foot.R"):
        assert role in bones
    for b, bone in enumerate(bones):
        np.testing.assert_allclose(np.array(bone.matrix_local), rig.rest_matrices[b], atol=1e-4)
        assert (bone.parent.name if bone.parent else None) == (rig.names[rig.parents[b]] if rig.parents[b] >= 0
                                                               else None)
    # the spheres: one vertex per point, radius attribute, tree edges, one vertex group per bone with the binding
    mesh = spheres.data
    assert len(mesh.vertices) == len(pts)
    co = np.zeros(3 * len(pts), np.float32)
    mesh.vertices.foreach_get("co", co)
    np.testing.assert_allclose(co.reshape(-1, 3), pts.centers, atol=1e-3)
    radius = np.zeros(len(pts), np.float32)
    mesh.attributes["radius"].data.foreach_get("value", radius)
    np.testing.assert_allclose(radius, pts.radii)
    assert len(mesh.edges) == len(saved.tree.edges)
    assert [g.name for g in spheres.vertex_groups] == rig.names
    from volrig_addon.objects import vertex_groups
    back = volrig.Binding.from_groups(vertex_groups(spheres), rig.names, len(pts))
    np.testing.assert_allclose(back.weights.toarray(), binding.weights.toarray(), atol=1e-6)
    assert spheres.parent == rig_obj and spheres.modifiers["Armature"].object == rig_obj
    assert vol.parent == rig_obj
    np.testing.assert_allclose(np.array(spheres.matrix_world), np.array(rig_obj.matrix_world))


def test_rig_reports_its_fit_refits_as_another_kind_and_takes_up_from_the_scene(rigged):
    """The Rig panel shows what autorig found; picking another body plan and pressing Rig refits; the scene's +Z,
    seen from the volume, is the up autorig is given, however the volume is turned."""
    vol = rigged
    assert vol.volrig.rig_found.startswith("humanoid, fit ")
    saved = volrig.load_rig(os.path.join(bpy.path.abspath(vol.volrig.cache_dir), vol.volrig.rig_file))
    upright_fit = saved.rig.fit
    np.testing.assert_allclose(saved.rig.up, [0, 0, 1], atol=1e-6)
    assert saved.rig.up_confidence == 1.0
    vol.volrig.body_plan = "chains"
    run_op(bpy.ops.volrig.rig)
    assert vol.volrig.rig_found.startswith("chains, fit ")
    assert all(b.name.startswith("chain") for b in _members(vol)["RIG"].data.bones)
    vol.volrig.body_plan = "winged"  # forced: built whatever its score, wings with the arm's bones
    run_op(bpy.ops.volrig.rig)
    assert vol.volrig.rig_found.startswith("winged, fit ")
    assert {"upper_arm.L", "forearm.R", "thigh.L"} <= {b.name for b in _members(vol)["RIG"].data.bones}
    # the volume lying on its back (turned -90 degrees about X): the scene's up is the volume's -y
    from mathutils import Matrix
    from volrig_addon.objects import scene_up
    rig_obj = _members(vol)["RIG"]
    rig_obj.matrix_world = Matrix.Rotation(-np.pi / 2, 4, "X") @ rig_obj.matrix_world
    bpy.context.view_layer.update()
    np.testing.assert_allclose(scene_up(vol), [0, -1, 0], atol=1e-6)
    vol.volrig.body_plan = "AUTO"
    run_op(bpy.ops.volrig.rig)
    saved = volrig.load_rig(os.path.join(bpy.path.abspath(vol.volrig.cache_dir), vol.volrig.rig_file))
    np.testing.assert_allclose(saved.rig.up, [0, -1, 0], atol=1e-6)
    # the phantom stands along its z: told that up is its -y, it lies on its back, and fits a humanoid worse
    assert saved.rig.kind != "humanoid" or saved.rig.fit < upright_fit - 0.1
    # Kept points: the rig's joints sit on the kept skeleton points themselves (end joints aside)
    vol.volrig.rig_kept_points = True
    run_op(bpy.ops.volrig.rig)
    saved = volrig.load_rig(os.path.join(bpy.path.abspath(vol.volrig.cache_dir), vol.volrig.rig_file))
    on = saved.rig.joint_points >= 0
    assert on.any() and np.allclose(saved.rig.joints[on], saved.points.centers[saved.rig.joint_points[on]])
    vol.volrig.rig_kept_points = False


def _evaluated_vertices(obj):
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    mesh = ev.to_mesh()
    co = np.zeros(3 * len(mesh.vertices), np.float32)
    mesh.vertices.foreach_get("co", co)
    ev.to_mesh_clear()
    return co.reshape(-1, 3)


def test_posing_a_bone_moves_its_spheres(rigged):
    parts = _members(rigged)
    rig_obj, spheres = parts["RIG"], parts["SPHERES"]
    n = len(spheres.data.vertices)
    rest = _evaluated_vertices(spheres)
    assert rest.shape == (n, 3)
    from volrig_addon.objects import vertex_groups
    groups = vertex_groups(spheres)
    forearm_idx, forearm_w = groups["forearm.L"]
    head_idx, head_w = groups["head"]
    only_forearm = forearm_idx[forearm_w > 0.999]
    only_head = head_idx[head_w > 0.999]
    assert len(only_forearm) > 20 and len(only_head) > 20
    pb = rig_obj.pose.bones["forearm.L"]
    pb.rotation_mode = "XYZ"
    pb.rotation_euler = Euler((0.9, 0.0, 0.3))
    bpy.context.view_layer.update()
    posed = _evaluated_vertices(spheres)
    # the forearm's own spheres move rigidly with it: posed = (pose @ rest^-1) applied to the rest position
    m = np.array(pb.matrix @ pb.bone.matrix_local.inverted())
    expect = rest[only_forearm] @ m[:3, :3].T + m[:3, 3]
    np.testing.assert_allclose(posed[only_forearm], expect, atol=1e-2)
    assert np.linalg.norm(posed[only_forearm] - rest[only_forearm], axis=1).max() > 10.0  # mm
    np.testing.assert_allclose(posed[only_head], rest[only_head], atol=1e-4)  # the head stays


def test_rebind_after_editing_the_armature(rigged):
    vol = rigged
    parts = _members(vol)
    rig_obj, spheres = parts["RIG"], parts["SPHERES"]
    old_file = vol.volrig.rig_file
    bpy.context.view_layer.objects.active = rig_obj
    bpy.ops.object.mode_set(mode="EDIT")
    ebs = rig_obj.data.edit_bones
    ebs.remove(ebs["hand.L"])
    head = ebs["head"]
    head.tail = head.tail + (head.tail - head.head) * 0.2  # a longer head
    bpy.ops.object.mode_set(mode="OBJECT")
    bpy.context.view_layer.objects.active = vol
    run_op(bpy.ops.volrig.rebind)
    names = [b.name for b in rig_obj.data.bones]
    assert "hand.L" not in names and [g.name for g in spheres.vertex_groups] == names
    from volrig_addon.objects import vertex_groups
    n = len(spheres.data.vertices)
    binding = volrig.Binding.from_groups(vertex_groups(spheres), names, n)  # every sphere has a bone again
    assert binding.weights.shape == (n, len(names))
    # the hand's spheres now follow the forearm
    saved_before = volrig.load_rig(os.path.join(bpy.path.abspath(vol.volrig.cache_dir), old_file))
    hand = saved_before.binding.points_of("hand.L")
    assert len(hand) > 0 and (np.array(names)[binding.bone[hand]] == "forearm.L").mean() > 0.9
    assert vol.volrig.rig_file != old_file
    saved = volrig.load_rig(os.path.join(bpy.path.abspath(vol.volrig.cache_dir), vol.volrig.rig_file))
    assert saved.rig.names == names


def test_rebind_without_rig_is_refused(empty_scene, phantom_file):
    run_op(bpy.ops.volrig.import_volume, filepath=phantom_file[0])
    assert not bpy.ops.volrig.rebind.poll()


class _Layout:
    """Records what a panel draws; checks every property it shows exists."""

    def __init__(self, drawn):
        self.drawn = drawn

    def prop(self, data, name, **kw):
        assert name in data.bl_rna.properties, f"no property {name!r}"
        self.drawn.append(name)

    def prop_search(self, data, name, search_data, search_name, **kw):
        assert name in data.bl_rna.properties and hasattr(search_data, search_name)
        self.drawn.append(name)

    def operator(self, idname, **kw):
        module, op = idname.split(".")
        assert hasattr(getattr(bpy.ops, module), op), idname
        self.drawn.append(idname)

    def label(self, **kw):
        self.drawn.append(kw.get("text", ""))

    def template_list(self, list_type, list_id, data, name, active_data, active_name, **kw):
        assert hasattr(bpy.types, list_type), list_type
        assert name in data.bl_rna.properties and active_name in active_data.bl_rna.properties
        self.drawn.append(name)

    def row(self, **kw):
        return self

    column = box = split = row


def test_panels_draw_every_stage(rigged):
    import volrig_addon
    drawn = []
    for cls in volrig_addon.PANELS:
        assert cls.poll(bpy.context)
        stub = type("PanelStub", (), {"layout": _Layout(drawn)})()
        cls.draw(stub, bpy.context)
    for expected in ("volrig.import_volume", "low", "thinness", "volrig.rig", "volrig.rebind", "volrig.walk_cycle",
                     "volrig.drive_with_bvh", "preset", "highlight_bone", "volrig.bake", "deform_mode", "keep_volume",
                     "lattice_tables",
                     "fly_ends", "frames_per_mm", "look_ahead", "volrig.fly_through", "volrig.straighten",
                     "straighten_bones", "volrig.straightening_rig"):
        assert expected in drawn
    assert any("21 bones" in str(t) for t in drawn)


def test_only_volrigs_errors_are_reported_bugs_raise(rigged, monkeypatch):
    """A user mistake (volrig.VolrigError, OSError) becomes a status-bar report; a programming error (say a
    KeyError) is not swallowed: it reaches the caller with its traceback."""
    from volrig import pipeline

    def mistake(*args, **kwargs):
        raise volrig.VolrigError("only 1 skeleton point(s): lower the thinness")

    def bug(*args, **kwargs):
        return {}["no such key"]

    monkeypatch.setattr(pipeline, "rig_skeleton", mistake)
    with pytest.raises(RuntimeError, match=r"volrig: only 1 skeleton point") as report:
        bpy.ops.volrig.rig()
    assert "Traceback" not in str(report.value)
    monkeypatch.setattr(pipeline, "rig_skeleton", bug)
    with pytest.raises(RuntimeError, match="Traceback") as trace:
        bpy.ops.volrig.rig()
    assert "KeyError" in str(trace.value) and "volrig: " not in str(trace.value).split("\n")[0]

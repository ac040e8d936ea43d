"""Per-tissue looks for label maps (issues 21, 56): the Tissues list from a tissue table, the rest volume's and the
baked frames' one ``tissue`` grid of class indices, a baked frame imported with its classes (from its metadata, no
table), and renders where a hidden tissue leaves nothing and a coloured one no fringe."""
import numpy as np
import pytest

import bpy
import volrig
from conftest import run_op
from silhouettes import PASS, compare
from test_looks import _grids, _projected, _render, _stage

PHANTOM_TABLE = "code\tname\n0\tExternalAir\n80\tMuscle\n100\tFat\n220\tBoneCortical\n"


def _tissue(vol, name):
    return next(t for t in vol.volrig.tissues if t.name == name)


def _index(vol, name):
    """The class index of tissue ``name`` in the ``tissue`` grid (its place in the list, 1-based)."""
    return [t.name for t in vol.volrig.tissues].index(name) + 1


def _read_attributes(vol):
    nodes = vol.data.materials[0].node_tree.nodes
    return {n.attribute_name for n in nodes if n.type == "ATTRIBUTE" and any(o.is_linked for o in n.outputs)}


@pytest.fixture
def blocks(empty_scene, tmp_path):
    """A label map of three separate blocks side by side along x (bone 84, muscle 180, fat 136) and a muscle bridge
    joining the last two, imported in mm, with its tissue table."""
    lab = np.zeros((16, 12, 48), np.uint8)
    lab[4:12, 3:9, 2:12] = 84
    lab[4:12, 3:9, 18:30] = 180
    lab[4:12, 3:9, 30:44] = 136
    path = tmp_path / "blocks.nrrd"
    volrig.Volume(lab, (1.0, 1.0, 1.0)).save(str(path))
    table = tmp_path / "blocks.tsv"
    table.write_text("code\tname\n84\tBoneCortical\n136\tFat\n180\tMuscle\n")
    run_op(bpy.ops.volrig.import_volume, filepath=str(path), unit="MM")
    vol = bpy.context.active_object
    vol.volrig.tissue_table = str(table)
    return vol, lab


def test_tissues_list_and_rest_volume(blocks):
    from volrig_addon import materials, tissue_looks
    vol, lab = blocks
    vol.volrig.use_tissues = True
    assert [t.name for t in vol.volrig.tissues] == ["fat", "muscle", "bone"]  # by opacity: the class indices
    assert [t.codes for t in vol.volrig.tissues] == ["136", "180", "84"]
    assert vol.volrig.sampling == "nearest"
    path = tissue_looks.rest_file(vol)
    assert bpy.path.abspath(vol.data.filepath) == path and not vol.data.is_sequence
    g, first = _grids(path, ["density", "tissue"])
    for name, code in (("bone", 84), ("muscle", 180), ("fat", 136)):
        assert np.array_equal(g["tissue"] == _index(vol, name), g["density"] == code)
    assert np.array_equal(g["tissue"] > 0, g["density"] > 0)
    assert "tissue" in _read_attributes(vol)  # one grid for every class
    fat = f"{materials.TISSUE_PREFIX} opacity fat"
    assert fat in vol.data.materials[0].node_tree.nodes
    _tissue(vol, "fat").visible = False  # a hidden tissue adds nothing
    assert fat not in vol.data.materials[0].node_tree.nodes
    # looks survive Find Tissues; without a table every label is its own class
    run_op(bpy.ops.volrig.find_tissues)
    assert not _tissue(vol, "fat").visible
    vol.volrig.tissue_table = ""
    assert [t.name for t in vol.volrig.tissues] == ["label 84", "label 136", "label 180"]
    vol.volrig.use_tissues = False
    assert bpy.path.abspath(vol.data.filepath).endswith("source.vdb")


def test_not_a_label_map_turns_the_looks_off_with_a_message(empty_scene, tmp_path, capsys):
    rng = np.random.default_rng(3)
    path = tmp_path / "ct.nrrd"
    volrig.Volume(rng.normal(size=(8, 8, 8)).astype(np.float32), (1.0, 1.0, 1.0)).save(str(path))
    run_op(bpy.ops.volrig.import_volume, filepath=str(path), unit="MM")
    vol = bpy.context.active_object
    vol.volrig.use_tissues = True
    assert not vol.volrig.use_tissues and len(vol.volrig.tissues) == 0
    assert "is not a label map" in capsys.readouterr().out


def test_hidden_and_coloured_tissues_render_exactly(blocks, tmp_path):
    from volrig_addon import tissue_looks
    vol, lab = blocks
    vol.volrig.use_tissues = True
    vol.volrig.density_scale = 3.0
    scene = _stage(vol, tmp_path)
    full = _render(scene, tmp_path / "full.png")
    assert compare("tissues_full", tmp_path / "full.png", alpha=True) > PASS  # the blocks of 3.4's Cycles
    g, first = _grids(tissue_looks.rest_file(vol), ["tissue"])
    bone = _projected(scene, vol, g["tissue"] == _index(vol, "bone"), first, grow=2)
    only_bone = _projected(scene, vol, g["tissue"] == _index(vol, "bone"), first, grow=0, outer=False)
    assert only_bone.sum() >= 10 and full[..., 3][only_bone].mean() > 0.9

    _tissue(vol, "bone").visible = False
    hidden = _render(scene, tmp_path / "hidden.png")
    # (one step of the 8-bit PNG allowed: the bone's grid no longer read shifts a few samples' random numbers)
    changed = np.abs(hidden[..., 3] - full[..., 3]) > 1.5 / 255
    assert changed.any() and not (changed & ~bone).any()  # the alpha changes inside the bone's region only
    # where the bone was, nothing is left: its surface's index passes the muscle's and the fat's (lower), but the
    # codes there are the bone's (materials.tissue_sums). (At most one step of the 8-bit PNG: EEVEE's texture
    # filtering interpolates the two grids with its own rounding.)
    assert hidden[..., 3][only_bone].max() < 1.5 / 255

    _tissue(vol, "bone").visible = True
    muscle = _projected(scene, vol, g["tissue"] == _index(vol, "muscle"), first, grow=2)
    _tissue(vol, "muscle").color = (0.0, 0.0, 1.0)
    blue = _render(scene, tmp_path / "blue.png")
    assert np.abs(blue[~muscle] - full[~muscle]).max() < 1.5 / 255  # no fringe outside the muscle's region
    inside = _projected(scene, vol, g["tissue"] == _index(vol, "muscle"), first, grow=0, outer=False) & (
        full[..., 3] > 0.2)
    assert inside.sum() >= 10
    bluer = (blue[..., 2] - blue[..., 0])[inside] - (full[..., 2] - full[..., 0])[inside]
    assert bluer.mean() > 0.1


def test_bake_writes_the_tissue_grid_and_an_imported_frame_gets_the_looks(rigged, tmp_path):
    from volrig_addon import bake, materials
    vol = rigged
    table = tmp_path / "phantom.tsv"
    table.write_text(PHANTOM_TABLE)
    vol.volrig.tissue_table = str(table)
    vol.volrig.use_tissues = True
    assert [t.name for t in vol.volrig.tissues] == ["fat", "muscle", "bone"]
    _tissue(vol, "muscle").color = (0.1, 0.2, 0.9)  # a look of the user's travels with the frames
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 1
    run_op(bpy.ops.volrig.bake)
    path = bake.frame_path(vol, 1)
    assert {g["name"] for g in volrig.vdb_grids(path)} == {"density", "bone", "tissue"}
    g, _ = _grids(path, ["density", "tissue"])
    for name, code in (("bone", 220), ("muscle", 80), ("fat", 100)):
        assert (g["tissue"] == _index(vol, name)).any()
        assert np.array_equal(g["tissue"] == _index(vol, name), np.isclose(g["density"], code))
    # trilinear sampling would blend the codes: the bake refuses
    vol.volrig.sampling = "trilinear"
    with pytest.raises(RuntimeError, match="nearest sampling"):
        bpy.ops.volrig.bake()
    # the frame imported on its own, no table: its classes and looks from its metadata
    run_op(bpy.ops.volrig.import_volume, filepath=path, unit="MM")
    frame = bpy.context.active_object
    s = frame.volrig
    assert frame != vol and s.tissue_table == "" and s.use_tissues and s.sampling == "nearest"
    assert [(t.name, t.codes) for t in s.tissues] == [("fat", "100"), ("muscle", "80"), ("bone", "220")]
    assert tuple(_tissue(frame, "muscle").color) == pytest.approx((0.1, 0.2, 0.9))
    assert "tissue" in _read_attributes(frame)
    nodes = frame.data.materials[0].node_tree.nodes
    for t in s.tissues:
        assert tuple(nodes[f"{materials.TISSUE_PREFIX} colour {t.key}"].outputs[0].default_value)[:3] == \
            pytest.approx(tuple(t.color))
        scaled = nodes[f"{materials.TISSUE_PREFIX} scaled {t.key}"].inputs[1].default_value  # 1 / its index
        assert scaled == pytest.approx(1.0 / _index(frame, t.name))


def test_rig_binds_the_tissue_tables_bone_rigidly(empty_scene, phantom_file, tmp_path):
    """Rigid tissue (issue 18) in the add-on: with a tissue table, Automatic binds its bone codes rigidly; Labels
    and Value range say it explicitly; the binding is volrig.bind's with that rigid tissue split into its segments,
    which also placed the limb joints (issue 54)."""
    import shutil
    from volrig_addon import scans
    run_op(bpy.ops.volrig.import_volume, filepath=phantom_file[0], unit="MM")
    vol = bpy.context.active_object
    assert vol.volrig.tissue_table == "" and scans.rigid(vol) is None  # Automatic without a table: nothing rigid
    # a table beside the label map's file is found on import
    shutil.copy(phantom_file[0], tmp_path / "phantom.nrrd")
    table = tmp_path / "phantom_tissues.tsv"
    table.write_text(PHANTOM_TABLE)
    (tmp_path / "notes.txt").write_text("not a table\n")
    run_op(bpy.ops.volrig.import_volume, filepath=str(tmp_path / "phantom.nrrd"), unit="MM")
    vol = bpy.context.active_object
    assert bpy.path.abspath(vol.volrig.tissue_table) == str(table)
    s = vol.volrig  # taken as a label map: its body codes, per-tissue looks on, nearest sampling
    assert s.use_tissues and s.sampling == "nearest" and s.segment_by == "LABELS" and s.labels == "80, 100, 220"
    assert [t.name for t in s.tissues] == ["fat", "muscle", "bone"]
    rigid = scans.rigid(vol)
    assert np.array_equal(rigid.array, phantom_file[1].volume.array == 220)
    vol.volrig.rigid_by = "LABELS"
    vol.volrig.rigid_labels = "220"
    assert np.array_equal(scans.rigid(vol).array, rigid.array)
    vol.volrig.rigid_by = "RANGE"
    vol.volrig.rigid_low, vol.volrig.rigid_high = 200, 255
    assert np.array_equal(scans.rigid(vol).array, rigid.array)
    vol.volrig.rigid_low, vol.volrig.rigid_high = 230, 255
    with pytest.raises(volrig.VolrigError, match="no voxel of"):
        scans.rigid(vol)
    vol.volrig.rigid_by = "AUTO"
    bpy.ops.object.select_all(action="DESELECT")
    vol.select_set(True)
    bpy.context.view_layer.objects.active = vol
    vol.volrig.low = 1.0
    run_op(bpy.ops.volrig.skeletonize)
    vol.volrig.thinness = 0.3
    run_op(bpy.ops.volrig.rig)
    saved = volrig.load_rig(scans.rig_path(vol))
    # the rigid tissue is the scan's bone too (issue 54): it placed the limb joints, and it is bound split into its
    # segments (voxels where two segments touch left out), each moving wholly with one bone
    assert "limb joints from the bones" in vol.volrig.rig_found, vol.volrig.rig_found
    layer = saved.binding.rigid
    assert saved.binding.rigid_whole and not (layer & ~rigid.array).any() and layer.sum() >= 0.9 * rigid.array.sum()
    expected = volrig.bind(saved.points, saved.rig, scans.mask(vol), mode="smooth", rigid=layer)
    got = saved.binding.weights.tocsr()
    assert np.array_equal(got.indptr, expected.weights.tocsr().indptr)
    np.testing.assert_allclose(got.data, expected.weights.tocsr().data, atol=1e-6)
    # spheres centred on bone carry one bone; some elsewhere blend
    on_bone = layer[tuple(np.asarray(saved.points.ijk).T)]
    rows = np.diff(got.indptr)
    assert on_bone.any() and (rows[on_bone] == 1).all() and (rows[~on_bone] > 1).any()
    # the rig file keeps the rigid tissue, and the bake's Deformer draws it as the rigid layer (issue 18)
    assert vol.volrig.rigid_voxels == layer.sum()  # the Rig panel says so
    from volrig_addon import bake, objects
    baker = bake.Baker(vol)
    assert np.array_equal(baker.binding.rigid, layer)
    pb = objects.members(vol)["RIG"].pose.bones["shin.L"]
    pb.rotation_mode = "XYZ"
    pb.rotation_euler = (1.2, 0.0, 0.0)
    bpy.context.view_layer.update()
    frame = baker.folder.deformer.frame(baker.bone_matrices(bpy.context.evaluated_depsgraph_get()), mode="linear",
                                        sampling="nearest")
    # the layer drew (nearly) all of its bone, and the frame holds about as much bone as at rest (the spheres sample
    # soft tissue under the layer; the few voxels left out of it where two segments touch are theirs to draw)
    bone_values = np.count_nonzero(np.asarray(frame.values.array) == 220)
    assert frame.stats["rigid_layer"] >= 0.9 * layer.sum()
    assert 0.9 * rigid.array.sum() <= bone_values <= 1.01 * rigid.array.sum()


def test_tissues_with_parts_on_and_off(rigged, tmp_path):
    """Per-tissue looks turned on while per-part looks are on: the parts' rest file carries the tissue grids, and
    turning the parts off shows the tissues' own rest file (never the bare source under a tissue material)."""
    from volrig_addon import looks, tissue_looks
    vol = rigged
    table = tmp_path / "phantom.tsv"
    table.write_text(PHANTOM_TABLE)
    vol.volrig.use_parts = True
    vol.volrig.tissue_table = str(table)
    vol.volrig.use_tissues = True
    shown = bpy.path.abspath(vol.data.filepath)
    assert shown == looks.rest_file(vol)
    assert {"tissue", "mask_left_arm"} <= {g["name"] for g in volrig.vdb_grids(shown)}
    vol.volrig.use_parts = False
    shown = bpy.path.abspath(vol.data.filepath)
    assert shown == tissue_looks.rest_file(vol)
    assert "tissue" in {g["name"] for g in volrig.vdb_grids(shown)}

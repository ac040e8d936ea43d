"""Import Drawing (issue 23): a drawn character becomes a rigged volume coloured by its drawing, optionally with a
mesh through Volume to Mesh; bad drawings are reported, not raised."""
import numpy as np
import pytest

from conftest import run_op

bpy = pytest.importorskip("bpy")

RIGIFY = ["hips", "spine", "chest", "neck", "head"] + [f"{b}.{s}" for s in "LR" for b in (
    "shoulder", "upper_arm", "forearm", "hand", "pelvis", "thigh", "shin", "foot")]


@pytest.fixture
def character_png(tmp_path):
    from volrig import drawing
    from volrig_support import sketches
    path = tmp_path / "hero.png"
    drawing.write_png(str(path), sketches.character())
    return str(path)


def test_import_drawing_rigs_a_coloured_humanoid(empty_scene, character_png):
    from volrig_addon import objects
    run_op(bpy.ops.volrig.import_drawing, filepath=character_png, resolution=150, height=1.8, mesh=True)
    vol = bpy.context.active_object
    assert vol.type == "VOLUME" and vol.name.startswith("hero")
    parts = objects.members(vol)
    rig = parts["RIG"]
    assert rig.type == "ARMATURE" and vol.parent == rig
    assert vol.volrig.rig_found.startswith("humanoid")
    assert set(RIGIFY) <= {b.name for b in rig.data.bones}
    # the drawing's up is the scene's +Z, the figure 1.8 units tall
    bones = {b.name: rig.matrix_world @ b.head_local for b in rig.data.bones}
    assert bones["head"].z > bones["hips"].z > bones["foot.L"].z
    assert bones["hand.L"].x > bones["hand.R"].x  # the character's left is the drawing's right: +X
    bpy.context.view_layer.update()
    corners = np.array([vol.matrix_world @ __import__("mathutils").Vector(c) for c in vol.bound_box])
    assert corners[:, 2].max() - corners[:, 2].min() == pytest.approx(1.8, rel=0.05)
    # coloured by the drawing: the label look with the drawing's palette (the red shirt among its colours)
    s = vol.volrig
    assert s.preset == "LABELS" and s.segment_by == "LABELS" and s.sampling == "nearest"
    from volrig import drawing
    labels, _ = drawing.colour_labels(character_png, resolution=150)
    assert s.mask_count == int((labels.array > 0).sum())  # every voxel of the solid is object
    palette = np.reshape(vol["volrig_palette"], (-1, 3))
    assert 4 <= len(palette) <= 24
    ramp = vol.data.materials[0].node_tree.nodes["volrig ramp"].color_ramp
    colours = np.array([e.color[:3] for e in ramp.elements[1:]])
    assert np.allclose(colours, palette[:len(colours)], atol=1e-4)
    assert any(c[0] > 0.5 and c[1] < 0.1 and c[2] < 0.1 for c in palette)  # the shirt, in linear RGB
    # the mesh follows the volume through Volume to Mesh
    mesh = bpy.data.objects[vol.name + "_mesh"]
    assert mesh.modifiers[0].type == "VOLUME_TO_MESH" and mesh.modifiers[0].object == vol
    evaluated = mesh.evaluated_get(bpy.context.evaluated_depsgraph_get())
    assert len(evaluated.data.vertices) > 1000


def test_import_drawing_quadruped_forced(empty_scene, tmp_path):
    from volrig import drawing
    from volrig_support import sketches
    from volrig_addon import objects
    path = tmp_path / "dog.png"
    drawing.write_png(str(path), sketches.quadruped())
    run_op(bpy.ops.volrig.import_drawing, filepath=str(path), body_plan="quadruped")
    vol = bpy.context.active_object
    assert vol.volrig.rig_found.startswith("quadruped")
    assert "RIG" in objects.members(vol)


def test_import_drawing_reports_bad_files(empty_scene, tmp_path):
    bad = tmp_path / "broken.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 40)
    blank = tmp_path / "blank.png"
    from volrig import drawing
    drawing.write_png(str(blank), np.ones((40, 40, 3)))
    n = len(bpy.data.objects)
    with pytest.raises(RuntimeError, match="broken.png"):
        bpy.ops.volrig.import_drawing(filepath=str(bad))
    with pytest.raises(RuntimeError, match="empty"):
        bpy.ops.volrig.import_drawing(filepath=str(blank))
    with pytest.raises(RuntimeError, match="no such file"):
        bpy.ops.volrig.import_drawing(filepath=str(tmp_path / "missing.png"))
    assert len(bpy.data.objects) == n

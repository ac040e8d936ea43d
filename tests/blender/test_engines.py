"""The render engine volrig picks (volrig_addon.engines): Cycles where it renders VDB grids, EEVEE where this Blender's
Cycles renders none (Debian's 5.2: no NanoVDB), the probe that tells, and how the add-on says so."""
import os
import shutil

import numpy as np

import bpy
from silhouettes import PASS, compare, read_png


def _render_cycles(scene, path):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 2
    scene.cycles.use_denoising = False
    scene.render.film_transparent = True
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_png(path)


def test_the_probe_tells_what_cycles_renders(rigged, tmp_path):
    """The probe's answer is what Cycles does with a real scene: the rigged phantom's volume at 32 x 32 pixels
    shows where the probe says Cycles renders grids, and is blank where it says not."""
    from volrig_addon import engines, staging
    scene = bpy.context.scene
    staging.stage(scene, rigged, resolution=(32, 32), samples=2)
    px = _render_cycles(scene, tmp_path / "cycles.png")
    shows = (px[..., 3] > 0.1).mean() > 0.03
    assert engines.cycles_renders_grids() == shows, (engines.cycles_renders_grids(), (px[..., 3] > 0.1).mean())
    print(f"Blender {bpy.app.version_string}: Cycles renders grids: {shows}; volrig renders with "
          f"{engines.volume_engine()}")
    # no data-block of the probe's is left behind
    assert not [d for d in (*bpy.data.scenes, *bpy.data.objects, *bpy.data.volumes, *bpy.data.materials)
                if d.name.startswith("volrig probe")]


def test_without_grids_in_cycles_it_renders_with_eevee_and_says_why(rigged, monkeypatch, capsys):
    from test_addon import _Layout
    from volrig_addon import engines, looks_ui, staging
    monkeypatch.setattr(engines, "_answer", False)
    monkeypatch.setattr(engines, "_told", False)
    scene = bpy.context.scene
    staging.stage(scene, rigged, resolution=(32, 32), samples=3)
    assert scene.render.engine == engines.eevee() and scene.render.engine in ("BLENDER_EEVEE", "BLENDER_EEVEE_NEXT")
    assert scene.eevee.taa_render_samples == 3 and not scene.cycles.use_denoising
    assert capsys.readouterr().out.count(engines.NO_GRIDS) == 1
    staging.stage(scene, rigged, resolution=(32, 32), samples=3)
    assert engines.NO_GRIDS not in capsys.readouterr().out  # once a session
    drawn = []
    looks_ui.VOLRIG_PT_look.draw(type("PanelStub", (), {"layout": _Layout(drawn)})(), bpy.context)
    assert "Cycles here renders no VDBs" in drawn and "blender.org build for Cycles" in drawn
    monkeypatch.setattr(engines, "_answer", True)
    staging.stage(scene, rigged, resolution=(32, 32), samples=3)
    assert scene.render.engine == "CYCLES" and scene.cycles.samples == 3
    drawn = []
    looks_ui.VOLRIG_PT_look.draw(type("PanelStub", (), {"layout": _Layout(drawn)})(), bpy.context)
    assert not [t for t in drawn if "Cycles" in str(t)]


def test_silhouette_comparison_tells_a_moved_or_missing_figure(tmp_path):
    ref = os.path.join(os.path.dirname(__file__), "references", "baked_frame_1.png")
    same = tmp_path / "baked_frame_1.png"
    shutil.copyfile(ref, same)
    assert compare("baked_frame_1", same) == 1.0
    px = (read_png(ref) * 255).round().astype(np.uint8)
    for name, img in (("shifted", np.roll(px, 6, axis=1)), ("blank", np.broadcast_to(px[:1, :1], px.shape))):
        path = tmp_path / f"{name}.png"
        image = bpy.data.images.new(name, px.shape[1], px.shape[0], alpha=True)
        image.pixels[:] = (img[::-1].astype(np.float32) / 255).ravel()
        image.filepath_raw = str(path)
        image.file_format = "PNG"
        image.save()
        bpy.data.images.remove(image)
        score = compare("baked_frame_1", path)
        assert score < PASS - 0.1, (name, score)


def test_eevee_engine_name_is_this_blenders():
    from volrig_addon import engines
    items = bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items.keys()
    assert engines.eevee() in items


def _reading(name, count):
    """A volume material whose density sums ``count`` grids (g0, g1, ...)."""
    from volrig_addon import compat
    mat = bpy.data.materials.new(name)
    compat.use_nodes(mat)
    tree = mat.node_tree
    tree.nodes.clear()
    vol = tree.nodes.new("ShaderNodeVolumePrincipled")
    tree.links.new(vol.outputs["Volume"], tree.nodes.new("ShaderNodeOutputMaterial").inputs["Volume"])
    total = None
    for k in range(count):
        grid = tree.nodes.new("ShaderNodeAttribute")
        grid.attribute_name = f"g{k}"
        if total is None:
            total = grid.outputs["Fac"]
            continue
        add = tree.nodes.new("ShaderNodeMath")
        tree.links.new(total, add.inputs[0])
        tree.links.new(grid.outputs["Fac"], add.inputs[1])
        total = add.outputs[0]
    tree.links.new(total, vol.inputs["Density"])
    return mat


def test_a_look_reading_more_grids_than_eevee_can_says_so(empty_scene, monkeypatch, capsys):
    """EEVEE renders nothing for a volume material reading more grids than the GPU's texture units allow (14 with
    Mesa's llvmpipe): where volrig renders with EEVEE, such a look says so, once. Per-tissue looks read two grids
    whatever the number of classes."""
    import volrig
    from volrig_addon import engines, materials
    monkeypatch.setattr(engines, "_answer", False)
    assert engines.EEVEE_GRIDS == 14
    tissues = [volrig.Tissue(name=f"t{k}", key=f"t{k}", codes=[k + 1], color=(1.0, 1.0, 1.0), opacity=0.5,
                             visible=True) for k in range(16)]
    assert engines.grids_read(materials.tissue_material("tissues", tissues)) == 2  # "tissue" and "density"
    few, many = _reading("few", 3), _reading("many", 16)
    assert engines.grids_read(few) == 3 and engines.grids_read(many) == 16
    assert engines.check_material(few) == ""
    message = engines.check_material(many)
    assert "reads 16 grids; EEVEE reads at most 14" in message
    engines.check_material(many)
    assert capsys.readouterr().out.count("reads 16 grids") == 1
    monkeypatch.setattr(engines, "_answer", True)  # Cycles reads them all
    assert engines.check_material(many) == ""

"""Per-part looks (hidden, coloured parts rendered without interpolation fringes: exactly in Cycles, within a froxel
in EEVEE where this Cycles renders no grids) and the Explode factor."""
import numpy as np
import pytest

import bpy
import volrig
from conftest import run_op
from silhouettes import PASS, compare, read_png, spread

PART = "left arm"


def _part(vol, name=PART):
    return next(p for p in vol.volrig.parts if p.name == name)


def _grids(path, names):
    """The named grids of a VDB file on one box (each grid is stored cropped to its active voxels), and the box's
    first voxel's position (x, y, z, volume units)."""
    vols = {n: volrig.load(path, grid=n) for n in names}
    spacing = np.asarray(next(iter(vols.values())).spacing)
    lo = np.min([v.origin for v in vols.values()], axis=0)
    starts = {n: np.rint((np.asarray(v.origin) - lo) / spacing).astype(int) for n, v in vols.items()}
    hi = np.max([starts[n] + v.dims for n, v in vols.items()], axis=0)
    out = {}
    for n, v in vols.items():
        a = np.zeros(tuple(hi[::-1]), dtype=np.float64)
        o = starts[n]
        z, y, x = v.array.shape
        a[o[2]:o[2] + z, o[1]:o[1] + y, o[0]:o[0] + x] = v.array
        out[n] = a
    return out, lo


def test_rig_lists_parts_and_writes_the_rest_volume_with_their_grids(rigged):
    from volrig_addon import looks
    vol = rigged
    vol.volrig.use_parts = True  # per-part looks on: the rest volume gets its part grids
    names = [p.name for p in vol.volrig.parts]
    assert set(names) == {"spine", "head", "left arm", "right arm", "left leg", "right leg"}
    assert _part(vol).bones.split(",") == ["shoulder.L", "upper_arm.L", "forearm.L", "hand.L"]
    path = looks.rest_file(vol)
    assert bpy.path.abspath(vol.data.filepath) == path and not vol.data.is_sequence
    keys = [p.key for p in vol.volrig.parts]
    g, _ = _grids(path, ["density"] + [f"{kind}_{k}" for k in keys for kind in ("density", "mask")])
    density = g["density"]
    parts = [g[f"density_{k}"] for k in keys]
    masks = [g[f"mask_{k}"] for k in keys]
    # the parts split the object's voxels: their densities sum to the density there, masks are 0/1 and disjoint
    total = np.sum(masks, axis=0)
    assert set(np.unique(total)) <= {0.0, 1.0}
    assert np.count_nonzero(total) == np.count_nonzero(density)  # every object voxel is in a part
    assert np.array_equal(np.sum(parts, axis=0)[total > 0], density[total > 0])
    # settings survive finding the parts again; Show Source shows the rest volume with its parts
    _part(vol).colored = True
    run_op(bpy.ops.volrig.find_parts)
    assert _part(vol).colored
    run_op(bpy.ops.volrig.show_rest)
    assert bpy.path.abspath(vol.data.filepath) == path


def _stage(vol, tmp_path):
    from volrig_addon import staging
    scene = bpy.context.scene
    staging.stage(scene, vol, resolution=(48, 96), samples=4)
    scene.render.film_transparent = True
    scene.cycles.pixel_filter_type = "BOX"  # every sample inside its own pixel: regions are exact
    scene.cycles.filter_width = 1.0
    scene.render.filter_size = 0.0  # (EEVEE's, likewise)
    if "1" in scene.eevee.bl_rna.properties["volumetric_tile_size"].enum_items.keys():  # (EEVEE 4.2+)
        scene.eevee.volumetric_tile_size = "1"  # a froxel a pixel (the add-on's 2 blurs a 48-pixel figure)
    scene.cycles.seed = 7
    scene.view_settings.view_transform = "Standard"  # (Filmic would turn a bright red towards white)
    return scene


def _render(scene, path):
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_png(path)


def _projected(scene, vol, mask_array, first, grow, outer=True):
    """Pixels (rows top-down) onto which the voxels of ``mask_array`` (z, y, x; voxel 0 at ``first``, volume
    units), dilated by ``grow`` voxels (the trilinear support and the voxel's extent), project; dilated by one
    pixel and the engine's spread (``outer``: every pixel they touch; silhouettes.spread: none in Cycles) or eroded
    by one (the pixels they cover)."""
    from scipy import ndimage
    padded = np.pad(mask_array > 0, grow)
    voxels = np.argwhere(ndimage.binary_dilation(padded, iterations=grow) if grow else padded)[:, ::-1] - grow
    local = np.asarray(first) + voxels * np.asarray(vol.volrig.spacing)
    # the orthographic camera's view: camera-space x, y against its frame
    to_cam = np.array(scene.camera.matrix_world.inverted() @ vol.matrix_world)
    xy = local @ to_cam[:2, :3].T + to_cam[:2, 3]
    frame = np.array([tuple(v) for v in scene.camera.data.view_frame(scene=scene)])[:, :2]
    lo, hi = frame.min(axis=0), frame.max(axis=0)
    uv = (xy - lo) / (hi - lo)
    w, h = scene.render.resolution_x, scene.render.resolution_y
    px, py = np.floor(uv[:, 0] * w).astype(int), np.floor((1.0 - uv[:, 1]) * h).astype(int)
    keep = (px >= 0) & (px < w) & (py >= 0) & (py < h)
    out = np.zeros((h, w), bool)
    out[py[keep], px[keep]] = True
    if not outer:
        return ndimage.binary_erosion(out)
    return ndimage.binary_dilation(out, iterations=1 + spread(scene))  # (EEVEE's froxels spread a voxel's look)


def test_hidden_and_coloured_parts_render_exactly(rigged, tmp_path):
    from volrig_addon import looks
    vol = rigged
    vol.volrig.use_parts = True  # per-part looks on: the rest volume gets its part grids
    vol.volrig.preset = "GREY"
    vol.volrig.density_scale = 3.0  # per mm (object space): opaque, a pixel crossing the part is covered
    scene = _stage(vol, tmp_path)
    full = _render(scene, tmp_path / "full.png")
    assert compare("parts_full", tmp_path / "full.png", alpha=True) > PASS  # the figure of 3.4's Cycles
    keys = [p.key for p in vol.volrig.parts]
    g, first = _grids(looks.rest_file(vol), [f"mask_{k}" for k in keys])
    arm = g.pop(f"mask_{_part(vol).key}")
    others = np.sum(list(g.values()), axis=0)
    region = _projected(scene, vol, arm, first, grow=2)
    only_arm = _projected(scene, vol, arm, first, grow=0, outer=False) & ~_projected(scene, vol, others, first, grow=2)
    assert region.mean() < 0.3 and only_arm.sum() >= 10
    assert full[..., 3][only_arm].mean() > 0.9  # the arm is there

    _part(vol).visible = False
    hidden = _render(scene, tmp_path / "hidden.png")
    changed = np.abs(hidden[..., 3] - full[..., 3]) > 1e-4
    assert changed.any() and not (changed & ~region).any()  # the alpha changes inside the arm's region only
    assert hidden[..., 3][only_arm].max() < 1e-3  # where only the arm was, nothing is left

    _part(vol).visible = True
    _part(vol).colored = True
    _part(vol).color = (1.0, 0.0, 0.0)
    red = _render(scene, tmp_path / "red.png")
    outside = ~region
    assert np.array_equal(red[outside], full[outside])  # no fringe: nothing outside the arm's region changes
    seen = only_arm & (full[..., 3] > 0.2)
    # the arm turns red (not all of it: Cycles interpolates a volume's grids stochastically, so at the arm's
    # surface, where most light scatters, the mask read is 0 or 1 at random)
    redder = (red[..., 0] - red[..., 1])[seen] - (full[..., 0] - full[..., 1])[seen]
    assert np.all(redder >= -1e-6) and redder.mean() > 0.05


def test_bake_writes_part_grids_and_explodes(rigged):
    from volrig_addon import bake
    vol = rigged
    vol.volrig.use_parts = True  # per-part looks on: the rest volume gets its part grids
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 2
    vol.volrig.explode = 0.0
    vol.volrig.keyframe_insert("explode", frame=1)
    vol.volrig.explode = 1.0
    vol.volrig.keyframe_insert("explode", frame=2)
    run_op(bpy.ops.volrig.bake)
    f1, f2 = bake.frame_path(vol, 1), bake.frame_path(vol, 2)
    keys = [p.key for p in vol.volrig.parts]
    assert {g["name"] for g in volrig._volrig.vdb_grids(f1)} == {"density", "bone"} | {
        f"{kind}_{k}" for k in keys for kind in ("density", "mask")}
    state = bake.RigState(vol)
    hand = state.names.index("hand.L") + 1
    b1, b2 = volrig.load(f1, grid="bone"), volrig.load(f2, grid="bone")
    world1 = np.asarray(b1.origin) + np.argwhere(b1.array == hand).mean(axis=0)[::-1] * np.asarray(b1.spacing)
    world2 = np.asarray(b2.origin) + np.argwhere(b2.array == hand).mean(axis=0)[::-1] * np.asarray(b2.spacing)
    expected = volrig.parts.explode_offsets(state.rig, 1.0)[hand - 1]
    assert np.linalg.norm(expected) > 20.0
    assert np.linalg.norm(world2 - world1 - expected) < 0.25 * np.linalg.norm(expected)
    # the arm's grids in the exploded frame: its density part equals the density on its voxels
    key = _part(vol).key
    g, _ = _grids(f2, ["density", f"density_{key}", f"mask_{key}"])
    inside = g[f"mask_{key}"] > 0
    assert inside.any() and np.array_equal(g[f"density_{key}"][inside], g["density"][inside])
    assert not g[f"density_{key}"][~inside].any()


def test_a_part_takes_its_values_from_a_substitute_volume(rigged, phantom_file, tmp_path, capsys):
    from volrig_addon import bake, looks
    vol = rigged
    vol.volrig.use_parts = True
    ph = phantom_file[1]
    doubled = tmp_path / "doubled.nrrd"
    ph.volume.like(ph.volume.array.astype(np.float32) * 2).save(str(doubled))
    _part(vol).substitute = str(doubled)  # the rest volume is written again with the arm's values from it
    top = float(ph.volume.array.max())
    assert volrig.load(looks.rest_file(vol), grid=f"density_{_part(vol).key}").array.max() == 2 * top
    assert volrig.load(looks.rest_file(vol), grid="density_right_leg").array.max() == top
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 1
    run_op(bpy.ops.volrig.bake)
    baked = volrig.load(bake.frame_path(vol, 1), grid=f"density_{_part(vol).key}")
    assert baked.array.max() == pytest.approx(2 * top, rel=1e-3)
    _part(vol).substitute = str(tmp_path / "missing.nrrd")
    assert "the substitute of part 'left arm'" in capsys.readouterr().out  # said at once, nothing raised
    with pytest.raises(RuntimeError, match="substitute of part 'left arm'"):
        bpy.ops.volrig.bake()


def test_a_part_with_its_own_transfer_function(rigged, tmp_path):
    from volrig_addon import looks
    vol = rigged
    vol.volrig.use_parts = True
    vol.volrig.preset = "GREY"
    vol.volrig.density_scale = 3.0
    scene = _stage(vol, tmp_path)
    full = _render(scene, tmp_path / "full.png")
    g, first = _grids(looks.rest_file(vol), [f"mask_{p.key}" for p in vol.volrig.parts])
    region = _projected(scene, vol, g[f"mask_{_part(vol).key}"], first, grow=2)
    _part(vol).preset = "SOFT_TISSUE"  # reddish and translucent where the volume's look is grey
    nodes = vol.data.materials[0].node_tree.nodes
    assert sum(n.type == "VALTORGB" for n in nodes) == 2  # the volume's ramp and the arm's own
    own = _render(scene, tmp_path / "own.png")
    assert np.abs(own[~region] - full[~region]).max() < 1.5 / 255  # nothing outside the arm's region changes
    inside = _projected(scene, vol, g[f"mask_{_part(vol).key}"], first, grow=0, outer=False) & (full[..., 3] > 0.2)
    redder = (own[..., 0] - own[..., 2])[inside] - (full[..., 0] - full[..., 2])[inside]
    assert inside.sum() >= 10 and redder.mean() > 0.05

"""Render tests in every Blender, each with the engine it can use (Cycles, or EEVEE where that Cycles renders no
grids: volrig_addon.engines): the figure's silhouette is compared against the Blender 3.4 Cycles frame of the same
scene, kept as a PNG in tests/blender/references/ (look at them: they are the renders themselves).

``VOLRIG_WRITE_REFERENCES=1`` in Blender 3.4 writes them anew (scripts/test never sets it)."""
import os
import shutil

import bpy
import numpy as np

REFERENCES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "references")
#: The score (see compare) a render must pass: the same figure scores 0.9 to 1 in Cycles and EEVEE; the figure
#: moved by 6 pixels of 96 scores about 0.6, a blank render 0.
PASS = 0.8


def read_png(path) -> np.ndarray:
    """RGBA float pixels (rows top-down) of a PNG, as stored (no colour management)."""
    img = bpy.data.images.load(str(path))
    try:
        img.colorspace_settings.name = "Non-Color"
        px = np.array(img.pixels[:], dtype=np.float32).reshape(img.size[1], img.size[0], 4)
    finally:
        bpy.data.images.remove(img)
    return px[::-1]  # Blender's pixels run bottom-up


def silhouette(px: np.ndarray, alpha: bool = False) -> np.ndarray:
    """The figure's pixels: alpha above 0.1 (a transparent film), else a luminance a fifth of the figure's
    brightest contrast away from the background (the median of the left and right three columns)."""
    if alpha:
        return px[..., 3] > 0.1
    lum = px[..., :3].mean(axis=2)
    background = np.median(np.concatenate([lum[:, :3].ravel(), lum[:, -3:].ravel()]))
    contrast = np.abs(lum - background)
    return contrast > max(0.2 * contrast.max(), 0.01)


def compare(name: str, rendered_path, alpha: bool = False) -> float:
    """How well the silhouette in ``rendered_path`` matches the one in the reference ``name``.png (Blender 3.4,
    Cycles): the share of their union's pixels where they agree to within a pixel (a pixel of one within a pixel of
    the other; Cycles' sampling noise at a translucent edge and EEVEE's froxels move edges by about one). 1 is the
    same figure; a figure shifted, missing a limb or blank scores far lower. In Blender 3.4 with
    VOLRIG_WRITE_REFERENCES=1 the render becomes the reference first."""
    from scipy import ndimage
    ref = os.path.join(REFERENCES, f"{name}.png")
    if os.environ.get("VOLRIG_WRITE_REFERENCES") == "1" and bpy.app.version[:2] == (3, 4):
        os.makedirs(REFERENCES, exist_ok=True)
        shutil.copyfile(str(rendered_path), ref)
    assert os.path.isfile(ref), f"no reference {ref}: make it in Blender 3.4 with VOLRIG_WRITE_REFERENCES=1"
    got, want = silhouette(read_png(rendered_path), alpha), silhouette(read_png(ref), alpha)
    assert got.shape == want.shape, (got.shape, want.shape)
    union = got | want
    assert union.any(), "both renders are empty"
    agree = (got & ndimage.binary_dilation(want)) | (want & ndimage.binary_dilation(got))
    score = np.count_nonzero(agree) / np.count_nonzero(union)
    print(f"silhouette {name} ({bpy.context.scene.render.engine}): {score:.3f}")
    return score


def spread(scene) -> int:
    """Pixels by which the engine spreads a voxel's look beyond the pixels it covers: none in Cycles (its
    samples stay in their pixels with the box filter the tests set); in EEVEE a froxel (``volumetric_tile_size``
    pixels) and its trilinear neighbour."""
    if scene.render.engine == "CYCLES":
        return 0
    return int(scene.eevee.volumetric_tile_size) + 1

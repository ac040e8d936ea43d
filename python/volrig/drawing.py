"""A drawing becomes a character: ``inflate`` lifts a single front-view drawing to a rounded solid to rig.

Frame (world units = ``pixel_size`` per pixel): the drawing's up is +Z, its right +X, and depth runs along +Y, away
from the viewer (the drawing is seen from -Y, as Blender's front view sees the scene). Pixel (row r, column c) of an
H-row drawing lies at x = c * pixel_size, z = (H - 1 - r) * pixel_size; y = 0 is the mid-plane of the parts that
touch the outline.

Steps (each a function below):

1. ``foreground``: alpha > 0.5 where the image has a (not fully opaque) alpha channel, else the pixels that differ
   clearly from the background colour (the median of the image border) and are not connected to the border
   through background-coloured pixels (so a line drawing with a white fill is solid). The largest 8-connected
   part is kept.
2. ``strokes``: dark pixels (luminance below ``stroke_level``) inside the silhouette that form thin lines (they
   vanish under an opening by a disc of radius ``stroke_width``: a dark filled shape is not a stroke).
3. ``parts``: the silhouette cut by the strokes into 4-connected regions (tiny ones merged into their nearest
   neighbour; stroke pixels go to the nearest region). A region is drawn *in front* (an arm across the body, a
   near leg over a side view's belly) when the outline of what lies behind it runs on under it: the rest of the
   silhouette, closed by a disc a little wider than the region, covers at least a square of the region's width
   of it (amodal completion across T-junctions). The largest region and the others form the base.
4. Inflation (after Teddy / Olsen & Samavati's distance-based inflation; paper 002 sweeps circular cross-sections
   around a 2-D skeleton): at a pixel at distance D from its part's outline, inside a part whose local radius
   (the radius of the largest inscribed disc covering the pixel, from the 2-D medial axis) is R, the solid spans
   half-depth ``depth_scale * sqrt(R^2 - (R - D)^2)`` on both sides of the part's mid-plane: circular cross
   sections (a disc becomes a ball, a bar a cylinder); ``depth_scale < 1`` flattens. The base is inflated as one
   shape, completed under the parts drawn in front of it (the gaps those parts leave in it closed). Each front
   part is inflated on its own, its mid-plane moved toward the viewer until it lies in front of everything
   inflated so far, plus ``gap`` voxels (0: touching, so the solid stays one piece).

``drawing_colours`` projects the drawing's colours along depth (the outline strokes replaced by the nearest fill
colour, paper 002's border expansion, so the sides are not painted black).
"""
from __future__ import annotations

import os
import zlib
import struct
from dataclasses import dataclass
from typing import List, Optional

import numpy as np

from . import _volrig
from ._optional import LazyModule
from ._volrig import VolrigError
from .volume import Volume

# scipy.ndimage on first use: importing this module (the add-on does) needs no scipy; reading a drawing does
ndi = LazyModule("scipy.ndimage", "volrig.drawing (inflate, drawing_colours: drawings as volumes)")

#: a pixel differs "clearly" from the background when a channel differs by more than this (0..1)
BACKGROUND_DIFFERENCE = 0.2
#: parts smaller than this share of the silhouette (or than stroke_width^2 pixels) merge into a neighbour
MIN_PART = 0.005
#: a part is drawn in front when the closed rest of the silhouette covers this many squares of its width of it
COVERED = 0.5


# ---- images -------------------------------------------------------------------------------------------------------

def read_png(path: str) -> np.ndarray:
    """An (H, W, 4) uint8 RGBA array from a PNG file (native libpng reader; FileFormatError when malformed)."""
    from .volume import _native_path
    return _volrig.read_png(_native_path(path)[1])


def write_png(path: str, image: np.ndarray) -> None:
    """Writes an image (as ``inflate`` takes it) as an 8-bit RGB or RGBA PNG (zlib, no filters), atomically."""
    from .files import atomic_output
    rgb, alpha = _rgb_alpha(_as_float(image))
    a = rgb if alpha is None else np.dstack([rgb, alpha])
    a = np.round(a * 255).astype(np.uint8)
    h, w, c = a.shape
    raw = b"".join(b"\0" + a[r].tobytes() for r in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    header = struct.pack(">IIBBBBB", w, h, 8, 6 if c == 4 else 2, 0, 0, 0)
    with atomic_output(os.fspath(path), suffix=".png") as tmp:
        with open(tmp, "wb") as f:
            f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 6))
                    + chunk(b"IEND", b""))


def _as_float(image) -> np.ndarray:
    """(H, W, C) float64 in 0..1, C in 1..4 (grey, grey+alpha, RGB, RGBA); a path is read as PNG."""
    if isinstance(image, (str, os.PathLike)):
        image = read_png(image)
    a = np.asarray(image)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4) or min(a.shape[:2]) < 3:
        raise VolrigError(f"a drawing must be an (H, W), (H, W, 3) or (H, W, 4) image at least 3 x 3 pixels, "
                          f"got shape {a.shape}")
    if a.dtype == np.bool_:
        return a.astype(np.float64)
    if a.dtype.kind == "u":
        return a.astype(np.float64) / float(np.iinfo(a.dtype).max)
    if a.dtype.kind != "f":
        raise VolrigError(f"a drawing's pixels must be unsigned integers, bool or floats in 0..1, not {a.dtype}")
    a = a.astype(np.float64)
    if not np.isfinite(a).all():
        raise VolrigError("the drawing holds NaN or infinite pixels")
    if a.min() < 0 or a.max() > 1:
        raise VolrigError(f"a float drawing's pixels must lie in 0..1, got {a.min():g} .. {a.max():g}")
    return a


def _rgb_alpha(a: np.ndarray):
    """(rgb (H, W, 3), alpha (H, W) or None) of a float image."""
    c = a.shape[2]
    rgb = np.repeat(a[:, :, :1], 3, axis=2) if c <= 2 else a[:, :, :3]
    alpha = a[:, :, -1] if c in (2, 4) else None
    return rgb, alpha


def _downscale(a: np.ndarray, factor: int) -> np.ndarray:
    """Block average by an integer factor (the image cropped to a multiple of it)."""
    if factor <= 1:
        return a
    h, w = a.shape[0] // factor * factor, a.shape[1] // factor * factor
    return a[:h, :w].reshape(h // factor, factor, w // factor, factor, -1).mean(axis=(1, 3))


# ---- silhouette, strokes, parts ---------------------------------------------------------------------------------

def _disc(r: float) -> np.ndarray:
    k = int(np.ceil(r))
    y, x = np.mgrid[-k:k + 1, -k:k + 1]
    return x * x + y * y <= r * r


def _largest(mask: np.ndarray) -> np.ndarray:
    lab, n = ndi.label(mask, structure=np.ones((3, 3)))
    if n <= 1:
        return mask
    sizes = np.bincount(lab.ravel())[1:]
    return lab == 1 + int(np.argmax(sizes))


def foreground(rgb: np.ndarray, alpha: Optional[np.ndarray]) -> np.ndarray:
    """The silhouette (see the module docstring, step 1); VolrigError when it is empty or when the image border is
    not a background (an image that is all figure)."""
    if alpha is not None and (alpha <= 0.5).any():
        fg = alpha > 0.5
    else:
        border = np.concatenate([rgb[0], rgb[-1], rgb[:, 0], rgb[:, -1]])
        bg = np.median(border, axis=0)
        like_bg = np.abs(rgb - bg).max(axis=2) <= BACKGROUND_DIFFERENCE
        ring = np.concatenate([like_bg[0], like_bg[-1], like_bg[:, 0], like_bg[:, -1]])
        if ring.mean() < 0.5:
            raise VolrigError("the drawing has no background: its border is not of one colour (draw the figure on "
                              "a plain light background, or give it an alpha channel)")
        lab, _ = ndi.label(like_bg)
        edge = np.unique(np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]]))
        fg = ~np.isin(lab, edge[edge > 0])
    if not fg.any():
        raise VolrigError("the drawing is empty: no pixel is opaque (alpha > 0.5) or differs from the background")
    return _largest(fg)


def strokes(rgb: np.ndarray, fg: np.ndarray, stroke_width: float, stroke_level: float) -> np.ndarray:
    """Thin dark lines inside the silhouette (step 2)."""
    dark = fg & (rgb @ np.array([0.2126, 0.7152, 0.0722]) < stroke_level)
    thick = ndi.binary_opening(dark, structure=_disc(stroke_width))
    return dark & ~thick


def _nearest_fill(labels: np.ndarray, where: np.ndarray) -> np.ndarray:
    """labels with every pixel of ``where`` set to the label of its nearest labelled (> 0) pixel."""
    idx = ndi.distance_transform_edt(labels == 0, return_distances=False, return_indices=True)
    out = labels.copy()
    out[where] = labels[idx[0][where], idx[1][where]]
    return out


def parts(fg: np.ndarray, lines: np.ndarray, stroke_width: float) -> np.ndarray:
    """(H, W) int32 part labels 1..n over the silhouette, 0 outside (step 3)."""
    lab, n = ndi.label(fg & ~lines)
    if n == 0:
        return fg.astype(np.int32)
    sizes = np.bincount(lab.ravel())[1:]
    keep = np.flatnonzero(sizes >= max(MIN_PART * fg.sum(), stroke_width ** 2)) + 1
    if keep.size == 0:
        keep = np.array([1 + int(np.argmax(sizes))])
    renumber = np.zeros(n + 1, np.int32)
    renumber[keep] = np.arange(1, keep.size + 1)
    return _nearest_fill(renumber[lab], fg).astype(np.int32) * fg


def closing(shape: np.ndarray, r: float) -> np.ndarray:
    """Binary closing of ``shape`` by a disc of radius ``r`` (through two distance transforms)."""
    grown = ndi.distance_transform_edt(~shape) <= r
    return ndi.distance_transform_edt(grown) > r


def in_front(labels: np.ndarray) -> List[int]:
    """The parts drawn in front of others: the rest of the silhouette, closed by a disc a little wider than the
    part, covers at least ``COVERED`` squares of the part's width of it (the outline of what lies behind runs on
    under the part: T-junctions). The largest part is never in front."""
    n = int(labels.max())
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    out = []
    for p in range(1, n + 1):
        shape = labels == p
        if p == int(np.argmax(sizes[1:])) + 1:
            continue
        r = float(ndi.distance_transform_edt(shape).max()) + 2.0
        covered = int((shape & closing((labels > 0) & ~shape, r)).sum())
        if covered >= COVERED * (2 * r) ** 2:
            out.append(p)
    return out


# ---- inflation --------------------------------------------------------------------------------------------------

def local_radius(shape: np.ndarray, edt: np.ndarray) -> np.ndarray:
    """Per pixel of ``shape``: the radius of the largest inscribed disc covering it, less half a pixel (the outline
    lies half a pixel inside the nearest background pixel's centre); ``edt`` is the distance to that centre. The
    native local thickness on a one-slice grid (discs are its balls; Hildebrand-Ruegsegger, time near-linear)."""
    thick = np.asarray(_volrig.local_thickness_from_dt(edt.astype(np.float32)[None], (1.0, 1.0, 1.0)))[0]
    return np.where(shape, thick / 2.0 - 0.5, 0.0)  # >= edt - 0.5: a pixel lies in its own disc


def half_depth(shape: np.ndarray, depth_scale: float) -> np.ndarray:
    """depth_scale * sqrt(R^2 - (R - D)^2) over ``shape`` (0 outside), in pixels."""
    edt = ndi.distance_transform_edt(shape)
    dist = np.where(shape, edt - 0.5, 0.0)
    r = local_radius(shape, edt)
    return depth_scale * np.sqrt(np.maximum(r * r - (r - dist) ** 2, 0.0)) * shape


def _completed(base: np.ndarray, front: np.ndarray) -> np.ndarray:
    """``base`` with the gaps the parts in ``front`` leave in it closed (a closing as wide as those parts)."""
    if not front.any():
        return base
    r = float(ndi.distance_transform_edt(front).max()) + 2.0
    return base | (front & ndi.binary_fill_holes(closing(base, r)))


@dataclass
class Layer:
    """One inflated part: its pixels, half-depth (pixels) and mid-plane (y, voxels; negative = toward the viewer)."""
    label: int
    shape: np.ndarray
    half: np.ndarray
    centre: int


def layers(labels: np.ndarray, depth_scale: float, gap: int) -> List[Layer]:
    """The base (label 0 stands for it) and each front part, placed along depth (step 4)."""
    front = in_front(labels)
    front_pixels = np.isin(labels, front)
    base = _completed((labels > 0) & ~front_pixels, front_pixels)
    out = [Layer(0, base, half_depth(base, depth_scale), 0)]
    # voxel y is in a layer where |y - centre| <= half, i.e. from centre - floor(half) to centre + floor(half)
    nearest = np.where(base, -np.floor(out[0].half), np.inf)  # the front-most voxel so far per pixel
    for p in sorted(front, key=lambda q: -int((labels == q).sum())):  # the larger first: behind the smaller
        shape = labels == p
        half = half_depth(shape, depth_scale)
        extent = np.floor(half)
        over = shape & np.isfinite(nearest)
        centre = int((nearest[over] - extent[over]).min()) - 1 - gap if over.any() else 0
        out.append(Layer(p, shape, half, centre))
        nearest = np.where(shape, np.minimum(nearest, centre - extent), nearest)
    return out


# ---- the drawing ------------------------------------------------------------------------------------------------

@dataclass
class Drawing:
    """A drawing read and analysed, cropped to the figure and a margin: rgb (h, w, 3) float 0..1, the silhouette,
    its strokes and parts (labels 1..n), the pixel size after any downscaling, the crop's first row and column and
    the whole image's row and column counts (which place the crop in the frame: see the module docstring)."""
    rgb: np.ndarray
    silhouette: np.ndarray
    strokes: np.ndarray
    parts: np.ndarray
    pixel_size: float
    row0: int = 0
    col0: int = 0
    rows: int = 0
    cols: int = 0

    def x_of(self, col):
        """World x of crop column(s) ``col``."""
        return (np.asarray(col) + self.col0) * self.pixel_size

    def z_of(self, row):
        """World z of crop row(s) ``row``."""
        return (self.rows - 1 - (np.asarray(row) + self.row0)) * self.pixel_size


def analyse(image, *, pixel_size: float = 1.0, stroke_width: float = 3.0, stroke_level: float = 0.3,
            resolution: Optional[int] = None) -> Drawing:
    """Steps 1-3 of the module docstring. ``resolution``: block-average the image down so that its longer side
    has at most about this many pixels (pixel_size grows by the same factor)."""
    if not (np.isfinite(pixel_size) and pixel_size > 0):
        raise VolrigError(f"pixel_size must be a positive number, got {pixel_size!r}")
    if not (np.isfinite(stroke_width) and stroke_width > 0):
        raise VolrigError(f"stroke_width must be a positive number of pixels, got {stroke_width!r}")
    if resolution is not None and not (int(resolution) == resolution and resolution >= 16):
        raise VolrigError(f"resolution must be a whole number of pixels >= 16, got {resolution!r}")
    a = _as_float(image)
    factor = 1 if not resolution else max(1, int(np.ceil(max(a.shape[:2]) / float(resolution))))
    a = _downscale(a, factor)
    rgb, alpha = _rgb_alpha(a)
    fg = foreground(rgb, alpha)
    (r0, r1), (c0, c1) = ((max(i.min() - 4, 0), i.max() + 5) for i in np.nonzero(fg))  # 4: blocks the crop's edge
    rgb, fg = rgb[r0:r1, c0:c1], fg[r0:r1, c0:c1]                                       # away from the figure
    lines = strokes(rgb, fg, stroke_width, stroke_level)
    return Drawing(rgb, fg, lines, parts(fg, lines, stroke_width), float(pixel_size) * factor, int(r0), int(c0),
                   int(a.shape[0]), int(a.shape[1]))


def _depth_range(placed: List[Layer]):
    lo = min(int(np.floor((l.centre - l.half[l.shape]).min())) for l in placed)
    hi = max(int(np.ceil((l.centre + l.half[l.shape]).max())) for l in placed)
    return lo - 1, hi + 1


#: the largest solid ``inflate`` builds unless told (voxels of its box: 1 GiB of int32 labels); docs/drawing.md
MAX_VOXELS = 2 ** 28


def _check_size(image, shape, longer_side: int, max_voxels: int) -> None:
    n = int(np.prod(shape, dtype=np.int64))
    if n > max_voxels:
        fits = int(longer_side * (max_voxels / n) ** (1 / 3))
        named = f"{os.fsdecode(image)}: " if isinstance(image, (str, bytes, os.PathLike)) else ""
        raise VolrigError(f"{named}the drawing inflates to a {shape[2]} x {shape[1]} x {shape[0]} solid "
                          f"({n:,} voxels), more than max_voxels={max_voxels:,}: pass resolution={fits} (or less) "
                          f"to downscale it, or raise max_voxels")


def _fill_layers(out: np.ndarray, y0: int, bounds) -> None:
    """Writes each layer's label into ``out`` [z, y, x] (z from the top row down), later layers over earlier: voxel
    y of column (z, x) is in a layer where lo <= y <= hi. One slice at a time: temporaries of one slice only."""
    ys = np.arange(y0, y0 + out.shape[1], dtype=np.int32)[:, None]
    nz = out.shape[0]
    for z in range(nz):
        dst = out[nz - 1 - z]
        for label, lo, hi in bounds:
            np.copyto(dst, label, where=(ys >= lo[z]) & (ys <= hi[z]), casting="unsafe")


def inflate_parts(image, *, pixel_size: float = 1.0, depth_scale: float = 1.0, stroke_width: float = 3.0,
                  stroke_level: float = 0.3, gap: int = 0, resolution: Optional[int] = None,
                  max_voxels: int = MAX_VOXELS):
    """``inflate``'s solid as part labels: (int32 Volume [z, y, x], 0 empty, the base 1 and the front parts
    2.. in the order they were placed; the ``Drawing``)."""
    if not (np.isfinite(depth_scale) and depth_scale > 0):
        raise VolrigError(f"depth_scale must be a positive number, got {depth_scale!r}")
    if int(gap) != gap or gap < 0:
        raise VolrigError(f"gap must be a whole number of voxels >= 0, got {gap!r}")
    d = analyse(image, pixel_size=pixel_size, stroke_width=stroke_width, stroke_level=stroke_level,
                resolution=resolution)
    placed = layers(d.parts, depth_scale, int(gap))
    rows, cols = np.nonzero(d.silhouette)
    r0, r1, c0, c1 = rows.min() - 1, rows.max() + 2, cols.min() - 1, cols.max() + 2
    y0, y1 = _depth_range(placed)
    shape = (int(r1 - r0), int(y1 - y0 + 1), int(c1 - c0))
    _check_size(image, shape, max(d.rows, d.cols), max_voxels)
    bounds = []
    for i, layer in enumerate(placed, start=1):
        extent = np.full((d.silhouette.shape[0] + 2, d.silhouette.shape[1] + 2), -1, np.int32)  # crops reach 1
        extent[1:-1, 1:-1] = np.where(layer.shape, np.floor(layer.half), -1)                 # pixel out
        e = extent[r0 + 1:r1 + 1, c0 + 1:c1 + 1]  # |y - centre| <= half  <=>  |y - centre| <= floor(half)
        bounds.append((i, layer.centre - e, layer.centre + e))
    out = np.zeros(shape, np.int32)
    _fill_layers(out, y0, bounds)
    s = d.pixel_size
    origin = (float(d.x_of(c0)), y0 * s, float(d.z_of(r1 - 1)))
    return Volume(out, (s, s, s), origin), d


def inflate(image, *, pixel_size: float = 1.0, depth_scale: float = 1.0, stroke_width: float = 3.0,
            stroke_level: float = 0.3, gap: int = 0, resolution: Optional[int] = None,
            max_voxels: int = MAX_VOXELS) -> Volume:
    """A rounded solid (bool mask Volume) from one front-view drawing (see the module docstring).

    image:        a PNG path, or an (H, W), (H, W, 3) or (H, W, 4) array (uint8/uint16, bool, or float in 0..1).
    pixel_size:   world units per pixel (the voxel size).
    depth_scale:  half-depth / the circular profile's (1: round cross-sections; < 1 flatter).
    stroke_width: the widest inner line (pixels) that separates parts; stroke_level: how dark (luminance 0..1).
    gap:          empty voxels between a part drawn in front and what lies behind it (0: they touch).
    resolution:   downscale a large drawing to about this many pixels along its longer side first.
    max_voxels:   refuse (VolrigError, naming the resolution that fits) a solid whose box holds more voxels.
    """
    labels, _ = inflate_parts(image, pixel_size=pixel_size, depth_scale=depth_scale, stroke_width=stroke_width,
                              stroke_level=stroke_level, gap=gap, resolution=resolution, max_voxels=max_voxels)
    return labels.like(labels.array > 0)


def fill_colours(d: Drawing, stroke_width: float = 3.0) -> np.ndarray:
    """(H, W, 3) colours: the outline strokes (dark lines within stroke_width + 1 of the silhouette's edge) and the
    background take the colour of the nearest fill pixel (paper 002's border expansion)."""
    near_edge = ndi.distance_transform_edt(d.silhouette) <= stroke_width + 1
    fill = d.silhouette & ~d.strokes
    if not fill.any():
        return d.rgb
    idx = ndi.distance_transform_edt(~fill, return_distances=False, return_indices=True)
    replace = (d.strokes & near_edge) | ~d.silhouette
    out = d.rgb.copy()
    out[replace] = d.rgb[idx[0][replace], idx[1][replace]]
    return out


def drawing_colours(image, volume: Volume, *, stroke_width: float = 3.0, stroke_level: float = 0.3,
                    resolution: Optional[int] = None) -> np.ndarray:
    """The drawing's colours projected along depth onto ``volume``'s grid (made by ``inflate`` of the same image
    and options): a read-only (nz, ny, nx, 3) float32 array in 0..1 (a broadcast view: no memory per voxel)."""
    d = analyse(image, stroke_width=stroke_width, stroke_level=stroke_level, resolution=resolution)
    colours = fill_colours(d, stroke_width).astype(np.float32)
    s = volume.spacing[0]
    nx, ny, nz = volume.dims
    cols = np.round((volume.origin[0] + s * np.arange(nx)) / s).astype(int) - d.col0
    rows = d.rows - 1 - np.round((volume.origin[2] + s * np.arange(nz)) / s).astype(int) - d.row0
    cols, rows = np.clip(cols, 0, colours.shape[1] - 1), np.clip(rows, 0, colours.shape[0] - 1)
    plane = colours[rows[:, None], cols[None, :]]  # (nz, nx, 3)
    return np.broadcast_to(plane[:, None, :, :], (nz, ny, nx, 3))


#: the VDB grids of a coloured drawing: the solid and its colour channels (what the add-on's material reads)
COLOUR_GRIDS = ("color_r", "color_g", "color_b")


def drawing_grids(image, **options):
    """``inflate(image, **options)`` and the grids to write for a renderer: (mask Volume, {"density": 0/1 float32,
    "color_r"/"color_g"/"color_b": the projected colour on the solid, 0 elsewhere})."""
    mask = inflate(image, **options)
    keep = {k: options[k] for k in ("stroke_width", "stroke_level", "resolution") if k in options}
    colours = drawing_colours(image, mask, **keep)
    grids = {"density": mask.like(mask.array.astype(np.float32))}
    for c, name in enumerate(COLOUR_GRIDS):
        grids[name] = mask.like(np.where(mask.array, colours[..., c], np.float32(0)))
    return mask, grids


def write_drawing_vdb(path: str, image, **options) -> Volume:
    """Inflates ``image`` and writes its grids (``drawing_grids``) to an OpenVDB file; returns the mask."""
    from .volume import write_vdb
    mask, grids = drawing_grids(image, **options)
    write_vdb(path, grids, half=False)
    return mask


def colour_labels(image, max_colours: int = 24, **options):
    """``inflate(image, **options)`` with its colour as a label map, which survives posing (a deformation
    resamples labels nearest) and renders through a palette: (float32 Volume, 0 outside the solid and 1..K
    inside, the label of each voxel's projected colour; palette (K, 3) float 0..1). The colours are quantized to
    at most ``max_colours`` (8 levels per channel, the most common bins kept, every pixel to the nearest)."""
    mask = inflate(image, **options)
    keep = {k: options[k] for k in ("stroke_width", "stroke_level", "resolution") if k in options}
    colours = drawing_colours(image, mask, **keep)[:, 0]  # (nz, nx, 3): the same along depth
    seen = mask.array.any(axis=1)
    bins = np.minimum((colours * 8).astype(np.int32), 7) @ np.array([64, 8, 1])
    counts = np.bincount(bins[seen], minlength=512)
    top = np.argsort(counts)[::-1][:max_colours]
    top = top[counts[top] >= max(1, counts[top[0]] // 1000)]  # specks (a few pixels of one colour) dropped
    palette = np.array([colours[seen & (bins == b)].mean(axis=0) for b in top])
    nearest = np.argmin(((colours[:, :, None, :] - palette[None, None]) ** 2).sum(axis=3), axis=2)
    labels = np.where(mask.array, (nearest + 1).astype(np.float32)[:, None, :], np.float32(0))
    return mask.like(labels), palette

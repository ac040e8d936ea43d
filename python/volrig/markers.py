"""Markers: joints the user points at (``autorig(..., markers=)``). A click on a view is a ray; the marker goes
where the ray crosses the body's nearest part, half-way through it (``ray_marker``), where a joint lies: a click
on a knee puts the marker inside the knee, not on its skin."""
from __future__ import annotations

from typing import Optional

import numpy as np

from .volume import Volume


def ray_marker(mask: Volume, origin, direction, max_length: Optional[float] = None) -> Optional[np.ndarray]:
    """The middle of the first run of object voxels along a ray (world frame of ``mask``: x, y, z), or None when
    the ray misses the object. Sampled every half of the finest spacing from where the ray enters the grid's box
    up to ``max_length`` (default: through the box)."""
    arr = np.asarray(mask.array, dtype=bool)
    o = np.asarray(origin, dtype=np.float64).reshape(3)
    d = np.asarray(direction, dtype=np.float64).reshape(3)
    if not (np.isfinite(o).all() and np.isfinite(d).all()) or not np.linalg.norm(d) > 0:
        raise ValueError("ray_marker: the ray needs a finite origin and a non-zero direction")
    d = d / np.linalg.norm(d)
    spacing, grid_origin = np.asarray(mask.spacing, float), np.asarray(mask.origin, float)
    lo = grid_origin - 0.5 * spacing
    hi = grid_origin + (np.array(arr.shape[::-1]) - 0.5) * spacing
    t0, t1 = _box_span(o, d, lo, hi)
    if t1 < max(t0, 0.0):
        return None
    t0 = max(t0, 0.0)
    if max_length is not None:
        t1 = min(t1, t0 + float(max_length))
    step = 0.5 * float(spacing.min())
    t = np.arange(t0, t1 + step, step)
    p = o + t[:, None] * d
    ijk = np.round((p - grid_origin) / spacing).astype(np.int64)
    ok = ((ijk >= 0) & (ijk < np.array(arr.shape[::-1]))).all(1)
    inside = np.zeros(len(t), bool)
    inside[ok] = arr[ijk[ok, 2], ijk[ok, 1], ijk[ok, 0]]
    hits = np.flatnonzero(inside)
    if len(hits) == 0:
        return None
    first = hits[0]
    gaps = np.flatnonzero(~inside[first:])
    last = first + (gaps[0] - 1 if len(gaps) else len(inside) - 1 - first)
    return o + 0.5 * (t[first] + t[last]) * d


def _box_span(o, d, lo, hi):
    """Ray parameters where the ray enters and leaves the box [lo, hi] (t1 < t0: it misses)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = (lo - o) / d, (hi - o) / d
    within = (o >= lo) & (o <= hi)  # along an axis the ray is parallel to: all of it or none
    a = np.where(d == 0, np.where(within, -np.inf, np.inf), a)
    b = np.where(d == 0, np.inf, b)
    return float(np.max(np.minimum(a, b))), float(np.min(np.maximum(a, b)))

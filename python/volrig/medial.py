"""Plates and thickness: the plane-like skeleton and local thickness (``../shared/docs/ALGORITHMS.md`` §11, the Amira paper).

``local_thickness(mask)``: for every object voxel, the diameter of the largest ball inside the object that contains
it (Hildebrand and Rüegsegger 1997; the balls are reconstruction's open balls |q - c| < DT(c), Euclidean, world
units). Computed in the native core: only the centres whose ball is not inside a neighbour's are painted, as x-runs,
slices in parallel; equal to the brute-force maximum over every object voxel's ball (tested).
"""
from __future__ import annotations

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .skeleton import ProgressFn, _geometry, _mask_array
from .volume import Volume


def local_thickness(mask, progress: ProgressFn = None) -> Volume:
    """Local thickness of ``mask`` (a ``Volume`` or a 3-D array [z, y, x]; non-zero = object) as a float32 Volume
    on the same grid, in world units (0 on the background). A plate n voxels thick reads n voxels (n even) or n + 1
    (n odd): DT is measured to the centre of the nearest background voxel. ``progress(fraction)`` may return False
    to cancel (``volrig.Cancelled``)."""
    spacing, origin = _geometry(mask)
    out = _volrig.local_thickness(_mask_array(mask), spacing, progress)
    return Volume(np.asarray(out), spacing, origin)


def _t_world(mask, t: float) -> float:
    if not (t > 0) or not np.isfinite(t):
        raise VolrigError(f"t must be a positive number of voxels, got {t}")
    return float(t) * min(_geometry(mask)[0])


def plane_measure(mask, t: float = 5.0, progress: ProgressFn = None) -> Volume:
    """The Amira paper's plane-like measure d of every object voxel (float32 Volume, world units, 0 on the
    background): the largest geodesic distance, along the object's boundary, between the voxel's nearest boundary
    voxel and those of its three lower neighbours. Large where the nearest boundary jumps across a plate (the way
    round its rim is long), small elsewhere. Distances beyond ``t`` voxels (of the smallest spacing) are not
    followed: they read +inf."""
    spacing, origin = _geometry(mask)
    d = _volrig.plane_measure(_mask_array(mask), spacing, _t_world(mask, t), progress)
    return Volume(np.asarray(d), spacing, origin)


def plane_like(mask, t: float = 5.0, progress: ProgressFn = None) -> Volume:
    """The plane-like skeleton voxels of ``mask`` (bool Volume): plane_measure above ``t`` voxels. On a plate at
    least ~2t across, one layer at its middle (the medial surface), away from its rim by about t; rods thinner
    than about t / pi across, and bumps on a noisy boundary, have none (the paper: t >= 5 against noise; larger t
    keeps only the larger plates)."""
    d = plane_measure(mask, t, progress)
    return Volume(d.array > _t_world(mask, t), d.spacing, d.origin)

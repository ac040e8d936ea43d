"""Thickness of plate-like and rod-like objects (``../shared/docs/ALGORITHMS.md`` §11, the Amira paper).

``local_thickness(mask)``: for every object voxel, the diameter of the largest ball inside the object that contains
it (Hildebrand and Rüegsegger 1997; the balls are reconstruction's open balls |q - c| < DT(c), Euclidean, world
units). Computed in the native core: only the centres whose ball is not inside a neighbour's are painted, as x-runs,
slices in parallel; equal to the brute-force maximum over every object voxel's ball (tested).
"""
from __future__ import annotations

import numpy as np

from . import _volrig
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

"""Segmentation: from a sampled volume to the boolean mask of the object to skeletonize."""
from __future__ import annotations

from typing import Iterable, Optional

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .volume import Volume


def check_range(lo: Optional[float], hi: Optional[float]) -> None:
    """VolrigError unless each given bound is finite and lo <= hi."""
    for name, v in (("lo", lo), ("hi", hi)):
        if v is not None and not np.isfinite(v):
            raise VolrigError(f"{name} must be finite, got {v}")
    if lo is not None and hi is not None and lo > hi:
        raise VolrigError(f"lo ({lo:g}) is above hi ({hi:g})")


def segment(volume: Volume, lo: Optional[float] = None, hi: Optional[float] = None,
            labels: Optional[Iterable[int]] = None, largest_component: bool = False) -> Volume:
    """Boolean mask of the object.

    lo, hi:            keep voxels with lo <= value <= hi (either bound may be omitted; in the volume's units,
                       e.g. Hounsfield units for CT).
    labels:            keep voxels whose value is one of these labels (label maps); combined with lo/hi by AND.
    largest_component: keep only the largest 26-connected part.
    With no criteria at all, every non-zero voxel is object. Raises ValueError for NaN bounds or lo > hi.
    """
    a = volume.array
    check_range(lo, hi)
    mask = None
    if lo is not None:
        mask = a >= lo
    if hi is not None:
        mask = (a <= hi) if mask is None else (mask & (a <= hi))
    if labels is not None:
        labels = np.asarray(list(labels))
        if labels.size == 0:
            raise VolrigError("labels is empty")
        m = np.isin(a, labels)
        mask = m if mask is None else (mask & m)
    if mask is None:
        mask = a != 0
    if np.issubdtype(a.dtype, np.floating):
        mask &= ~np.isnan(a)
    if largest_component:
        mask = _volrig.largest_component(np.ascontiguousarray(mask).view(np.uint8)).view(np.bool_)
    return Volume(mask, volume.spacing, volume.origin)


def label_components(mask):
    """26-connected components of a mask: (labels int32 [z, y, x] with 1 = largest, sizes int64 descending)."""
    arr = mask.array if isinstance(mask, Volume) else np.asarray(mask)
    return _volrig.label_components(np.ascontiguousarray(arr != 0).view(np.uint8))

"""The thinness skeleton (Gagvani's parameter-controlled skeletonization) and binary reconstruction.

``skeletonize(mask)`` computes the distance transform DT, the thinness score s = DT - MNT of every object voxel
(MNT = mean DT of the 26 neighbours) and sorts the voxels by score once. ``Skeleton.at(tp)`` then returns the
skeleton at thinness ``tp`` (voxels with s > tp, Condition 1) in a few milliseconds, for any ``tp``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .volume import Volume

#: Largest useful thinness for each metric: the score of a voxel whose 26 neighbours all lie one step downhill.
MAX_THINNESS = {
    "euclidean": (6 + 12 * np.sqrt(2.0) + 8 * np.sqrt(3.0)) / 26,  # 1.416 (voxel units on unit grids)
    "chamfer345": 106 / 26,                                          # 4.077 (chamfer units)
}

ProgressFn = Optional[Callable[[float], Optional[bool]]]


def _mask_array(mask) -> np.ndarray:
    arr = mask.array if isinstance(mask, Volume) else np.asarray(mask)
    if arr.ndim != 3:
        raise VolrigError(f"mask must be 3-D [z, y, x], got shape {arr.shape}")
    if arr.dtype != np.bool_ and arr.dtype != np.uint8:
        arr = arr != 0
    return np.ascontiguousarray(arr).view(np.uint8)


def _geometry(mask):
    if isinstance(mask, Volume):
        return mask.spacing, mask.origin
    return (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class SkeletonPoints:
    """A skeleton at one thinness: N points sorted by descending score.

    ijk:     (N, 3) int32 voxel indices [z, y, x].
    centers: (N, 3) float64 world positions (x, y, z).
    radii:   (N,) float32 sphere radii in world units (the Euclidean DT; a <3,4,5> DT divided by 3 and scaled by
             the smallest spacing).
    dt:      (N,) float32 DT in the metric's own units (what reconstruction uses).
    scores:  (N,) float32 thinness scores s = DT - MNT.
    metric:  "euclidean" or "chamfer345"; thinness: the TP these points were taken at (None if by count).
    """

    ijk: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    dt: np.ndarray
    scores: np.ndarray
    metric: str
    spacing: tuple
    origin: tuple
    thinness: Optional[float] = None

    def __len__(self) -> int:
        return len(self.ijk)


class Skeleton:
    """Distance transform, scores and the score order of a mask; see ``skeletonize``."""

    def __init__(self, native, spacing, origin, shape):
        self._native = native
        self.spacing = tuple(spacing)
        self.origin = tuple(origin)
        self.shape = tuple(shape)

    @property
    def metric(self) -> str:
        return self._native.metric

    @property
    def dt(self) -> np.ndarray:
        """DT per voxel, [z, y, x] float32 (world units for Euclidean, chamfer units for <3,4,5>). A view: no copy."""
        return self._native.dt

    @property
    def score(self) -> np.ndarray:
        """Thinness score per voxel, [z, y, x] float32; background voxels hold 0. Computed on each access."""
        return self._native.dense_scores()

    @property
    def object_count(self) -> int:
        """Number of object voxels (the skeleton at any TP below every score)."""
        return self._native.object_count

    def count(self, tp: float) -> int:
        """Number of skeleton points at thinness ``tp`` (voxels with score > tp)."""
        return self._native.count_at(float(tp))

    def tp_for_count(self, n: int) -> float:
        """The smallest thinness whose skeleton has at most ``n`` points (exactly ``n`` unless scores tie there)."""
        if n < 0:
            raise VolrigError("n must be >= 0")
        return self._native.tp_for_count(int(n))

    def at(self, tp: float) -> SkeletonPoints:
        """The skeleton at thinness ``tp`` (Condition 1: keep p iff DT(p) - MNT(p) > tp). ``tp`` is in DT units:
        voxels of world size for Euclidean (useful range 0 to 1.416 on unit grids), chamfer units for <3,4,5>
        (0 to 4.077). Larger ``tp`` gives a thinner skeleton; each is a subset of any thicker one."""
        if not np.isfinite(tp):
            raise VolrigError(f"thinness must be finite, got {tp}")
        return self._points(self.count(tp), float(tp))

    def top(self, n: int) -> SkeletonPoints:
        """The ``n`` points of highest score."""
        return self._points(min(int(n), self.object_count), None)

    def _points(self, n: int, tp) -> SkeletonPoints:
        ijk, centers, dt, scores = self._native.points(n)
        radii = dt if self.metric == "euclidean" else (dt / np.float32(3.0)) * np.float32(min(self.spacing))
        return SkeletonPoints(ijk, centers, radii, dt, scores, self.metric, self.spacing, self.origin, tp)

    def __repr__(self) -> str:
        z, y, x = self.shape
        return f"Skeleton({x} x {y} x {z}, {self.metric}, {self.object_count} object voxels)"


def skeletonize(mask, metric: str = "euclidean", progress: ProgressFn = None) -> Skeleton:
    """Distance transform and thinness scores of a binary mask, sorted once.

    mask:     a ``Volume`` (spacing honoured) or a 3-D array [z, y, x]; non-zero / True = object.
    metric:   "euclidean" (exact, world units, anisotropic spacing honoured) or "chamfer345" (weighted <3,4,5>
              chamfer in chamfer units of grid steps; spacing not used).
    progress: optional callable(fraction) -> bool; return False to cancel (raises ``volrig.Cancelled``).
    Voxels outside the array count as background.
    """
    arr = _mask_array(mask)
    spacing, origin = _geometry(mask)
    if metric == "chamfer345" and len(set(spacing)) > 1:
        import warnings
        warnings.warn("chamfer345 ignores anisotropic spacing; use metric='euclidean' for world distances",
                      stacklevel=2)
    native = _volrig.skeletonize(arr, spacing, origin, metric, progress)
    return Skeleton(native, spacing, origin, arr.shape)


def distance_transform(mask, metric: str = "euclidean", progress: ProgressFn = None) -> np.ndarray:
    """DT of a mask alone (see ``skeletonize``): float32 [z, y, x], 0 on background."""
    return _volrig.distance_transform(_mask_array(mask), _geometry(mask)[0], metric, progress)


def reconstruct(points: SkeletonPoints, like, progress: ProgressFn = None) -> Volume:
    """Union of the open balls |q - p| < DT(p) of the skeleton points (in their metric), scan-filled on the grid
    of ``like`` (a Volume or an array giving the shape; the points' spacing and origin are used). Returns a bool
    Volume."""
    shape = (like.array if isinstance(like, Volume) else np.asarray(like)).shape
    if len(shape) != 3:
        raise VolrigError(f"like must be 3-D, got shape {shape}")
    out = _volrig.reconstruct(points.ijk, points.dt, tuple(int(s) for s in shape), points.spacing, points.metric,
                              progress)
    return Volume(out.view(np.bool_), points.spacing, points.origin)


def reconstruction_loss(a, b) -> int:
    """Number of voxels in the symmetric difference of two masks (Volumes or arrays of the same shape)."""
    x = a.array if isinstance(a, Volume) else np.asarray(a)
    y = b.array if isinstance(b, Volume) else np.asarray(b)
    if x.shape != y.shape:
        raise VolrigError(f"masks differ in shape: {x.shape} vs {y.shape}")
    return int(np.count_nonzero((x != 0) != (y != 0)))

"""The skeleton-tree: skeleton points joined by edges that stay inside the object (docs/ALGORITHMS.md §5).

An edge i-j exists only when |i - j| <= E and every voxel of the discrete 3D line between them is an object voxel;
it weighs alpha * |i - j| + (1 - alpha) * |r_i - r_j|. The tree is the minimum spanning forest of that graph
(one tree per part of the object); ``bridge=True`` joins the parts by their closest point pairs.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .skeleton import ProgressFn, SkeletonPoints, _mask_array
from .volume import Volume


@dataclass(frozen=True)
class SkeletonTree:
    """Minimum spanning forest over N skeleton points.

    edges:           (M, 2) uint32 point indices (i < j); M = N - component_count.
    weights:         (M,) float64 edge weights alpha * length + (1 - alpha) * |radius difference|.
    bridged:         (M,) bool, True for edges added by bridging (they may cross background).
    component:       (N,) uint32 component of each point, 0 = the one with most points.
    component_count: number of trees in the forest.
    alpha, max_edge: the parameters used (max_edge in world units).
    """

    edges: np.ndarray
    weights: np.ndarray
    bridged: np.ndarray
    component: np.ndarray
    component_count: int
    alpha: float
    max_edge: float

    def __len__(self) -> int:
        return len(self.edges)

    def degree(self) -> np.ndarray:
        """Number of tree edges at each point."""
        return np.bincount(self.edges.ravel(), minlength=len(self.component)).astype(np.int64)


def _point_arrays(points: SkeletonPoints):
    if not isinstance(points, SkeletonPoints):
        raise TypeError(f"points must be SkeletonPoints (from Skeleton.at), got {type(points).__name__}")
    return np.ascontiguousarray(points.ijk, dtype=np.int32), np.ascontiguousarray(points.radii, dtype=np.float32)


def _mask_for(points: SkeletonPoints, mask) -> np.ndarray:
    arr = _mask_array(mask)
    if isinstance(mask, Volume):
        if not (np.allclose(mask.spacing, points.spacing) and np.allclose(mask.origin, points.origin)):
            raise VolrigError(f"mask geometry (spacing {mask.spacing}, origin {mask.origin}) differs from the "
                             f"skeleton's (spacing {points.spacing}, origin {points.origin})")
    return arr


def skeleton_tree(points: SkeletonPoints, mask, alpha: float = 0.9, max_edge: Optional[float] = None,
                  bridge: bool = False, progress: ProgressFn = None) -> SkeletonTree:
    """Skeleton-tree of ``points`` (from ``Skeleton.at``) inside ``mask`` (the mask they were computed from).

    alpha:    connectivity parameter in [0, 1]: 1 weighs edges by length only, lower values prefer joining points
              of similar radius (the thesis finds 0.8 - 0.95 useful).
    max_edge: longest edge E in world units; default 4 voxel diagonals.
    bridge:   join the parts of the forest by their closest point pairs (ignoring containment), giving one tree.
    """
    ijk, radii = _point_arrays(points)
    arr = _mask_for(points, mask)
    edges, weights, bridged, component, count, e = _volrig.skeleton_tree(
        arr, points.spacing, points.origin, ijk, radii, float(alpha), 0.0 if max_edge is None else float(max_edge), bool(bridge), progress)
    return SkeletonTree(edges, weights, bridged.view(np.bool_), component, int(count), float(alpha), float(e))

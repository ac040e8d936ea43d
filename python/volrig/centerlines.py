"""Centerlines of tubular objects, centerline trees of branching ones, and straightening (issue 20).

``centerline(mask, start, end)`` is the minimal path between two points inside the object where a step costs its
length times (h / DT)^power (the discrete form of VMTK's minimal integral of 1/R: the path keeps to the ridge of the
distance transform DT, so it stays in the middle and avoids narrow bridges), smoothed, moved into the centroid of
each cross-section and sampled at equal arc length, with the DT (the radius of the largest inscribed ball) at each
sample. ``centerline_tree(mask, root)`` grows such paths from the root to every far end (TEASAR) and cuts them into
branches. ``straighten(volume, centerline, radius)`` resamples a volume on the planes normal to a centerline
(rotation-minimising frames, trilinear) into a straight volume. The heavy parts are native
(native/src/centerline/).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .skeleton import _geometry, _mask_array
from .volume import Volume


@dataclass(frozen=True)
class Centerline:
    """A curve through the middle of a tube.

    points: (N, 3) float64 world positions (x, y, z), equal arc-length steps from start to end.
    radii:  (N,) float64 radius of the largest inscribed ball at each point (the Euclidean DT, world units).
    length: arc length in world units.
    voxels: (M, 3) int64 voxel indices [z, y, x] of the minimal voxel path the curve was made from.
    """

    points: np.ndarray
    radii: np.ndarray
    length: float
    voxels: np.ndarray

    def __len__(self) -> int:
        return len(self.points)

    @property
    def step(self) -> float:
        """The arc length between consecutive points."""
        return self.length / max(len(self.points) - 1, 1)

    def tangents(self) -> np.ndarray:
        """(N, 3) unit tangents (central differences)."""
        d = np.gradient(self.points, axis=0)
        return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)


@dataclass(frozen=True)
class CenterlineTree:
    """The centerlines of a branching object, from a root.

    branches:    list of ``Centerline``, parents before children; each runs from its branch point (the root for
                 branch 0) to its end (a tip or the next branch point).
    parents:     (B,) int32 parent branch, -1 for a branch starting at the root.
    generations: (B,) int32, 0 for the root branch, parent + 1 below.
    """

    branches: List[Centerline]
    parents: np.ndarray
    generations: np.ndarray

    def __len__(self) -> int:
        return len(self.branches)

    @property
    def lengths(self) -> np.ndarray:
        """(B,) arc length of each branch, world units."""
        return np.array([b.length for b in self.branches])

    @property
    def branch_points(self) -> np.ndarray:
        """(K, 3) world positions where branches split (the start of every branch with a parent), unique."""
        pts = [b.points[0] for b, p in zip(self.branches, self.parents) if p >= 0]
        return np.unique(np.round(np.array(pts).reshape(-1, 3), 9), axis=0)

    @property
    def root(self) -> np.ndarray:
        """World position of the root."""
        return self.branches[0].points[0]

    def children(self, branch: int) -> np.ndarray:
        """Indices of the branches whose parent is ``branch``."""
        return np.flatnonzero(self.parents == branch)


@dataclass(frozen=True)
class StraightenMap:
    """Where each voxel of a straightened volume came from.

    The straight volume's voxel (a, b, k) (array index [k, b, a]) was sampled at
    ``points[k] + (a - half) * step * normals[k] + (b - half) * step * binormals[k]`` in the source's world.
    """

    points: np.ndarray
    tangents: np.ndarray
    normals: np.ndarray
    binormals: np.ndarray
    step: float
    half: int

    def to_world(self, abk) -> np.ndarray:
        """Source world positions (M, 3) of straight-volume voxel coordinates (M, 3) as (a, b, k); k may be
        fractional (linear along the curve)."""
        q = np.atleast_2d(np.asarray(abk, dtype=np.float64))
        k = np.clip(q[:, 2], 0, len(self.points) - 1)
        k0 = np.minimum(np.floor(k).astype(np.int64), len(self.points) - 2) if len(self.points) > 1 else 0 * k
        w = (k - k0)[:, None]

        def lerp(a):
            return a[k0] * (1 - w) + a[np.minimum(k0 + 1, len(a) - 1)] * w

        x = ((q[:, 0] - self.half) * self.step)[:, None]
        y = ((q[:, 1] - self.half) * self.step)[:, None]
        return lerp(self.points) + x * lerp(self.normals) + y * lerp(self.binormals)


def _point(p, what: str) -> Optional[Tuple[float, float, float]]:
    if p is None:
        return None
    a = np.asarray(p, dtype=np.float64).ravel()
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise VolrigError(f"{what} must be three finite world coordinates (x, y, z), got {p!r}")
    return tuple(float(x) for x in a)  # type: ignore[return-value]


def _cropped(mask):
    """The mask as uint8 cropped to its object's bounding box plus one voxel, its DT, spacing, cropped origin and
    the crop's offset (z, y, x). Raises VolrigError on an empty mask or NaN samples."""
    raw = mask.array if isinstance(mask, Volume) else np.asarray(mask)
    if raw.dtype.kind == "f" and not np.all(np.isfinite(raw)):
        raise VolrigError("mask: holds NaN or infinite samples")
    arr = _mask_array(mask)
    spacing, origin = _geometry(mask)
    nz = [np.flatnonzero(arr.any(axis=tuple(a for a in range(3) if a != ax))) for ax in range(3)]
    if any(len(n) == 0 for n in nz):
        raise VolrigError("mask: the mask is empty (no object voxel), so it has no centerline")
    lo = [max(int(n[0]) - 1, 0) for n in nz]
    hi = [min(int(n[-1]) + 2, s) for n, s in zip(nz, arr.shape)]
    crop = np.ascontiguousarray(arr[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]])
    corigin = tuple(o + s * i for o, s, i in zip(origin, spacing, (lo[2], lo[1], lo[0])))
    dt = _volrig.distance_transform(crop, spacing, "euclidean", None)
    return crop, dt, tuple(spacing), corigin, np.array(lo)


def _line(t, shape, offset) -> Centerline:
    points, radii, length, lin = t
    zyx = np.stack(np.unravel_index(lin, shape), axis=1).astype(np.int64) + offset
    return Centerline(points, radii.astype(np.float64), float(length), zyx)


def _options(power, step, smoothing, refine):
    if not (np.isfinite(power) and 0 <= power <= 16):
        raise VolrigError(f"power must be 0 to 16, got {power}")
    s = 0.0 if step is None else float(step)
    if not (np.isfinite(s) and s >= 0):
        raise VolrigError(f"step must be positive and finite, got {step}")
    return float(power), s, float(smoothing), int(refine)


def centerline(mask, start: Optional[Sequence[float]] = None, end: Optional[Sequence[float]] = None,
               power: float = 4.0, step: Optional[float] = None, smoothing: float = 2.0,
               refine: int = 2) -> Centerline:
    """The centerline of the tube ``mask`` (a ``Volume``, spacing honoured, or a 3-D array) from ``start`` to ``end``.

    start, end: world points (x, y, z) on the object (snapped to the nearest object voxel within two voxels);
                either or both left out are found automatically: the object's two ends farthest apart along it
                (geodesically), each at the centre of its end.
    power:      k in the step cost (h / DT)^k; higher keeps the path more strictly on the DT's ridge.
    step:       arc length between samples (default the smallest voxel spacing).
    smoothing:  Gaussian sigma of the voxel path's smoothing, in voxels; refine: cross-section centroid passes.
    Raises ``VolrigError`` on an empty mask, NaN, endpoints off the object or in different parts of it.
    """
    s, e = _point(start, "start"), _point(end, "end")
    opts = _options(power, step, smoothing, refine)
    crop, dt, spacing, origin, offset = _cropped(mask)
    return _line(_volrig.centerline(crop, dt, spacing, origin, s, e, *opts), crop.shape, offset)


def centerline_tree(mask, root: Optional[Sequence[float]] = None, power: float = 4.0, step: Optional[float] = None,
                    smoothing: float = 2.0, refine: int = 2, scale: float = 2.0, constant: float = 0.0,
                    prune: float = 3.0) -> CenterlineTree:
    """Centerlines of every branch of a branching object (airways, vessels) from ``root``.

    root:     a world point on the object; default the end of its thickest terminal branch (the trachea of an
              airway tree).
    scale, constant: TEASAR's covering ball, scale * DT + constant (world units; 0 = two voxels): a new branch
              starts only from voxels outside every ball around the branches found so far.
    prune:    terminal branches shorter than ``prune`` times the radius at their branch point are spurs, removed.
    Other options as ``centerline``. Only the part of the object holding the root is followed.
    """
    r = _point(root, "root")
    opts = _options(power, step, smoothing, refine)
    for name, v in (("scale", scale), ("constant", constant), ("prune", prune)):
        if not (np.isfinite(v) and v >= 0):
            raise VolrigError(f"{name} must be >= 0 and finite, got {v}")
    crop, dt, spacing, origin, offset = _cropped(mask)
    branches, parents, generations = _volrig.centerline_tree(crop, dt, spacing, origin, r, *opts, float(scale),
                                                             float(constant), float(prune))
    return CenterlineTree([_line(b, crop.shape, offset) for b in branches], parents, generations)


def straighten(volume: Volume, line: Centerline, radius: float, step: Optional[float] = None,
               fill: float = 0.0) -> Tuple[Volume, StraightenMap]:
    """Curved planar reformation: ``volume`` resampled (trilinear) on the planes normal to ``line`` (rotation-
    minimising frames) into a straight float32 Volume. Slice k (array [k, :, :]) is the plane at ``line.points[k]``,
    ``radius`` (world units) either side of the curve; in-plane spacing ``step`` (default the line's step), slice
    spacing the line's step, so the straight volume's z is arc length and its axis is x = y = 0. Samples outside the
    source get ``fill``. Returns the volume and the ``StraightenMap`` back to the source's world."""
    if not isinstance(volume, Volume):
        raise TypeError(f"volume must be a volrig.Volume, got {type(volume).__name__}")
    if not isinstance(line, Centerline):
        raise TypeError(f"line must be a volrig.Centerline, got {type(line).__name__}")
    if not (np.isfinite(radius) and radius > 0):
        raise VolrigError(f"radius must be positive and finite, got {radius}")
    ds = line.step if step is None else float(step)
    if not (np.isfinite(ds) and ds > 0):
        raise VolrigError(f"step must be positive and finite, got {step}")
    half = int(np.ceil(radius / ds))
    if half > 2048:
        raise VolrigError(f"radius / step = {radius / ds:.0f}: at most 2048 samples either side of the curve")
    values, origin = _crop_around(volume, line.points, radius + 2 * max(volume.spacing))
    out, t, u, v = _volrig.straighten(values, volume.spacing, origin, np.ascontiguousarray(line.points), half, ds,
                                      float(fill))
    straight = Volume(out, (ds, ds, line.step), (-half * ds, -half * ds, 0.0))
    return straight, StraightenMap(np.array(line.points), t, u, v, ds, half)


def _crop_around(volume: Volume, points: np.ndarray, margin: float):
    """The float32 samples of ``volume`` within ``margin`` of the points' bounding box, and that crop's origin."""
    sp, org = np.array(volume.spacing), np.array(volume.origin)
    lo_xyz = np.floor((points.min(axis=0) - margin - org) / sp).astype(np.int64)
    hi_xyz = np.ceil((points.max(axis=0) + margin - org) / sp).astype(np.int64) + 1
    shape_xyz = np.array(volume.dims)
    lo_xyz = np.clip(lo_xyz, 0, shape_xyz)
    hi_xyz = np.clip(hi_xyz, 0, shape_xyz)
    a = volume.array[lo_xyz[2]:hi_xyz[2], lo_xyz[1]:hi_xyz[1], lo_xyz[0]:hi_xyz[0]]
    if a.size == 0:
        raise VolrigError("straighten: the centerline lies outside the volume")
    if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
        raise VolrigError("straighten: the volume holds NaN or infinite samples along the centerline")
    return np.ascontiguousarray(a, dtype=np.float32), tuple(org + sp * lo_xyz)

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

from . import _optional, _volrig
from ._volrig import VolrigError
from .rig import Rig
from .skeleton import ProgressFn, _geometry, _mask_array
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


def _span(progress: ProgressFn, lo: float, hi: float) -> ProgressFn:
    """``progress`` seeing fractions lo..hi for a step's 0..1 (None stays None)."""
    if progress is None:
        return None
    return lambda f: progress(lo + (hi - lo) * float(f))


#: The share of the progress bar the distance transform takes before the native search.
_DT_SHARE = 0.2


def _cropped(mask, progress: ProgressFn = None):
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
    dt = _volrig.distance_transform(crop, spacing, "euclidean", _span(progress, 0.0, _DT_SHARE))
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
               refine: int = 2, progress: ProgressFn = None) -> Centerline:
    """The centerline of the tube ``mask`` (a ``Volume``, spacing honoured, or a 3-D array) from ``start`` to ``end``.

    start, end: world points (x, y, z) on the object (snapped to the nearest object voxel within two voxels);
                either or both left out are found automatically: the object's two ends farthest apart along it
                (geodesically), each at the centre of its end.
    power:      k in the step cost (h / DT)^k; higher keeps the path more strictly on the DT's ridge.
    step:       arc length between samples (default the smallest voxel spacing).
    smoothing:  Gaussian sigma of the voxel path's smoothing, in voxels; refine: cross-section centroid passes.
    progress:   optional callable(fraction) -> bool; return False to cancel (raises ``volrig.Cancelled``).
    Raises ``VolrigError`` on an empty mask, NaN, endpoints off the object or in different parts of it.
    """
    s, e = _point(start, "start"), _point(end, "end")
    opts = _options(power, step, smoothing, refine)
    crop, dt, spacing, origin, offset = _cropped(mask, progress)
    return _line(_volrig.centerline(crop, dt, spacing, origin, s, e, *opts, _span(progress, _DT_SHARE, 1.0)),
                 crop.shape, offset)


def centerline_tree(mask, root: Optional[Sequence[float]] = None, power: float = 4.0, step: Optional[float] = None,
                    smoothing: float = 2.0, refine: int = 2, scale: float = 2.0, constant: float = 0.0,
                    prune: float = 3.0, progress: ProgressFn = None) -> CenterlineTree:
    """Centerlines of every branch of a branching object (airways, vessels) from ``root``.

    root:     a world point on the object; default the end of its thickest terminal branch (the trachea of an
              airway tree).
    scale, constant: TEASAR's covering ball, scale * DT + constant (world units; 0 = two voxels): a new branch
              starts only from voxels outside every ball around the branches found so far.
    prune:    terminal branches shorter than ``prune`` times the radius at their branch point are spurs, removed.
    Other options (and ``progress``) as ``centerline``. Only the part of the object holding the root is followed.
    """
    r = _point(root, "root")
    opts = _options(power, step, smoothing, refine)
    for name, v in (("scale", scale), ("constant", constant), ("prune", prune)):
        if not (np.isfinite(v) and v >= 0):
            raise VolrigError(f"{name} must be >= 0 and finite, got {v}")
    crop, dt, spacing, origin, offset = _cropped(mask, progress)
    branches, parents, generations = _volrig.centerline_tree(crop, dt, spacing, origin, r, *opts, float(scale),
                                                             float(constant), float(prune),
                                                             _span(progress, _DT_SHARE, 1.0))
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


# ---- straightening through the rig machinery (docs/ALGORITHMS.md §9.3) ----

def _turn(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation (3x3) taking unit vector a onto unit vector b (a half turn about a perpendicular when
    they are opposite)."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -1.0 + 1e-12:
        p = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(p) < 1e-6:
            p = np.cross(a, [0.0, 1.0, 0.0])
        p /= np.linalg.norm(p)
        return 2.0 * np.outer(p, p) - np.eye(3)
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + K + K @ K / (1.0 + c)


def _rotation_power(R: np.ndarray, t: float) -> np.ndarray:
    """R^t for a rotation R (same axis, t times the angle)."""
    try:
        from scipy.spatial.transform import Rotation
    except ImportError:
        return _optional.rotation_power(R)(t)
    return Rotation.from_rotvec(Rotation.from_matrix(R).as_rotvec() * float(t)).as_matrix()


def _rigid(R: np.ndarray, pivot: np.ndarray, to: np.ndarray) -> np.ndarray:
    """The 4x4 matrix rotating by R and taking ``pivot`` to ``to``."""
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = to - R @ pivot
    return M


@dataclass(frozen=True)
class StraighteningRig:
    """A chain armature along a centerline and the pose that lays it straight (thesis §9.3: straightening an organ
    by animating its articulated skeleton).

    rig:      ``Rig`` of B bones "seg.000", "seg.001", ... from the start of the centerline to its end, each an
              equal-arc piece, each the parent of the next (connected: a bone's head is its parent's tail).
    straight: (B, 4, 4) rest-to-pose matrices (for ``volrig.deform`` / ``Deformer.frame``; Blender's bases from
              ``rig.basis_matrices``) that lay the chain on the straight line from its first joint along ``axis``,
              every bone keeping its length, neighbours not twisted about each other (rotation-minimising frames
              along the bones), the first joint fixed.
    axis:     (3,) unit direction of the straight line (default the chord from the first joint to the last).
    local:    (B, 3, 3) each bone's rotation relative to its parent, about its head: the straight pose is
              ``M[b] = M[parent] @ (rotation local[b] about head b)``.
    """

    rig: Rig
    straight: np.ndarray
    axis: np.ndarray
    local: np.ndarray

    def matrices(self, fraction: float) -> np.ndarray:
        """(B, 4, 4) rest-to-pose matrices ``fraction`` of the way from the curved rest (0) to straight (1): each
        bone's rotation relative to its parent turned by that fraction of its angle about the same axis, then
        forward kinematics down the chain."""
        t = float(fraction)
        if not np.isfinite(t):
            raise VolrigError(f"fraction must be finite, got {fraction}")
        heads = self.rig.heads()
        M = np.repeat(np.eye(4)[None], len(self.rig), axis=0)
        for b in range(len(self.rig)):
            p = int(self.rig.parents[b])
            L = _rigid(_rotation_power(self.local[b], t), heads[b], heads[b])
            M[b] = (M[p] if p >= 0 else np.eye(4)) @ L
        return M


#: The bones of a straightening rig unless told (the add-on's Straighten > Bones starts at it too).
STRAIGHTENING_BONES = 12


def straightening_rig(line: Centerline, bones: int = STRAIGHTENING_BONES, axis: Optional[Sequence[float]] = None) \
        -> StraighteningRig:
    """The chain armature along ``line`` (``bones`` equal-arc pieces) and the rest-to-pose matrices that make it
    straight: bind skeleton points of the organ to ``.rig`` (``volrig.bind``) and deform the organ with
    ``.straight`` (or ``.matrices(f)`` for the frames between) to straighten it through the rig machinery.
    ``axis``: direction of the straight line (default: from the line's start to its end)."""
    if not isinstance(line, Centerline):
        raise TypeError(f"line must be a volrig.Centerline, got {type(line).__name__}")
    bones = int(bones)
    if not 1 <= bones <= 1000:
        raise VolrigError(f"bones must be 1 to 1000, got {bones}")
    pts = np.asarray(line.points, dtype=np.float64)
    if len(pts) < 2 or not line.length > 0:
        raise VolrigError("the centerline is too short to rig")
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    q = np.linspace(0.0, s[-1], bones + 1)
    joints = np.stack([np.interp(q, s, pts[:, a]) for a in range(3)], axis=1)
    d = np.diff(joints, axis=0)
    lengths = np.linalg.norm(d, axis=1)
    if np.any(lengths <= 1e-9 * s[-1]):
        raise VolrigError(f"{bones} bones are too many for a centerline of {len(pts)} points")
    d /= lengths[:, None]
    if axis is None:
        chord = joints[-1] - joints[0]
        a = chord / np.linalg.norm(chord) if np.linalg.norm(chord) > 1e-6 * s[-1] else d[0]
    else:
        a = np.asarray(axis, dtype=np.float64).reshape(-1)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
            raise VolrigError(f"axis must be a non-zero 3-vector, got {axis!r}")
        a = a / np.linalg.norm(a)
    # rotation-minimising frames along the bones: bone b's frame is bone b-1's turned by the smallest rotation
    # between their directions; the straight line's frame is bone 0's turned onto the axis, the same for all
    frames = [np.eye(3)]
    for b in range(1, bones):
        frames.append(_turn(d[b - 1], d[b]) @ frames[-1])
    R0 = _turn(d[0], a)
    # bone b's straight rotation: take its frame back to bone 0's, then onto the axis
    R = np.stack([R0 @ F.T for F in frames])
    offsets = np.concatenate([[0.0], np.cumsum(lengths)])
    targets = joints[0] + offsets[:, None] * a
    straight = np.stack([_rigid(R[b], joints[b], targets[b]) for b in range(bones)])
    local = np.stack([R[0]] + [R[b - 1].T @ R[b] for b in range(1, bones)])
    names = [f"seg.{b:03d}" for b in range(bones)]
    rig = Rig(joints, np.stack([np.arange(bones), np.arange(1, bones + 1)], axis=1), names,
              np.arange(-1, bones - 1), kind="chains")
    return StraighteningRig(rig, straight, a, local)


# ---- fly-throughs (virtual endoscopy) ----

def flight_path(mask, start: Optional[Sequence[float]] = None, end: Optional[Sequence[float]] = None,
                progress: ProgressFn = None) -> Centerline:
    """The centerline a fly-through follows: ``centerline(mask, start, end)``, except that a start left out is the end
    of the object's thickest terminal branch (the root of ``centerline_tree``: the trachea of an airway tree, the
    wide end of a tube), and an end left out the end farthest from the start along the object."""
    if start is None:
        if end is None:
            tree = centerline_tree(mask, progress=_span(progress, 0.0, 0.5))
            line = centerline(mask, start=tree.root, progress=_span(progress, 0.5, 1.0))
            return _thick_end_first(line) if len(tree) == 1 else line
        # the given end is where the flight stops: start from the far end
        return _reversed(centerline(mask, start=end, progress=progress))
    return centerline(mask, start=start, end=end, progress=progress)


def _thick_end_first(line: Centerline) -> Centerline:
    """An unbranched tube's line (its tree's root is then just one end) running from its wider end: the median
    radius over the first quarter against the last."""
    q = max(len(line) // 4, 1)
    return _reversed(line) if np.median(line.radii[-q:]) > np.median(line.radii[:q]) else line


def _reversed(line: Centerline) -> Centerline:
    return Centerline(line.points[::-1].copy(), line.radii[::-1].copy(), line.length, line.voxels[::-1].copy())


@dataclass(frozen=True)
class FlightFrames:
    """A camera's path along a centerline, one entry per frame (world units of the line).

    positions:  (F, 3) camera positions, equal arc-length steps of 1 / frames_per_mm.
    directions: (F, 3) unit view directions: the line's tangent averaged over ``look_ahead`` ahead of the camera.
    ups:        (F, 3) unit up vectors, perpendicular to the directions, turned from frame to frame by the smallest
                rotation (no roll, no flip when the path turns straight up or down).
    radii:      (F,) the lumen's radius at each position (the line's inscribed-ball radius).
    arc:        (F,) arc length of each position from the line's start.
    """

    positions: np.ndarray
    directions: np.ndarray
    ups: np.ndarray
    radii: np.ndarray
    arc: np.ndarray

    def __len__(self) -> int:
        return len(self.positions)


def flight_frames(line: Centerline, frames_per_mm: float = 1.0, look_ahead: float = 10.0,
                  up: Optional[Sequence[float]] = None, stop_short: Optional[float] = None,
                  min_radius: float = 0.0) -> FlightFrames:
    """Camera positions, view directions and up vectors along ``line`` for a fly-through: ``frames_per_mm`` frames
    per unit of arc length (the speed), the view along the tangent averaged over the next ``look_ahead`` units,
    ``up`` (default +z, or +y when the line starts along z) projected off the first view direction and carried
    along without roll. The flight starts and ends ``stop_short`` (default the lumen's radius there) inside the line's
    ends,
    so the camera starts and stops in front of the wall that closes the lumen, and ends where the lumen's radius
    first drops below ``min_radius`` (narrower than a camera fits: the wall's soft edge would fill the view)."""
    if not isinstance(line, Centerline):
        raise TypeError(f"line must be a volrig.Centerline, got {type(line).__name__}")
    if not (np.isfinite(frames_per_mm) and frames_per_mm > 0):
        raise VolrigError(f"frames per mm must be positive and finite, got {frames_per_mm}")
    if not (np.isfinite(look_ahead) and look_ahead >= 0):
        raise VolrigError(f"look ahead must be >= 0 and finite, got {look_ahead}")
    pts = np.asarray(line.points, dtype=np.float64)
    if len(pts) < 2:
        raise VolrigError("the centerline has fewer than 2 points")
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    # the radius at an end is the cap's (it shrinks to 0 there): take the widest within the widest radius of it
    reach = float(line.radii.max())
    first = float(line.radii[s <= reach].max()) if stop_short is None else float(stop_short)
    first = min(max(first, 0.0), 0.25 * s[-1])
    short = float(line.radii[s >= s[-1] - reach].max()) if stop_short is None else float(stop_short)
    stop = max(s[-1] - max(short, 0.0), 0.5 * s[-1])
    narrow = np.flatnonzero((s > first) & (s < stop) & (line.radii < min_radius))
    if len(narrow):
        stop = max(s[narrow[0]], first + 0.1 * (s[-1] - first))
    count = max(int(np.floor((stop - first) * frames_per_mm)) + 1, 2)
    arc = first + np.arange(count) / frames_per_mm
    if arc[-1] > stop:
        arc = np.linspace(first, stop, count)
    positions = np.stack([np.interp(arc, s, pts[:, a]) for a in range(3)], axis=1)
    radii = np.interp(arc, s, line.radii)
    # the averaged tangent over [a, a + look_ahead] is the chord to the point look_ahead ahead (clamped at the end;
    # near the end, where the window shrinks, it is at least the local tangent)
    tangents = line.tangents()
    ahead = np.minimum(arc + max(look_ahead, 1e-9), s[-1])
    tips = np.stack([np.interp(ahead, s, pts[:, a]) for a in range(3)], axis=1)
    d = tips - positions
    n = np.linalg.norm(d, axis=1)
    local = np.stack([np.interp(arc, s, tangents[:, a]) for a in range(3)], axis=1)
    short_window = n < 0.25 * max(look_ahead, 1e-9)
    d[short_window] = local[short_window]
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    u0 = np.array([0.0, 0.0, 1.0]) if up is None else np.asarray(up, dtype=np.float64).reshape(3)
    if up is None and abs(d[0] @ u0) > 0.9:
        u0 = np.array([0.0, 1.0, 0.0])
    u = u0 - (u0 @ d[0]) * d[0]
    if np.linalg.norm(u) < 1e-6:
        raise VolrigError(f"up {tuple(u0)} is along the first view direction")
    ups = np.empty_like(d)
    ups[0] = u / np.linalg.norm(u)
    for k in range(1, len(d)):
        v = _turn(d[k - 1], d[k]) @ ups[k - 1]
        v -= (v @ d[k]) * d[k]
        ups[k] = v / np.linalg.norm(v)
    return FlightFrames(positions, d, ups, radii, arc)


def lumen_wall(mask, thickness: float = 3.0, sigma: float = 1.5) -> Volume:
    """A float32 Volume, 0 inside the lumen (the mask), rising to 1 across its boundary and 1 in a shell
    ``thickness`` voxels thick around it, 0 beyond: the wall a camera inside the lumen sees, as a volume renderer
    needs it (only the shell is non-zero, so it alone is stored and marched). The boundary is the 0.5 level of the
    mask blurred by ``sigma`` voxels (so it does not show the voxel steps), the rise a smoothstep across a third of
    the blurred range. Cropped to the shell's bounding box."""
    if not (np.isfinite(thickness) and 0 < thickness <= 100):
        raise VolrigError(f"thickness must be 0 to 100 voxels, got {thickness}")
    crop, _, spacing, origin, offset = _cropped_mask(mask, int(np.ceil(thickness + 3 * sigma)) + 1)
    inside = crop.astype(np.float32)
    try:
        from scipy.ndimage import gaussian_filter
    except ImportError:
        gaussian_filter = _optional.gaussian_filter  # the same computation in numpy
    soft = gaussian_filter(inside, sigma) if sigma > 0 else inside
    # the shell: within `thickness` (smallest) voxels of the lumen (the native Euclidean DT of the outside)
    # (the DT counts the grid's border as background: padded beyond reach)
    k = int(np.ceil(thickness)) + 2
    outside = _volrig.distance_transform(np.pad(1 - crop, k, constant_values=1), spacing, "euclidean", None)
    near = outside[k:-k, k:-k, k:-k] <= thickness * min(spacing)
    # the blurred mask's 0.5 level is a smooth wall without the voxel steps; a narrow ramp across it (0.35 to 0.65)
    # keeps the lumen itself clear (a blurred value there would fog a long view down a narrow tube)
    x = np.clip((1.0 - soft - 0.35) / 0.3, 0.0, 1.0)
    wall = np.where(near, x * x * (3.0 - 2.0 * x), 0.0).astype(np.float32)
    return Volume(wall, spacing, origin)


def _cropped_mask(mask, pad: int):
    """The mask (uint8) cropped to its object's bounding box plus ``pad`` voxels (the grid grown where needed), its
    spacing, the crop's origin and offset (z, y, x)."""
    arr = _mask_array(mask)
    spacing, origin = _geometry(mask)
    nz = [np.flatnonzero(arr.any(axis=tuple(a for a in range(3) if a != ax))) for ax in range(3)]
    if any(len(n) == 0 for n in nz):
        raise VolrigError("mask: the mask is empty (no object voxel)")
    lo = np.array([int(n[0]) - pad for n in nz])
    hi = np.array([int(n[-1]) + pad + 1 for n in nz])
    out = np.zeros(tuple(hi - lo), np.uint8)
    src_lo = np.maximum(lo, 0)
    src_hi = np.minimum(hi, arr.shape)
    out[tuple(slice(a - l, b - l) for a, b, l in zip(src_lo, src_hi, lo))] = \
        arr[tuple(slice(a, b) for a, b in zip(src_lo, src_hi))]
    corigin = tuple(o + s * i for o, s, i in zip(origin, spacing, (lo[2], lo[1], lo[0])))
    return out, None, tuple(spacing), corigin, lo

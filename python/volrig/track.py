"""Feature tracking over time steps by the overlap of skeletons (thesis 9.1, after Silver and Wang; docs/track.md).

``track(steps, lo=...)`` segments each step's features (6-connected components above ``lo`` of at least
``min_size`` voxels, numbered as ``scipy.ndimage.label`` numbers them), skeletonizes each step once and matches
features of consecutive steps by the overlap of their skeletons: each skeleton point stands for its share of its
feature's volume (its ball's volume, the feature's balls summing to the feature), and counts where it lies in the
other step, both ways. At thinness 0 every voxel is a point of weight 1: the exact overlap of the whole features,
Silver and Wang's volume test (counted from the features' runs along x, row by row). ``Tracking.at(thinness)``
re-tracks without skeletonizing again.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Callable, List, Optional

import numpy as np

from . import _volrig
from ._volrig import Cancelled, VolrigError
from .skeleton import skeletonize
from .volume import FORMATS, Volume, load

#: The kinds of event between two steps, by how many features before and after a group of matches holds.
EVENT_KINDS = ("continuation", "split", "merge", "split-merge", "creation", "dissipation")

ProgressFn = Optional[Callable[[float], Optional[bool]]]


@dataclass(frozen=True)
class Event:
    """Features ``before`` (of step ``step``) became features ``after`` (of step ``step + 1``): one group of the
    matches between the two steps (a connected component of the bipartite match graph). ``kind``: continuation
    (1 to 1), split (1 to 2 or more: Silver and Wang's bifurcation), merge (2 or more to 1: amalgamation),
    split-merge (several to several), creation (none to 1), dissipation (1 to none)."""

    step: int
    kind: str
    before: tuple
    after: tuple


@dataclass
class _Step:
    """One time step, prepared once: its features, and its voxels in index order (the full-volume test's points)
    and in descending score order (the skeleton at a thinness is a prefix: its positions in index order, sorted,
    take it in memory order)."""

    labels: np.ndarray        # int32 [z, y, x], 0 = no feature
    look: np.ndarray          # the same labels in the smallest type holding them (uint8, uint16 or int32): looked up
    runs: Optional[np.ndarray]  # int32 (4, n) the features' runs along x (row, x0, x1, label): the full-volume test
    sizes: np.ndarray         # int64 voxels per feature
    centroids: np.ndarray     # (F, 3) world x, y, z
    voxels: np.ndarray        # flat index (uint32; int64 on grids of 2^32 voxels or more) of every feature voxel,
    #                           ascending: the full-volume test's points, and the skeleton's at any thinness
    voxel_label: np.ndarray   # their features (look's type)
    voxel_ball: np.ndarray    # float32 dt³: their balls' volumes (to a constant)
    rank: np.ndarray          # uint32 (int64 likewise) per point by descending score, its position in ``voxels``
    first: np.ndarray         # int64 per feature, the position of its first (best) point by descending score
    points: np.ndarray        # int64 flat index of the skeleton's points, by descending score
    point_label: np.ndarray   # int32 their features
    dt: np.ndarray            # float32 their distance transform (ball radius in the metric's units)
    scores: np.ndarray        # float32 their thinness scores (descending)
    spacing: tuple
    origin: tuple
    metric: str


def _step_files(folder: str) -> List[str]:
    names = sorted(n for n in os.listdir(folder) if any(n.lower().endswith(e) for e in FORMATS if e.startswith(".")))
    if not names:
        raise VolrigError(f"{folder}: no volume files (endings {', '.join(sorted(FORMATS))})")
    return [os.path.join(folder, n) for n in names]


def _volumes(steps):
    """The steps as a list of things to load lazily: Volumes, arrays or file names (a folder: its files by name)."""
    if isinstance(steps, (str, os.PathLike)):
        if not os.path.isdir(steps):
            raise VolrigError(f"{os.fspath(steps)}: not a folder of time steps")
        steps = _step_files(os.fspath(steps))
    steps = list(steps)
    if len(steps) < 2:
        raise VolrigError(f"tracking needs at least two time steps, got {len(steps)}")
    return steps


def _vdb_box(path: str):
    """The index box (min, max; x, y, z) of the grid ``load`` reads from a VDB file (density, else the first)."""
    from .volume import vdb_grids
    grids = vdb_grids(path)
    g = next((g for g in grids if g["name"] == "density"), grids[0] if grids else None)
    return None if g is None else (np.array(g["bbox_min"]), np.array(g["bbox_max"]))


def _common_boxes(items):
    """Per step, the [z, y, x] offset of its array in the box all steps fit, and that box's shape; (None, None)
    where the steps share a grid as they are (arrays, dense files). VDB steps are stored cropped to their active
    voxels, each step its own box on one lattice: they are placed in the box around them all. Volumes likewise, by
    origin."""
    first = next((x for x in items if isinstance(x, Volume)), None)
    boxes = []
    for it in items:
        if isinstance(it, (str, os.PathLike)) and os.fspath(it).lower().endswith(".vdb"):
            boxes.append(_vdb_box(os.fspath(it)))
        elif isinstance(it, Volume):
            lo = np.round((np.array(it.origin) - first.origin) / np.array(first.spacing)).astype(np.int64)
            boxes.append((lo, lo + np.array(it.dims) - 1))
        else:
            return None, None
    if any(b is None for b in boxes) or len({(tuple(b[0]), tuple(b[1])) for b in boxes}) == 1:
        return None, None
    low = np.min([b[0] for b in boxes], axis=0)
    high = np.max([b[1] for b in boxes], axis=0)
    return [tuple(int(v) for v in (b[0] - low)[::-1]) for b in boxes], tuple(int(v) for v in (high - low + 1)[::-1])


def _placed(mask: np.ndarray, spacing, origin, offset, shape):
    """``mask`` placed at ``offset`` ([z, y, x]) in a box of ``shape``, and that box's origin (x, y, z)."""
    box = np.zeros(shape, np.bool_)
    z, y, x = offset
    if any(o + n > m for o, n, m in zip(offset, mask.shape, shape)):
        raise VolrigError("time steps on different lattices: their boxes do not line up")
    box[z:z + mask.shape[0], y:y + mask.shape[1], x:x + mask.shape[2]] = mask
    return box, tuple(o - i * s for o, i, s in zip(origin, (x, y, z), spacing))


def _prepare(step, lo: float, hi: Optional[float], min_size: int, metric: str, place=None) -> _Step:
    v = load(step) if isinstance(step, (str, os.PathLike)) else step
    arr = v.array if isinstance(v, Volume) else np.asarray(v)
    spacing, origin = (v.spacing, v.origin) if isinstance(v, Volume) else ((1.0, 1.0, 1.0), (0.0, 0.0, 0.0))
    if arr.ndim != 3:
        raise VolrigError(f"a time step must be 3-D [z, y, x], got shape {arr.shape}")
    with np.errstate(invalid="ignore"):  # NaN is no feature
        mask = arr >= lo if hi is None else (arr >= lo) & (arr <= hi)
    del arr, v
    if place is not None:
        mask, origin = _placed(mask, spacing, origin, *place)
    labels, sizes, centroids = _volrig.track_features(np.ascontiguousarray(mask).view(np.uint8), int(min_size))
    del mask
    skel = skeletonize(Volume(labels > 0, spacing, origin), metric=metric)
    ijk, _, dt, scores = skel._native.points(skel.object_count)  # object voxels by descending score
    del skel
    ny, nx = labels.shape[1:]
    order = (ijk[:, 0].astype(np.int64) * ny + ijk[:, 1]) * nx + ijk[:, 2]
    flat = labels.reshape(-1)
    world = np.asarray(origin) + centroids * np.asarray(spacing)
    point_label = flat[order]
    dt, scores = np.asarray(dt), np.asarray(scores)
    first = np.full(len(sizes) + 1, len(order), np.int64)
    np.minimum.at(first, point_label, np.arange(len(order)))
    by_index = np.argsort(order, kind="stable")
    look = labels.astype(_label_type(len(sizes)))
    index_type = np.uint32 if labels.size <= 2 ** 32 else np.int64
    rank = np.empty(len(order), index_type)
    rank[by_index] = np.arange(len(order), dtype=index_type)
    voxels = order[by_index].astype(index_type)
    return _Step(labels, look, _runs(labels), sizes, world, voxels, look.reshape(-1)[voxels], dt[by_index] ** 3,
                 rank, first[1:], order, point_label, dt, scores, tuple(spacing), tuple(origin), metric)


def _label_type(features: int):
    """The smallest label type holding 0..features: the other step's labels read per point are then 1 or 2 bytes
    a voxel for the usual feature counts, a quarter or half the memory traffic of int32."""
    return np.uint8 if features < 2 ** 8 else np.uint16 if features < 2 ** 16 else np.int32


def _count_above(scores: np.ndarray, thinness: float) -> int:
    """Points with a score above ``thinness`` (``scores`` descending): a prefix, found by bisection (over the
    scores reversed, a view: negating them would copy every voxel's)."""
    return len(scores) - int(np.searchsorted(scores[::-1], np.float32(thinness), side="right"))


def _points_at(s: _Step, thinness: float):
    """Step ``s`` as ``step_overlaps`` takes it: (labels, features, flat index, feature, weight, sizes, totals) of
    the points standing for its features at ``thinness``, in index order (the other step's labels are then read in
    memory order): every voxel with weight 1 at thinness 0 (no weights); else the skeleton (score > thinness), each
    point weighted by its ball's volume, ``totals`` summing them per feature (the overlaps are scaled by sizes /
    totals, so a feature's points stand for its voxels). A feature whose skeleton is empty there keeps its best
    point."""
    if thinness <= 0:
        return (s.look, len(s.sizes), s.voxels, s.voxel_label, None, None, None)
    k = _count_above(s.scores, thinness)
    if k < len(s.voxels) // 16:  # a few points: their positions in index order, sorted
        keep = np.sort(np.concatenate([s.rank[:k], s.rank[s.first[s.first >= k]]]))  # each feature's best too
    else:  # many: marked by position in index order, a sort without sorting
        keep = np.zeros(len(s.voxels), np.bool_)
        keep[s.rank[:k]] = True
        keep[s.rank[s.first]] = True  # each feature's best point, at any thinness
        keep = np.flatnonzero(keep)
    label, ball = s.voxel_label[keep], s.voxel_ball[keep]
    totals = np.bincount(label, weights=ball, minlength=len(s.sizes) + 1).astype(np.float64, copy=False)  # no
    # points (a step without features): numpy counts in int64
    return (s.look, len(s.sizes), s.voxels[keep], label, ball, s.sizes, totals)


def _overlaps(a: _Step, b: _Step, pa, pb, clock: list):
    """(features of a, features of b, overlaps in voxels) sorted by pair, in one native call: each step's points
    looked up in the other (a point's weight scaled so that its feature's points sum to the feature's voxels), the
    larger estimate of the two directions kept. At thinness 0 (every voxel a point of weight 1): |A ∩ B| exactly,
    from the two steps' runs along x merged row by row (a cost per run: the fastest full-volume test volrig has;
    a's voxels looked up in b's labels, one pass, on grids too large for int32 runs)."""
    t0 = time.perf_counter()
    if pa[4] is None and a.runs is not None and b.runs is not None:
        out = _volrig.run_overlaps(a.runs, len(a.sizes), b.runs, len(b.sizes))
    else:
        out = _volrig.step_overlaps(pa, pb, pa[4] is not None)
    clock[0] += time.perf_counter() - t0
    return out


def _runs(labels: np.ndarray):
    """The features as runs along x, int32 (4, n): row (z * ny + y), x0, x1 (past the end), label, sorted by (row,
    x0) as ``run_overlaps`` takes them; None when the grid's rows or columns do not fit int32."""
    nz, ny, nx = labels.shape
    if nz * ny >= 2 ** 31 or nx >= 2 ** 31:
        return None
    rows = labels.reshape(-1, nx)
    start, end = rows != 0, rows != 0
    start[:, 1:] &= rows[:, 1:] != rows[:, :-1]
    end[:, :-1] &= rows[:, :-1] != rows[:, 1:]
    row, x0 = np.nonzero(start)
    x1 = np.nonzero(end)[1] + 1  # the same runs in the same order: one start and one end each
    return np.ascontiguousarray(np.stack([row, x0, x1, rows[row, x0]]).astype(np.int32))


def _groups(na: int, nb: int, pairs) -> list:
    """Connected components of the bipartite match graph over features 1..na (before) and 1..nb (after), as
    (before, after) tuples of sorted feature numbers, in order of their least feature."""
    parent = list(range(na + nb))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b in pairs:
        ra, rb = root(a - 1), root(na + b - 1)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    groups = {}
    for i in range(na + nb):
        before, after = groups.setdefault(root(i), ([], []))
        (before if i < na else after).append(i + 1 if i < na else i - na + 1)
    return [(tuple(b), tuple(a)) for b, a in groups.values()]


def _kind(before: tuple, after: tuple) -> str:
    if not before:
        return "creation"
    if not after:
        return "dissipation"
    if len(before) == 1:
        return "continuation" if len(after) == 1 else "split"
    return "merge" if len(after) == 1 else "split-merge"


def _pass_ids(ids_a: np.ndarray, a: _Step, b: _Step, pairs, next_id: int):
    """Track ids of b's features: each match, larger features first (the successor's volume, then the
    predecessor's), passes its predecessor's id on if neither has taken part yet; so a continuation keeps its id, a
    split's largest branch and a merge's result keep the largest one's. The rest get new ids."""
    ids_b = np.zeros(len(b.sizes), np.int32)
    used = set()
    for x, y in sorted(pairs, key=lambda p: (-b.sizes[p[1] - 1], -a.sizes[p[0] - 1], p)):
        if ids_b[y - 1] == 0 and x not in used:
            ids_b[y - 1] = ids_a[x - 1]
            used.add(x)
    for j in np.flatnonzero(ids_b == 0):
        ids_b[j] = next_id
        next_id += 1
    return ids_b, next_id


@dataclass
class Tracking:
    """The tracking graph of a time series at one thinness (see ``track``).

    labels:    per step, the feature label volume (int32 [z, y, x]; features 1.. as scipy.ndimage.label numbers
               6-connected components above ``lo``, those under ``min_size`` voxels removed and the rest renumbered).
    volumes:   per step, int64 voxels of each feature (index f - 1).
    centroids: per step, (F, 3) world x, y, z of each feature.
    edges:     one (step, feature, next_feature, overlap) a match: overlap in voxels (estimated from the skeletons,
               exact at thinness 0); a pair matches when it overlaps by ``tolerance`` of the smaller feature.
    events:    the ``Event`` of every group of matches, step by step.
    track_ids: per step, int32 track id of each feature (index f - 1), kept while a feature continues.
    seconds:   time spent tracking (overlaps, events, ids), not preparing the steps; overlap_seconds: of which the
               overlap test (the points looked up in the other step), the part the skeleton makes cheaper;
               points_seconds: taking each step's skeleton at this thinness, in index order (the skeletonization's
               part, as in the thesis' Table 9.1).
    """

    thinness: float
    tolerance: float
    labels: List[np.ndarray]
    volumes: List[np.ndarray]
    centroids: List[np.ndarray]
    edges: list
    events: List[Event]
    track_ids: List[np.ndarray]
    seconds: float
    overlap_seconds: float
    points_seconds: float
    _steps: List[_Step] = field(repr=False)

    @property
    def steps(self) -> int:
        return len(self._steps)

    @property
    def spacing(self) -> tuple:
        return self._steps[0].spacing

    @property
    def origin(self) -> tuple:
        return self._steps[0].origin

    def at(self, thinness: float, tolerance: Optional[float] = None) -> "Tracking":
        """The same steps tracked at another thinness (no skeletonization: each step's skeleton is kept)."""
        return _track_steps(self._steps, thinness, self.tolerance if tolerance is None else tolerance)

    def skeleton_points(self, step: int, feature: int, thinness: Optional[float] = None):
        """(ijk (N, 3) int [z, y, x], radii in world units) of one feature's skeleton at ``thinness`` (default:
        this tracking's)."""
        s = self._steps[step]
        tp = self.thinness if thinness is None else thinness
        k = _count_above(s.scores, tp)
        sel = np.flatnonzero(s.point_label[:k] == feature)
        ijk = np.stack(np.unravel_index(s.points[sel], s.labels.shape), axis=1)
        r = s.dt[sel] if s.metric == "euclidean" else s.dt[sel] / np.float32(3.0) * np.float32(min(s.spacing))
        return ijk, r

    def track_volume(self, step: int) -> np.ndarray:
        """int32 [z, y, x]: each voxel its feature's track id (0 outside the features)."""
        lut = np.concatenate([[0], self.track_ids[step]]).astype(np.int32)
        return lut[self.labels[step]]

    @property
    def track_count(self) -> int:
        """How many tracks the series holds (ids 1..track_count)."""
        return int(max((int(t.max()) for t in self.track_ids if len(t)), default=0))

    def event_counts(self) -> dict:
        return {k: sum(e.kind == k for e in self.events) for k in EVENT_KINDS}

    def agreement(self, reference: "Tracking") -> dict:
        """How far this tracking agrees with ``reference`` (say the full-volume one, thinness 0): the share of
        matched feature pairs matched by both among those matched by either, and the same for events."""
        mine = {(s, a, b) for s, a, b, _ in self.edges}
        theirs = {(s, a, b) for s, a, b, _ in reference.edges}
        ev = {(e.step, e.kind, e.before, e.after) for e in self.events}
        ev_ref = {(e.step, e.kind, e.before, e.after) for e in reference.events}
        share = (lambda x, y: len(x & y) / len(x | y) if x | y else 1.0)
        return {"matches": share(mine, theirs), "events": share(ev, ev_ref)}

    def to_dict(self) -> dict:
        """A JSON-ready summary: features (step, feature, track, volume, centroid), edges, events."""
        feats = [{"step": s, "feature": f + 1, "track": int(self.track_ids[s][f]), "volume": int(v[f]),
                  "centroid": [round(float(c), 4) for c in self.centroids[s][f]]}
                 for s, v in enumerate(self.volumes) for f in range(len(v))]
        return {"thinness": self.thinness, "tolerance": self.tolerance, "steps": self.steps, "features": feats,
                "edges": [{"step": s, "feature": a, "next_feature": b, "overlap": round(o, 3)}
                          for s, a, b, o in self.edges],
                "events": [{"step": e.step, "kind": e.kind, "before": list(e.before), "after": list(e.after)}
                           for e in self.events]}


def _track_steps(steps: List[_Step], thinness: float, tolerance: float) -> Tracking:
    if not np.isfinite(thinness) or thinness < 0:
        raise VolrigError(f"thinness must be a finite number >= 0, got {thinness}")
    if not 0 < tolerance <= 1:
        raise VolrigError(f"tolerance must lie in (0, 1], got {tolerance}")
    t0 = time.perf_counter()
    points = [_points_at(s, thinness) for s in steps]  # the skeletons at this thinness: not tracking's time
    t0, clock, points_seconds = time.perf_counter(), [0.0], time.perf_counter() - t0
    edges, events = [], []
    ids = [np.arange(1, len(steps[0].sizes) + 1, dtype=np.int32)]
    next_id = len(steps[0].sizes) + 1
    for t in range(len(steps) - 1):
        a, b = steps[t], steps[t + 1]
        fa, fb, over = _overlaps(a, b, points[t], points[t + 1], clock)
        keep = over >= tolerance * np.minimum(a.sizes[fa - 1], b.sizes[fb - 1])
        found = list(zip(fa[keep].tolist(), fb[keep].tolist(), over[keep].tolist()))
        pairs = [(x, y) for x, y, _ in found]
        edges += [(t, x, y, w) for x, y, w in found]
        events += [Event(t, _kind(bf, af), bf, af) for bf, af in _groups(len(a.sizes), len(b.sizes), pairs)]
        ids_b, next_id = _pass_ids(ids[-1], a, b, pairs, next_id)
        ids.append(ids_b)
    seconds = time.perf_counter() - t0
    return Tracking(float(thinness), float(tolerance), [s.labels for s in steps], [s.sizes for s in steps],
                    [s.centroids for s in steps], edges, events, ids, seconds, clock[0], points_seconds,
                    steps)


def track(steps, lo: float, hi: Optional[float] = None, thinness: float = 1.0, min_size: int = 20,
          tolerance: float = 0.1, metric: str = "chamfer345", progress: ProgressFn = None) -> Tracking:
    """Track the features of a time series (thesis 9.1) and return the ``Tracking`` graph.

    steps:     a folder of volume files (any format ``load`` reads, ``.vti`` too; taken in name order), or a list of
               file names, Volumes or arrays [z, y, x], one per step, all on one grid (VDB files and Volumes may
               each cover their own box of one lattice: they are placed in the box around them all).
    lo, hi:    a feature is a 6-connected component of voxels >= lo (and <= hi) with at least ``min_size`` voxels.
    thinness:  the skeleton's thinness (in the metric's units; the thesis' <3,4,5> chamfer by default, whose useful
               range is 0 to 4.08 as in its Table 9.1); 0 tracks by the whole features (Silver and Wang).
    tolerance: a pair of features of consecutive steps matches when they overlap by at least this share of the
               smaller one.
    progress:  called with the fraction of steps prepared; returning False cancels (``volrig.Cancelled``).
    """
    if min_size < 1:
        raise VolrigError(f"min_size must be >= 1, got {min_size}")
    if not np.isfinite(lo) or (hi is not None and not hi >= lo):
        raise VolrigError(f"the feature range must be finite with hi >= lo, got lo={lo}, hi={hi}")
    items = _volumes(steps)
    offsets, shape = _common_boxes(items)
    prepared: List[_Step] = []
    for i, item in enumerate(items):
        place = None if offsets is None else (offsets[i], shape)
        s = _prepare(item, float(lo), None if hi is None else float(hi), min_size, metric, place)
        if prepared and s.labels.shape != prepared[0].labels.shape:
            raise VolrigError(f"time step {i} has shape {s.labels.shape}, step 0 {prepared[0].labels.shape}: "
                              "all steps must share one grid")
        prepared.append(s)
        if progress is not None and progress((i + 1) / len(items)) is False:
            raise Cancelled("track: cancelled")
    return _track_steps(prepared, thinness, tolerance)


__all__ = ["track", "Tracking", "Event", "EVENT_KINDS"]

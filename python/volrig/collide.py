"""Collision detection between animated volumes, and a body against itself (docs/ALGORITHMS.md §8).

A rigged volume's deformed frame is the union of its moved reconstruction balls. ``collide`` answers, without
reconstructing either frame, which of A's lattice points lie inside both deformed volumes: the same voxels as two
``deform`` frames intersected on A's lattice. ``Collider`` builds the per-rig hierarchy once (one ball tree per bone
or smooth blend group, moved rigidly with it); a test then costs microseconds when the bodies are apart and grows
with the contact. See ``native/include/volrig/collide.hpp``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, List, Optional, Sequence, Tuple

import numpy as np

from . import _volrig
from ._volrig import Cancelled, VolrigError
from .deform import _matrices, _radius_scale, _sphere_arrays
from .rig import Binding, Rig
from .skeleton import SkeletonPoints


@dataclass
class Collision:
    """One test's answer.

    hit:        whether any voxel is in contact.
    voxels:     contact voxels: lattice points of A's grid inside both deformed volumes (for self-contact: inside
                two moved balls of the body that may touch, see ``self_collide``).
    bones_a, bones_b: names of the bones whose balls hold a contact voxel (for self-contact both list every bone
                involved).
    bone_pairs: (bone of A, bone of B) name pairs sharing a contact voxel (self-contact: each pair once).
    box:        (2, 3) world bounding box (min, max corner) of the contact voxels' centres; None without contact.
    points:     (voxels, 3) world centres of the contact voxels (sorted by z, y, x) when asked for, else None.
    stats:      work done: field_pairs (bone or blend-group pairs whose bounds overlap), node_pairs (bounding
                sphere pairs tested), sphere_pairs (ball pairs that intersect), lattice_tests (points decided one
                by one: the ends of rows through a ball; the rows between are inside by a margin).
    """

    hit: bool
    voxels: int
    bones_a: List[str]
    bones_b: List[str]
    bone_pairs: List[Tuple[str, str]]
    box: Optional[np.ndarray]
    stats: dict
    points: Optional[np.ndarray] = None

    def __bool__(self) -> bool:
        return self.hit


class Collider:
    """Per-rig data for collision tests, built once per binding.

    points, binding: the skeleton points and their binding (as for ``Deformer``).
    rig:   the rig (its bone parents are needed for ``self_collide``; its names label the answers).
    shape: the source volume's array shape (z, y, x) the points index; default the points' own extent. Give it to
           match ``Deformer`` frames exactly when bone matrices lie within float noise of the identity.
    parents: the bones' parents without a Rig (an armature's, as the add-on has them); the binding names the bones.
    """

    def __init__(self, points: SkeletonPoints, binding: Binding, rig: Optional[Rig] = None,
                 shape: Optional[Sequence[int]] = None, parents: Optional[Sequence[int]] = None):
        ijk, radius, bone, bone_count, offsets, wbones, weights = _sphere_arrays(points, binding)
        if shape is None:
            shape = (ijk.max(axis=0) + 1) if len(ijk) else (1, 1, 1)
        if len(shape) != 3:
            raise VolrigError(f"shape must be (z, y, x), got {tuple(shape)}")
        if rig is not None and len(rig.names) != bone_count:
            raise VolrigError(f"the rig has {len(rig.names)} bones but the binding {bone_count}")
        if parents is None:
            parents = [] if rig is None else rig.parents
        parents = [int(p) for p in parents]
        if parents and len(parents) != bone_count:
            raise VolrigError(f"{len(parents)} parents for {bone_count} bones")
        self.spacing, self.origin = tuple(points.spacing), tuple(points.origin)
        self.names = list(rig.names if rig is not None else binding.bone_names) or [str(b) for b in range(bone_count)]
        self.smooth = binding.mode == "smooth"
        self._native = _volrig.Collider(tuple(points.spacing), tuple(points.origin),
                                        (int(shape[2]), int(shape[1]), int(shape[0])), ijk, radius, bone, bone_count,
                                        offsets, wbones, weights, parents)
        self.has_parents = bool(parents)

    @property
    def bone_count(self) -> int:
        return self._native.bone_count

    def __len__(self) -> int:
        return self._native.sphere_count

    @property
    def memory_bytes(self) -> int:
        return self._native.memory_bytes


def _collision(d: dict, a: Collider, names_b: List[str], points: bool) -> Collision:
    box = np.array(d["box"], dtype=np.float64).reshape(2, 3) if d["hit"] else None
    world = np.asarray(a.origin) + np.asarray(a.spacing) * d["points"] if points else None
    return Collision(bool(d["hit"]), int(d["voxels"]), [a.names[b] for b in d["bones_a"]],
                     [names_b[b] for b in d["bones_b"]], [(a.names[x], names_b[y]) for x, y in d["bone_pairs"]],
                     box, dict(d["stats"]), world)


def _check(c, what: str) -> Collider:
    if not isinstance(c, Collider):
        raise TypeError(f"{what} must be a volrig.Collider, got {type(c).__name__}")
    return c


def collide(a: Collider, matrices_a, b: Collider, matrices_b, mode: str = "rigid", mode_b: Optional[str] = None,
            radius_scale_a=None, radius_scale_b=None, points: bool = False, reference: bool = False,
            keep_volume: bool = True) -> Collision:
    """Contact between two posed bodies: ``matrices_a`` (B_a, 4, 4) and ``matrices_b`` rest-to-pose bone matrices
    (world coordinates, as ``deform`` takes them); ``mode`` how their spheres move ("rigid", "linear",
    "dual_quaternion"; ``mode_b`` for B, default the same); radius scales and ``keep_volume`` (smooth modes: the
    blended spheres' radii follow the pose) as ``deform``'s. ``points``: also the
    contact voxels' world centres (``Collision.points``). ``reference``: the brute force (every lattice point
    against every ball), for tests."""
    _check(a, "a")
    _check(b, "b")
    f = _volrig.collide_reference if reference else _volrig.collide
    d = f(a._native, _matrices(matrices_a), mode, _radius_scale(radius_scale_a, len(a)), b._native,
          _matrices(matrices_b), mode_b or mode, _radius_scale(radius_scale_b, len(b)), bool(points or reference),
          keep_volume=bool(keep_volume))
    return _collision(d, a, b.names, points)


def _min_distance(exclude_adjacent: bool, min_bone_distance: Optional[int]) -> int:
    if min_bone_distance is not None:
        if min_bone_distance < 0:
            raise VolrigError(f"min_bone_distance must be >= 0, got {min_bone_distance}")
        return int(min_bone_distance)
    return 2 if exclude_adjacent else 1


def self_collide(a: Collider, matrices, exclude_adjacent: bool = True, min_bone_distance: Optional[int] = None,
                 ignore_rest_contact: bool = True, mode: str = "rigid", radius_scale=None, points: bool = False,
                 reference: bool = False, keep_volume: bool = True) -> Collision:
    """Parts of one posed body that interpenetrate (a hand through a thigh).

    A contact voxel lies inside two moved balls of bones at least ``min_bone_distance`` bones apart in the rig
    (default: 2 with ``exclude_adjacent``, so parent and child never count; 1 without); with
    ``ignore_rest_contact`` two balls that already intersect at rest never count (tissue joined at rest, as around
    a hip or between the arm and the chest of a scan lying with its arms at its sides)."""
    _check(a, "a")
    k = _min_distance(exclude_adjacent, min_bone_distance)
    if k > 0 and not a.has_parents:
        raise VolrigError("self_collide needs the rig's bone parents: build the Collider with rig=")
    f = _volrig.self_collide_reference if reference else _volrig.self_collide
    d = f(a._native, _matrices(matrices), mode, _radius_scale(radius_scale, len(a)), k, bool(ignore_rest_contact),
          bool(points or reference), keep_volume=bool(keep_volume))
    return _collision(d, a, a.names, points)


@dataclass
class Contact:
    """A run of consecutive frames with contact: ``first``..``last`` (frame numbers as given), the bones involved
    over the run, the most contact voxels in one frame and the frame where they were most."""
    first: int
    last: int
    bone_pairs: List[Tuple[str, str]]
    voxels: int
    peak_frame: int

    @property
    def name(self) -> str:
        """A short name (timeline markers hold 63 characters): "hand.R/thigh.R" for one bone pair, else the bones
        involved and the pair count."""
        if len(self.bone_pairs) == 1:
            return "/".join(self.bone_pairs[0])
        bones = " ".join(sorted({b for pair in self.bone_pairs for b in pair}))
        tail = f" ({len(self.bone_pairs)} pairs)"
        return (bones if len(bones) + len(tail) <= 50 else bones[:49 - len(tail)] + "…") + tail


@dataclass
class ClipContacts:
    """``collisions``' answer: per frame the ``Collision`` (``results``, in the order of ``frames``) and the runs of
    frames in contact (``contacts``)."""
    frames: List[int]
    results: List[Collision]
    contacts: List[Contact] = field(default_factory=list)

    @property
    def hit_frames(self) -> List[int]:
        return [f for f, r in zip(self.frames, self.results) if r.hit]


def contact_runs(frames: List[int], results: List[Collision]) -> List[Contact]:
    """The runs of consecutive frames with contact in per-frame results."""
    out: List[Contact] = []
    previous = None
    for f, r in zip(frames, results):
        if not r.hit:
            previous = None
            continue
        if previous is None:
            out.append(Contact(f, f, list(r.bone_pairs), r.voxels, f))
        else:
            c = out[-1]
            c.last = f
            c.bone_pairs = sorted(set(c.bone_pairs) | set(r.bone_pairs))
            if r.voxels > c.voxels:
                c.voxels, c.peak_frame = r.voxels, f
        previous = f
    return out


def collisions(a: Collider, clip_a, b: Optional[Collider] = None, clip_b=None, frames: Optional[Sequence[int]] = None,
               progress: Optional[Callable[[float], bool]] = None, **options) -> ClipContacts:
    """Contacts over a clip. ``clip_a`` (F, B_a, 4, 4) per-frame matrices (``animate``'s, or the add-on's armature
    poses); with ``b`` the two-body test against ``clip_b`` (F, B_b, 4, 4, or one (B_b, 4, 4) pose held still),
    without it self-contact of ``a``. ``frames``: the frame numbers to report (default 0..F-1). ``options`` go to
    ``collide`` or ``self_collide``. ``progress(fraction)`` returning False cancels (``volrig.Cancelled``)."""
    ma = np.asarray(clip_a, dtype=np.float64)
    if ma.ndim != 4:
        raise VolrigError(f"clip_a must have shape (frames, bones, 4, 4), got {ma.shape}")
    n = len(ma)
    if b is not None:
        mb = np.asarray(clip_b, dtype=np.float64)
        if mb.ndim == 3:
            mb = np.broadcast_to(mb, (n,) + mb.shape)
        if mb.ndim != 4 or len(mb) != n:
            raise VolrigError(f"clip_b must have shape ({n}, bones, 4, 4) or (bones, 4, 4), got {mb.shape}")
    labels = list(range(n)) if frames is None else [int(f) for f in frames]
    if len(labels) != n:
        raise VolrigError(f"{len(labels)} frame numbers for a clip of {n} frames")
    results = []
    for k in range(n):
        results.append(collide(a, ma[k], b, mb[k], **options) if b is not None else self_collide(a, ma[k], **options))
        if progress is not None and not progress((k + 1) / n):
            raise Cancelled("cancelled")
    return ClipContacts(labels, results, contact_runs(labels, results))

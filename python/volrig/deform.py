"""Per-frame sampled reconstruction: ``Deformer``, ``deform`` and ``Frame`` (docs/ALGORITHMS.md §7).

Every skeleton point is a sphere bound to bones. Given one rest-to-pose matrix per bone, each output voxel covered
by a moved sphere takes the source value at the inverse-transformed position, from the covering sphere that wins
the proximity buffer. See ``native/include/volrig/deform.hpp`` for how it is made fast.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .parts import part_grids
from .rigid_layer import RigidLayer
from .tissues import GRID as TISSUE_GRID
from .tissues import brick_classes, classes_metadata, tissue_grid
from .rig import Binding, rest_pose
from .skeleton import ProgressFn, SkeletonPoints
from .volume import Volume, _source_array, build_vdb

#: The deform modes (the core's names, ``_volrig.DEFORM_MODES``), each with a label and a description for menus:
#: the one list the command line's choices and the add-on's menu come from. The add-on stores a choice by its
#: position: append only.
MODE_INFO = {
    "linear": ("Linear blend", "Blend the bones' matrices by the weights (smooth near joints)"),
    "dual_quaternion": ("Dual quaternion", "Blend as dual quaternions (keeps volume at twisted joints)"),
    "rigid": ("Rigid", "Each sphere follows its heaviest bone"),
}
MODES = tuple(MODE_INFO)
PROXIMITIES = tuple(_volrig.PROXIMITIES)
#: Sampling names with their label and description (the add-on stores a choice by its position: append only).
SAMPLING_INFO = {
    "trilinear": ("Trilinear", "Interpolate the scan's samples (intensities)"),
    "nearest": ("Nearest", "Take the nearest sample (label maps)"),
}
SAMPLINGS = tuple(SAMPLING_INFO)
#: The revision of what a frame holds for the same inputs: bumped when the deformation's output changes (a bake
#: record made with another revision is out of date). 2: sliding contact and the slab factor's bound (issue 18). 3:
#: closed cubes rely only on the corner labels a query reads (a voxel or two a frame could be missing before).
DEFORM_REVISION = 3

#: The default proximity: the power distance |q - c|² - r² (the sphere q lies deepest inside). It keeps the
#: thesis' bend test unbroken further and reverses more exactly than the nearest centre; see docs/deform.md, Proximity.
DEFAULT_PROXIMITY = "power"


@dataclass
class Frame:
    """One deformed frame.

    values: Volume float32 with the source's spacing (0 outside the object); None for binary reconstructions.
    bone:   Volume int16 on the same grid: index + 1 of the bone each voxel came from, 0 = empty.
    offset: (x, y, z) source-lattice index of output voxel (0, 0, 0): the output grid lies on the source lattice.
    stats:  covered voxels, exact queries the bounds did not settle, blended spheres, and how the covered voxels were
            decided: by_block (whole blocks or 4³ sub-blocks one field covers and wins alone), by_cube (per-cube
            power ranges), by_sphere (the power of the sphere labelling the cube), by_search (the full per-voxel
            search); exact_sub_blocks counts the (field, 4³ sub-block) pairs whose powers came straight from the
            one sphere that is the field's nearest over the sub-block's whole preimage (no per-voxel table
            lookups).

    The arrays are read-only: once a frame is gone, its Deformer reuses the memory for the next one, re-zeroing only
    what it wrote. Copy an array (``np.array(frame.values.array)``) to change it; drop frames you are done with
    (as a bake loop does) so that the next frame finds the memory free.
    """

    values: Optional[Volume]
    bone: Volume
    offset: Tuple[int, int, int]
    stats: dict

    @property
    def mask(self) -> Volume:
        """The binary reconstruction: voxels covered by a moved sphere."""
        return self.bone.like(self.bone.array > 0)

    def shared_voxels(self, other: "Frame") -> int:
        """How many voxels both frames cover: frames of one source lattice (or two sources sharing a lattice), the
        reference ``volrig.collide`` equals."""
        oa, ob = np.array(self.offset), np.array(other.offset)
        if self.bone.spacing != other.bone.spacing or not np.allclose(
                np.array(self.bone.origin) - np.array(self.bone.spacing) * oa,
                np.array(other.bone.origin) - np.array(other.bone.spacing) * ob):
            raise VolrigError("shared_voxels: the frames lie on different lattices")
        lo, hi = np.maximum(oa, ob), np.minimum(oa + self.bone.dims, ob + other.bone.dims)
        if (hi <= lo).any():
            return 0
        a = self.bone.array[lo[2] - oa[2]:hi[2] - oa[2], lo[1] - oa[1]:hi[1] - oa[1], lo[0] - oa[0]:hi[0] - oa[0]]
        b = other.bone.array[lo[2] - ob[2]:hi[2] - ob[2], lo[1] - ob[1]:hi[1] - ob[1], lo[0] - ob[0]:hi[0] - ob[0]]
        return int(np.count_nonzero((a > 0) & (b > 0)))

    def save(self, path, half: bool = True, parts=(), tissues=(), substitutes=None) -> None:
        """Writes an OpenVDB file with the grids ``density`` (the values, or the mask for binary frames; half
        floats when ``half``) and ``bone`` (int32), for each of ``parts`` (``volrig.Part``) its
        ``density_<key>`` and ``mask_<key>`` (``volrig.part_grids``) and, with ``tissues`` (``volrig.Tissue``; the
        values a label map sampled nearest), the ``tissue`` label grid of class indices (``volrig.tissue_grid``) with
        the classes in the file's metadata (``volrig.tissues.classes_metadata``), placed by spacing and origin;
        atomically. ``substitutes``: grids replacing some of those (``{name:
        Volume}``, e.g. a part's ``density_<key>`` from another volume: ``volrig.parts.substitute_grid``)."""
        self.vdb(path, half, parts, tissues, substitutes).write(os.fspath(path))

    def vdb(self, path, half: bool = True, parts=(), tissues=(), substitutes=None):
        """``save``'s grids built, for ``.write(path)`` later (``volrig.volume.build_vdb``): the frame may go in
        between (a bake writes on another thread)."""
        density = self.values if self.values is not None else self.mask
        grids = {"density": density, "bone": self.bone}
        grids.update(part_grids(density, self.bone, parts) if parts else {})
        grids.update(_tissue_grid(self.values, tissues, tissue_grid))
        grids.update(substitutes or {})
        return build_vdb(os.fspath(path), grids, half=half, labels=("bone", TISSUE_GRID),
                         metadata=classes_metadata(tissues) if tissues else None)


class BrickedFrame:
    """A frame in 8³ bricks (``Deformer.frame(..., bricks=True)``; what a bake writes): its box is the posed
    spheres' grown to multiples of 8, held brick by brick, so that it costs memory only in the bricks it covers, and
    ``save`` writes the bricks as OpenVDB leaves without a dense copy. ``values``, ``bone``, ``offset``, ``mask``
    and ``shared_voxels`` are a ``Frame``'s (``dense()``, made on first use: the covered voxels' box, C order), so
    that it stands in for one; ``stats`` and ``extent`` (the covered box in the brick box, {x, y, z, dims}) are at
    hand without it.

    brick_values / brick_bone: arrays [brick z, y, x, z, y, x] (read-only, the Deformer's recycled memory;
    brick_values float16 and brick_bone uint8 (when the rig has fewer than 255 bones) with
    ``frame(..., half=True)``; brick_bone int16 otherwise);
    box_offset: the source-lattice index of the brick box's first voxel."""

    def __init__(self, d: dict, source: Volume):
        self.brick_values, self.brick_bone = d["values"], d["bone"]
        self.box_offset = tuple(int(x) for x in d["offset"])
        self.extent = tuple(int(x) for x in d["extent"])
        self.stats = dict(d["stats"])
        self.spacing, self._origin = tuple(source.spacing), tuple(d["origin"])
        self._dense = None

    def dense(self) -> Frame:
        """The same frame as a ``Frame``: C-order arrays over the covered voxels' box (made once, then kept)."""
        if self._dense is None:
            e = np.array(self.extent)
            lo, n = e[:3], np.maximum(e[3:], 1)  # a frame covering nothing: one empty voxel, as a cropped one
            b0, b1 = lo // 8, (lo + n + 7) // 8  # the bricks holding the extent, then the voxels in them

            def cut(a):
                if a is None:
                    return None
                part = a[b0[2]:b1[2], b0[1]:b1[1], b0[0]:b1[0]]
                if part.dtype == np.float16:  # half values (frame(..., half=True)): a Frame's are float32
                    part = part.astype(np.float32)
                if part.dtype == np.uint8:  # byte bone labels (likewise): a Frame's are int16
                    part = part.astype(np.int16)
                nb = part.shape[:3]
                whole = part.transpose(0, 3, 1, 4, 2, 5).reshape(nb[0] * 8, nb[1] * 8, nb[2] * 8)
                r = lo - b0 * 8
                return np.ascontiguousarray(whole[r[2]:r[2] + n[2], r[1]:r[1] + n[1], r[0]:r[0] + n[0]])

            origin = tuple(o + sp * float(x) for o, sp, x in zip(self._origin, self.spacing, lo))
            vals = cut(self.brick_values)
            self._dense = Frame(None if vals is None else Volume(vals, self.spacing, origin),
                                Volume(cut(self.brick_bone), self.spacing, origin),
                                tuple(int(o + x) for o, x in zip(self.box_offset, lo)), self.stats)
        return self._dense

    values = property(lambda self: self.dense().values)
    bone = property(lambda self: self.dense().bone)
    offset = property(lambda self: self.dense().offset)
    mask = property(lambda self: self.dense().mask)

    def shared_voxels(self, other) -> int:
        return self.dense().shared_voxels(other)

    def save(self, path, half: bool = True, parts=(), tissues=(), substitutes=None) -> None:
        """As ``Frame.save``."""
        self.vdb(path, half, parts, tissues, substitutes).write(os.fspath(path))

    def vdb(self, path, half: bool = True, parts=(), tissues=(), substitutes=None):
        """As ``Frame.vdb``; the grids ``density``, ``bone`` and ``tissue`` straight from the bricks (parts and
        substitutes from ``dense()``)."""
        if parts or substitutes:
            return self.dense().vdb(path, half, parts, tissues, substitutes)
        density = self.brick_values if self.brick_values is not None else (self.brick_bone > 0).view(np.uint8)
        grids = {"density": density, "bone": self.brick_bone}
        grids.update(_tissue_grid(self.brick_values, tissues, brick_classes))
        return build_vdb(os.fspath(path), grids, self.spacing, self._origin, half=half, labels=("bone", TISSUE_GRID),
                         metadata=classes_metadata(tissues) if tissues else None)


def _tissue_grid(values, tissues, classes) -> dict:
    """{"tissue": ``classes(values, tissues)``} with tissues (the values a label map's codes), else {}."""
    if not tissues:
        return {}
    if values is None:
        raise VolrigError("tissue looks need the label map's values: a binary frame has none")
    return {TISSUE_GRID: classes(values, tissues)}


def _sphere_arrays(points: SkeletonPoints, binding: Binding):
    """The arrays the core's BoundSpheres views (conversion only: the bindings and the core check them)."""
    if not isinstance(points, SkeletonPoints):
        raise TypeError(f"points must be volrig.SkeletonPoints, got {type(points).__name__}")
    w = binding.weights.tocsr()
    return (np.ascontiguousarray(points.ijk, dtype=np.int32), np.ascontiguousarray(points.radii, dtype=np.float32),
            np.ascontiguousarray(binding.bone, dtype=np.int32), int(w.shape[1]),
            np.ascontiguousarray(w.indptr, dtype=np.int64), np.ascontiguousarray(w.indices, dtype=np.int32),
            np.ascontiguousarray(w.data, dtype=np.float32))


def _matrices(m) -> np.ndarray:
    """(B, 4, 4) float64, C order; shape, count, finiteness and rigidity are the bindings' and the core's checks."""
    return np.ascontiguousarray(m, dtype=np.float64)


def _radius_scale(radius_scale, n: int):
    """None, or one factor per point (a number is repeated); the core checks the count and the range."""
    if radius_scale is None:
        return None
    s = np.asarray(radius_scale, dtype=np.float32)
    return np.full(n, float(s), dtype=np.float32) if s.ndim == 0 else s


def _frame(d: dict, source: Volume):
    if d["bricks"]:
        return BrickedFrame(d, source)
    sp = source.spacing
    values = Volume(d["values"], sp, d["origin"]) if d["values"] is not None else None
    return Frame(values, Volume(d["bone"], sp, d["origin"]), tuple(int(x) for x in d["offset"]), dict(d["stats"]))


class Deformer:
    """Reusable per-rig state: build once, then call ``frame`` for every pose.

    The first frame (and any change of mode family, radius_scale or binding) builds the spheres' k-d trees, one per
    bone and blend group: a rig change costs little. Once ``lattice_after`` frames (default 8) have been drawn
    without a change, the next one also builds each bone's lattice tables (its rest-space power diagram and per-cube
    power ranges: about four rigid frames' time), after which a frame costs about one gather per output voxel; until
    then bones take their powers from the balls meeting each preimage, as blend groups always do (the same frame,
    1.2-1.3x slower rigid and 1.0-1.1x smooth on the phantom at scale 1, up to 2x / 1.4x at scale 2: docs/deform.md,
    When the tables are built; benchmarks/RESULTS.md). ``lattice_after=0`` builds the tables at the
    first frame (many frames to come), ``-1`` never (one frame, or a rig about to change again).

    A binding with rigid tissue (``bind(..., rigid=)``) deforms in two layers (``volrig.rigid_layer``): the spheres
    sample a source whose rigid voxels hold the nearest soft tissue, and each bone's piece of rigid tissue, moved by
    that bone alone, is drawn over them.
    """

    LATTICE_AFTER = _volrig.LATTICE_AFTER  # the default lattice_after

    def __init__(self, source: Volume, points: SkeletonPoints, binding: Binding, proximity: str = DEFAULT_PROXIMITY,
                 lattice_after: Optional[int] = None):
        # the core sees the points' voxel indices only, not the grid they were taken on: checked here
        if tuple(points.spacing) != tuple(source.spacing):
            raise VolrigError(f"the skeleton points were taken on a grid of spacing {points.spacing} but the source "
                             f"has spacing {source.spacing}")
        if tuple(points.origin) != tuple(source.origin):
            raise VolrigError(f"the skeleton points were taken on a grid with origin {points.origin} but the source "
                             f"has origin {source.origin}")
        self.source = source
        self.points = points
        self.binding = binding
        self.proximity = proximity
        self._layer = None if binding.rigid is None else RigidLayer(source, np.asarray(binding.rigid, dtype=bool),
                                                                    binding.rigid_whole)
        self._layer_proximity = None  # the proximity its pieces were labelled with
        ijk, radii, bone, nb, off, wb, w = _sphere_arrays(points, binding)
        self.bone_count = nb
        self._native = _volrig.Deformer(_source_array(source), source.spacing, source.origin, ijk, radii, bone, nb,
                                        off, wb, w)
        if lattice_after is not None:
            self.lattice_after = lattice_after

    @property
    def lattice_after(self) -> int:
        """Frames drawn without a rig change before the bones' lattice tables are built (0: at once, -1: never)."""
        return int(self._native.lattice_after)

    @lattice_after.setter
    def lattice_after(self, frames: int) -> None:
        self._native.lattice_after = int(frames)

    @property
    def lattice_tables(self) -> bool:
        """Whether every bone's lattice tables are built (False before the first frame)."""
        return bool(self._native.lattice_tables)

    @property
    def memory_bytes(self) -> int:
        """Bytes of per-rig data currently held (the rigid layer's soft source and pieces included)."""
        return int(self._native.memory_bytes) + (0 if self._layer is None else self._layer.memory_bytes)

    @property
    def kept_frame_bytes(self) -> int:
        """Bytes of output memory kept from frames that are gone, for the next frame (resident only where they
        wrote)."""
        return int(self._native.kept_frame_bytes)

    def release_frame_memory(self) -> None:
        """Frees the output memory kept for the next frame (say, after a bake); frames still alive keep theirs."""
        self._native.release_frame_memory()

    def rebind(self, binding: Binding) -> None:
        """Takes a new binding of the same points (say, weights repainted). The next frame rebuilds only the per-rig
        data of the bones and blend groups whose spheres changed (``reused_fields`` says how many it kept)."""
        old, new = self.binding.rigid, binding.rigid
        if self.binding.rigid_whole != binding.rigid_whole or \
                (old is not new and ((old is None) != (new is None) or not np.array_equal(old, new))):
            self.__init__(self.source, self.points, binding, self.proximity,  # other rigid tissue: another source
                          self.lattice_after)
            return
        ijk, radii, bone, nb, off, wb, w = _sphere_arrays(self.points, binding)
        self._native.rebind(ijk, radii, bone, nb, off, wb, w)
        self.binding = binding
        if self._layer is not None:  # which bone carries which rigid voxel follows the binding
            self._layer.pieces = None
            self._native.set_source(_source_array(self.source), self.source.spacing, self.source.origin)

    @property
    def reused_fields(self) -> int:
        """How many bones' and blend groups' per-rig data the last build took over unchanged."""
        return int(self._native.reused_fields)

    def frame(self, bone_matrices, mode: str = "rigid", sampling: str = "trilinear", radius_scale=None,
              values: bool = True, progress: ProgressFn = None, proximity: Optional[str] = None,
              keep_volume: bool = True, bricks: bool = False, half: bool = False):
        """Reconstructs one pose. ``bone_matrices`` (B, 4, 4): rest-to-pose in the source's world coordinates.
        ``keep_volume`` (smooth modes; the default): the blended spheres' radii follow the pose so that a bent limb
        keeps its volume (docs/deform.md); False gives the plain blend. Rigid frames ignore it. Returns a
        ``Frame``, or with ``bricks`` a ``BrickedFrame`` (the same frame in 8³ bricks: memory only where it covers,
        written to OpenVDB without a dense copy; what bakes use). ``half`` (with ``bricks``): its values as float16,
        rounded as OpenVDB stores half floats, and its bone labels as uint8 when the rig has fewer than 255 bones
        (half the memory; the same file when saved with ``half=True``)."""
        m, scale = _matrices(bone_matrices), _radius_scale(radius_scale, len(self.points))
        proximity = proximity or self.proximity
        if self._layer is not None and (self._layer.pieces is None or self._layer_proximity != proximity):
            self._label_layer(mode, proximity)
        d = self._native.frame(m, mode, proximity, sampling, scale, bool(values), progress,
                               keep_volume=bool(keep_volume), bricks=bool(bricks), half=bool(half))
        return _frame(d, self.source)

    def _label_layer(self, mode: str, proximity: str) -> None:
        """The rigid layer from this binding's rest frame (its own radii, the proximity asked for; in the mode
        family asked for, so that its per-rig data serves the frames after it): the spheres then sample the soft
        source and the pieces are drawn. A frame with another proximity labels it again."""
        src = _source_array(self.source)
        self._native.set_rigid_layer(src, self.source.spacing, self.source.origin, [])
        rest = self._native.frame(_matrices(rest_pose(self.bone_count)), mode, proximity, "nearest", None, False,
                                  None)
        self._layer_proximity = proximity
        self._layer.build(np.asarray(rest["bone"]), rest["offset"])
        del rest
        self._native.set_source(self._layer.soft, self.source.spacing, self.source.origin)
        self._native.set_rigid_layer(src, self.source.spacing, self.source.origin,
                                     [p.native() for p in self._layer.pieces])


def coarse_level(source: Volume, points: SkeletonPoints, binding: Binding, factor: int):
    """The source and rig at a coarser level, for a live preview: every ``factor``-th voxel of the source along each
    axis (voxel (0, 0, 0) stays where it is; spacing times ``factor``), each skeleton point moved to its nearest
    coarse voxel with its world radius, one point per coarse voxel (the largest ball's, with its binding row).
    Returns ``(source, points, binding)`` for a ``Deformer``: a frame costs about factor³ times less."""
    f = int(factor)
    if not 1 <= f <= 16:
        raise VolrigError(f"factor must be 1 to 16, got {factor!r}")
    if f == 1:
        return source, points, binding
    arr = np.asarray(source.array)[::f, ::f, ::f]
    coarse = Volume(np.ascontiguousarray(arr), tuple(s * f for s in source.spacing), source.origin)
    shape = np.array(arr.shape)
    ijk = np.minimum(np.rint(np.asarray(points.ijk) / f).astype(np.int64), shape - 1)
    key = (ijk[:, 0] * shape[1] + ijk[:, 1]) * shape[2] + ijk[:, 2]
    order = np.lexsort((-np.asarray(points.radii), key))  # per coarse voxel, the largest ball first
    keep = order[np.r_[True, key[order][1:] != key[order][:-1]]]
    keep.sort()
    ijk = ijk[keep].astype(np.int32)
    centers = np.asarray(coarse.origin) + ijk[:, ::-1] * np.asarray(coarse.spacing)
    radii = np.asarray(points.radii)[keep]
    pts = SkeletonPoints(ijk, centers, radii, np.asarray(points.dt)[keep], np.asarray(points.scores)[keep],
                         points.metric, coarse.spacing, coarse.origin, points.thinness)
    rigid = None if binding.rigid is None else np.ascontiguousarray(binding.rigid[::f, ::f, ::f])
    b = Binding(np.asarray(binding.bone)[keep], binding.weights.tocsr()[keep], binding.mode,
                np.asarray(binding.unreachable)[keep], list(binding.bone_names), rigid, binding.rigid_whole)
    return coarse, pts, b


def deform(source: Volume, points: SkeletonPoints, binding: Binding, bone_matrices, mode: str = "rigid",
           proximity: str = DEFAULT_PROXIMITY, sampling: str = "trilinear", radius_scale=None,
           progress: ProgressFn = None, keep_volume: bool = True) -> Frame:
    """The deformed volume of one pose.

    source:        the scan (any dtype); points: the skeleton points the rig was bound with; binding: their bones.
    bone_matrices: (B, 4, 4) rest-to-pose matrices in the source's world coordinates (posed = M @ rest); rigid.
    mode:          "rigid" (the thesis: each sphere moves with its bone), "linear" or "dual_quaternion" (each
                   sphere's transform blends its bones' by the binding weights; use a smooth binding).
    proximity:     "power" (default: |q - c|² - r², the sphere q is deepest inside) or "nearest" (the thesis'
                   nearest centre).
    sampling:      "trilinear" or "nearest" (use nearest for label maps).
    radius_scale:  a number or one factor per point, for bulge and pinch.
    keep_volume:   smooth modes: blended spheres' radii follow the pose so that bent limbs keep their volume
                   (the default; False: the plain blend).
    For many frames of one rig, build a ``Deformer`` once.
    """
    return Deformer(source, points, binding, proximity).frame(bone_matrices, mode, sampling, radius_scale,
                                                              progress=progress, keep_volume=keep_volume)


def deform_reference(source: Volume, points: SkeletonPoints, binding: Binding, bone_matrices, mode: str = "rigid",
                     proximity: str = DEFAULT_PROXIMITY, sampling: str = "trilinear", radius_scale=None,
                     values: bool = True, like: Optional[Frame] = None, keep_volume: bool = True) -> Frame:
    """The literal thesis algorithm (every moved sphere scattered over its bounding box with a proximity buffer,
    in point order): the reference that tests and benchmarks compare ``deform`` with. ``like`` fixes the output
    grid to another frame's. A binding with rigid tissue scatters the soft source and draws the rigid layer
    over it, as ``Deformer`` does."""
    ijk, radii, bone, nb, off, wb, w = _sphere_arrays(points, binding)
    box = None if like is None else tuple(like.offset) + tuple(like.bone.dims)
    scale = _radius_scale(radius_scale, len(points))
    layer = None if binding.rigid is None else RigidLayer(source, np.asarray(binding.rigid, dtype=bool),
                                                          binding.rigid_whole)

    def scatter(src, matrices, sampling_, scale_, values_, box_):
        return _volrig.deform_reference(_source_array(src), source.spacing, source.origin, ijk, radii, bone, nb, off,
                                        wb, w, _matrices(matrices), mode, proximity, sampling_, scale_, values_, box_,
                                        keep_volume=bool(keep_volume))
    if layer is not None:  # the rigid layer from the rest pose (the binding's own radii), as the Deformer builds it
        rest = scatter(source, rest_pose(nb), "nearest", None, False, None)
        layer.build(np.asarray(rest["bone"]), rest["offset"])
        source_ = source.like(layer.soft)
    else:
        source_ = source
    d = scatter(source_, bone_matrices, sampling, scale, bool(values), box)
    if layer is not None:
        d = layer.paint(d, _matrices(bone_matrices), sampling, fixed=box is not None)
    return _frame(d, source)


def inverse_warp(source: Volume, matrix, sampling: str = "trilinear", like: Optional[Frame] = None) -> Volume:
    """The source resampled through one rest-to-pose matrix (one gather per output voxel): the speed reference of
    ``deform``. The output grid is the source's, or ``like``'s (a Frame) to compare per output voxel."""
    m = _matrices(matrix)
    box = None if like is None else tuple(like.offset) + tuple(like.bone.dims)
    arr = _volrig.inverse_warp(_source_array(source), source.spacing, source.origin, m, sampling, box)
    if like is None:
        return source.like(arr)
    return Volume(arr, source.spacing, like.bone.origin)

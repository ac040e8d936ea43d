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
from .rig import Binding
from .skeleton import ProgressFn, SkeletonPoints
from .volume import Volume, write_vdb

MODES = ("rigid", "linear", "dual_quaternion")
PROXIMITIES = ("power", "nearest")
SAMPLINGS = ("trilinear", "nearest")
#: The default proximity: the power distance |q - c|² - r² (the sphere q lies deepest inside). It keeps the
#: thesis' bend test unbroken further and reverses more exactly than the nearest centre; see the README.
DEFAULT_PROXIMITY = "power"


@dataclass
class Frame:
    """One deformed frame.

    values: Volume float32 with the source's spacing (0 outside the object); None for binary reconstructions.
    bone:   Volume int16 on the same grid: index + 1 of the bone each voxel came from, 0 = empty.
    offset: (x, y, z) source-lattice index of output voxel (0, 0, 0): the output grid lies on the source lattice.
    stats:  covered voxels, exact queries the bounds did not settle, blended spheres, and how the covered voxels were
            decided: by_block (whole blocks one bone covers alone), by_cube (per-cube power ranges), by_sphere (the
            power of the sphere labelling the cube), by_search (the full per-voxel search).

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

    def save(self, path, half: bool = True) -> None:
        """Writes an OpenVDB file with the grids ``density`` (the values, or the mask for binary frames; half
        floats when ``half``) and ``bone`` (int32), placed by spacing and origin; atomically."""
        density = self.values.array if self.values is not None else self.mask.array
        write_vdb(os.fspath(path), {"density": density, "bone": self.bone.array}, self.bone.spacing,
                  self.bone.origin, half=half)


def _check_choice(name, value, allowed):
    if value not in allowed:
        raise ValueError(f"{name} must be one of {', '.join(repr(a) for a in allowed)}, got {value!r}")


def _sphere_arrays(points: SkeletonPoints, binding: Binding, bone_count: Optional[int] = None):
    if not isinstance(points, SkeletonPoints):
        raise TypeError(f"points must be volrig.SkeletonPoints, got {type(points).__name__}")
    n = len(points)
    bone = np.ascontiguousarray(binding.bone, dtype=np.int32)
    if bone.shape != (n,):
        raise ValueError(f"the binding has {bone.shape[0] if bone.ndim else 0} points but there are {n} skeleton "
                         "points: bind the same points you deform")
    w = binding.weights.tocsr()
    if w.shape[0] != n:
        raise ValueError(f"the binding's weights have {w.shape[0]} rows for {n} skeleton points")
    bones = int(bone_count if bone_count is not None else w.shape[1])
    return (np.ascontiguousarray(points.ijk, dtype=np.int32), np.ascontiguousarray(points.radii, dtype=np.float32),
            bone, bones, np.ascontiguousarray(w.indptr, dtype=np.int64),
            np.ascontiguousarray(w.indices, dtype=np.int32), np.ascontiguousarray(w.data, dtype=np.float32))


def _matrices(bone_matrices, bones: int) -> np.ndarray:
    m = np.asarray(bone_matrices, dtype=np.float64)
    if m.ndim != 3 or m.shape[1:] != (4, 4):
        raise ValueError(f"bone_matrices must have shape (B, 4, 4), got {m.shape}")
    if m.shape[0] != bones:
        raise ValueError(f"got {m.shape[0]} bone matrices for a rig of {bones} bones")
    if not np.all(np.isfinite(m)):
        bad = np.flatnonzero(~np.isfinite(m).all(axis=(1, 2)))
        raise ValueError(f"bone matrices {bad.tolist()} hold non-finite values")
    return np.ascontiguousarray(m)


def _source_array(source: Volume) -> np.ndarray:
    if not isinstance(source, Volume):
        raise TypeError(f"source must be a volrig.Volume, got {type(source).__name__}")
    a = source.array
    if a.dtype == np.bool_:
        a = a.view(np.uint8)
    if np.issubdtype(a.dtype, np.floating) and not np.all(np.isfinite(a)):
        raise ValueError("the source volume holds NaN or infinite samples")
    return np.ascontiguousarray(a)


def _radius_scale(radius_scale, n: int):
    if radius_scale is None:
        return None
    s = np.asarray(radius_scale, dtype=np.float32)
    if s.ndim == 0:
        s = np.full(n, float(s), dtype=np.float32)
    if s.shape != (n,):
        raise ValueError(f"radius_scale must be a number or one factor per point ({n}), got shape {s.shape}")
    return s


def _frame(d: dict, source: Volume) -> Frame:
    sp = source.spacing
    values = Volume(d["values"], sp, d["origin"]) if d["values"] is not None else None
    stats = {k: int(d[k]) for k in ("covered", "exact_queries", "blended_spheres", "by_block", "by_cube", "by_sphere",
                                     "by_search")}
    return Frame(values, Volume(d["bone"], sp, d["origin"]), tuple(int(x) for x in d["offset"]), stats)


class Deformer:
    """Reusable per-rig state: build once, then call ``frame`` for every pose.

    The first frame (and any change of mode family or radius_scale) builds each bone's rest-space power diagram
    and k-d tree; later frames cost about one gather per output voxel.
    """

    def __init__(self, source: Volume, points: SkeletonPoints, binding: Binding, proximity: str = DEFAULT_PROXIMITY):
        _check_choice("proximity", proximity, PROXIMITIES)
        if tuple(points.spacing) != tuple(source.spacing):
            raise ValueError(f"the skeleton points were taken on a grid of spacing {points.spacing} but the source "
                             f"has spacing {source.spacing}")
        if tuple(points.origin) != tuple(source.origin):
            raise ValueError(f"the skeleton points were taken on a grid with origin {points.origin} but the source "
                             f"has origin {source.origin}")
        self.source = source
        self.points = points
        self.binding = binding
        self.proximity = proximity
        ijk, radii, bone, nb, off, wb, w = _sphere_arrays(points, binding)
        self.bone_count = nb
        self._native = _volrig.Deformer(_source_array(source), source.spacing, source.origin, ijk, radii, bone, nb,
                                        off, wb, w)

    @property
    def memory_bytes(self) -> int:
        """Bytes of per-rig data currently held."""
        return int(self._native.memory_bytes)

    @property
    def kept_frame_bytes(self) -> int:
        """Bytes of output memory kept from frames that are gone, for the next frame (resident only where they
        wrote)."""
        return int(self._native.kept_frame_bytes)

    def release_frame_memory(self) -> None:
        """Frees the output memory kept for the next frame (say, after a bake); frames still alive keep theirs."""
        self._native.release_frame_memory()

    def frame(self, bone_matrices, mode: str = "rigid", sampling: str = "trilinear", radius_scale=None,
              values: bool = True, progress: ProgressFn = None, proximity: Optional[str] = None) -> Frame:
        """Reconstructs one pose. ``bone_matrices`` (B, 4, 4): rest-to-pose in the source's world coordinates."""
        _check_choice("mode", mode, MODES)
        _check_choice("sampling", sampling, SAMPLINGS)
        prox = proximity or self.proximity
        _check_choice("proximity", prox, PROXIMITIES)
        m = _matrices(bone_matrices, self.bone_count)
        d = self._native.frame(m, mode, prox, sampling, _radius_scale(radius_scale, len(self.points)), bool(values),
                               progress)
        return _frame(d, self.source)


def deform(source: Volume, points: SkeletonPoints, binding: Binding, bone_matrices, mode: str = "rigid",
           proximity: str = DEFAULT_PROXIMITY, sampling: str = "trilinear", radius_scale=None,
           progress: ProgressFn = None) -> Frame:
    """The deformed volume of one pose.

    source:        the scan (any dtype); points: the skeleton points the rig was bound with; binding: their bones.
    bone_matrices: (B, 4, 4) rest-to-pose matrices in the source's world coordinates (posed = M @ rest); rigid.
    mode:          "rigid" (the thesis: each sphere moves with its bone), "linear" or "dual_quaternion" (each
                   sphere's transform blends its bones' by the binding weights; use a smooth binding).
    proximity:     "power" (default: |q - c|² - r², the sphere q is deepest inside) or "nearest" (the thesis'
                   nearest centre).
    sampling:      "trilinear" or "nearest" (use nearest for label maps).
    radius_scale:  a number or one factor per point, for bulge and pinch.
    For many frames of one rig, build a ``Deformer`` once.
    """
    return Deformer(source, points, binding, proximity).frame(bone_matrices, mode, sampling, radius_scale,
                                                              progress=progress)


def deform_reference(source: Volume, points: SkeletonPoints, binding: Binding, bone_matrices, mode: str = "rigid",
                     proximity: str = DEFAULT_PROXIMITY, sampling: str = "trilinear", radius_scale=None,
                     values: bool = True, like: Optional[Frame] = None) -> Frame:
    """The literal thesis algorithm (every moved sphere scattered over its bounding box with a proximity buffer,
    in point order): the reference that tests and benchmarks compare ``deform`` with. ``like`` fixes the output
    grid to another frame's."""
    _check_choice("mode", mode, MODES)
    _check_choice("proximity", proximity, PROXIMITIES)
    _check_choice("sampling", sampling, SAMPLINGS)
    ijk, radii, bone, nb, off, wb, w = _sphere_arrays(points, binding)
    box = None if like is None else tuple(like.offset) + tuple(like.bone.dims)
    d = _volrig.deform_reference(_source_array(source), source.spacing, source.origin, ijk, radii, bone, nb, off, wb,
                                 w, _matrices(bone_matrices, nb), mode, proximity, sampling,
                                 _radius_scale(radius_scale, len(points)), bool(values), box)
    return _frame(d, source)


def inverse_warp(source: Volume, matrix, sampling: str = "trilinear", like: Optional[Frame] = None) -> Volume:
    """The source resampled through one rest-to-pose matrix (one gather per output voxel): the speed reference of
    ``deform``. The output grid is the source's, or ``like``'s (a Frame) to compare per output voxel."""
    _check_choice("sampling", sampling, SAMPLINGS)
    m = np.ascontiguousarray(matrix, dtype=np.float64)
    box = None if like is None else tuple(like.offset) + tuple(like.bone.dims)
    arr = _volrig.inverse_warp(_source_array(source), source.spacing, source.origin, m, sampling, box)
    if like is None:
        return source.like(arr)
    return Volume(arr, source.spacing, like.bone.origin)

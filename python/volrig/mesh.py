"""Meshes in: read OBJ/PLY/OFF/STL/Medit triangle meshes and TGF skeletons, and voxelize a mesh into a mask ``Volume``.

``voxelize`` fills the solid a surface encloses. It tolerates small holes: the exterior is flood-filled from the
grid border through voxels farther than ``closing_radius`` voxels from the surface, so holes narrower than about
twice that radius are bridged (see native/include/volrig/mesh.hpp for the method and its limits). Surfaces that
are not closed (soups of open parts, missing caps) are better served by ``method="winding"`` (the generalized
winding number) or ``method="auto"`` (for a mesh that is not closed, the union of both), which ``rig_mesh`` and
the command line use.
"""
from __future__ import annotations

import numbers
from typing import Callable, Optional, Tuple

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .volume import Volume, _native_path

ProgressFn = Optional[Callable[[float], Optional[bool]]]


#: File endings ``read_mesh`` reads (lower-case; matched case-insensitively): the one list, from the native core.
MESH_EXTENSIONS: Tuple[str, ...] = tuple(_volrig.MESH_EXTENSIONS)


def read_mesh(path) -> Tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh; the reader is chosen by the file's ending (``MESH_EXTENSIONS``).

    ``.obj`` (Wavefront), ``.ply`` (ascii or binary), ``.off`` (Geomview OFF, COFF, NOFF...), ``.stl`` (ASCII or
    binary; identical corners welded into shared vertices) and ``.mesh`` (Medit ASCII: its Triangles and
    Quadrilaterals, or when it has none the boundary of its Tetrahedra; binary ``.meshb`` is not read).

    Returns ``(vertices, faces)``: vertices (V, 3) float64 positions, faces (F, 3) int64 0-based vertex indices.
    Polygons are fan-triangulated. Raises FileNotFoundError, or ``volrig.FileFormatError`` (a ValueError) naming
    the file, the line (text formats) or byte (binary) and what is wrong.
    """
    vertices, faces = _volrig.read_mesh(_native_path(path)[1])
    return vertices, faces.astype(np.int64)


def read_tgf(path) -> Tuple[np.ndarray, np.ndarray]:
    """Read a skeleton in libigl's Trivial Graph Format (``.tgf``).

    Returns ``(joints, edges)``: joints (K, 3) float64 positions, edges (E, 2) int64 0-based joint indices.
    """
    joints, edges = _volrig.read_tgf(_native_path(path)[1])
    return joints, edges.astype(np.int64)


#: voxelize's inside/outside tests.
VOXELIZE_METHODS: Tuple[str, ...] = ("auto", "winding", "flood")


def _number(value, what: str) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise VolrigError(f"{what} must be a number, got {value!r}")
    value = float(value)
    if not np.isfinite(value):
        raise VolrigError(f"{what} must be finite, got {value}")
    return value


def voxelize(vertices, faces, voxel_size: float, padding: float = 2, progress: ProgressFn = None, *,
             closing_radius: float = 1.5, anchor=None, method: str = "flood") -> Volume:
    """The solid a triangle mesh encloses, as a boolean mask ``Volume``.

    vertices:       (V, 3) positions (x, y, z), any real dtype; finite.
    faces:          (F, 3) integer 0-based vertex indices (triangles; see ``read_mesh``).
    voxel_size:     edge of a voxel, in the mesh's units (> 0). Spacing is (voxel_size,) * 3.
    padding:        whole empty voxels around the mesh's bounding box on each side (rounded up; 0 to 1000).
    progress:       callable(fraction) -> bool|None; return False to cancel (raises ``volrig.Cancelled``).
    closing_radius: hole closing, in voxels (0.5 to 4, default 1.5): holes and gaps narrower than about twice this
                    are closed (creases that narrow are filled too). 0 uses OpenVDB's own inside/outside, which
                    needs a watertight mesh and loses the whole interior through any hole wider than ~1.5 voxels.
    anchor:         (x, y, z) a point the voxel lattice must pass through (voxel centres at anchor + k * voxel_size;
                    the grid may start a voxel lower), e.g. another voxelization's origin, to compare the two voxel
                    for voxel (a mesh and its posed copy).
    method:         "flood" (default; the exterior flood fill above, exact for closed surfaces), "winding" (inside
                    where the generalized winding number |w| >= 0.5: for meshes that are not closed: separate open
                    parts, missing caps, open skirts, overlapping or reversed pieces; ``closing_radius`` unused) or
                    "auto" (flood for a closed mesh, so it gives exactly flood's mask; when some edge is not shared
                    by exactly two triangles, the union of flood's and winding's masks: the winding number restores
                    the interiors the flood loses through wide holes, the flood keeps what its closing joins).
                    ``rig_mesh`` and the command line use "auto".

    The volume's origin is the world position of voxel (0, 0, 0)'s centre; voxel (x, y, z) is inside when its
    centre is. Raises ValueError for bad arguments, a grid above the size limit ($VOLRIG_MAX_BYTES, default 16 GiB
    at two bytes per voxel), or a mesh that encloses no voxel centre.
    """
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise VolrigError(f"vertices must have shape (V, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise VolrigError(f"faces must have shape (F, 3) (triangles), got {f.shape}")
    if len(v) == 0:
        raise VolrigError("vertices is empty")
    if len(f) == 0:
        raise VolrigError("faces is empty")
    if v.dtype == np.bool_ or not (np.issubdtype(v.dtype, np.floating) or np.issubdtype(v.dtype, np.integer)):
        raise VolrigError(f"vertices must be real numbers, got dtype {v.dtype}")
    if f.dtype == np.bool_ or not np.issubdtype(f.dtype, np.integer):
        raise VolrigError(f"faces must be integer vertex indices, got dtype {f.dtype}")
    v = np.ascontiguousarray(v, dtype=np.float64)
    if not np.isfinite(v).all():
        bad = int(np.argmin(np.isfinite(v).all(axis=1)))
        raise VolrigError(f"vertices must be finite: vertex {bad} is {v[bad].tolist()}")
    if f.min() < 0 or f.max() >= len(v):
        bad = f.min() if f.min() < 0 else f.max()
        raise VolrigError(f"faces index vertex {int(bad)}, out of range for {len(v)} vertices")
    f = np.ascontiguousarray(f, dtype=np.int64)
    size = _number(voxel_size, "voxel_size")
    if size <= 0:
        raise VolrigError(f"voxel_size must be positive, got {size}")
    pad = _number(padding, "padding")
    if not 0 <= pad <= 1000:
        raise VolrigError(f"padding must be between 0 and 1000 voxels, got {pad}")
    closing = _number(closing_radius, "closing_radius")
    if not (closing == 0 or 0.5 <= closing <= 4):
        raise VolrigError(f"closing_radius must be 0 or between 0.5 and 4 voxels, got {closing}")
    if method not in VOXELIZE_METHODS:
        raise VolrigError(f"method must be one of {', '.join(map(repr, VOXELIZE_METHODS))}, got {method!r}")
    if anchor is not None:
        anchor = tuple(_number(a, "anchor") for a in np.asarray(anchor, dtype=np.float64).reshape(3))
    mask, spacing, origin = _volrig.voxelize(v, f, size, pad, closing, progress, anchor, method)
    return Volume(mask.view(np.bool_), spacing, origin)


def subdivide(vertices, faces) -> Tuple[np.ndarray, np.ndarray]:
    """Midpoint subdivision: every triangle split into four at its edges' midpoints (the surface is unchanged; a
    shared edge gets one midpoint). Returns ``(vertices, faces)`` with V + E vertices and 4F faces."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise VolrigError(f"subdivide needs vertices (V, 3) and faces (F, 3), got {v.shape} and {f.shape}")
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    ab, bc, ca = (len(v) + inverse.reshape(-1)).reshape(3, -1)
    a, b, c = f.T
    quads = [np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))]
    return np.concatenate([v, v[unique].mean(axis=1)]), np.concatenate(quads)

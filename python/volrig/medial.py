"""Plates and thickness: the plane-like skeleton and local thickness (ALGORITHMS.md §11 of the shared docs, the Amira paper).

``local_thickness(mask)``: for every object voxel, the diameter of the largest ball inside the object that contains
it (Hildebrand and Rüegsegger 1997; the balls are reconstruction's open balls |q - c| < DT(c), Euclidean, world
units). Computed in the native core: only the centres whose ball is not inside a neighbour's are painted, as x-runs,
slices in parallel; equal to the brute-force maximum over every object voxel's ball (tested).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import List

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .skeleton import ProgressFn, _geometry, _mask_array
from .volume import Volume


def local_thickness(mask, progress: ProgressFn = None) -> Volume:
    """Local thickness of ``mask`` (a ``Volume`` or a 3-D array [z, y, x]; non-zero = object) as a float32 Volume
    on the same grid, in world units (0 on the background). A plate n voxels thick reads n voxels (n even) or n + 1
    (n odd): DT is measured to the centre of the nearest background voxel. ``progress(fraction)`` may return False
    to cancel (``volrig.Cancelled``)."""
    spacing, origin = _geometry(mask)
    out = _volrig.local_thickness(_mask_array(mask), spacing, progress)
    return Volume(np.asarray(out), spacing, origin)


def _t_world(mask, t: float) -> float:
    if not (t > 0) or not np.isfinite(t):
        raise VolrigError(f"t must be a positive number of voxels, got {t}")
    return float(t) * min(_geometry(mask)[0])


def plane_measure(mask, t: float = 5.0, progress: ProgressFn = None) -> Volume:
    """The Amira paper's plane-like measure d of every object voxel (float32 Volume, world units, 0 on the
    background): the largest geodesic distance, along the object's boundary, between the voxel's nearest boundary
    voxel and those of its three lower neighbours. Large where the nearest boundary jumps across a plate (the way
    round its rim is long), small elsewhere. Distances beyond ``t`` voxels (of the smallest spacing) are not
    followed: they read +inf."""
    spacing, origin = _geometry(mask)
    d = _volrig.plane_measure(_mask_array(mask), spacing, _t_world(mask, t), progress)
    return Volume(np.asarray(d), spacing, origin)


def plane_like(mask, t: float = 5.0, progress: ProgressFn = None) -> Volume:
    """The plane-like skeleton voxels of ``mask`` (bool Volume): plane_measure above ``t`` voxels. On a plate at
    least ~2t across, one layer at its middle (the medial surface), away from its rim by about t; rods thinner
    than about t / pi across, and bumps on a noisy boundary, have none (the paper: t >= 5 against noise; larger t
    keeps only the larger plates)."""
    d = plane_measure(mask, t, progress)
    return Volume(d.array > _t_world(mask, t), d.spacing, d.origin)


#: Skeleton voxel classes of ``MedialSurface.skeleton``.
SKELETON_CLASSES = {0: "none", 1: "surface", 2: "curve", 3: "junction"}


@dataclass(frozen=True)
class MedialSurface:
    """The medial surface of the plates of a mask, its rods and the classified voxel skeleton (``medial_surface``).

    vertices:  (V, 3) float64 positions, world units, in the grid frame (origin + spacing * index, as every volrig
               result; ``Volume.grid_to_world()`` takes them to the patient frame).
    faces:     (F, 3) int64 vertex indices, oriented consistently where the surface is a manifold.
    thickness: (V,) float64 plate thickness at each vertex (twice the distance to the object's boundary), world units.
    rods:      list of (N, 3) float64 polylines (voxel centres of the curve skeleton), world units.
    rod_radii: list of (N,) float64 radii along each rod, world units.
    skeleton:  uint8 Volume: 0 background, 1 surface, 2 curve, 3 junction (``SKELETON_CLASSES``); homotopic to the
               mask (26-connected object, 6-connected background).
    """
    vertices: np.ndarray
    faces: np.ndarray
    thickness: np.ndarray
    rods: List[np.ndarray] = field(default_factory=list)
    rod_radii: List[np.ndarray] = field(default_factory=list)
    skeleton: Volume = None  # type: ignore[assignment]

    @property
    def area(self) -> float:
        """Total area of the triangles (world units squared)."""
        if len(self.faces) == 0:
            return 0.0
        p = self.vertices[self.faces]
        return float(0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum())

    def save_ply(self, path: str) -> None:
        """Writes a binary little-endian PLY: the mesh's vertices (x, y, z float, ``thickness`` float) and faces,
        then each rod's points as further vertices (``thickness`` twice their radius) joined by ``edge`` elements."""
        from .files import atomic_output
        rods = [np.asarray(r, np.float64).reshape(-1, 3) for r in self.rods]
        v = np.concatenate([np.asarray(self.vertices, np.float64).reshape(-1, 3), *rods]) if rods else \
            np.asarray(self.vertices, np.float64).reshape(-1, 3)
        th = np.concatenate([np.asarray(self.thickness, np.float64), *[2.0 * np.asarray(r) for r in self.rod_radii]])
        edges, at = [], len(self.vertices)
        for r in rods:
            i = np.arange(at, at + len(r), dtype=np.int32)
            edges.append(np.stack([i[:-1], i[1:]], axis=1))
            at += len(r)
        e = np.concatenate(edges) if edges else np.zeros((0, 2), np.int32)
        f = np.asarray(self.faces, np.int64).reshape(-1, 3)
        head = ("ply\nformat binary_little_endian 1.0\ncomment volrig medial surface (world units, grid frame)\n"
                f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
                f"property float thickness\nelement face {len(f)}\nproperty list uchar int vertex_indices\n"
                f"element edge {len(e)}\nproperty int vertex1\nproperty int vertex2\nend_header\n")
        verts = np.empty(len(v), dtype=[("p", "<f4", 3), ("t", "<f4")])
        verts["p"], verts["t"] = v, th
        faces = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", 3)])
        faces["n"], faces["i"] = 3, f
        with atomic_output(path, suffix=".ply") as tmp, open(tmp, "wb") as out:
            out.write(head.encode("ascii"))
            out.write(verts.tobytes())
            out.write(faces.tobytes())
            out.write(e.astype("<i4").tobytes())

    def euler_characteristic(self) -> int:
        """V - E + F over the vertices used by faces."""
        f = np.asarray(self.faces, dtype=np.int64)
        if len(f) == 0:
            return 0
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        return int(len(np.unique(f)) - len(np.unique(e, axis=0)) + len(f))


def medial_surface(mask, t: float = 5.0, progress: ProgressFn = None) -> MedialSurface:
    """Medial surface mesh of the plates of ``mask`` (a ``Volume`` or a 3-D array [z, y, x]; non-zero = object),
    its rods as polylines with radii, and its homotopic skeleton classified as surface, curve or junction.

    ``t`` (voxels of the smallest spacing) is the plane-like threshold of ``plane_like``: a lattice edge between
    two object voxels whose nearest boundary voxels lie more than t apart along the boundary crosses the medial
    surface of a plate (rods whose circumference exceeds about 2t give a thin strip there, dropped as not
    surface-like). See ``native/include/volrig/medial_surface.hpp`` for the construction.
    ``progress(fraction)`` may return False to cancel (``volrig.Cancelled``)."""
    spacing, origin = _geometry(mask)
    v, f, th, rods, radii, skel = _volrig.medial_surface(_mask_array(mask), spacing, origin, _t_world(mask, t),
                                                         progress)
    return MedialSurface(np.asarray(v), np.asarray(f), np.asarray(th), [np.asarray(r) for r in rods],
                         [np.asarray(r) for r in radii], Volume(np.asarray(skel), spacing, origin))

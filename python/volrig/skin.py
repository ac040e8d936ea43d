"""Meshes rigged through their volume: ``rig_mesh`` (``volrig.pipeline.rig_mesh``, which chains the steps)
voxelizes a mesh, skeletonizes, auto-rigs and skins it; ``skin_weights`` gives any points' weights from a rig and a
mask; ``MeshRig.pose`` and ``MeshRig.thicken`` move the vertices (linear blend skinning, as Blender's Armature
modifier does; thickness editing along bones).

Skin weights come from geodesic distances through the voxelized solid (native/include/volrig/skin.hpp): a vertex is
weighted by the bones that reach it along the inside, so a hand resting on a thigh does not pull the thigh's skin.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Union

import numpy as np

from . import _optional, _volrig
from ._volrig import VolrigError
from .mesh import ProgressFn
from .rig import Binding, Rig
from .skeleton import Skeleton, SkeletonPoints
from .tree import SkeletonTree
from .volume import Volume

#: voxels along the longest side of a mesh's bounding box when ``rig_mesh`` chooses the voxel size
MESH_VOXELS = 160
#: how far a vertex's weights blend across a joint, in limb radii, unless told (``skin_weights``, ``rig_mesh``)
SKIN_BLEND = 1.0


def _span(progress: ProgressFn, lo: float, hi: float) -> ProgressFn:
    if progress is None:
        return None
    return lambda f: progress(lo + (hi - lo) * f)


def _points(vertices) -> np.ndarray:
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise VolrigError(f"vertices must have shape (V, 3), got {v.shape}")
    return v


def skin_weights(mask: Volume, rig: Rig, vertices, influences: int = 4, blend: float = SKIN_BLEND,
                 progress: ProgressFn = None):
    """Weights of ``vertices`` (V, 3; world positions in the mask's frame) for ``rig``'s bones, by geodesic distance
    through ``mask`` (a bool Volume: the solid the vertices bound, e.g. ``voxelize``'s).

    influences: bones per vertex at most (1 to 8). blend: falloff width across joints (default 1: a limb of radius r
    blends its neighbour within about 1.5 r of the joint; larger is smoother, smaller stiffer).
    Returns a (V, B) scipy.sparse CSR matrix, float32, every row 1 to ``influences`` entries summing to 1 (without
    scipy, a ``volrig._optional.CSR`` of the same arrays).
    """
    v = _points(vertices)
    m = np.ascontiguousarray(np.asarray(mask.array) != 0, dtype=np.uint8)
    indptr, bone, weight, _ = _volrig.skin_weights(m, mask.spacing, mask.origin, rig.joints, rig.bones, rig.names,
                                                   rig.parents, v, int(influences), float(blend), progress)
    return _optional.csr_matrix(weight, bone, indptr, (len(v), len(rig.bones)), dtype=np.float32)


def _closest_on_bone(rig: Rig, b: int, points: np.ndarray) -> np.ndarray:
    """(V, 3): each point's closest point on bone b's segment."""
    return _closest_on_segments(rig.heads()[[b]], rig.tails()[[b]], points)[0]


def _closest_on_bones(rig: Rig, vertices: np.ndarray) -> np.ndarray:
    """(B, V, 3): each vertex's closest point on each bone segment."""
    return _closest_on_segments(rig.heads(), rig.tails(), vertices)


def _closest_on_segments(h: np.ndarray, t: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    d = t - h
    s = np.einsum("bvk,bk->bv", vertices[None] - h[:, None], d) / np.einsum("bk,bk->b", d, d)[:, None]
    return h[:, None] + np.clip(s, 0.0, 1.0)[..., None] * d[:, None]


@dataclass
class MeshRig:
    """A mesh rigged through its volume (``rig_mesh``).

    vertices, faces: the mesh (as given). rig: the armature (``Rig``; bones named as autorig names them).
    weights: (V, B) CSR skin weights (``skin_weights``). mask: the voxelized solid; voxel_size its edge.
    skeleton, points, tree, binding: the volume's own rig data (the same rig binds the voxelized volume, so the
    mesh and its volume can be posed alike with ``volrig.deform``).
    """
    vertices: np.ndarray
    faces: np.ndarray
    rig: Rig
    weights: object
    mask: Volume
    voxel_size: float
    skeleton: Skeleton
    points: SkeletonPoints
    tree: SkeletonTree
    binding: Binding

    def pose(self, bone_matrices, method: str = "linear") -> np.ndarray:
        """The vertices moved by (B, 4, 4) rest-to-pose matrices (posed = M @ rest), blended by the weights:
        ``pose_vertices`` (linear: Blender's Armature modifier; dual_quaternion: its Preserve Volume)."""
        return pose_vertices(self.vertices, self.weights, bone_matrices, method)

    def thicken(self, scales: Mapping[Union[str, int], float], vertices=None) -> np.ndarray:
        """Thickness editing: the vertices (default: the rest mesh) with the local radius around the given bones
        scaled, ``{bone name or index: factor}`` (1 = unchanged, 2 = twice as thick, 0.5 half). Each vertex moves
        along its direction from its closest point on the bone, by its weight for that bone, so joints blend."""
        v = _points(self.vertices if vertices is None else vertices)
        return v + thickness_offsets(self.rig, self.weights, v, scales)


def _check_matrices(weights, bone_matrices) -> np.ndarray:
    m = np.asarray(bone_matrices, dtype=np.float64)
    if m.ndim != 3 or m.shape[1:] != (4, 4) or m.shape[0] != weights.shape[1]:
        raise VolrigError(f"bone_matrices must have shape ({weights.shape[1]}, 4, 4), got {m.shape}")
    if not np.isfinite(m).all():
        raise VolrigError("bone_matrices must be finite")
    return m


def _dual_quaternions(m: np.ndarray):
    """(B, 4) rotation quaternions (w, x, y, z) and (B, 4) dual parts of rigid matrices."""
    try:
        from scipy.spatial.transform import Rotation
    except ImportError:
        xyzw = _optional.matrix_quaternions(m[:, :3, :3])
    else:
        xyzw = Rotation.from_matrix(m[:, :3, :3]).as_quat()
    q = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    t = np.concatenate([np.zeros((len(m), 1)), m[:, :3, 3]], axis=1)
    return q, 0.5 * _qmul(t, q)


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def pose_vertices(vertices, weights, bone_matrices, method: str = "linear") -> np.ndarray:
    """Skinning: ``method="linear"`` sums weight * (M_b @ v) over the bones (linear blend skinning: Blender's
    Armature modifier); ``"dual_quaternion"`` blends the bones' rigid motions as dual quaternions (the modifier's
    Preserve Volume: no collapse at bent joints). ``bone_matrices`` (B, 4, 4) rest-to-pose, rigid for dual
    quaternions."""
    v = _points(vertices)
    m = _check_matrices(weights, bone_matrices)
    if method == "linear":
        out = np.zeros_like(v)
        w = weights.tocsc()
        for b in range(m.shape[0]):
            rows = w.indices[w.indptr[b]:w.indptr[b + 1]]
            if len(rows):
                wb = w.data[w.indptr[b]:w.indptr[b + 1]].astype(np.float64)[:, None]
                out[rows] += wb * (v[rows] @ m[b, :3, :3].T + m[b, :3, 3])
        return out
    if method != "dual_quaternion":
        raise VolrigError(f"method must be 'linear' or 'dual_quaternion', got {method!r}")
    q, d = _dual_quaternions(m)
    w = weights.tocsr()
    rows = np.repeat(np.arange(len(v)), np.diff(w.indptr))
    first = w.indices[w.indptr[:-1]]  # the heaviest bone of each row (rows are stored heaviest first)
    sign = np.sign(np.einsum("ij,ij->i", q[w.indices], q[first[rows]]))
    sign[sign == 0] = 1
    ww = (w.data * sign)[:, None]
    qr = np.zeros((len(v), 4))
    qd = np.zeros((len(v), 4))
    np.add.at(qr, rows, ww * q[w.indices])
    np.add.at(qd, rows, ww * d[w.indices])
    n = np.linalg.norm(qr, axis=1, keepdims=True)
    qr, qd = qr / n, qd / n
    conj = qr * [1, -1, -1, -1]
    p = np.concatenate([np.zeros((len(v), 1)), v], axis=1)
    rotated = _qmul(_qmul(qr, p), conj)[:, 1:]
    t = 2 * _qmul(qd, conj)[:, 1:]
    return rotated + t


def _scale_array(rig: Rig, scales: Mapping[Union[str, int], float]) -> np.ndarray:
    s = np.ones(len(rig.bones))
    for key, value in scales.items():
        b = rig.index(key) if isinstance(key, str) else int(key)
        if not 0 <= b < len(s):
            raise VolrigError(f"thickness: no bone {key!r}")
        f = float(value)
        if not (np.isfinite(f) and 0 <= f <= 100):
            raise VolrigError(f"thickness: the factor for {key!r} must lie in [0, 100], got {value!r}")
        s[b] = f
    return s


def thickness_offsets(rig: Rig, weights, vertices, scales: Mapping[Union[str, int], float]) -> np.ndarray:
    """(V, 3): what ``MeshRig.thicken`` adds to each vertex: sum over the scaled bones b of
    (factor_b - 1) * w_b(v) * (v - closest point of bone b). Linear in each factor, so a shape key holding the
    offset for factor 2 reproduces any factor as key value = factor - 1."""
    v = _points(vertices)
    s = _scale_array(rig, scales)
    out = np.zeros_like(v)
    w = weights.tocsc()
    for b in np.flatnonzero(s != 1.0):
        rows = w.indices[w.indptr[b]:w.indptr[b + 1]]
        if not len(rows):
            continue
        wb = w.data[w.indptr[b]:w.indptr[b + 1]].astype(np.float64)[:, None]
        near = _closest_on_bone(rig, b, v[rows])
        out[rows] += (s[b] - 1.0) * wb * (v[rows] - near)
    return out


def point_scales(binding: Binding, rig: Rig, scales: Mapping[Union[str, int], float]) -> np.ndarray:
    """(N,) float32: each skeleton point's radius factor, its bones' factors blended by its binding weights (the
    ``radius_scale`` that goes with ``thicken_volume``)."""
    return np.asarray(binding.weights.tocsr() @ _scale_array(rig, scales), dtype=np.float32).reshape(-1)


def thicken_volume(source: Volume, points: SkeletonPoints, binding: Binding, rig: Rig,
                   scales: Mapping[Union[str, int], float], sampling: str = "trilinear", background: float = 0.0):
    """Thickness editing on a volume: returns ``(thickened source, radius_scale)`` for ``{bone: factor}``.

    The spheres take ``radius_scale`` = ``point_scales`` (their bones' factors, blended by weight); the voxels the
    scaled spheres of a scaled bone cover (at rest) take the source value from the bone's axis outwards divided by
    the factor (a radial stretch about the bone segment), so a limb twice as thick holds its own tissue stretched,
    not the background. Voxels no sphere covers any more (a thinner limb) become ``background``. Pose the result
    with ``Deformer(thickened, points, binding).frame(M, radius_scale=radius_scale)``; the same factors per frame
    animate thickness. The grid is the source's: what would grow past its border is cut (pad the source first).
    sampling: "trilinear" (scans) or "nearest" (label maps, masks).
    """
    from .deform import Deformer
    from .rig import rest_pose
    if sampling not in ("trilinear", "nearest"):
        raise VolrigError(f"sampling must be 'trilinear' or 'nearest', got {sampling!r}")
    factors = _scale_array(rig, scales)
    radius_scale = point_scales(binding, rig, scales)
    if np.all(factors == 1.0):
        return source, radius_scale
    ndimage = _optional.scipy_module("scipy.ndimage", "volrig.skin.thicken_volume (thickness editing of a volume)")
    covered = Deformer(source, points, binding).frame(rest_pose(len(rig.bones)), radius_scale=radius_scale,
                                                      values=False).bone
    label = np.zeros(source.array.shape, np.int16)  # the covering bone + 1 on the source grid (0 = uncovered)
    off = np.array(covered.origin) - np.array(source.origin)
    o = np.round(off / np.array(source.spacing)).astype(int)[::-1]  # (z, y, x)
    lo, hi = np.maximum(o, 0), np.minimum(o + covered.array.shape, label.shape)
    if (hi > lo).all():
        label[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = covered.array[
            lo[0] - o[0]:hi[0] - o[0], lo[1] - o[1]:hi[1] - o[1], lo[2] - o[2]:hi[2] - o[2]]
    src = np.asarray(source.array)
    out = np.array(src, dtype=src.dtype if sampling == "nearest" else np.float32)
    out[label == 0] = background
    spacing, origin = np.array(source.spacing), np.array(source.origin)
    for b in np.flatnonzero(factors != 1.0):
        zyx = np.argwhere(label == b + 1)
        if not len(zyx):
            continue
        q = origin + zyx[:, ::-1] * spacing
        near = _closest_on_bone(rig, b, q)
        p = (near + (q - near) / factors[b] - origin) / spacing  # (x, y, z) voxel coordinates
        values = ndimage.map_coordinates(src.astype(np.float32, copy=False) if sampling == "trilinear" else src,
                                         p[:, ::-1].T, order=1 if sampling == "trilinear" else 0, mode="constant",
                                         cval=background)
        out[tuple(zyx.T)] = values
    return source.like(out), radius_scale


def mesh_voxel_size(vertices, voxels: int = MESH_VOXELS) -> float:
    """The voxel size ``rig_mesh`` chooses: the bounding box's longest side / ``voxels``."""
    v = _points(vertices)
    if not len(v):
        raise VolrigError("the mesh has no vertices")
    side = float((v.max(0) - v.min(0)).max())
    if not side > 0:
        raise VolrigError("the mesh has no extent (all vertices at one point)")
    return side / int(voxels)

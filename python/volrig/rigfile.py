"""One file for a whole rigged skeleton: points, radii, skeleton-tree, rig, binding and the source file's path.

The file (``.vrig``) is a compressed numpy archive (no pickled objects) with a format name and version. Loading
checks every array's type and shape against the others before anything is built, so a damaged or hand-edited file
gives a ``volrig.FileFormatError`` naming the file and the problem, and a file from a newer volrig says so.
"""
from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from . import _optional
from ._volrig import FileFormatError, VolrigError
from .files import atomic_output
from .rig import Binding, Rig
from .skeleton import SkeletonPoints
from .tree import SkeletonTree

FORMAT = "volrig-rig"
#: The version this volrig writes and the newest it reads.
VERSION = 1


@dataclass
class RiggedSkeleton:
    """What ``load_rig`` returns; any of tree, rig, binding may be None when they were not saved."""
    points: SkeletonPoints
    tree: Optional[SkeletonTree] = None
    rig: Optional[Rig] = None
    binding: Optional[Binding] = None
    source: Optional[str] = None


def save_rig(path, points: SkeletonPoints, tree: Optional[SkeletonTree] = None, rig: Optional[Rig] = None,
             binding: Optional[Binding] = None, source: Optional[str] = None) -> None:
    """Writes the rigged skeleton to ``path`` atomically. ``source`` is the volume file the skeleton came from
    (stored as given; relative paths are resolved against the rig file's folder by ``load_rig``)."""
    n = len(points)
    if tree is not None and len(tree.component) != n:
        raise VolrigError(f"the tree has {len(tree.component)} points, the skeleton {n}")
    if binding is not None:
        if rig is None:
            raise VolrigError("a binding needs its rig")
        if len(binding.bone) != n or binding.weights.shape != (n, len(rig.bones)):
            raise VolrigError(f"the binding ({binding.weights.shape}) does not match {n} points and "
                             f"{len(rig.bones)} bones")
    a = dict(format=np.array(FORMAT), version=np.array(VERSION, np.int64),
             ijk=points.ijk, centers=points.centers, radii=points.radii, dt=points.dt, scores=points.scores,
             metric=np.array(points.metric), spacing=np.asarray(points.spacing, np.float64),
             origin=np.asarray(points.origin, np.float64),
             thinness=np.array(np.nan if points.thinness is None else points.thinness, np.float64),
             source=np.array(source or ""))
    if tree is not None:
        a.update(tree_edges=tree.edges, tree_weights=tree.weights, tree_bridged=tree.bridged,
                 tree_component=tree.component, tree_count=np.array(tree.component_count, np.int64),
                 tree_alpha=np.array(tree.alpha), tree_max_edge=np.array(tree.max_edge))
    if rig is not None:
        a.update(rig_joints=rig.joints, rig_bones=rig.bones, rig_names=np.array(rig.names, dtype=np.str_),
                 rig_parents=rig.parents, rig_kind=np.array(rig.kind), rig_joint_points=rig.joint_points,
                 rig_fit=np.array(rig.fit, np.float64), rig_up=np.asarray(rig.up, np.float64),
                 rig_up_confidence=np.array(rig.up_confidence, np.float64), rig_runner_up=np.array(rig.runner_up),
                 rig_runner_up_fit=np.array(rig.runner_up_fit, np.float64))
    if binding is not None:
        w = binding.weights.tocsr()
        a.update(binding_mode=np.array(binding.mode), binding_bone=binding.bone,
                 binding_unreachable=binding.unreachable, weights_data=w.data.astype(np.float32),
                 weights_indices=w.indices.astype(np.int64), weights_indptr=w.indptr.astype(np.int64))
        if binding.rigid is not None:  # one bit a voxel
            a.update(binding_rigid_shape=np.array(binding.rigid.shape, np.int64),
                     binding_rigid_bits=np.packbits(np.asarray(binding.rigid, bool).reshape(-1)))
            if binding.rigid_whole:
                a.update(binding_rigid_whole=np.array(True))
    with atomic_output(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **a)


def _budget(demand: int, file_bytes: int, max_bytes: Optional[int], bad, what: str) -> None:
    """The readers' file budget (docs/io.md): without max_bytes (or $VOLRIG_MAX_BYTES), refuse a demand of more
    than 1 GB (10**9 bytes) that is also more than 1000 times the file's bytes; with it, refuse more than
    max_bytes."""
    if max_bytes is not None:
        if demand > max_bytes:
            raise bad(f"{what} need {demand:,} bytes, more than max_bytes={max_bytes:,}")
        return
    if demand > 10 ** 9 and demand > 1000 * file_bytes and not os.environ.get("VOLRIG_MAX_BYTES"):
        raise bad(f"{what} need {demand:,} bytes from a file of {file_bytes:,} bytes: more than 1 GB and more than "
                  f"1,000 times the file, so it is refused as broken or hostile; if the file is right, allow it "
                  f"with max_bytes={demand} (Python) or VOLRIG_MAX_BYTES={demand} in the environment")


def _rigid(get, bad, file_bytes: int, max_bytes: Optional[int]) -> np.ndarray:
    """The binding's rigid tissue (bool, z, y, x) from its shape and packed bits."""
    shape = get("binding_rigid_shape", "i", 1, (3,))
    if (shape <= 0).any() or int(np.prod(shape.astype(np.float64))) > 2 ** 34:
        raise bad(f"rigid tissue of impossible shape {tuple(int(v) for v in shape)}")
    count = int(np.prod(shape))
    _budget(count, file_bytes, max_bytes, bad, f"the {' x '.join(str(int(v)) for v in shape)} rigid tissue mask")
    bits = get("binding_rigid_bits", "u", 1, ((count + 7) // 8,))
    return np.unpackbits(bits, count=count).view(bool).reshape(tuple(int(v) for v in shape))


def _open_archive(path: str, max_bytes: Optional[int], bad) -> Tuple[dict, int]:
    """The rig file's arrays by name and the file's size: a regular file, its members within the budget."""
    if "\0" in path:
        raise VolrigError(f"{path.split(chr(0))[0]}...: a file name must not contain a NUL character")
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such file")
    if not os.path.isfile(path):
        raise FileFormatError(f"{path}: not a regular file")
    file_bytes = os.path.getsize(path)
    try:
        with zipfile.ZipFile(path) as zf:  # the members' unpacked sizes, before np.load unpacks them
            _budget(sum(i.file_size for i in zf.infolist()), file_bytes, max_bytes, bad, "the archive's members")
    except zipfile.BadZipFile as e:
        raise bad(f"not a readable volrig rig file ({e})") from None
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}, file_bytes
    except (zipfile.BadZipFile, OSError, ValueError, EOFError, KeyError, zipfile.LargeZipFile) as e:
        raise bad(f"not a readable volrig rig file ({e})") from None
    except Exception as e:  # zlib errors and the like from a damaged member
        raise bad(f"damaged archive ({type(e).__name__}: {e})") from None


def _binding(a: dict, get, bad, rig, n: int, file_bytes: int, max_bytes: Optional[int]) -> Binding:
    """The binding a rig file holds (``get`` reads and checks one array, ``bad`` makes the error)."""
    if rig is None:
        raise bad("a binding without a rig")
    nb = len(rig.bones)
    bone = get("binding_bone", "i", 1, (n,))
    if n and (bone.min() < 0 or bone.max() >= nb):
        raise bad(f"binding refers to a bone outside 0..{nb - 1}")
    indptr = get("weights_indptr", "i", 1, (n + 1,))
    indices = get("weights_indices", "i", 1)
    data = get("weights_data", "f", 1, (len(indices),))
    if indptr[0] != 0 or indptr[-1] != len(indices) or (np.diff(indptr) < 0).any() or \
            (len(indices) and (indices.min() < 0 or indices.max() >= nb)):
        raise bad("binding weights are not a valid sparse matrix")
    w = _optional.csr_matrix(data.astype(np.float32), indices, indptr, (n, nb))
    mode = str(get("binding_mode", "U", 0))
    if mode not in ("rigid", "smooth"):
        raise bad(f"unknown binding mode {mode!r}")
    return Binding(bone.astype(np.int32), w, mode, get("binding_unreachable", "b", 1, (n,)), list(rig.names),
                   _rigid(get, bad, file_bytes, max_bytes) if "binding_rigid_shape" in a else None,
                   bool(get("binding_rigid_whole", "b", 0)) if "binding_rigid_whole" in a else False)


def load_rig(path, *, max_bytes: Optional[int] = None) -> RiggedSkeleton:
    """Reads a file written by ``save_rig``. Raises FileNotFoundError, or ``volrig.FileFormatError`` for anything
    that is not a complete, consistent rig file of a version this volrig reads. ``max_bytes``: the most memory the
    arrays may take once unpacked (default: the readers' file budget, docs/io.md)."""
    path = os.fspath(path)
    name = os.path.basename(path)

    def bad(what: str):
        return FileFormatError(f"{name}: {what}")

    a, file_bytes = _open_archive(path, max_bytes, bad)

    def get(key, dtype_kind, ndim, shape=None):
        if key not in a:
            raise bad(f"missing '{key}'")
        v = a[key]
        if v.dtype.kind not in dtype_kind or v.ndim != ndim:
            raise bad(f"'{key}' has type {v.dtype} and {v.ndim} dimensions")
        if shape is not None and any(s is not None and s != t for s, t in zip(shape, v.shape)):
            raise bad(f"'{key}' has shape {v.shape}, expected {tuple('?' if s is None else s for s in shape)}")
        if v.dtype.kind == "f" and not np.isfinite(v).all() and key != "thinness":
            raise bad(f"'{key}' holds non-finite values")
        return v

    if "format" not in a or str(a["format"]) != FORMAT:
        raise bad(f"not a volrig rig file (format {str(a.get('format', 'missing'))!r})")
    version = int(get("version", "iu", 0))
    if version > VERSION:
        raise bad(f"written by a newer volrig (rig format version {version}; this volrig reads up to {VERSION})")
    if version < 1:
        raise bad(f"invalid rig format version {version}")
    ijk = get("ijk", "i", 2, (None, 3))
    n = len(ijk)
    metric = str(get("metric", "U", 0))
    if metric not in ("euclidean", "chamfer345"):
        raise bad(f"unknown metric {metric!r}")
    thinness = float(get("thinness", "f", 0))
    points = SkeletonPoints(ijk.astype(np.int32), get("centers", "f", 2, (n, 3)).astype(np.float64),
                            get("radii", "f", 1, (n,)).astype(np.float32), get("dt", "f", 1, (n,)).astype(np.float32),
                            get("scores", "f", 1, (n,)).astype(np.float32), metric,
                            tuple(float(x) for x in get("spacing", "f", 1, (3,))),
                            tuple(float(x) for x in get("origin", "f", 1, (3,))),
                            None if np.isnan(thinness) else thinness)
    if (points.radii < 0).any() or (ijk < 0).any():
        raise bad("negative radii or voxel indices")
    source = str(get("source", "U", 0)) or None
    if source and not os.path.isabs(source):
        source = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(path)), source))
    tree = rig = binding = None
    if "tree_edges" in a:
        edges = get("tree_edges", "iu", 2, (None, 2))
        m = len(edges)
        if m and (edges.min() < 0 or edges.max() >= n):
            raise bad(f"tree edge refers to a point outside 0..{n - 1}")
        tree = SkeletonTree(edges.astype(np.uint32), get("tree_weights", "f", 1, (m,)).astype(np.float64),
                            get("tree_bridged", "b", 1, (m,)), get("tree_component", "iu", 1, (n,)).astype(np.uint32),
                            int(get("tree_count", "iu", 0)), float(get("tree_alpha", "f", 0)),
                            float(get("tree_max_edge", "f", 0)))
    if "rig_joints" in a:
        joints = get("rig_joints", "f", 2, (None, 3))
        bones = get("rig_bones", "iu", 2, (None, 2))
        names = [str(s) for s in get("rig_names", "U", 1, (len(bones),))]
        try:
            # what autorig found (absent from files written before it reported them)
            found = dict(fit=float(get("rig_fit", "f", 0)), up=get("rig_up", "f", 1, (3,)),
                         up_confidence=float(get("rig_up_confidence", "f", 0)),
                         runner_up=str(get("rig_runner_up", "U", 0)),
                         runner_up_fit=float(get("rig_runner_up_fit", "f", 0))) if "rig_fit" in a else {}
            rig = Rig(joints, bones, names, get("rig_parents", "i", 1, (len(bones),)), str(get("rig_kind", "U", 0)),
                      get("rig_joint_points", "i", 1, (len(joints),)), **found)
        except VolrigError as e:
            raise bad(f"inconsistent rig ({e})") from None
    if "binding_bone" in a:
        binding = _binding(a, get, bad, rig, n, file_bytes, max_bytes)
    return RiggedSkeleton(points, tree, rig, binding, source)

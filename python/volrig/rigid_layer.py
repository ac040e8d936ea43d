"""Rigid tissue as a layer of its own (issue 18): bone moves with its bone alone, soft tissue bends around it.

A binding made with ``bind(..., rigid=)`` keeps its rigid tissue (``Binding.rigid``). Deforming it then takes two
layers. The *soft layer* is the usual sphere reconstruction of a source in which every rigid voxel holds the value
of the nearest soft voxel of the body (``soft_source``): where a bent joint's blended spheres carry the ends of the
bones along with the flesh, they carry flesh. The *rigid layer* is each bone's piece of rigid tissue moved by that
bone's matrix alone, voxel for voxel (an output voxel is the piece's when its rest position, through the inverse of
the bone's matrix, is one of the piece's voxels), sampled from the real source: it is drawn over the soft layer.
Which bone carries which rigid voxel is read from the binding's own rest pose (the bone of the sphere each rigid
voxel comes from at rest), so at rest the two layers give back the source.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .volume import Volume, _source_array


def soft_source(source: Volume, body: np.ndarray, rigid: np.ndarray) -> np.ndarray:
    """The source's array with every rigid voxel given the value of the body's nearest soft voxel (fewest 26-steps
    through rigid tissue: ``_volrig.nearest_seed_fill``); rigid tissue no soft voxel touches keeps its value."""
    code = np.zeros(rigid.shape, dtype=np.uint8)
    code[body] = 1
    code[rigid] = 2
    pairs = _volrig.nearest_seed_fill(code)
    out = np.array(source.array, copy=True)
    flat = out.reshape(-1)
    flat[pairs[:, 0]] = np.asarray(source.array).reshape(-1)[pairs[:, 1]]
    return out


@dataclass
class Piece:
    """One bone's rigid tissue on the source-lattice box ``box`` = (offset x, y, z, dims x, y, z): ``bits``, one bit
    a voxel of the box (C order z, y, x; ``np.packbits(..., bitorder="little")``), 1 = the piece's."""

    bone: int
    box: Tuple[int, int, int, int, int, int]
    bits: np.ndarray

    @property
    def voxels(self) -> np.ndarray:
        """The piece as uint8 (z, y, x) over its box (unpacked)."""
        n = int(np.prod(self.box[3:]))
        return np.unpackbits(self.bits, count=n, bitorder="little").reshape(self.box[3:][::-1])

    def native(self):
        return (self.bone, self.box, self.bits)


def _covered(rest_bone: np.ndarray, rest_offset, shape) -> np.ndarray:
    """The rest frame's covered voxels (bool) on the source grid of ``shape`` (z, y, x)."""
    out = np.zeros(shape, dtype=bool)
    o = np.asarray(rest_offset, dtype=np.int64)
    lo, hi = np.maximum(o, 0), np.minimum(o + np.array(rest_bone.shape[::-1]), np.array(shape[::-1]))
    if (hi > lo).all():
        out[lo[2]:hi[2], lo[1]:hi[1], lo[0]:hi[0]] = rest_bone[lo[2] - o[2]:hi[2] - o[2], lo[1] - o[1]:hi[1] - o[1],
                                                           lo[0] - o[0]:hi[0] - o[0]] > 0
    return out


def _labels_at(index: np.ndarray, shape, rest_bone: np.ndarray, rest_offset) -> np.ndarray:
    """The rest frame's bone labels (index + 1; 0 where it covers nothing) at the source voxels ``index`` (flat)."""
    zyx = np.stack(np.unravel_index(index, shape), axis=1) - np.asarray(rest_offset, dtype=np.int64)[::-1]
    inside = ((zyx >= 0) & (zyx < np.array(rest_bone.shape))).all(axis=1)
    out = np.zeros(len(index), dtype=np.int16)
    out[inside] = rest_bone[zyx[inside, 0], zyx[inside, 1], zyx[inside, 2]]
    return out


def _whole_components(rigid: np.ndarray, index: np.ndarray, label: np.ndarray) -> np.ndarray:
    """``label`` (per rigid voxel ``index``) with every 26-connected component of ``rigid`` given its most
    frequent label (uncovered voxels, 0, not counted)."""
    comp = _volrig.label_components(np.ascontiguousarray(rigid).view(np.uint8))[0].reshape(-1)[index]
    width = int(label.max()) + 1
    counts = np.bincount(comp.astype(np.int64) * width + label, minlength=(int(comp.max()) + 1) * width)
    counts = counts.reshape(-1, width)
    counts[:, 0] = 0
    major = counts.argmax(axis=1)
    return np.where(counts.max(axis=1)[comp] > 0, major[comp], label).astype(label.dtype)


def pieces_from_rest(rigid: np.ndarray, rest_bone: np.ndarray, rest_offset=(0, 0, 0),
                     whole: bool = False) -> List[Piece]:
    """The rigid voxels grouped by the bone they come from in the rest frame (``rest_bone``: its bone labels,
    index + 1, at source-lattice ``rest_offset``); rigid voxels the rest frame leaves uncovered take the label of the
    nearest labelled rigid voxel. Memory: a few bytes per rigid voxel, one byte a voxel while some are uncovered, and kept, a bit a voxel of each
    piece's box."""
    index = np.flatnonzero(rigid)
    label = _labels_at(index, rigid.shape, rest_bone, rest_offset)
    if whole and len(index) and label.any():  # each component with its majority bone (rigid_whole)
        label = _whole_components(rigid, index, label)
    missing = label == 0
    if missing.any() and not missing.all():
        code = np.zeros(rigid.shape, dtype=np.uint8).reshape(-1)
        code[index] = np.where(missing, 2, 1)
        pairs = _volrig.nearest_seed_fill(code.reshape(rigid.shape))
        label[np.searchsorted(index, pairs[:, 0])] = label[np.searchsorted(index, pairs[:, 1])]
    keep = label > 0
    index, label = index[keep], label[keep]
    order = np.argsort(label, kind="stable")
    bones, starts = np.unique(label[order], return_index=True)
    pieces = []
    for b, first, last in zip(bones, starts, list(starts[1:]) + [len(order)]):
        zyx = np.stack(np.unravel_index(index[order[first:last]], rigid.shape), axis=1)
        lo, hi = zyx.min(axis=0), zyx.max(axis=0) + 1
        voxels = np.zeros(tuple(hi - lo), dtype=bool)
        voxels[tuple((zyx - lo).T)] = True
        pieces.append(Piece(int(b) - 1, tuple(int(v) for v in lo[::-1]) + tuple(int(v) for v in (hi - lo)[::-1]),
                            np.packbits(voxels.reshape(-1), bitorder="little")))
    return pieces


class RigidLayer:
    """The rigid tissue of one binding on one source. Once built from the binding's rest frame (``build``): the
    soft source the spheres sample and the bones' pieces drawn over each frame."""

    def __init__(self, source: Volume, rigid: np.ndarray, whole: bool = False):
        if rigid.shape != np.asarray(source.array).shape:
            raise VolrigError(f"rigid tissue of shape {rigid.shape} does not lie on the source's grid "
                             f"{np.asarray(source.array).shape}")
        self.source = source
        self.rigid = rigid
        self.whole = whole  # Binding.rigid_whole: each component moves with its majority bone
        self.soft: Optional[np.ndarray] = None
        self.pieces: Optional[List[Piece]] = None

    @property
    def memory_bytes(self) -> int:
        """Bytes held once built: the soft source and the pieces (the rigid mask is the binding's)."""
        return (0 if self.soft is None else self.soft.nbytes) + sum(p.bits.nbytes for p in self.pieces or ())

    def build(self, rest_bone: np.ndarray, rest_offset) -> None:
        """From the rest frame's bone labels (at source-lattice ``rest_offset``): the body is what it covers."""
        body = _covered(rest_bone, rest_offset, self.rigid.shape)
        body &= ~self.rigid
        self.soft = soft_source(self.source, body, self.rigid)
        del body
        self.pieces = pieces_from_rest(self.rigid, rest_bone, rest_offset, self.whole)

    def paint(self, frame: dict, matrices, sampling: str, fixed: bool) -> dict:
        """A frame (the core's dict: values, bone, offset) with the pieces drawn over it: the brute-force
        reference's rigid layer (the Deformer draws its own). ``fixed``: keep the frame's box (pieces beyond it are
        clipped), else grow it to hold the pieces and crop to what is covered."""
        src, pieces = self.source, [p.native() for p in self.pieces]
        m = np.ascontiguousarray(matrices, dtype=np.float64)
        offset, bone = np.asarray(frame["offset"]), np.asarray(frame["bone"])
        lo, hi = offset, offset + bone.shape[::-1]
        if pieces and not fixed:
            reach = np.asarray(_volrig.rigid_pieces_box(src.array.shape, src.spacing, src.origin, pieces, m, len(m)))
            lo, hi = np.minimum(lo, reach[:3]), np.maximum(hi, reach[:3] + reach[3:])
        box = tuple(int(v) for v in lo) + tuple(int(v) for v in hi - lo)
        out, o = dict(frame), offset - lo
        for key in ("values", "bone"):
            if frame[key] is not None:
                a = np.asarray(frame[key])
                out[key] = np.zeros(tuple(box[3:][::-1]), dtype=a.dtype)
                out[key][o[2]:o[2] + a.shape[0], o[1]:o[1] + a.shape[1], o[0]:o[0] + a.shape[2]] = a
        _volrig.paint_rigid_pieces(_source_array(src), src.spacing, src.origin, pieces, m, len(m), sampling, box,
                                   out["values"], out["bone"])
        if not fixed:  # cropped to the covered voxels, as the Deformer crops
            covered = out["bone"] != 0
            ranges = [np.flatnonzero(covered.any(axis=tuple(a for a in range(3) if a != k))) for k in range(3)]
            if all(len(r) for r in ranges):
                s = tuple(slice(r[0], r[-1] + 1) for r in ranges)
                out = {**out, "bone": out["bone"][s], "values": None if out["values"] is None else out["values"][s]}
                lo = lo + np.array([ranges[2][0], ranges[1][0], ranges[0][0]])
        out["offset"] = tuple(int(v) for v in lo)
        out["origin"] = tuple(np.asarray(src.origin) + lo * np.asarray(src.spacing))
        return out

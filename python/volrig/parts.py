"""The rig's parts: bone groups with their own look, and exploded views (docs/ALGORITHMS.md §12, VolEdit).

A *part* is a group of bones ("left arm", "spine", "head" from Rigify-style names; one part per bone chain for other
names). ``part_grids`` splits a labelled volume into per-part grids that a renderer can show or hide exactly:

- ``density_<part>``: the values on the part's voxels, 0 elsewhere, and ``density_outside`` the values of the
  voxels in no part (``outside=True``). The sum over the visible parts (and the outside) is the density of the
  volume whose hidden voxels are empty, however the renderer interpolates (even stochastically, one neighbour
  per lookup: a hidden part's values are in no grid that is read).
- ``mask_<part>``: 1 on the part's voxels, 0 elsewhere: the weight of the part's colour and opacity. It is non-zero
  only within one voxel of the part's voxels, so a part's colour never reaches beyond that.

``explode_matrices`` moves every part away from its parent: a pose of translations for ``volrig.Deformer``.
"""
from __future__ import annotations

import re
from typing import Dict, List, NamedTuple, Optional, Sequence

import numpy as np

from ._volrig import VolrigError
from .rig import Rig
from .volume import Volume

#: Rigify-style bone names (side suffix and numbering removed) -> the part they belong to ("{side}" is left or
#: right). Names not listed make one part per chain.
REGIONS = {
    "head": "head", "head_top": "head", "neck": "head", "jaw": "head",
    "hips": "spine", "spine": "spine", "chest": "spine", "chest2": "spine", "pelvis": "spine",
    "shoulder": "{side} arm", "upper_arm": "{side} arm", "forearm": "{side} arm", "hand": "{side} arm",
    "hand_tip": "{side} arm", "palm": "{side} arm", "thumb": "{side} arm", "f_index": "{side} arm",
    "f_middle": "{side} arm", "f_ring": "{side} arm", "f_pinky": "{side} arm",
    "thigh": "{side} leg", "shin": "{side} leg", "foot": "{side} leg", "toe": "{side} leg",
    "tail": "tail",
}
_SIDES = {"L": "left", "R": "right"}
_NAME = re.compile(r"^(?P<base>.+?)(?:\.(?P<side>[LR]))?(?:\.\d+)?$")


class Part(NamedTuple):
    """A named group of bones. ``key`` names its grids (``density_<key>``, ``mask_<key>``)."""
    name: str
    key: str
    bones: List[int]


def _region(name: str) -> Optional[str]:
    m = _NAME.match(name)
    base, side = m.group("base"), m.group("side")
    region = REGIONS.get(base)
    if region is None or ("{side}" in region) != (side is not None):
        # a sided bone of a middle region (pelvis.L: the hip of a leg) goes with its side's leg or arm
        if region == "spine" and side is not None:
            return f"{_SIDES[side]} leg"
        return None
    return region.format(side=_SIDES.get(side, ""))


def _chain_head(b: int, parents: Sequence[int], children: Dict[int, List[int]]) -> int:
    """The first bone of b's chain: up through parents that have this one child only."""
    while parents[b] >= 0 and len(children[parents[b]]) == 1:
        b = parents[b]
    return b


def bone_parts(names: Sequence[str], parents: Sequence[int]) -> List[Part]:
    """The parts of a rig: bones with Rigify-style names grouped by region (head, spine, left/right arm and leg,
    tail); every other bone with its chain (a run of bones each the only child of the one before), named after the
    chain's first bone. Parts come in the order of their first bone."""
    if len(names) != len(parents):
        raise VolrigError(f"bone_parts: {len(names)} names but {len(parents)} parents")
    children: Dict[int, List[int]] = {b: [] for b in range(len(names))}
    for b, p in enumerate(parents):
        if p >= 0:
            children[int(p)].append(b)
    groups: Dict[str, List[int]] = {}
    for b, name in enumerate(names):
        part = _region(name) or names[_chain_head(b, parents, children)]
        groups.setdefault(part, []).append(b)
    return [Part(name, part_key(name), bones) for name, bones in groups.items()]


def part_key(name: str) -> str:
    """A part's name as a grid name suffix (letters, digits, underscores)."""
    return re.sub(r"[^A-Za-z0-9]+", "_", name).strip("_") or "part"


#: The grid of the values of the voxels in no part.
OUTSIDE = "density_outside"


def cropped_grids(like: Volume, at: np.ndarray, grids: Dict[str, tuple]) -> Dict[str, Volume]:
    """Grids on ``like``'s lattice cropped to the voxels ``at`` (flat indices into ``like.array``): per name,
    ``(dtype, values)`` with ``values`` a number or one value per voxel of ``at``; 0 elsewhere. No voxel: a 1-voxel
    grid of zeros at the origin."""
    shape_all = np.asarray(like.array).shape
    zyx = np.array(np.unravel_index(at, shape_all)) if len(at) else np.zeros((3, 0), np.int64)
    lo = zyx.min(axis=1) if len(at) else np.zeros(3, np.int64)
    shape = tuple(zyx.max(axis=1) - lo + 1) if len(at) else (1, 1, 1)
    origin = tuple(o + s * i for o, s, i in zip(like.origin, like.spacing, lo[::-1]))
    local = tuple(zyx - lo[:, None])
    out = {}
    for name, (dtype, v) in grids.items():
        a = np.zeros(shape, dtype)
        a[local] = v
        out[name] = Volume(a, like.spacing, origin)
    return out


def part_grids(values: Volume, labels: Volume, parts: Sequence[Part], outside: bool = False) -> Dict[str, Volume]:
    """``density_<key>`` (float32: ``values`` on the part's voxels) and ``mask_<key>`` (uint8 0/1) per part, each
    cropped to the part's voxels (its own origin on the same lattice: ``write_vdb`` writes it where it lies), and
    with ``outside`` ``density_outside`` (``values`` on the voxels in no part, on the whole grid). ``labels``: bone
    index + 1 per voxel (0 = no bone; a Frame's ``bone``), on the grid of ``values``."""
    lab, flat_values = np.asarray(labels.array), np.asarray(values.array).reshape(-1)
    if lab.shape != values.array.shape:
        raise VolrigError(f"part_grids: labels {lab.shape} and values {values.array.shape} differ in shape")
    bone_count = 1 + max((b for p in parts for b in p.bones), default=-1)
    lut = np.zeros(max(bone_count, int(lab.max(initial=0))) + 1, dtype=np.int32)
    for k, part in enumerate(parts):
        lut[np.asarray(part.bones, dtype=np.int64) + 1] = k + 1
    labelled = np.flatnonzero(lab)  # the labelled voxels only: a fraction of the box
    part_of = lut[lab.reshape(-1)[labelled]]
    grids = {}
    for k, part in enumerate(parts):
        at = labelled[part_of == k + 1]
        grids.update(cropped_grids(values, at, {f"density_{part.key}": (np.float32, flat_values[at]),
                                                f"mask_{part.key}": (np.uint8, 1)}))
    if outside:
        density = np.array(flat_values, dtype=np.float32)
        density[labelled[part_of > 0]] = 0
        grids[OUTSIDE] = values.like(density.reshape(lab.shape))
    return grids


def explode_offsets(rig: Rig, factor: float, pose=None) -> np.ndarray:
    """(B, 3) translation of every bone in an exploded view: each bone moves away from its parent by ``factor``
    times its own length, along the direction from the parent's head to the bone's centre (the parent's direction
    for a bone continuing it, outward for a branch), plus its parent's translation (accumulated down the tree).
    With ``pose`` ((B, 4, 4) rest-to-pose matrices) the directions are those of the posed bones."""
    heads, tails = rig.heads(), rig.tails()
    if pose is not None:
        pose = np.asarray(pose, dtype=np.float64)
        heads = np.einsum("bij,bj->bi", pose[:, :3, :3], heads) + pose[:, :3, 3]
        tails = np.einsum("bij,bj->bi", pose[:, :3, :3], tails) + pose[:, :3, 3]
    offsets = np.full((len(rig), 3), np.nan)

    def offset(b: int) -> np.ndarray:
        if np.isnan(offsets[b, 0]):
            p = int(rig.parents[b])
            if p < 0:
                offsets[b] = 0.0
            else:
                away = 0.5 * (heads[b] + tails[b]) - heads[p]
                if np.linalg.norm(away) < 1e-9:
                    away = tails[p] - heads[p]
                length = np.linalg.norm(tails[b] - heads[b])
                offsets[b] = offset(p) + factor * length * away / max(np.linalg.norm(away), 1e-12)
        return offsets[b]

    for b in range(len(rig)):
        offset(b)
    return offsets


def explode_matrices(rig: Rig, factor: float, pose=None) -> np.ndarray:
    """(B, 4, 4) rest-to-pose matrices of an exploded view (``explode_offsets``): for ``volrig.Deformer`` (use
    rigid mode, so that every part moves as one piece). Without ``pose`` the rest skeleton is taken apart; with it,
    the posed one: each matrix is the pose's followed by the translation. ``factor`` 0 gives the pose itself."""
    if not np.isfinite(factor):
        raise VolrigError(f"explode factor must be finite, got {factor}")
    if pose is None:
        pose = np.broadcast_to(np.eye(4), (len(rig), 4, 4))
    pose = np.asarray(pose, dtype=np.float64)
    if pose.shape != (len(rig), 4, 4):
        raise VolrigError(f"explode: pose must be ({len(rig)}, 4, 4) for the rig's bones, got {pose.shape}")
    out = np.array(pose, copy=True)
    if factor != 0.0:
        out[:, :3, 3] += explode_offsets(rig, factor, pose)
    return out


def substitute_grid(labels: Volume, matrices, bones: Sequence[int], substitute: Volume,
                    sampling: str = "trilinear") -> Volume:
    """The values of the voxels labelled with ``bones`` taken from another volume: ``substitute`` (co-registered
    with the source the labels were deformed from: same world frame, any lattice, e.g. the full-resolution scan
    under a downsampled source, or a bone CT under a soft-tissue scan) gathered through each bone's rest-to-pose
    matrix (one gather per output voxel per bone: what rigid mode does for those voxels). The grid lies on the
    substitute's lattice and covers the labelled voxels' box; a voxel's bone is the label of the ``labels`` voxel
    nearest it; 0 elsewhere. ``labels``: bone index + 1 per voxel (a Frame's ``bone``), ``matrices`` (B, 4, 4)."""
    from . import _volrig
    lab = np.asarray(labels.array)
    if not isinstance(substitute, Volume):
        raise TypeError(f"substitute must be a volrig.Volume, got {type(substitute).__name__}")
    ids = np.asarray(bones, dtype=np.int64) + 1
    zyx = np.argwhere(np.isin(lab, ids))
    lab_sp, lab_org = np.asarray(labels.spacing, float), np.asarray(labels.origin, float)
    sub_sp, sub_org = np.asarray(substitute.spacing, float), np.asarray(substitute.origin, float)
    if not len(zyx):
        return Volume(np.zeros((1, 1, 1), np.float32), substitute.spacing, substitute.origin)
    # the labelled voxels' world box (half a voxel around their centres), on the substitute's lattice
    lo_w = lab_org + zyx.min(axis=0)[::-1] * lab_sp - lab_sp / 2
    hi_w = lab_org + zyx.max(axis=0)[::-1] * lab_sp + lab_sp / 2
    lo = np.ceil((lo_w - sub_org) / sub_sp - 1e-9).astype(np.int64)
    hi = np.floor((hi_w - sub_org) / sub_sp + 1e-9).astype(np.int64)
    dims = np.maximum(hi - lo + 1, 1)
    box = tuple(int(v) for v in lo) + tuple(int(v) for v in dims)
    # each output voxel's bone: the nearest labels voxel's
    axes = [np.clip(np.rint((sub_org[a] + (lo[a] + np.arange(dims[a])) * sub_sp[a] - lab_org[a]) / lab_sp[a]),
                    0, lab.shape[2 - a] - 1).astype(np.int64) for a in range(3)]
    near = lab[np.ix_(axes[2], axes[1], axes[0])]
    out = np.zeros(tuple(dims[::-1]), np.float32)
    src = np.ascontiguousarray(substitute.array.view(np.uint8) if substitute.array.dtype == np.bool_
                               else substitute.array)
    m = np.ascontiguousarray(matrices, dtype=np.float64)
    for b in ids:
        where = near == b
        if where.any():
            warped = _volrig.inverse_warp(src, substitute.spacing, substitute.origin, m[b - 1], sampling, box)
            out[where] = warped[where]
    return Volume(out, substitute.spacing, tuple(sub_org + lo * sub_sp))

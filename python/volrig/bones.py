"""Rigs from a scan's bones (issue 54; docs/rig.md, "Rigs from the bones").

A scan shows where its joints are, in its bones (a CT's bone by Hounsfield units, a label map's bone codes).
``bone_segments`` splits the bone tissue into rigid segments at its articulations; ``rig_to_bones`` moves a
role-named rig's limb joints (shoulders, elbows, wrists, hips, knees, ankles) to the articulations those segments
show. ``autorig(..., bone=)`` does both after fitting the outer shape. The core is native (native/src/rig/bones/).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Dict, List, Optional, Tuple

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .skeleton import _geometry, _mask_array
from .volume import Volume


@dataclass(frozen=True)
class BoneJoint:
    """One limb joint as the bones placed it.

    joint:   index into ``rig.joints``; name: "knee.L", "hip.R", ... (.L = the rig's left).
    before, after: (3,) world positions (equal when the joint was kept).
    how:     "contact" (centre of the contact between two segments), "ball" (centre of a sphere fitted to a head
             where it faces its socket), "thickest" (a head fused with its socket at the voxel size: its thickest
             bone), "section" (one segment spans the joint, or a bone fused on to the parent's end beyond a contact:
             its narrowest section, where it is split; or a wrist or ankle sought again at its mirror's length),
             "bulge" (one segment spans a knee, elbow or ankle with no narrower section: its widest bone along the
             limb, split there) or "kept".
    why:     for a kept joint, why the bones could not place it ("" otherwise).
    parent_segment, child_segment: the segments either side (labels of ``BonesFit.segments``; 0 = none).
    """
    joint: int
    name: str
    before: Tuple[float, float, float]
    after: Tuple[float, float, float]
    how: str
    why: str
    parent_segment: int
    child_segment: int

    @property
    def moved(self) -> bool:
        return self.how != "kept"

    @property
    def shift(self) -> float:
        """How far the joint moved (world units)."""
        return float(np.linalg.norm(np.subtract(self.after, self.before)))


@dataclass
class BonesFit:
    """What ``rig_to_bones`` found.

    rig:          the rig with its limb joints at the bones' articulations (names, bones and parents unchanged).
    joints:       a ``BoneJoint`` per limb joint of the rig (moved or kept).
    segments:     int32 Volume on the bone's grid: 0 = no segment, 1..n the rigid segments (after splits).
    bone_segment: rig bone name -> the segment it runs through (0 = none).
    """
    rig: "object"
    joints: List[BoneJoint]
    segments: Volume
    bone_segment: Dict[str, int]

    def moved(self) -> List[str]:
        """Names of the joints the bones moved."""
        return [j.name for j in self.joints if j.moved]


def _bone_array(bone, like_shape=None) -> np.ndarray:
    arr = _mask_array(bone)
    if like_shape is not None and arr.shape != tuple(like_shape):
        raise VolrigError(f"the bone mask has shape {arr.shape} but the mask it rigs has {tuple(like_shape)}: "
                          f"give the bone on the same grid (z, y, x)")
    if not arr.any():
        raise VolrigError("the bone mask is empty: no bone voxels to rig from (check --bone-labels / --bone-range)")
    return arr


def bare_bone_share(body, bone) -> float:
    """The share of ``body``'s surface voxels (a 6-neighbour outside it, inside the grid) that are ``bone``: about 0
    for a scan with skin, large for organs and bones without skin or the bone alone. ``autorig(bone=)`` reads the
    body plan from the bone itself at ``volrig.rig.BARE_BONE_SHARE`` or more."""
    arr = _mask_array(body)
    return float(_volrig.bare_bone_share(arr, _bone_array(bone, like_shape=arr.shape)))


def bone_body(bone) -> Tuple[Volume, float, float]:
    """The bone grown into a body whose shape the body-plan search reads when the flesh is missing: the voxels
    within a radius of the bone, the largest 26-connected component. The radius starts at twice the bone's median
    depth (at least 1.5 voxels) and grows by half, at most 5 times, until that component holds 95% of the bone
    (joint spaces and girdles apart from the spine bridged). Returns (bool Volume, radius in mm, share of the bone
    joined)."""
    arr = _bone_array(bone)
    spacing, origin = _geometry(bone)
    mask, radius, joined = _volrig.bone_body(arr, spacing, origin)
    return Volume(mask.view(bool), spacing, origin), float(radius), float(joined)


def bone_segments(bone, opening: Optional[float] = None, min_volume: Optional[float] = None) -> Tuple[Volume, np.ndarray]:
    """The bone tissue (a bool Volume or array, z, y, x) split into rigid segments: an opening of ``opening`` mm
    (default 4, or a twentieth of the skeleton's size, the cube root of its bone's volume, when smaller; at least
    one voxel) parts bones touching across a joint at the voxel size; the eroded bone's 26-connected components of
    at least ``min_volume`` mm^3 (default 1000, or 1/600 of the bone's volume when smaller: a mouse's skeleton gets
    its own proportions) are the segments, and every bone voxel joins the one it reaches first through the bone.
    Returns (int32 labels Volume, voxels per segment)."""
    arr = _bone_array(bone)
    spacing, origin = _geometry(bone)
    labels, sizes = _volrig.bone_segments(arr, spacing, origin, float(opening or 0.0), float(min_volume or 0.0))
    return Volume(labels, spacing, origin), sizes


def rig_to_bones(rig, bone, opening: Optional[float] = None, min_volume: Optional[float] = None,
                 reach: Optional[float] = None, like_shape=None) -> BonesFit:
    """``rig`` (role-named: from ``autorig``, humanoid or quadruped) with its limb joints moved to the
    articulations ``bone`` shows (a bool Volume or array on the rigged mask's grid).

    Each limb bone is matched to the segment its middle half runs through (the femur for a thigh); a joint between
    two segments goes to the centre of their contact (the midpoint of the centroids of each one's surface facing
    the other; a hinge's child side takes every segment meeting the parent beyond the joint: ulna and radius),
    a hip or shoulder to the centre of a sphere fitted to the head's surface facing its socket, a joint inside one
    segment to its narrowest section (the segment is split there). End joints (hand and foot tips) move with their
    bone's head, keeping its direction. Joints the bones cannot show keep their position (``BoneJoint.why``).
    ``reach``: how far apart (mm) two segments may be and still meet (default 20, or a quarter of the skeleton's
    size when smaller; the fitter's other windows shrink with the skeleton below the frog's the same way). On
    slices at least twice as far apart as the pixels (an anisotropic CT) the bone is first interpolated between its
    slices (shape-based) and fitted on that; the segments come back on the scan's own grid (docs/rig.md)."""
    arr = _bone_array(bone, like_shape)
    spacing, origin = _geometry(bone)
    d = _volrig.rig_to_bones(arr, spacing, origin, rig.joints, rig.bones, rig.names, rig.parents,
                             float(opening or 0.0), float(min_volume or 0.0), float(reach or 0.0))
    joints = [BoneJoint(int(m["joint"]), m["name"], tuple(m["from"]), tuple(m["to"]), m["how"], m["why"],
                        int(m["parent_segment"]), int(m["child_segment"])) for m in d["moves"]]
    jp = rig.joint_points.copy()
    for j in joints:
        if j.moved:
            jp[j.joint] = -1
    new = replace(rig, joints=d["joints"], joint_points=jp, bone_joints=joints)
    return BonesFit(new, joints, Volume(d["segments"], spacing, origin),
                    {n: int(s) for n, s in zip(rig.names, d["bone_segment"])})


def separated(segments: Volume, bone=None) -> np.ndarray:
    """A bool rigid-tissue array whose 26-connected components are the segments (for ``bind(..., rigid=)``, which
    gives each component wholly to one bone): the voxels of a segment touching a segment of a higher label are
    left out. Bone voxels in no segment (``bone`` given) are kept as they are."""
    lab = np.asarray(segments.array)
    keep = lab > 0
    pad = np.pad(lab, 1)
    core = pad[1:-1, 1:-1, 1:-1]
    n0, n1, n2 = lab.shape
    for dz in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dz == dy == dx == 0:
                    continue
                nb = pad[1 + dz:1 + dz + n0, 1 + dy:1 + dy + n1, 1 + dx:1 + dx + n2]
                keep &= ~((nb > core) & (core > 0))
    if bone is not None:
        keep |= (_mask_array(bone) != 0) & (lab == 0)
    return keep

"""Motion capture: read BVH files and drive a volrig ``Rig`` with them.

``read_bvh(path) -> Motion`` reads and validates a Biovision Hierarchy file (the native reader; any malformed file
raises ``volrig.FileFormatError`` naming the file, the line and the problem). ``Motion.forward_kinematics`` gives
per-frame world joint positions and global rotations in the file's own coordinates and units.

``animate(rig, motion)`` retargets the motion onto a rig and returns per-frame rest-to-pose bone matrices in the
rig's world coordinates (``posed_point = M[f, b] @ rest_point``):

* **Bone map**: a plain dict ``{BVH joint: rig bone}``. ``default_bone_map`` builds one from names: both
  skeletons' names are read as body roles (hips, spine, chest, neck, head; shoulder, upper arm, forearm, hand,
  pelvis, thigh, shin, foot on each side), which covers Rigify/volrig role names, CMU's BVH names (both the
  ``LeftUpLeg``/``LowerBack``/``Spine1`` release and the ``LeftHip``/``lowerback``/``Chest2`` 3ds Max release),
  Mixamo (``mixamorig:LeftArm``), ASF-style ``lfemur``/``lhumerus`` and ``l_thigh``/``thigh.L``/``Thigh_L``.
* **Axes**: BVH files are Y-up (``up_axis="y"``, the default; ``"z"`` for Z-up files); volrig worlds are Z-up. A
  Y-up file is turned by +90 degrees about X: BVH (x, y, z) -> (x, -z, y), so a BVH character facing +Z (CMU's,
  Blender's importer convention) faces -Y like volrig's phantom, its left staying on +X. The result is then turned
  about Z so the BVH's left hip -> right hip line matches the rig's (when both skeletons have mapped thighs).
* **Scale**: rig units per BVH unit = the rig's hip-to-ankle length (thigh + shin, along the chain) over the
  BVH's, averaged over the legs both map (or ``scale=``).
* **Rest-pose alignment**: each mapped rig bone is first swung from its own rest direction onto the rest
  direction of the BVH segment it stands for (the rig's T-pose or A-pose becomes the BVH's); then it turns with
  the BVH joint's world rotation from the BVH's rest (``W G W^T``, ``G`` the joint's global rotation and ``W`` the
  axis change above). Its posed direction is therefore the BVH joint's global rotation times its rest direction;
  twist comes along. Unmapped bones follow their parent rigidly. Bone lengths are kept; a child connected to its
  parent (head on the parent's tail) stays connected.
* **Root motion**: the rig's root bones carry the BVH root's motion. Vertically always: when legs are mapped, the
  whole pose is raised or lowered so that the rig's lower ankle stands as high above its rest ankle height as the
  BVH's lower ankle stands above the lowest any ankle reaches in the whole clip, times the scale (feet stay on the
  floor at contact, whatever the two skeletons' proportions); without mapped legs, the root rises and falls with
  the BVH root's scaled height change from the clip's first frame. Horizontally ``root_motion="travel"`` adds the
  scaled horizontal displacement of the BVH root from the clip's first frame; ``"in_place"`` (default) drops it.
  References are taken on the whole clip, so any frame range gives the same matrices for its frames (farms can
  split a clip).
"""
from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .files import atomic_output
from .rig import Rig

_AXES = {"X": 0, "Y": 1, "Z": 2}


@dataclass
class Motion:
    """A BVH clip.

    names:       J joint names (ROOT and JOINT entries, file order: a parent precedes its children).
    parents:     (J,) int32 parent joint, -1 for roots.
    offsets:     (J, 3) float64 OFFSETs: each joint's rest position in its parent's frame.
    channels:    J tuples of channel names ("Xposition" ... "Zrotation") in file order.
    frame_time:  seconds per frame.
    frames:      (F, C) float64 channel values, C = sum of the channel counts; angles in degrees.
    end_parents: (E,) int32 joint of each End Site; end_offsets (E, 3) their OFFSETs.
    source:      the file it was read from.
    """

    names: List[str]
    parents: np.ndarray
    offsets: np.ndarray
    channels: List[Tuple[str, ...]]
    frame_time: float
    frames: np.ndarray
    end_parents: np.ndarray
    end_offsets: np.ndarray
    source: str = ""

    @property
    def frame_count(self) -> int:
        return int(self.frames.shape[0])

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    def __len__(self) -> int:
        return self.frame_count

    def index(self, name: str) -> int:
        """Joint index of ``name``; raises KeyError naming the joints."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint named {name!r} in {self.source or 'the BVH'}; joints: "
                           f"{', '.join(self.names)}") from None

    def columns(self) -> np.ndarray:
        """(J,) first column in ``frames`` of each joint's channels."""
        counts = np.array([len(c) for c in self.channels], np.int64)
        return np.concatenate([[0], np.cumsum(counts)[:-1]]) if len(counts) else counts

    def rest_positions(self) -> Tuple[np.ndarray, np.ndarray]:
        """Joint (J, 3) and end-site (E, 3) positions at rest (every channel 0), in the file's coordinates."""
        p = np.zeros((len(self.names), 3))
        for j, par in enumerate(self.parents):
            p[j] = self.offsets[j] + (p[par] if par >= 0 else 0.0)
        return p, p[self.end_parents] + self.end_offsets if len(self.end_parents) else np.zeros((0, 3))

    def forward_kinematics(self, frames=None) -> Tuple[np.ndarray, np.ndarray]:
        """World joint positions (F, J, 3) and global rotations (F, J, 3, 3) of the given frames (default all), in
        the file's own coordinates and units.

        BVH semantics: a joint's local transform is a translation by OFFSET (plus its position channels, in the
        parent's frame) followed by its rotation channels, which multiply left to right in the order listed
        (intrinsic): ``CHANNELS 3 Zrotation Xrotation Yrotation`` is ``Rz(z) @ Rx(x) @ Ry(y)``. Then
        ``G_j = G_parent @ R_j`` and ``p_j = p_parent + G_parent @ (offset_j + t_j)``.
        """
        idx = frame_indices(self, frames)
        data = self.frames[idx]
        n, nj = len(idx), len(self.names)
        pos = np.zeros((n, nj, 3))
        rot = np.zeros((n, nj, 3, 3))
        for j, (par, chans, col) in enumerate(zip(self.parents, self.channels, self.columns())):
            local = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
            t = np.broadcast_to(self.offsets[j], (n, 3)).copy()
            for k, c in enumerate(chans):
                values = data[:, col + k]
                axis = _AXES[c[0]]
                if c.endswith("position"):
                    t[:, axis] += values
                else:
                    local = local @ axis_rotations(axis, np.radians(values))
            if par < 0:
                pos[:, j] = t
                rot[:, j] = local
            else:
                pos[:, j] = pos[:, par] + np.einsum("fij,fj->fi", rot[:, par], t)
                rot[:, j] = rot[:, par] @ local
        return pos, rot

    def end_site_positions(self, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
        """(F, E, 3) End Site positions from ``forward_kinematics``'s output."""
        if not len(self.end_parents):
            return np.zeros((positions.shape[0], 0, 3))
        return positions[:, self.end_parents] + np.einsum("feij,ej->fei", rotations[:, self.end_parents],
                                                         self.end_offsets)

    def __repr__(self) -> str:
        return (f"Motion({os.path.basename(self.source) or 'BVH'}: {len(self.names)} joints, {self.frame_count} "
                f"frames at {self.fps:.4g} fps)")


def read_bvh(path) -> Motion:
    """Read a BVH file. Raises FileNotFoundError, or ``volrig.FileFormatError`` (a ValueError) whose message starts
    with the file name and names the line and the problem (see native/include/volrig/mocap.hpp for what is
    checked)."""
    from .volume import _native_path
    path, raw = _native_path(path)
    d = _volrig.read_bvh(raw)
    return Motion(list(d["names"]), d["parents"], d["offsets"], [tuple(c) for c in d["channels"]],
                  float(d["frame_time"]), d["frames"], d["end_parents"], d["end_offsets"], path)


def axis_rotations(axis: int, angles: np.ndarray) -> np.ndarray:
    """(N, 3, 3) right-handed rotations by ``angles`` (radians) about axis 0 (X), 1 (Y) or 2 (Z)."""
    c, s = np.cos(angles), np.sin(angles)
    r = np.zeros(angles.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r[..., axis, axis] = 1.0
    r[..., i, i] = c
    r[..., j, j] = c
    r[..., i, j] = -s
    r[..., j, i] = s
    return r


def frame_indices(motion: Motion, frames) -> np.ndarray:
    """0-based frame indices from None (all), an int, a slice/range or a sequence; checked against the clip."""
    n = motion.frame_count
    if frames is None:
        return np.arange(n)
    if isinstance(frames, slice):
        return np.arange(n)[frames]
    idx = np.asarray(frames)
    if idx.dtype == np.bool_ or not np.issubdtype(idx.dtype, np.integer):
        raise TypeError(f"frames must be frame indices (integers), got {idx.dtype}")
    idx = idx.astype(np.int64).reshape(-1)
    if len(idx) and (idx.min() < 0 or idx.max() >= n):
        raise IndexError(f"frames must lie in 0..{n - 1} (the clip has {n} frames), got "
                         f"{idx.min()}..{idx.max()}")
    return idx


# ---- bone maps ----------------------------------------------------------------------------------------------

#: Body roles and the name stems that play them, most specific first; a name is used for one role only. Sided
#: roles (the second list) need a side in the name (Left/L/left_/_l/.L ...).
_CENTRE_ROLES = [
    ("hips", ["hips", "hip", "pelvis", "root"]),
    ("spine", ["lowerback", "abdomen", "spine", "spine1", "spine01", "torso"]),
    ("chest", ["chest2", "spine2", "upperchest", "chest", "spine1", "thorax", "upperback", "spine3"]),
    ("neck", ["lowerneck", "neck", "neck1", "neck01"]),
    ("head", ["head"]),
]
_SIDED_ROLES = [
    ("shoulder", ["collar", "clavicle", "shoulder"]),
    ("upper_arm", ["upperarm", "arm", "shldr", "humerus", "shoulder"]),
    ("forearm", ["forearm", "lowerarm", "elbow", "radius"]),
    ("hand", ["hand", "wrist"]),
    ("pelvis", ["hipjoint", "pelvis"]),
    ("thigh", ["upleg", "thigh", "upperleg", "femur", "hip"]),
    ("shin", ["leg", "shin", "lowerleg", "knee", "calf", "tibia"]),
    ("foot", ["foot", "ankle"]),
]
_SIDED_STEMS = {s for _, stems in _SIDED_ROLES for s in stems}
_SIDES = {"l": "L", "left": "L", "r": "R", "right": "R"}


def _stem_and_side(name: str) -> Tuple[str, Optional[str]]:
    """('upleg', 'L') for 'LeftUpLeg', 'mixamorig:LeftUpLeg', 'l_upleg', 'UpLeg.L', 'lupleg'; ('spine1', None)
    for 'Spine1'."""
    words = [w.lower() for w in re.split(r"[\s_.\-]+", name.rsplit(":", 1)[-1]) if w]
    if not words:
        return "", None
    if len(words) > 1 and words[0] in _SIDES:
        return "".join(words[1:]), _SIDES[words[0]]
    if len(words) > 1 and words[-1] in _SIDES:
        return "".join(words[:-1]), _SIDES[words[-1]]
    joined = "".join(words)
    for prefix in ("left", "right"):
        if joined.startswith(prefix) and len(joined) > len(prefix):
            return joined[len(prefix):], _SIDES[prefix]
    if joined[0] in "lr" and joined[1:] in _SIDED_STEMS:
        return joined[1:], _SIDES[joined[0]]
    return joined, None


def body_roles(names: Sequence[str], root: Optional[str] = None) -> Dict[str, str]:
    """Role -> name for a skeleton's joint or bone names: 'hips', 'spine', 'chest', 'neck', 'head' and
    'shoulder.L', 'upper_arm.L', 'forearm.L', 'hand.L', 'pelvis.L', 'thigh.L', 'shin.L', 'foot.L' (and .R).
    Roles nobody plays are left out; ``root`` (the root joint) plays hips when no name does."""
    parsed = [(n, *_stem_and_side(n)) for n in names]
    taken, roles = set(), {}

    def pick(role, stems, side):
        for stem in stems:
            for n, s, sd in parsed:
                if s == stem and sd == side and n not in taken:
                    roles[role] = n
                    taken.add(n)
                    return

    for role, stems in _CENTRE_ROLES:
        pick(role, stems, None)
    for side in ("L", "R"):
        for role, stems in _SIDED_ROLES:
            pick(f"{role}.{side}", stems, side)
    if "hips" not in roles and root is not None and root not in taken:
        roles["hips"] = root
    return roles


def default_bone_map(motion: Motion, rig) -> Dict[str, str]:
    """The automatic bone map {BVH joint: rig bone} from the body roles both skeletons' names play (see the module
    docstring). Raises ValueError when they share none (pass your own map to ``animate`` then)."""
    rig = _rig_of(rig)
    roots = [n for n, p in zip(motion.names, motion.parents) if p < 0]
    bvh_roles = body_roles(motion.names, roots[0] if roots else None)
    rig_roles = body_roles(rig.names)  # a rig's root is not taken for hips: neutral chains map nothing
    m = {bvh_roles[r]: rig_roles[r] for r in bvh_roles if r in rig_roles}
    if not m:
        raise VolrigError(f"no automatic bone map: the BVH's joints ({', '.join(motion.names[:12])}"
                         f"{', ...' if len(motion.names) > 12 else ''}) and the rig's bones "
                         f"({', '.join(rig.names[:12])}{', ...' if len(rig.names) > 12 else ''}) share no body "
                         "roles; pass bone_map={BVH joint: rig bone}")
    return m


def check_bone_map(bone_map, motion: Motion, rig) -> Dict[str, str]:
    """The map as a plain {str: str} dict, after checking every name exists and no rig bone is driven twice."""
    rig = _rig_of(rig)
    if not isinstance(bone_map, dict):
        raise TypeError(f"a bone map is a dict {{BVH joint: rig bone}}, got {type(bone_map).__name__}")
    out, driver = {}, {}
    for j, b in bone_map.items():
        if not isinstance(j, str) or not isinstance(b, str):
            raise TypeError(f"bone map entries must be names (str: str), got {j!r}: {b!r}")
        if j not in motion.names:
            raise VolrigError(f"bone map: unknown BVH joint {j!r}; the BVH's joints: {', '.join(motion.names)}")
        if b not in rig.names:
            raise VolrigError(f"bone map: unknown rig bone {b!r} (for BVH joint {j!r}); the rig's bones: "
                             f"{', '.join(rig.names)}")
        if b in driver:
            raise VolrigError(f"bone map: rig bone {b!r} is mapped from both {driver[b]!r} and {j!r}")
        driver[b] = j
        out[j] = b
    if not out:
        raise VolrigError("bone map is empty: nothing would move")
    return out


def save_bone_map(path, bone_map: Dict[str, str]) -> None:
    """Writes a bone map as a JSON object {BVH joint: rig bone}, atomically."""
    if not isinstance(bone_map, dict) or not all(isinstance(k, str) and isinstance(v, str)
                                                 for k, v in bone_map.items()):
        raise TypeError("a bone map is a dict {BVH joint: rig bone} of names")
    with atomic_output(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(bone_map, f, indent=2, sort_keys=True)
            f.write("\n")


def load_bone_map(path) -> Dict[str, str]:
    """Reads a JSON bone map {BVH joint: rig bone}; ValueError naming the file when it is not one."""
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as f:
            m = json.load(f)
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise VolrigError(f"{path}: not a JSON bone map ({e})") from None
    if not isinstance(m, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in m.items()):
        raise VolrigError(f"{path}: a bone map is a JSON object {{\"BVH joint\": \"rig bone\", ...}} of names")
    return m


# ---- retargeting --------------------------------------------------------------------------------------------

def _rig_of(rig) -> Rig:
    """A Rig from a Rig or anything holding one (load_rig's RiggedSkeleton)."""
    r = getattr(rig, "rig", rig)
    if not isinstance(r, Rig):
        raise TypeError(f"expected a volrig.Rig (or a loaded rig file holding one), got {type(rig).__name__}")
    return r


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector a onto unit vector b (a half turn about an axis normal to a when
    they are opposite)."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -1.0 + 1e-12:
        n = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        n /= np.linalg.norm(n)
        return 2.0 * np.outer(n, n) - np.eye(3)
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def _unit(v: np.ndarray) -> Optional[np.ndarray]:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else None


def _up_axis_matrix(up_axis: str) -> np.ndarray:
    """BVH coordinates -> Z-up coordinates."""
    if up_axis == "y":
        return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # +90 degrees about X
    if up_axis == "z":
        return np.eye(3)
    raise VolrigError(f"up_axis must be 'y' (BVH's usual) or 'z', got {up_axis!r}")


def _bone_order(rig: Rig) -> List[int]:
    """Bones with every parent before its children."""
    order, placed = [], np.zeros(len(rig.bones), bool)
    while len(order) < len(rig.bones):
        before = len(order)
        for b, p in enumerate(rig.parents):
            if not placed[b] and (p < 0 or placed[p]):
                order.append(b)
                placed[b] = True
        if len(order) == before:
            raise VolrigError("the rig's bone parents form a cycle")
    return order


def _subtree_sizes(motion: Motion) -> np.ndarray:
    """Joints plus end sites below and including each joint."""
    size = np.ones(len(motion.names), np.int64)
    np.add.at(size, motion.end_parents, 1)
    for j in range(len(motion.names) - 1, -1, -1):
        if motion.parents[j] >= 0:
            size[motion.parents[j]] += size[j]
    return size


def _is_below(motion: Motion, j: int, ancestor: int) -> bool:
    while j >= 0:
        if j == ancestor:
            return True
        j = int(motion.parents[j])
    return False


def _segment_end(motion: Motion, rest: np.ndarray, rest_ends: np.ndarray, j: int, start: int,
                 eps: float) -> Optional[np.ndarray]:
    """Rest position of the far end of the BVH segment starting at joint j: joint ``start`` when it lies away from
    j, else the first point away from j down the branch with the most joints."""
    size = _subtree_sizes(motion)
    k = start
    while True:
        if np.linalg.norm(rest[k] - rest[j]) > eps:
            return rest[k]
        children = np.flatnonzero(motion.parents == k)
        ends = np.flatnonzero(motion.end_parents == k)
        if not len(children):
            far = [rest_ends[e] for e in ends if np.linalg.norm(rest_ends[e] - rest[j]) > eps]
            return far[0] if far else None
        k = int(children[np.argmax(size[children])])


@dataclass
class _Leg:
    """A leg both skeletons map: BVH thigh and foot joints, the rig bones they drive, hip-to-ankle lengths."""
    bvh_thigh: int
    bvh_foot: int
    rig_thigh: int
    rig_foot: int
    bvh_length: float
    rig_length: float


def _legs(motion: Motion, rig: Rig, bone_map: Dict[str, str]) -> List[_Leg]:
    """The legs (left first) whose thigh and foot are mapped, found through either skeleton's names. Lengths run
    along the chain: the BVH's offsets from the thigh joint down to the foot joint, the rig's bones from the thigh
    bone's head to the foot bone's head."""
    roots = [n for n, p in zip(motion.names, motion.parents) if p < 0]
    bvh_roles = body_roles(motion.names, roots[0])
    rig_roles = body_roles(rig.names)
    to_bvh = {b: j for j, b in bone_map.items()}
    legs = []
    for side in ("L", "R"):
        pairs = []
        if f"thigh.{side}" in bvh_roles and f"foot.{side}" in bvh_roles:
            pairs.append((bvh_roles[f"thigh.{side}"], bvh_roles[f"foot.{side}"]))
        if f"thigh.{side}" in rig_roles and f"foot.{side}" in rig_roles:
            pairs.append((to_bvh.get(rig_roles[f"thigh.{side}"]), to_bvh.get(rig_roles[f"foot.{side}"])))
        for thigh, foot in pairs:
            if thigh not in bone_map or foot not in bone_map:
                continue
            t, f = motion.names.index(thigh), motion.names.index(foot)
            bt, bf = rig.names.index(bone_map[thigh]), rig.names.index(bone_map[foot])
            if f == t or not _is_below(motion, f, t):
                continue
            length, k = 0.0, f
            while k != t:
                length += float(np.linalg.norm(motion.offsets[k]))
                k = int(motion.parents[k])
            rig_length, b = 0.0, int(rig.parents[bf])
            while b >= 0:
                h, tl = rig.joints[rig.bones[b]]
                rig_length += float(np.linalg.norm(tl - h))
                if b == bt:
                    break
                b = int(rig.parents[b])
            if b != bt or length <= 0 or rig_length <= 0:
                continue
            legs.append(_Leg(t, f, bt, bf, length, rig_length))
            break
    return legs


def _leg_scale(legs, scale: Optional[float]) -> float:
    """Rig units per BVH unit: ``scale`` as given, else the ratio of the mapped legs' lengths."""
    if scale is None:
        if not legs:
            raise VolrigError("cannot scale by leg length: no leg (thigh and foot) is mapped on both skeletons; "
                              "map the legs or pass scale=")
        scale = float(np.mean([g.rig_length for g in legs]) / np.mean([g.bvh_length for g in legs]))
    scale = float(scale)
    if not np.isfinite(scale) or scale <= 0:
        raise VolrigError(f"scale must be a positive number, got {scale}")
    return scale


def _rest_alignment(rig, motion, to_rig, b: int, ends, rest_pose, w, eps: float) -> np.ndarray:
    """The rotation turning rig bone ``b``'s rest direction onto the rest direction (in rig world, through ``w``)
    of the BVH segment it stands for: from its joint to where the mapped child continuing it (the straightest)
    starts; identity when either direction is undefined."""
    heads, tails = ends
    rest, rest_ends = rest_pose
    j = to_rig[b]
    r0 = _unit(tails[b] - heads[b])
    start = j
    straightest = -2.0
    for c in np.flatnonzero(rig.parents == b):
        dc = _unit(tails[c] - heads[c])
        if c in to_rig and rig.bones[c, 0] == rig.bones[b, 1] and dc is not None and r0 is not None \
                and _is_below(motion, to_rig[c], j) and float(dc @ r0) > straightest:
            straightest, start = float(dc @ r0), to_rig[c]
    end = _segment_end(motion, rest, rest_ends, j, start, eps)
    d0 = None if end is None else _unit(w @ (end - rest[j]))
    if r0 is not None and d0 is not None:
        return _swing(r0, d0)
    return np.eye(3)


def animate(rig, motion, frames=None, bone_map: Optional[Dict[str, str]] = None, root_motion: str = "in_place",
            up_axis: str = "y", scale: Optional[float] = None) -> np.ndarray:
    """Per-frame rest-to-pose bone matrices driving ``rig`` with a BVH clip.

    rig:         a ``volrig.Rig`` (or ``load_rig``'s result).
    motion:      a ``Motion`` or a BVH path.
    frames:      0-based BVH frame indices (None = all; an int, a slice/range or a sequence).
    bone_map:    {BVH joint: rig bone}; default ``default_bone_map(motion, rig)``.
    root_motion: "in_place" (horizontal root translation removed) or "travel" (scaled).
    up_axis:     the BVH's up axis, "y" (usual) or "z".
    scale:       rig units per BVH unit; default the ratio of the two skeletons' leg lengths.

    Returns (F, B, 4, 4) float64 matrices in the rig's world coordinates: ``posed = M[f, b] @ rest`` for points
    (homogeneous) of bone b; each is a rotation plus a translation. See the module docstring for the method.
    """
    rig = _rig_of(rig)
    if not isinstance(motion, Motion):
        motion = read_bvh(motion)
    if root_motion not in ("in_place", "travel"):
        raise VolrigError(f"root_motion must be 'in_place' or 'travel', got {root_motion!r}")
    axes = _up_axis_matrix(up_axis)
    bone_map = check_bone_map(default_bone_map(motion, rig) if bone_map is None else bone_map, motion, rig)
    idx = frame_indices(motion, frames)

    legs = _legs(motion, rig, bone_map)
    scale = _leg_scale(legs, scale)

    rest, rest_ends = motion.rest_positions()
    # Heading: turn about the up axis so the BVH's hip line (left thigh joint to right) runs along the rig's.
    heading = np.eye(3)
    if len(legs) == 2:
        a = _unit((axes @ (rest[legs[0].bvh_thigh] - rest[legs[1].bvh_thigh])) * [1, 1, 0])
        b = _unit((rig.joints[rig.bones[legs[0].rig_thigh, 0]] - rig.joints[rig.bones[legs[1].rig_thigh, 0]])
                  * [1, 1, 0])
        if a is not None and b is not None:
            heading = _swing(a, b)
    w = heading @ axes  # BVH directions -> rig world directions

    pos_all, rot_all = motion.forward_kinematics()
    root = int(np.flatnonzero(motion.parents < 0)[0])
    up = 2 if up_axis == "z" else 1
    # Horizontal root motion from the clip's first frame (whole-clip reference: any frame range agrees).
    shift = scale * (w @ (pos_all[idx, root] - pos_all[0, root]).T).T
    if root_motion == "in_place":
        shift[:, :2] = 0.0
    # Vertical: set below from the feet when legs are mapped, else the root's scaled rise from frame 0.
    shift[:, 2] = 0.0 if legs else scale * (pos_all[idx, root, up] - pos_all[0, root, up])

    n, nb = len(idx), len(rig.bones)
    rot = rot_all[idx]
    heads, tails = rig.heads(), rig.tails()
    eps = 1e-9 * max(1.0, float(np.abs(rest).max()))
    to_rig = {rig.index(b): motion.index(j) for j, b in bone_map.items()}

    delta = np.zeros((n, nb, 3, 3))
    posed_head = np.zeros((n, nb, 3))
    posed_tail = np.zeros((n, nb, 3))
    out = np.zeros((n, nb, 4, 4))
    out[:, :, 3, 3] = 1.0
    for b in _bone_order(rig):
        p = int(rig.parents[b])
        if b in to_rig:
            j = to_rig[b]
            align = _rest_alignment(rig, motion, to_rig, b, (heads, tails), (rest, rest_ends), w, eps)
            delta[:, b] = np.einsum("ij,fjk,lk->fil", w, rot[:, j], w) @ align  # W G W^T, then the alignment
        elif p >= 0:
            delta[:, b] = delta[:, p]
        else:
            delta[:, b] = np.eye(3)
        if p < 0:
            posed_head[:, b] = heads[b] + shift
        elif rig.bones[b, 0] == rig.bones[p, 1]:
            posed_head[:, b] = posed_tail[:, p]
        else:
            posed_head[:, b] = posed_head[:, p] + delta[:, p] @ (heads[b] - heads[p])
        posed_tail[:, b] = posed_head[:, b] + delta[:, b] @ (tails[b] - heads[b])
        out[:, b, :3, :3] = delta[:, b]
        out[:, b, :3, 3] = posed_head[:, b] - delta[:, b] @ heads[b]
    if legs:
        # Feet on the floor: the rig's lower ankle stands as high above its rest ankle height as the BVH's lower
        # ankle stands above the lowest any ankle goes in the whole clip, times the scale.
        ankle_floor = min(float(pos_all[:, g.bvh_foot, up].min()) for g in legs)
        target = np.min([heads[g.rig_foot, 2] + scale * (pos_all[idx, g.bvh_foot, up] - ankle_floor)
                         for g in legs], axis=0)
        actual = np.min([posed_head[:, g.rig_foot, 2] for g in legs], axis=0)
        out[:, :, 2, 3] += (target - actual)[:, None]
    return out

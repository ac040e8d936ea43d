"""The shared test subjects for automatic rigging, as masks with what is known about them.

Every loader returns a ``Subject``: the mask ``Volume`` to skeletonize and rig, the kind of rig expected
("humanoid" or "quadruped"; "chains" for shapes with no body plan), the up vector and head direction in the
mask's world frame, and reference joints (world positions, named) where there are any:

- ``phantom`` (scale): ``volrig.phantom.humanoid``; its true joints.
- ``vhm4``, ``vhm2``, ``vhm1``: the Visible Human Male (AustinMan labels) at 4, 2 and 1 mm; the body is every
  labelled voxel (InternalAir, the airways, included so the body is solid); its shoulders, elbows,
  wrists, hips, knees and ankles derived from the bone labels by ``visible_human_joints``.
- ``capsules_<pose>`` (scale): a humanoid of capsules generated here (``capsule_subject``) in a pose autorig was
  not developed on (``CAPSULE_POSES``: knees apart, feet wide, a stride, a T-pose, arms up...); its true joints.
  ``capsule_quadruped_subject(tail, scale)``: a dog of capsules with a tail of any length (not in ``SUBJECTS``).
  ``bones_only_quadruped(scale, tail)``: a small four-legged animal's bone and organ labels, no skin, its tail
  ``tail`` vertebrae long (14: longer than its trunk, as a mouse's), and each leg's long bones.
- ``arm``, ``hand``: libigl's meshes with their TGF skeletons (``joints`` named "j0", "j1", ...; ``bones`` the
  TGF edges), voxelized; ``knight``, ``cow``, ``lion``, ``horse``, ``camel``: meshes without reference joints.

Data come from ``$VOLRIG_DATA`` or ``../shared/data`` beside the repository; a missing file raises
FileNotFoundError naming it. Meshes are voxelized with about ``MESH_VOXELS`` voxels along their longest side.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, Optional

import numpy as np

from volrig._optional import LazyModule
from volrig.mesh import read_mesh, read_tgf, voxelize
from volrig.volume import Volume, load

from . import data_root

ndi = LazyModule("scipy.ndimage", "volrig_support.subjects (the real test subjects)")

#: voxels along a mesh's longest bounding-box side
MESH_VOXELS = 160
#: AustinMan tissue codes of bone: 84 BoneCortical, 92 BoneMarrow
BONE_LABELS = (84, 92)
#: the rig joint each reference joint name corresponds to: the head of this Rigify bone
RIGIFY_JOINT = {"shoulder": "upper_arm", "elbow": "forearm", "wrist": "hand", "hip": "thigh", "knee": "shin",
                "ankle": "foot"}


@dataclass
class Subject:
    """A shape to rig and what is known about it (world frame of ``mask``).

    name:    subject name ("phantom", "vhm2", "cow", ...).
    mask:    bool Volume [z, y, x].
    kind:    the rig kind expected from ``autorig``.
    up:      unit vector (x, y, z): the character's up.
    head:    unit vector toward the head end (quadrupeds: along the body; humanoids: same as up).
    joints:  reference joints, name -> world (x, y, z) (empty when none).
    bones:   (E, 2) joint-index edges of a TGF reference skeleton (joint i is named f"j{i}"), else None.
    source:  the file (or generator) it came from.
    """
    name: str
    mask: Volume
    kind: str
    up: np.ndarray
    head: np.ndarray
    joints: Dict[str, np.ndarray] = field(default_factory=dict)
    bones: Optional[np.ndarray] = None
    source: str = ""


def data_dir() -> Path:
    """Where the shared data live: $VOLRIG_DATA, else ../shared/data beside the repository (``data_root``)."""
    return data_root()


def _data(relative: str) -> Path:
    p = data_dir() / relative
    if not p.exists():
        raise FileNotFoundError(f"shared data file not found: {p} (set $VOLRIG_DATA or place ../shared/data)")
    return p


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


# ---- meshes ----------------------------------------------------------------------------------------------------

#: mesh subjects: file, TGF, expected kind, up and head direction in the file's frame. Up and head were read off
#: silhouettes of the voxelized meshes rendered along the three axes (benchmarks/autorig_eval.py --pictures DIR
#: draws them with the up and head arrows).
MESHES = {
    # arm: lies along x, shoulder (thick end) at -x, hand at +x (silhouette along z); no body plan
    "arm": ("meshes/arm.obj", "meshes/arm.tgf", "chains", (1, 0, 0), (1, 0, 0)),
    # hand: palm in the x-y plane, fingers toward +y (silhouette along z)
    "hand": ("meshes/hand.mesh", "meshes/hand.tgf", "hand", (0, 1, 0), (0, 1, 0)),
    # knight: standing along +y, head at +y, arms out along x (silhouette along z)
    "knight": ("meshes/decimated-knight.off", None, "humanoid", (0, 1, 0), (0, 1, 0)),
    # cow: legs toward -y, head at +x (silhouette along z)
    "cow": ("meshes/cow.off", None, "quadruped", (0, 1, 0), (1, 0, 0)),
    # lion: only a HEAD (a bust open at the neck; vertex scatter in three views): ears +y, face toward -z. Not a
    # quadruped, whatever issue 16 says: expected "chains"
    "lion": ("meshes/lion.off", None, "chains", (0, 1, 0), (0, 0, -1)),
    # horse: legs toward -y, head at -x (silhouette along z)
    "horse": ("meshes/horse_quad.obj", None, "quadruped", (0, 1, 0), (-1, 0, 0)),
    # camel: legs toward -y, neck and head at +z (silhouette along x)
    "camel": ("meshes/camel_b.obj", None, "quadruped", (0, 1, 0), (0, 0, 1)),
}


def _weld(v, f):
    """The mesh with vertices at identical positions merged (faces left degenerate by it dropped)."""
    v, inverse = np.unique(np.asarray(v), axis=0, return_inverse=True)
    f = inverse.reshape(-1)[np.asarray(f)]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    return v, f[keep]


def _close_holes(v, f):
    """Caps every boundary loop of a triangle mesh with a fan around the loop's centroid (the lion statue is open
    at its base: a hole far wider than voxelize's hole closing). Corners at the same place are welded first: a mesh
    cut open along a seam (camel_b, for flattening) has a slit there, not a hole."""
    v, f = _weld(v, f)
    directed = {(int(a), int(b)) for a, b in np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])}
    nxt = {b: a for a, b in directed if (b, a) not in directed}  # boundary edges, reversed: walks each loop
    v, faces = [v], [f]
    count = len(v[0])
    while nxt:
        start = next(iter(nxt))
        loop = [start]
        while nxt.get(loop[-1], start) != start and len(loop) <= len(nxt):
            loop.append(nxt[loop[-1]])
        for k in loop:
            nxt.pop(k, None)
        v.append(v[0][loop].mean(axis=0, keepdims=True))
        faces.append(np.array([[loop[i], loop[(i + 1) % len(loop)], count] for i in range(len(loop))]))
        count += 1
    return np.concatenate(v), np.concatenate(faces).astype(np.int64)


def mesh_subject(name: str, voxels: int = MESH_VOXELS) -> Subject:
    """A mesh subject voxelized with ``voxels`` voxels along its longest side."""
    if name not in MESHES:
        raise KeyError(f"no mesh subject {name!r} (known: {', '.join(MESHES)})")
    rel, tgf, kind, up, head = MESHES[name]
    path = _data(rel)
    v, f = _close_holes(*read_mesh(str(path)))
    size = float((v.max(0) - v.min(0)).max()) / voxels
    mask = voxelize(v, f, voxel_size=size)
    joints, bones = {}, None
    if tgf:
        j, bones = read_tgf(_data(tgf))
        joints = {f"j{i}": p for i, p in enumerate(j)}
    return Subject(name, mask, kind, _unit(up), _unit(head), joints, bones, str(path))


# ---- the phantom and the Visible Human ---------------------------------------------------------------------------

def phantom_subject(scale: float = 0.5) -> Subject:
    """The humanoid phantom at ``scale``; reference joints are its true joints."""
    from volrig import phantom
    from volrig.segment import segment
    ph = phantom.humanoid(scale)
    return Subject(f"phantom{scale:g}", segment(ph.volume), "humanoid", _unit((0, 0, 1)), _unit((0, 0, 1)),
                   dict(ph.joints), None, f"volrig.phantom.humanoid({scale:g})")


def visible_human_labels(mm: int) -> Volume:
    """The AustinMan tissue labels at 4, 2 or 1 mm (+x the body's left, +y posterior, +z up)."""
    if mm not in (1, 2, 4):
        raise ValueError(f"the Visible Human comes at 1, 2 or 4 mm, not {mm}")
    return load(str(_data(f"visible-human/austinman_{mm}mm_labels.nii.gz")))


#: The bone a limb joint moves with (its head's bone).
_JOINT_BONE = {"shoulder": "upper_arm", "elbow": "forearm", "wrist": "hand", "hip": "thigh", "knee": "shin",
               "ankle": "foot"}


def posed_visible_human(labels: Volume, rigged, arms: float, legs: float, reference: Dict[str, np.ndarray]):
    """The Visible Human's labels posed by its own rig (``rigged``: ``pipeline.rig_skeleton`` with the rigid bone
    layer; nearest sampling, so the frame is a label map again): both arms raised ``arms`` degrees from hanging
    (90: a T-pose) and both legs ``legs`` degrees apart, sideways. Returns (posed int16 labels Volume, the
    ``reference`` limb joints moved by their bones' matrices)."""
    from volrig.deform import Deformer
    rig = rigged.rig
    pose = rig.pose({"upper_arm.L": ([0, 1, 0], -arms), "upper_arm.R": ([0, 1, 0], arms),
                     "thigh.L": ([0, 1, 0], -legs), "thigh.R": ([0, 1, 0], legs)})
    frame = Deformer(labels, rigged.points, rigged.binding).frame(pose, mode="dual_quaternion", sampling="nearest")
    moved = {}
    for name, at in reference.items():
        m = pose[rig.index(_JOINT_BONE[name.split(".")[0]] + name[-2:])]
        moved[name] = m[:3, :3] @ at + m[:3, 3]
    out = frame.values
    return Volume(np.rint(np.asarray(out.array)).astype(np.int16), out.spacing, out.origin), moved


def visible_human_subject(mm: int = 4, joints: bool = True) -> Subject:
    """The Visible Human body mask at ``mm`` resolution, with its bone-derived joints (``joints=False`` skips
    them: about 30 s at 1 mm)."""
    labels = visible_human_labels(mm)
    ref = visible_human_joints(labels) if joints else {}
    body = labels.array != 0
    return Subject(f"vhm{mm}", Volume(body, labels.spacing, labels.origin), "humanoid", _unit((0, 0, 1)),
                   _unit((0, 0, 1)), ref, None, labels.path or "")


# ---- a humanoid of capsules in poses -----------------------------------------------------------------------------

#: pose -> (elbow, wrist) and (knee, ankle) of the left side (x > 0; the right mirrored), in units of a figure
#: 180 tall (z up, facing -y); poses without an entry keep the arms down and the legs straight.
CAPSULE_POSES = {
    "down": ({}, {}),
    "knees_apart": ({}, {"knee": (15, 0, 50), "ankle": (22, 0, 10)}),
    "wide": ({}, {"knee": (22, 0, 50), "ankle": (35, 0, 10)}),
    "stride": ({}, {"knee": (9, -16, 52), "ankle": (9, 4, 12)}),
    "tpose": ({"elbow": (46, 0, 145), "wrist": (72, 0, 145)}, {}),
    "armsup": ({"elbow": (26, 0, 172), "wrist": (32, 0, 198)}, {}),
}
#: the capsules' radii (figure units): limbs as thick as these, at scale 1
CAPSULE_RADII = {"trunk": 15, "neck": 6, "collar": 8, "upper_arm": 5.5, "forearm": 4.5, "hand": 4, "pelvis": 10,
                 "thigh": 7.5, "shin": 5.5, "foot": 4, "head": 12}


def _capsule_joints(pose: str) -> Dict[str, np.ndarray]:
    arms, legs = CAPSULE_POSES[pose]
    j = {"pelvis": (0, 0, 95), "chest": (0, 0, 135), "neck": (0, 0, 152), "head": (0, 0, 168)}
    left = {"shoulder": (19, 0, 145), "hip": (9, 0, 90), "elbow": (22, 2, 117), "wrist": (24, -2, 91),
            "knee": (9, 0, 50), "ankle": (9, 0, 10), **arms, **legs}
    for side, s in (("L", 1), ("R", -1)):
        for name, (x, y, z) in left.items():
            j[f"{name}.{side}"] = (s * x, s * y if name in ("knee", "ankle") else y, z)
        j[f"toe.{side}"] = np.add(j[f"ankle.{side}"], (0, -14, -5))
        j[f"hand.{side}"] = np.add(j[f"wrist.{side}"], 0.35 * np.subtract(j[f"wrist.{side}"], j[f"elbow.{side}"]))
    return {k: np.asarray(v, dtype=np.float64) for k, v in j.items()}


def capsule_subject(pose: str = "down", scale: float = 1.0) -> Subject:
    """A humanoid of capsules (trunk, limbs, feet, hands) and a ball for the head, in ``pose`` (``CAPSULE_POSES``),
    ``scale`` voxels per unit of a figure 180 units tall (z up, facing -y, its left at +x); reference joints: the
    capsules' ends (shoulders, elbows, wrists, hips, knees, ankles). A stride puts the left knee forward."""
    if pose not in CAPSULE_POSES:
        raise KeyError(f"no capsule pose {pose!r} (known: {', '.join(CAPSULE_POSES)})")
    if not scale > 0:
        raise ValueError(f"scale must be positive, got {scale}")
    j, r = _capsule_joints(pose), CAPSULE_RADII
    caps = [("pelvis", "chest", r["trunk"]), ("chest", "neck", r["neck"])]
    for side in "LR":
        def limb(a, b):
            return (a if a in j else f"{a}.{side}", f"{b}.{side}")
        caps += [(*limb("chest", "shoulder"), r["collar"]), (*limb("shoulder", "elbow"), r["upper_arm"]),
                 (*limb("elbow", "wrist"), r["forearm"]), (*limb("wrist", "hand"), r["hand"]),
                 (*limb("pelvis", "hip"), r["pelvis"]), (*limb("hip", "knee"), r["thigh"]),
                 (*limb("knee", "ankle"), r["shin"]), (*limb("ankle", "toe"), r["foot"])]
    mask, shift = _capsule_mask([(j[a], j[b], rad) for a, b, rad in caps], [(j["head"], r["head"])], scale,
                                pad=2 * r["head"] - 2)
    joints = {n: (j[n] + shift) * scale for n in LIMB_JOINTS}
    return Subject(f"capsules_{pose}{scale:g}", Volume(mask), "humanoid", _unit((0, 0, 1)), _unit((0, 0, 1)),
                   joints, None, f"volrig_support.subjects.capsule_subject({pose!r}, {scale:g})")


def _capsule_mask(capsules, balls, scale: float, pad: float):
    """The union of capsules (a, b, radius) and balls (centre, radius), in figure units, drawn ``scale`` voxels per
    unit with ``pad`` units around; returns the bool array [z, y, x] and the shift added to figure positions."""
    ends = np.array([p for a, b, _ in capsules for p in (a, b)] + [c for c, _ in balls], dtype=np.float64)
    shift = pad - ends.min(0)
    shape = tuple(int(n) for n in np.ceil((ends.max(0) + shift + pad) * scale)[::-1])
    z, y, x = (np.arange(n, dtype=np.float32) for n in shape)
    z, y, x = z[:, None, None], y[None, :, None], x[None, None, :]
    mask = np.zeros(shape, bool)
    for a, b, rad in capsules:
        pa, pb = (np.asarray(a, np.float64) + shift) * scale, (np.asarray(b, np.float64) + shift) * scale
        d = pb - pa
        t = np.clip(((x - pa[0]) * d[0] + (y - pa[1]) * d[1] + (z - pa[2]) * d[2]) / float(d @ d), 0, 1)
        mask |= (x - pa[0] - t * d[0]) ** 2 + (y - pa[1] - t * d[1]) ** 2 + (z - pa[2] - t * d[2]) ** 2 \
            <= (rad * scale) ** 2
    for c, rad in balls:
        pc = (np.asarray(c, np.float64) + shift) * scale
        mask |= (x - pc[0]) ** 2 + (y - pc[1]) ** 2 + (z - pc[2]) ** 2 <= (rad * scale) ** 2
    return mask, shift


def capsule_quadruped_subject(tail: float = 40.0, scale: float = 1.0, front: float = 1.0) -> Subject:
    """A four-legged animal of capsules (a dog: trunk 58 units long, legs 40, a neck and a ball head at -y, z up)
    with a tail ``tail`` units long from the rump (0 for none), ``scale`` voxels per unit, front legs ``front``
    times as thick as the dog's (a bull's may be its thickest); reference joints: the legs' (shoulder/elbow/wrist
    in front, hip/knee/ankle behind)."""
    if not scale > 0 or not tail >= 0:
        raise ValueError(f"scale must be positive and tail not negative, got {scale}, {tail}")
    j = {"hips": (0, 30, 45), "chest": (0, -28, 48), "head": (0, -55, 70)}
    for side, s in (("L", 1), ("R", -1)):
        j.update({f"shoulder.{side}": (s * 9, -28, 42), f"elbow.{side}": (s * 9, -30, 24),
                  f"wrist.{side}": (s * 9, -28, 6), f"hip.{side}": (s * 9, 30, 40), f"knee.{side}": (s * 9, 36, 24),
                  f"ankle.{side}": (s * 9, 30, 6)})
    j = {k: np.asarray(v, dtype=np.float64) for k, v in j.items()}
    caps = [(j["hips"], j["chest"], 13), (j["chest"], (0, -48, 62), 6)]
    if tail > 0:
        root = np.array([0, 38, 48.0])
        caps.append((root, root + tail * np.array([0, 37, 14]) / np.hypot(37, 14), 3.5))
    for side in "LR":
        for a, b, r in (("shoulder", "elbow", 5 * front), ("elbow", "wrist", 4 * front), ("hip", "knee", 6),
                        ("knee", "ankle", 4)):
            caps.append((j[f"{a}.{side}"], j[f"{b}.{side}"], r))
        for end in ("wrist", "ankle"):
            caps.append((j[f"{end}.{side}"], j[f"{end}.{side}"] + (0, -7, -3), 3.5))
    mask, shift = _capsule_mask(caps, [(j["head"], 10)], scale, pad=8)
    joints = {n: (p + shift) * scale for n, p in j.items() if "." in n}
    return Subject(f"quadruped_tail{tail:g}_{scale:g}" + (f"_front{front:g}" if front != 1 else ""), Volume(mask), "quadruped", _unit((0, 0, 1)),
                   _unit((0, -1, 0)), joints, None,
                   f"volrig_support.subjects.capsule_quadruped_subject({tail:g}, {scale:g})")


def capsule_bird_subject(scale: float = 1.0, span: float = 60.0) -> Subject:
    """A bird of capsules standing (z up; trunk along y, head at -y): a trunk 38 units long, a neck and a ball head,
    two legs 36 long with feet forward, a short tail, and two wings ``span`` units long held out level: flat plates
    3 thick with an elliptical planform (chord 26 at the shoulder); ``scale`` voxels per unit. Reference joints:
    shoulders, wing tips, hips, knees, ankles."""
    j = {"hips": (0, 18, 46), "chest": (0, -16, 52), "head": (0, -30, 70)}
    for side, s_ in (("L", 1), ("R", -1)):
        j.update({f"shoulder.{side}": (s_ * 8, -10, 54), f"wingtip.{side}": (s_ * (8 + span), -10, 54),
                  f"hip.{side}": (s_ * 6, 14, 40), f"knee.{side}": (s_ * 6, 20, 22), f"ankle.{side}": (s_ * 6, 14, 5)})
    j = {k: np.asarray(v, dtype=np.float64) for k, v in j.items()}
    caps = [(j["hips"], j["chest"], 11), (j["chest"], (0, -26, 62), 5), (j["hips"], (0, 34, 50), 4),
            (j["wingtip.L"], j["wingtip.R"], 1.5)]  # the wings' span, for the box (the plates are drawn below)
    for side in "LR":
        caps += [(j[f"hip.{side}"], j[f"knee.{side}"], 3.5), (j[f"knee.{side}"], j[f"ankle.{side}"], 2.5),
                 (j[f"ankle.{side}"], j[f"ankle.{side}"] + (0, -9, -2), 2)]
    mask, shift = _capsule_mask(caps, [(j["head"], 8)], scale, pad=10)
    z, y, x = (np.arange(n, dtype=np.float64)[:, None, None] if a == 0 else
               np.arange(n, dtype=np.float64)[None, :, None] if a == 1 else np.arange(n, dtype=np.float64)[None, None, :]
               for a, n in enumerate(mask.shape))
    fx, fy, fz = x / scale - shift[0], y / scale - shift[1], z / scale - shift[2]
    u = (np.abs(fx) - 8) / span  # 0 at the shoulder, 1 at the tip
    chord = 13 * np.sqrt(np.clip(1 - u ** 2, 0, 1))
    mask |= (u >= 0) & (u <= 1) & (np.abs(fy + 10) <= chord) & (np.abs(fz - 54) <= 1.5)
    joints = {n: (p + shift) * scale for n, p in j.items() if "." in n}
    return Subject(f"capsule_bird_{scale:g}", Volume(mask), "winged", _unit((0, 0, 1)), _unit((0, -1, 0)), joints, None,
                   f"volrig_support.subjects.capsule_bird_subject({scale:g}, {span:g})")


SUBJECTS = ("phantom", "vhm4", "vhm2", "vhm1") + tuple(MESHES) + tuple(f"capsules_{p}" for p in CAPSULE_POSES)


def bones_only_quadruped(scale=2.0, tail=4):
    """A small four-legged animal's skeleton and organs, no skin (as a frog's or a mouse's labels may be): label 13
    its bones (vertebrae, girdles, leg bones with joint spaces between them, a tail, a skull thicker than the trunk
    on a neck), label 5 organs in the trunk; trunk along y (head at -y), legs down (z up), ``scale`` voxels a unit;
    ``tail`` vertebrae 6 units long from the pelvis (14: a tail longer than the trunk, as a mouse's).
    Returns the labels Volume and each leg's long bones (name -> [(a, b)] in voxels, x, y, z)."""
    def apart(a, b, gap):  # a bone from a to b, short of both joints by ``gap``
        a, b = np.asarray(a, float), np.asarray(b, float)
        d = (b - a) / np.linalg.norm(b - a)
        return a + gap * d, b - gap * d

    j = {"hips": np.array([0, 30, 45.]), "chest": np.array([0, -28, 48.])}
    legs = {}
    for side, s in (("L", 1), ("R", -1)):
        legs[f"front.{side}"] = [(s * 9, -28, 42), (s * 9, -30, 24), (s * 9, -28, 6)]
        legs[f"hind.{side}"] = [(s * 9, 30, 40), (s * 9, 36, 24), (s * 9, 30, 6)]
    spine = [j["hips"] + t * (j["chest"] - j["hips"]) for t in np.linspace(0, 1, 9)]
    bones = [(*apart(a, b, 0.8), 2.2) for a, b in zip(spine[:-1], spine[1:])]
    bones.append((*apart(j["chest"], (0, -46, 56), 1.0), 1.8))  # neck
    bones += [(*apart((0, 31 + 6 * k, 45 - k), (0, 37 + 6 * k, 44 - k), 0.6), 1.2) for k in range(tail)]  # tail
    for name, (top, mid, low) in legs.items():
        girdle = j["chest" if name.startswith("front") else "hips"]
        bones += [(girdle, np.add(top, (-np.sign(top[0]) * 1.5, 0, 0.5)), 2.0),
                  (*apart(top, mid, 1.5), 2.4), (*apart(mid, low, 1.5), 1.9), (*apart(low, np.add(low, (0, -7, -3)), 1.0), 1.2)]
    skull = [((0, -55, 60), 7)]
    bone, shift = _capsule_mask(bones, skull, scale, pad=10)
    body, _ = _capsule_mask([(j["hips"] + (0, -3, -2), j["chest"] + (0, 3, -2), 8)] + bones, skull, scale, pad=10)
    labels = np.where(bone, 13, np.where(body, 5, 0)).astype(np.uint8)
    at = {name: [(np.add(a, shift) * scale, np.add(b, shift) * scale) for a, b in zip(p[:-1], p[1:])]
          for name, p in legs.items()}
    return Volume(labels), at


def load_subject(name: str, **kw) -> Subject:
    """Any subject by name: "phantom" (scale=...), "vhm4"/"vhm2"/"vhm1", "capsules_<pose>" (scale=...), or a mesh
    name (voxels=...)."""
    if name.startswith("phantom"):
        scale = kw.get("scale", float(name[7:]) if len(name) > 7 else 0.5)
        return phantom_subject(scale)
    if name.startswith("capsules_"):
        return capsule_subject(name[len("capsules_"):], **kw)
    if name.startswith("vhm"):
        return visible_human_subject(int(name[3:]), **kw)
    return mesh_subject(name, **kw)


def rig_joint(rig, name: str) -> Optional[np.ndarray]:
    """World position of a reference joint ("elbow.L", ...) in a Rigify-named rig: the head of the matching bone
    (``RIGIFY_JOINT``); None when the rig has no such bone."""
    base, _, side = name.partition(".")
    bone = RIGIFY_JOINT.get(base)
    if bone is None:
        return None
    bone = f"{bone}.{side}" if side else bone
    if bone not in rig.names:
        return None
    return np.asarray(rig.joints[rig.bones[rig.names.index(bone)][0]], dtype=np.float64)


LIMB_JOINTS = [f"{j}.{s}" for s in "LR" for j in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")]


def rotations24():
    """The 24 axis-aligned rotations, as signed permutation matrices (3, 3) acting on (x, y, z)."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product([-1, 1], repeat=3):
            m = np.zeros((3, 3))
            m[range(3), perm] = signs
            if np.linalg.det(m) > 0:
                out.append(m)
    return out


def rotate_mask(mask: Volume, m):
    """The mask turned by the axis-aligned rotation ``m`` (from ``rotations24``), on a grid with origin 0, and a
    function mapping world points (..., 3) of the original onto the turned grid's world (a direction ``d`` maps
    to ``m @ d``)."""
    m = np.asarray(m)
    perm = [int(np.nonzero(m[i])[0][0]) for i in range(3)]
    signs = [int(m[i, perm[i]]) for i in range(3)]
    a = np.asarray(mask.array).transpose(2, 1, 0).transpose(perm)     # [x', y', z']
    a = np.flip(a, axis=[i for i in range(3) if signs[i] < 0])
    sp, org = np.asarray(mask.spacing), np.asarray(mask.origin)
    dims = np.asarray(mask.array.shape[::-1])
    turned = Volume(np.ascontiguousarray(a.transpose(2, 1, 0)), tuple(sp[perm]), (0.0, 0.0, 0.0))

    def to_turned(p):
        idx = (np.asarray(p, dtype=np.float64) - org) / sp
        out = [idx[..., perm[i]] if signs[i] > 0 else dims[perm[i]] - 1 - idx[..., perm[i]] for i in range(3)]
        return np.stack(out, axis=-1) * sp[perm]
    return turned, to_turned


def rig_difference(rig0, rig, to_turned, radius) -> float:
    """How far ``rig`` (of a turned mask) is from ``rig0`` turned by ``to_turned``: the largest distance of a bone
    end from its counterpart, in local radii (``radius(p)`` at rig0's end p); inf when the kinds, bone names (rigs
    with roles) or bone counts differ. Bones of rigs without roles ("chains", named in traversal order) are paired
    each with the nearest bone of the other rig."""
    if rig.kind != rig0.kind or len(rig) != len(rig0):
        return float("inf")
    ends0 = [to_turned(rig0.joints[list(b)]) for b in rig0.bones]
    r0 = [np.array([radius(p) for p in rig0.joints[list(b)]]) for b in rig0.bones]
    ends = [rig.joints[list(b)] for b in rig.bones]
    if rig0.kind in ("humanoid", "quadruped"):
        if sorted(rig.names) != sorted(rig0.names):
            return float("inf")
        pairs = [[ends[rig.names.index(n)]] for n in rig0.names]
    else:
        pairs = [ends] * len(ends0)
    return max(min(float((np.linalg.norm(e - e0, axis=1) / r).max()) for e in cand)
               for e0, r, cand in zip(ends0, r0, pairs))


def quadruped_problems(subject: Subject, rig) -> list:
    """What is wrong with a quadruped's rig: the kind, the head bone not at the head end (its tail in the last
    quarter of the body along ``subject.head``), fewer than two tail bones, or a tail not in the back half."""
    if rig.kind != "quadruped":
        return [f"rigged as {rig.kind}"]
    bad = []
    along = rig.joints @ subject.head
    lo, span = along.min(), along.max() - along.min()
    if "head" not in rig.names or rig.joints[rig.bones[rig.names.index("head")][1]] @ subject.head < lo + 0.75 * span:
        bad.append("the head bone is not at the head end")
    tail = [b for b, n in enumerate(rig.names) if n.startswith("tail")]
    if len(tail) < 2:
        bad.append(f"{len(tail)} tail bones")
    elif (rig.joints[rig.bones[tail]] @ subject.head).max() > lo + 0.5 * span:
        bad.append("the tail is not at the back")
    return bad


def local_radius(dt: np.ndarray, mask: Volume, point, at_least: float = 1.0) -> float:
    """The object's thickness at ``point`` (world): the largest Euclidean distance transform value (``dt``, world
    units, e.g. ``Skeleton.dt``) within one voxel of it, at least ``at_least`` voxels."""
    sp = np.asarray(mask.spacing, dtype=np.float64)
    ijk = np.round((np.asarray(point, dtype=np.float64) - np.asarray(mask.origin)) / sp).astype(int)[::-1]
    c = np.clip(ijk, 0, np.array(dt.shape) - 1)
    s = tuple(slice(max(c[a] - 1, 0), c[a] + 2) for a in range(3))
    return max(float(dt[s].max()), at_least * float(sp.min()))


SAME_JOINT_VOXELS = 2.0 * 3 ** 0.5
"""Joints of two rigs are the same within half a local radius (``rig_difference``), that radius at least this many
voxels: joints a voxel apart (diagonally too) are the same; one on a part a voxel or two thick cannot be placed closer."""


# ---- Visible Human reference joints from its bone labels ----------------------------------------------------------
#
# The bones are not labelled one by one, so each limb's long bones are found from where they must be in a standing
# man (the fractions of the skeleton's height below give slabs of shaft that hold one long bone or one pair), and
# every joint from the bone voxels around them, measured in millimetres on the voxel centres so that 4, 2 and 1 mm
# give the same joints (within ~7 mm; the test checks 1 cm):
# - long bone axes: principal axis of a shaft slab (femur, tibia: the larger 3-D piece of the shin slab, humerus,
#   radius + ulna);
# - knee: the deepest gap in the bone's cross-section along the line from the femur's shaft to the tibia's (the
#   patella, in front, left out); the joint is the midpoint of the two facing ends (the bone within 10 mm either
#   side of the gap);
# - ankle and wrist: past the tibia's (forearm's) shaft, where the section first flares (the distal metaphysis) and
#   then thins most within 35 mm: the gap to the talus (carpals); midpoint of the facing ends;
# - elbow: the deepest gap along the humerus' axis near the arm's bend (the arm is bent: its centre line is fitted
#   with three lines, humerus, forearm, hand);
# - hip and shoulder: the femoral (humeral) head, the thickest ball of bone above the shaft (distance transform
#   maximum, averaged over its top 2 mm).
# Arms are separated from the trunk on a 4 mm grid with one-cell gaps bridged, below the upper-arm slab: the
# component holding the slab's most lateral bone.

_COARSE = 4.0  # mm: the grid on which limb bones are grouped (the 4 mm file's own)


def _pca(p):
    """Centroid and principal direction of points, the direction pointing down (-z)."""
    c = p.mean(axis=0)
    d = np.linalg.svd(p - c, full_matrices=False)[2][0]
    return c, (d if d[2] < 0 else -d)


def _along(p, c, d):
    """Axial coordinate along the line c + t d, and distance from it."""
    q = p - c
    t = q @ d
    return t, np.linalg.norm(q - t[:, None] * d, axis=1)


def _profile(t, lo, hi, cell, window=8.0):
    """Bone cross-section area (mm^2) along t at 1 mm steps from lo to hi, over a sliding window wider than the
    coarsest voxel (a tilted axis does not alias the voxel layers)."""
    ts = np.sort(t)
    x = np.arange(lo, hi + 1.0, 1.0)
    n = np.searchsorted(ts, x + window / 2) - np.searchsorted(ts, x - window / 2)
    return x, n * cell / window


def _valley(t, lo, hi, cell, wall=30.0):
    """The deepest gap of the section profile within [lo, hi]: the minimum whose lower wall (the most bone within
    ``wall`` mm on each side) stands highest above it."""
    x, area = _profile(t, lo - wall, hi + wall, cell)
    k = int(round(wall))
    depth = [min(area[i - k:i + 1].max(), area[i:i + k + 1].max()) - area[i] for i in range(k, len(area) - k)]
    return x[k + int(np.argmax(depth))]


def _end_gap(t, start, cell, reach=35.0, flare=1.8):
    """The gap at a long bone's distal end (t increasing distally, shaft before ``start``): the first section
    past ``start`` wider than ``flare`` times the shaft's median, then the thinnest within ``reach`` mm."""
    x, area = _profile(t, start - 60.0, start + 200.0, cell)
    shaft = np.median(area[x < start])
    wide = np.nonzero((x >= start) & (area > flare * shaft))[0]
    i0 = wide[0] if len(wide) else int(np.argmax(x >= start))
    seg = (x >= x[i0]) & (x <= x[i0] + reach)
    return x[seg][np.argmin(area[seg])]


def _facing_ends(p, t, t_gap, width=10.0):
    """Midpoint of the centroids of the bone just before and just after a gap."""
    before = p[(t >= t_gap - width) & (t < t_gap)]
    after = p[(t > t_gap) & (t <= t_gap + width)]
    return 0.5 * (before.mean(axis=0) + after.mean(axis=0))


def _labels_of(cells, bridge: bool = True):
    """26-connected labels, one per cell, of the occupied cells (integer (N, 3) xyz); ``bridge``: after a
    one-cell dilation (gaps of one cell do not separate)."""
    lo = cells.min(0)
    c = cells - lo
    grid = np.zeros((c.max(0) + 1)[::-1], dtype=bool)
    grid[c[:, 2], c[:, 1], c[:, 0]] = True
    full = np.ones((3, 3, 3), dtype=bool)
    lab, _ = ndi.label(ndi.binary_dilation(grid, full) if bridge else grid, full)
    return lab[c[:, 2], c[:, 1], c[:, 0]]


class _Bones:
    """Bone voxel centres (mm) of a label volume or bone mask, and the distance transform on demand."""

    def __init__(self, vol: Volume):
        arr = np.asarray(vol.array)
        self.mask = arr if arr.dtype == np.bool_ else np.isin(arr, BONE_LABELS)
        if not self.mask.any():
            raise ValueError("no bone voxels (labels 84 BoneCortical, 92 BoneMarrow) in the volume")
        self.spacing = np.asarray(vol.spacing, dtype=np.float64)
        self.origin = np.asarray(vol.origin, dtype=np.float64)
        z, y, x = np.nonzero(self.mask)
        self.p = np.stack([x, y, z], axis=1) * self.spacing + self.origin
        self.cell = float(np.prod(self.spacing))
        self.z0 = float(self.p[:, 2].min())
        self.height = float(self.p[:, 2].max()) - self.z0
        self.xc = float(np.median(self.p[:, 0]))
        self.cells = np.floor((self.p - self.p.min(0)) / _COARSE).astype(np.int64)

    def z(self, fraction: float) -> float:
        return self.z0 + fraction * self.height

    def thickest(self, sel) -> np.ndarray:
        """Centre of the largest ball of bone among the points ``sel``."""
        p = self.p[sel]
        lo = np.maximum(np.floor((p.min(0) - self.origin) / self.spacing).astype(int) - 2, 0)
        hi = np.ceil((p.max(0) - self.origin) / self.spacing).astype(int) + 3
        crop = self.mask[lo[2]:hi[2], lo[1]:hi[1], lo[0]:hi[0]]
        dt = ndi.distance_transform_edt(crop, sampling=self.spacing[::-1])
        ijk = np.round((p - self.origin) / self.spacing).astype(int) - lo
        d = dt[ijk[:, 2], ijk[:, 1], ijk[:, 0]]
        return p[d >= d.max() - max(self.spacing.max(), 2.0)].mean(axis=0)

    def arm(self, side: int, z0: float, z1: float) -> np.ndarray:
        """Mask of one arm's bone points below z1: the coarse component holding the most lateral bone of the
        slab [z0, z1] on this side."""
        below = np.nonzero(self.p[:, 2] < z1)[0]
        lab = _labels_of(self.cells[below])
        lateral = (self.p[below, 0] - self.xc) * side
        slab = (self.p[below, 2] >= z0) & (lateral > 0)
        count = np.bincount(lab[slab], minlength=lab.max() + 1).astype(np.float64)
        mean = np.bincount(lab[slab], lateral[slab], minlength=lab.max() + 1) / np.maximum(count, 1)
        mean[(count < 0.1 * count.max()) | (np.arange(len(count)) == 0)] = -np.inf
        out = np.zeros(len(self.p), dtype=bool)
        out[below[lab == int(np.argmax(mean))]] = True
        return out


def _three_lines(z, c):
    """Breakpoints (z1 > z2) of the best fit of three lines to the centre line points c (ordered by z, down)."""
    n = len(z)
    cost = np.full((n + 1, n + 1), np.inf)
    for i in range(n):
        for j in range(i + 3, n + 1):
            s = np.linalg.svd(c[i:j] - c[i:j].mean(0), compute_uv=False)
            cost[i, j] = (s[1:] ** 2).sum()
    pairs = [(cost[0, i] + cost[i, j] + cost[j, n], i, j) for i in range(3, n - 5) for j in range(i + 3, n - 2)]
    _, i, j = min(pairs)
    return z[i], z[j]


def _centre_line(p, step=4.0):
    """Centroids of points in z slabs of ``step`` mm, top down: (z, centroids)."""
    k = np.floor((p[:, 2].max() - p[:, 2]) / step).astype(int)
    counts = np.bincount(k)
    keep = np.nonzero(counts > 3)[0]
    cen = np.stack([np.bincount(k, p[:, a])[keep] / counts[keep] for a in range(3)], axis=1)
    return cen[:, 2], cen


def _leg_joints(b: _Bones, side: int):
    p = b.p
    leg = ((p[:, 0] - b.xc) * side > 0) & (p[:, 2] < b.z(0.47))
    cf, df = _pca(p[leg & (p[:, 2] >= b.z(0.36)) & (p[:, 2] <= b.z(0.46))])
    shin = np.nonzero(leg & (p[:, 2] >= b.z(0.12)) & (p[:, 2] <= b.z(0.24)))[0]
    lab = _labels_of(b.cells[shin], bridge=False)
    ct, dt = _pca(p[shin[lab == np.bincount(lab)[1:].argmax() + 1]])  # the tibia: the shin slab's larger piece
    # knee: along the line from the femur's shaft to the tibia's; the patella (more than 25 mm in front) left out
    dk = (ct - cf) / np.linalg.norm(ct - cf)
    t, r = _along(p, cf, dk)
    cyl = leg & (r < 45.0) & (p[:, 1] - (cf[1] + t * dk[1]) > -25.0)
    tk = _valley(t[cyl], (b.z(0.36) - cf[2]) / dk[2], (b.z(0.24) - cf[2]) / dk[2], b.cell)
    knee = _facing_ends(p[cyl], t[cyl], tk)
    # ankle: below the tibia's shaft, in a narrow cylinder that leaves the malleoli out
    t, r = _along(p, ct, dt)
    cyl = leg & (r < 18.0)
    ankle = _facing_ends(p[cyl], t[cyl], _end_gap(t[cyl], (b.z(0.12) - ct[2]) / dt[2], b.cell))
    # hip: the femoral head, the thickest bone 40-220 mm above the femur's shaft slab
    t, r = _along(p, cf, -df)
    top = (b.z(0.46) - cf[2]) / -df[2]
    hip = b.thickest(((p[:, 0] - b.xc) * side > 0) & (r < 70.0) & (t > top + 40.0) & (t < top + 220.0))
    return dict(hip=hip, knee=knee, ankle=ankle)


def _arm_joints(b: _Bones, side: int):
    p = b.p
    z0, z1 = b.z(0.72), b.z(0.80)
    arm = b.arm(side, z0, z1)
    ze, zw = _three_lines(*_centre_line(p[arm]))        # the bends: elbow, and (roughly) the wrist
    ch, dh = _pca(p[arm & (p[:, 2] > ze + 40.0)])
    cfa, dfa = _pca(p[arm & (p[:, 2] < ze - 25.0) & (p[:, 2] > zw + 25.0)])
    t, r = _along(p, ch, dh)
    cyl = arm & (r < 35.0)
    t_e = (ze - ch[2]) / dh[2]
    elbow = _facing_ends(p[cyl], t[cyl], _valley(t[cyl], t_e - 50.0, t_e + 30.0, b.cell))
    t, r = _along(p, cfa, dfa)
    cyl = arm & (r < 30.0)
    wrist = _facing_ends(p[cyl], t[cyl], _end_gap(t[cyl], 0.0, b.cell))
    t, r = _along(p, ch, -dh)
    top = (z1 - ch[2]) / -dh[2]
    shoulder = b.thickest((r < 50.0) & (t > top - 20.0) & (t < top + 150.0))
    return dict(shoulder=shoulder, elbow=elbow, wrist=wrist)


def visible_human_joints(mask_or_labels: Volume) -> Dict[str, np.ndarray]:
    """Shoulders, elbows, wrists, hips, knees and ankles (``"elbow.L"``, ...; .L = +x, the body's left) of the
    Visible Human, in world mm, derived from its bone: a label Volume (84 and 92 are bone) or a bool bone mask,
    +x the body's left, +z up, standing (see the comment above for the method). About 1.5 s at 4 mm, 4 s at
    2 mm, 35 s at 1 mm."""
    b = _Bones(mask_or_labels)
    out = {}
    for side, sfx in ((1, ".L"), (-1, ".R")):
        for name, p in {**_arm_joints(b, side), **_leg_joints(b, side)}.items():
            out[name + sfx] = p
    return out

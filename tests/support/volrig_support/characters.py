"""Characters with a known body plan, for fitting and judging autorig's plan choice (issue 53).

``plan_subjects()`` gives every subject: the shared characters (``characters/index.json``: artists' and RigNet
skeletons, posed figures, shapes with a known plan), the older meshes and the Visible Human. Each one can be
rigged (``PlanSubject.rig``) the way a user rigs it: a mesh through ``volrig.rig_mesh`` at the default 160 voxels,
a volume through its skeleton at the default thinness, up given.

``rig_distances`` is the learned riggers' metric (RigNet, MagicArticulate, Puppeteer): the mesh centred on its
bounding box and scaled so its longest side is 1; CD-J2J the symmetric chamfer distance between the joint sets,
J2B joints against bones sampled every 0.005 (both ways), B2B sampled bones against sampled bones; all x 100.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, replace
from typing import List, Optional, Sequence

import numpy as np

from . import data_root

AXES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}
#: Plans autorig builds; any other known plan (fish, many-armed, none) is judged right as neutral chains.
RIGGED_PLANS = ("humanoid", "quadruped", "winged", "hand")
#: The older subjects (volrig_support.subjects) used besides the shared characters: meshes, the phantom, the
#: Visible Human, capsule humanoids in three poses and capsule dogs with tails of 0, 40 and 70 units (the last also
#: with front legs 1.6 times as thick: a bull's). "name@240": the mesh voxelized at 240 voxels instead of 160.
OLD_SUBJECTS = ("arm", "hand", "knight", "cow", "horse", "camel", "lion", "arm@240", "hand@240", "knight@240",
                "cow@240", "horse@240", "camel@240", "lion@240", "phantom", "vhm4", "capsules_down",
                "capsules_wide", "capsules_armsup", "quadruped_tail0", "quadruped_tail40", "quadruped_tail70",
                "quadruped_tail70_front1.6")


def plan_label(plan: str) -> str:
    return plan if plan in RIGGED_PLANS else "chains"


@dataclass
class PlanSubject:
    """A subject with a known plan: a mesh (vertices, faces) or a mask Volume, its up, its plan, its reference
    rig (joints, bones; None when it has none) and its category for tables."""
    name: str
    plan: str
    up: tuple
    category: str
    mesh: Optional[tuple] = None
    mask: object = None
    reference: Optional[tuple] = None
    head: Optional[tuple] = None  #: the direction of the head end, when known (a humanoid's: up)
    phase: Optional[tuple] = None  #: the voxel lattice moved by these fractions of a voxel (mesh_skeleton)

    @property
    def plan_label(self) -> str:
        return plan_label(self.plan)

    def rig(self, **options):
        """The rig a user gets (options go to autorig: detail=, plan_weights=, markers=, kind=): a mesh voxelized and
        skeletonized as ``volrig.rig_mesh`` does it (``pipeline.mesh_skeleton``: its longest side / 160, finer when
        its parts come out thinner than 2 voxels), a mask skeletonized at the default thinness, then
        ``pipeline.rig_skeleton``: rig_mesh's steps without its skin weights."""
        from volrig import pipeline as P
        if self.mesh is not None:
            mask, _, _, pts = P.mesh_skeleton(*self.mesh, lattice_phase=self.phase)
        else:
            mask = self.mask
            sk = P.skeleton_of(mask)
            pts = P.skeleton_points(sk, thinness=P.thinness_from_voxels(P.DEFAULT_THINNESS_VOXELS, sk.metric,
                                                                         mask.spacing))
        return P.rig_skeleton(pts, mask, up=self.up, **options).rig

    def vertices(self) -> np.ndarray:
        """Points whose bounding box normalises the metric: the mesh's vertices, or the mask's corners."""
        if self.mesh is not None:
            return np.asarray(self.mesh[0], float)
        m = self.mask
        idx = np.argwhere(np.asarray(m.array))[:, ::-1]
        lo, hi = idx.min(0), idx.max(0) + 1
        return np.array([lo, hi], float) * np.asarray(m.spacing) + np.asarray(m.origin)


def read_rig(path):
    """A RigNet text rig ('joints NAME x y z', 'hier PARENT CHILD' lines) -> (joints (J, 3), bones (B, 2), names)."""
    joints, names, hier = [], [], []
    with open(path) as f:
        for line in f:
            t = line.split()
            if t and t[0] == "joints":
                names.append(t[1])
                joints.append([float(x) for x in t[2:5]])
            elif t and t[0] == "hier":
                hier.append((t[1], t[2]))
    index = {n: i for i, n in enumerate(names)}
    return np.array(joints, float), np.array([(index[a], index[b]) for a, b in hier], int).reshape(-1, 2), names


def characters(names: Optional[Sequence[str]] = None) -> List[PlanSubject]:
    """The shared characters (``characters/index.json``), those named when given (by mesh file stem)."""
    import volrig
    root = data_root() / "characters"
    out = []
    for row in json.loads((root / "index.json").read_text()):
        stem = row["mesh"].split("/")[-1].rsplit(".", 1)[0]
        if names and stem not in names:
            continue
        v, f = volrig.read_mesh(str(root / row["mesh"]))
        ref = read_rig(root / row["rig"])[:2] if row.get("rig") else None
        out.append(PlanSubject(row["mesh"], row["plan"], AXES[row["up"]], row["mesh"].split("/")[0],
                               mesh=(np.asarray(v, float), np.asarray(f)), reference=ref,
                               head=AXES[row["up"]] if row["plan"] == "humanoid" else None))
    return out


#: Blender's OBJ import (forward -Z, up Y): (x, y, z) -> (x, -z, y).
BLENDER_IMPORT = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])


def turned(sub: "PlanSubject", rotation=BLENDER_IMPORT) -> "PlanSubject":
    """The same character turned by ``rotation`` (a mesh's vertices, its up, its head direction and its reference
    joints with it), as a user gets it in another frame: the same shape on another voxel lattice (voxelize puts the
    lattice at the bounding box's low corner, so a flipped axis moves it by a fraction of a voxel)."""
    R = np.asarray(rotation, float)

    def turn(u):
        return None if u is None else tuple(float(x) for x in R @ np.asarray(u, float))
    mesh = None if sub.mesh is None else (sub.mesh[0] @ R.T, sub.mesh[1])
    ref = None if sub.reference is None else (np.asarray(sub.reference[0], float) @ R.T, sub.reference[1])
    return replace(sub, mesh=mesh, up=turn(sub.up), head=turn(sub.head), reference=ref)


def old_subjects(names: Sequence[str] = OLD_SUBJECTS) -> List[PlanSubject]:
    from .subjects import capsule_quadruped_subject, load_subject
    out = []
    for name in names:
        if name.startswith("quadruped_tail"):
            tail, _, front = name[len("quadruped_tail"):].partition("_front")
            s = capsule_quadruped_subject(float(tail), front=float(front or 1))
        elif "@" in name:
            mesh, voxels = name.split("@")
            s = load_subject(mesh, voxels=int(voxels))
        else:
            s = load_subject(name)
        out.append(PlanSubject(name, s.kind, tuple(float(u) for u in s.up), "older", mask=s.mask,
                               head=tuple(float(u) for u in s.head)))
    return out


def plan_subjects(names: Optional[Sequence[str]] = None, without_up: bool = False) -> List[PlanSubject]:
    """Every subject with a known plan: the shared characters, then the older ones (named ones only when given);
    ``without_up`` adds each again with no up given (named "<name> (no up)")."""
    old = [n for n in OLD_SUBJECTS if not names or n in names]
    out = characters(names) + old_subjects(old)
    if without_up:
        out += [replace(s, name=s.name + " (no up)", up=None) for s in out]
    return out


def _chamfer(a, b):
    d = np.linalg.norm(a[None] - b[:, None], axis=2)
    return (d.min(0).mean() + d.min(1).mean()) / 2


def _one_way(src, dst):
    return np.linalg.norm(src[None] - dst[:, None], axis=2).min(0).mean()


def _bone_samples(joints, bones, step=0.005):
    parts = []
    for a, b in bones:
        n = max(1, int(round(np.linalg.norm(joints[b] - joints[a]) / step)))
        parts.append(joints[a] + (joints[b] - joints[a]) * (np.arange(n + 1) / n)[:, None])
    return np.concatenate(parts) if parts else joints.copy()


def rig_distances(joints, bones, ref_joints, ref_bones, vertices):
    """(CD-J2J, J2B, B2B) x 100 with the longest side of ``vertices``' bounding box = 1 (module docstring)."""
    v = np.asarray(vertices, float)
    lo, hi = v.min(0), v.max(0)
    centre, size = (lo + hi) / 2, (hi - lo).max()
    pj = (np.asarray(joints, float) - centre) / size
    gj = (np.asarray(ref_joints, float) - centre) / size
    ps, gs = _bone_samples(pj, np.asarray(bones)), _bone_samples(gj, np.asarray(ref_bones))
    return 100 * _chamfer(pj, gj), 100 * (_one_way(pj, gs) + _one_way(gj, ps)) / 2, 100 * _chamfer(ps, gs)

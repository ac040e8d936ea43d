"""The articulated skeleton: ``Rig``, ``autorig`` and ``bind`` (docs/ALGORITHMS.md §6).

``autorig`` reduces a skeleton-tree to a small set of joints and bones (spurs pruned, joints at branch points,
end points and bends), naming bones by role when the shape is humanoid- or quadruped-like (Rigify's names: hips,
spine, chest, neck, head, shoulder/upper_arm/forearm/hand and pelvis/thigh/shin/foot with .L/.R) or a hand (palm,
thumb.01-03, f_index / f_middle / f_ring / f_pinky .01-03, .L/.R from the thumb's side). ``bind``
attaches every skeleton point to the bone that owns it, by geodesic distance inside the object.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import List, Optional, Sequence

import numpy as np

from . import _optional, _volrig
from ._volrig import VolrigError
from .skeleton import ProgressFn, SkeletonPoints
from .volume import Volume
from .tree import SkeletonTree, _mask_for, _point_arrays


@dataclass
class Rig:
    """Joints and the bones between them.

    joints:  (K, 3) float64 world positions.
    bones:   (B, 2) int32 joint indices (head, tail).
    names:   B unique bone names.
    parents: (B,) int32 parent bone of each bone, -1 for roots. Defaults to the bone whose tail is this bone's
             head (-1 when there is none).
    kind:    one of ``KINDS`` ("humanoid", "quadruped", "winged", "hand", "chains": from ``autorig``) or "custom".
    joint_points: (K,) int64 skeleton point each joint sits on, -1 when none (end joints moved to the surface,
             joints placed by hand and not snapped).
    fit:     how well autorig's template fits the shape, 0..1 (0 for other rigs).
    up:      (3,) the up direction autorig used (given) or inferred (unit; zeros when unknown).
    up_confidence: 1 when up was given, else how clearly the shape showed it (0..1).
    runner_up: the second-best template's kind ("" when there was none); runner_up_fit its fit.
    note:    what the user should know about an automatic rig ("" when nothing), e.g. "no body plan fits; place
             markers or choose a plan".
    bone_joints: None, or (``autorig(..., bone=)``, ``volrig.bones.rig_to_bones``) a ``volrig.bones.BoneJoint`` per
             limb joint: where the bones put it, how, or why not.
    """

    joints: np.ndarray
    bones: np.ndarray
    names: List[str]
    parents: Optional[np.ndarray] = None
    kind: str = "custom"
    joint_points: Optional[np.ndarray] = None
    fit: float = 0.0
    up: Optional[np.ndarray] = None
    up_confidence: float = 0.0
    runner_up: str = ""
    runner_up_fit: float = 0.0
    note: str = ""
    bone_joints: Optional[list] = None

    def __post_init__(self):
        self.joints = np.array(self.joints, dtype=np.float64, copy=True).reshape(-1, 3) if np.size(self.joints) \
            else np.zeros((0, 3))
        self.bones = np.array(self.bones, dtype=np.int32, copy=True).reshape(-1, 2) if np.size(self.bones) \
            else np.zeros((0, 2), np.int32)
        self.names = [str(n) for n in self.names]
        if self.parents is None:
            tail_of = {int(t): b for b, (h, t) in enumerate(self.bones)}
            self.parents = np.array([tail_of.get(int(h), -1) for h, _ in self.bones], dtype=np.int32)
        self.parents = np.array(self.parents, dtype=np.int32, copy=True).reshape(-1)
        if self.joint_points is None:
            self.joint_points = np.full(len(self.joints), -1, dtype=np.int64)
        self.joint_points = np.array(self.joint_points, dtype=np.int64, copy=True).reshape(-1)
        if len(self.joint_points) != len(self.joints):
            raise VolrigError(f"joint_points has {len(self.joint_points)} entries for {len(self.joints)} joints")
        self.up = np.zeros(3) if self.up is None else np.array(self.up, dtype=np.float64, copy=True).reshape(3)
        _volrig.check_rig(self.joints, self.bones, self.names, self.parents)

    def __len__(self) -> int:
        return len(self.bones)

    def index(self, name: str) -> int:
        """Bone index of ``name``; raises KeyError naming the known bones."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no bone named {name!r}; bones: {', '.join(self.names)}") from None

    def heads(self) -> np.ndarray:
        """(B, 3) bone head positions."""
        return self.joints[self.bones[:, 0]]

    def tails(self) -> np.ndarray:
        """(B, 3) bone tail positions."""
        return self.joints[self.bones[:, 1]]

    @property
    def rest_matrices(self) -> np.ndarray:
        """(B, 4, 4) rest matrices in Blender's convention (roll 0): columns X, Y, Z, translation; Y runs head ->
        tail, X and Z come from the smallest rotation taking +Y onto the bone, as Blender computes them."""
        return np.stack([_volrig.rest_matrix(tuple(h), tuple(t)) for h, t in zip(self.heads(), self.tails())]) \
            if len(self.bones) else np.zeros((0, 4, 4))

    @classmethod
    def from_bones(cls, heads, tails, names: Sequence[str], parents, kind: str = "custom",
                   tolerance: float = 1e-6) -> "Rig":
        """A rig from bones given by head and tail positions (B, 3) and parent indices (-1 for roots), as an
        armature stores them (Blender edit bones). Heads and tails closer than ``tolerance`` times the rig's size
        become one joint, so connected bones share their joint."""
        heads = np.asarray(heads, dtype=np.float64).reshape(-1, 3)
        tails = np.asarray(tails, dtype=np.float64).reshape(-1, 3)
        if len(heads) != len(tails):
            raise VolrigError(f"{len(heads)} heads but {len(tails)} tails")
        ends = np.concatenate([heads, tails])
        if not np.isfinite(ends).all():
            raise VolrigError("bone ends must be finite")
        size = float(np.ptp(ends, axis=0).max()) if len(ends) else 0.0
        eps = tolerance * max(size, 1.0)
        joints: List[np.ndarray] = []
        index = np.empty(len(ends), dtype=np.int32)
        for i, p in enumerate(ends):
            for j, q in enumerate(joints):
                if np.abs(p - q).max() <= eps:
                    index[i] = j
                    break
            else:
                index[i] = len(joints)
                joints.append(p)
        b = len(heads)
        return cls(np.array(joints).reshape(-1, 3), np.stack([index[:b], index[b:]], axis=1), list(names),
                   np.asarray(parents, dtype=np.int32), kind)

    def pose(self, rotations) -> np.ndarray:
        """(B, 4, 4) rest-to-pose matrices from local rotations: ``rotations`` maps a bone name to (axis, degrees),
        a rotation about the bone's rest head in world axes, applied after its parent's motion (forward kinematics:
        M[b] = M[parent] @ R_b). Bones not named follow their parents."""
        for name in rotations:
            self.index(name)  # KeyError naming the known bones
        heads = self.heads()
        M = rest_pose(len(self))
        done = np.zeros(len(self), dtype=bool)

        def world(b: int) -> np.ndarray:
            if not done[b]:
                p = int(self.parents[b])
                local = rotation_about(*rotations[self.names[b]], heads[b]) if self.names[b] in rotations else np.eye(4)
                M[b] = (world(p) if p >= 0 else np.eye(4)) @ local
                done[b] = True
            return M[b]

        for b in range(len(self)):
            world(b)
        return M

    def basis_matrices(self, matrices) -> np.ndarray:
        """Blender's ``pose_bone.matrix_basis`` (the bone's local pose, relative to its rest and its parent's pose)
        for rest-to-pose matrices ``matrices`` (..., B, 4, 4): with R the rest matrices, the posed bone matrix is
        ``M[b] @ R[b]`` = ``M[p] @ R[p] @ (R[p]^-1 @ R[b]) @ basis[b]``, so ``basis[b] = R[b]^-1 @ M[p]^-1 @ M[b] @
        R[b]`` (``M[p]`` = identity for roots). Rigid matrices give rotation-plus-translation bases."""
        m = np.asarray(matrices, dtype=np.float64)
        if m.shape[-3:] != (len(self), 4, 4):
            raise VolrigError(f"matrices must have shape (..., {len(self)}, 4, 4), got {m.shape}")
        rest = self.rest_matrices
        parent = np.where(self.parents[:, None, None] >= 0, m[..., self.parents, :, :], np.eye(4))
        return np.linalg.inv(rest) @ np.linalg.solve(parent, m) @ rest

    def snap(self, points: SkeletonPoints, joints: Optional[Sequence[int]] = None) -> "Rig":
        """A copy with the given joints (default: all) moved onto their nearest skeleton point."""
        idx = np.arange(len(self.joints)) if joints is None else np.asarray(joints, dtype=np.int64).reshape(-1)
        if len(idx) and (idx.min() < 0 or idx.max() >= len(self.joints)):
            raise IndexError(f"joint indices must lie in 0..{len(self.joints) - 1}")
        if len(points) == 0:
            raise VolrigError("no skeleton points to snap to")
        new = self.joints.copy()
        jp = self.joint_points.copy()
        for k in idx:
            d = np.einsum("ij,ij->i", points.centers - new[k], points.centers - new[k])
            p = int(np.argmin(d))
            new[k] = points.centers[p]
            jp[k] = p
        return replace(self, joints=new, joint_points=jp)

    def __repr__(self) -> str:
        return f"Rig({self.kind}, {len(self.joints)} joints, {len(self.bones)} bones: {', '.join(self.names[:6])}" \
               f"{', ...' if len(self.names) > 6 else ''})"


def rest_pose(bone_count: int) -> np.ndarray:
    """(B, 4, 4) identity matrices: the rest pose."""
    return np.repeat(np.eye(4)[None], int(bone_count), axis=0)


def rotation_about(axis, angle_degrees: float, pivot) -> np.ndarray:
    """4x4 rigid matrix rotating by ``angle_degrees`` (right-handed) about ``axis`` through the world point
    ``pivot``."""
    a = np.asarray(axis, dtype=np.float64)
    n = np.linalg.norm(a)
    if a.shape != (3,) or not np.isfinite(n) or n == 0:
        raise VolrigError(f"axis must be a non-zero 3-vector, got {axis!r}")
    a = a / n
    t = np.radians(float(angle_degrees))
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    R = np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * K @ K
    M = np.eye(4)
    M[:3, :3] = R
    p = np.asarray(pivot, dtype=np.float64)
    M[:3, 3] = p - R @ p
    return M


@dataclass
class AutorigResult:
    """What ``autorig`` worked on, for pictures and diagnostics.

    kept:       (N,) bool, the points whose level-set node survived spur pruning.
    root:       the point the pruned tree was rooted at.
    nodes:      (K, 3) centroids of the level-set tree's nodes; node_radius (K,); node_edges (K-1, 2);
    node_kept:  (K,) bool, nodes left after pruning.
    reading_kind, reading_features, reading_leaves: every body-plan reading the search scored: its kind,
                (R, len(PLAN_TERMS)) features and (R, 5) extremities (node indices: head, legs, arms; a hand's
                wrist then -1) (for fitting the plan weights: benchmarks/fit_plan_weights.py).
    chains_fit: neutral chains' fit (-1 when not built).
    """
    kept: np.ndarray
    root: int
    nodes: np.ndarray
    node_radius: np.ndarray
    node_edges: np.ndarray
    node_kept: np.ndarray
    reading_kind: List[str] = field(default_factory=list)
    reading_features: Optional[np.ndarray] = None
    chains_fit: float = -1.0
    reading_leaves: Optional[np.ndarray] = None


#: The templates autorig fits (spelled once in the core: volrig/rig.hpp kAutorigKinds).
KINDS = tuple(_volrig.AUTORIG_KINDS)
#: The joints a user may mark for autorig (``markers=``): chin, neck, head_top, groin and per side shoulder, elbow,
#: wrist, hand_tip, hip, knee, ankle, toe (``wrist.L``...). Spelled once in the core (kMarkerNames).
MARKER_NAMES = tuple(_volrig.MARKER_NAMES)
#: ``autorig(bone=)`` reads the body plan from the bone itself (grown into a body: ``volrig.bones.bone_body``) when
#: at least this share of the outer surface is bare bone (organs and bones without skin, or the bone alone).
BARE_BONE_SHARE = float(_volrig.BARE_BONE_SHARE)
#: The body-plan features whose weights are fitted to data (``plan_weights=`` adds neutral chains' score).
PLAN_TERMS = tuple(_volrig.PLAN_TERMS)
#: The fitted weights (``PLAN_TERMS``', then neutral chains' score): ``plan_weights``' default.
PLAN_WEIGHTS = tuple(_volrig.PLAN_WEIGHTS)


def bone_plan_weights() -> List[float]:
    """The weights a body plan read from the bone itself (``autorig(bone=)`` without flesh) is scored with: the
    fitted ones, but a head thinner than an extremity the reading leaves out costs a reading its whole margin over
    no plan (neutral chains' score less the lower of the humanoid's and the quadruped's bias: what an ideal reading
    scores), and nothing is a sheet (below). A skeleton's head is its skull, the thickest end of a vertebrate's
    bones, even where a long tail sticks out further; an outer shape's head leaf is often an ear or a muzzle
    thinner than its tail, which is why the weight fitted to the characters' shapes is small."""
    w = list(PLAN_WEIGHTS)
    ideal = min(w[PLAN_TERMS.index("bias_humanoid")], w[PLAN_TERMS.index("bias_quadruped")])
    w[PLAN_TERMS.index("head_thin")] = max(w[-1] - ideal, w[PLAN_TERMS.index("head_thin")])
    # Flat bones (shoulder blades, the pelvis, the skull's plates) make no limb a sheet, and no wing is read from
    # bones: the flatness terms are left out, and a winged reading starts at chains' score (its penalties are at
    # least 0, and a plan must score below chains).
    for term in ("arms_flat", "legs_flat", "w_wings_round"):
        w[PLAN_TERMS.index(term)] = 0.0
    w[PLAN_TERMS.index("bias_winged")] = w[-1]
    return w


def autorig(points: SkeletonPoints, tree: SkeletonTree, mask, bones: Optional[int] = None,
            prune_scale: float = 1.5, tolerance: float = 0.35, roles: bool = True, progress: ProgressFn = None,
            detail: Optional[list] = None, kind: Optional[str] = None, up=None, own_scale: bool = True,
            markers: Optional[dict] = None, plan_weights=None, bone=None) -> Rig:
    """Articulated skeleton from a skeleton-tree (see the module docstring).

    Every template (humanoid, quadruped, winged, hand, neutral chains) is fitted and scored; the best wins. The result's
    ``kind``, ``fit`` (0..1), ``runner_up`` / ``runner_up_fit``, ``up`` and ``up_confidence`` say what was found.
    The rig is made from the object's own skeleton at autorig's scale (the object resampled to about 400 voxels
    along its longest extent when finer), whatever ``points`` and ``tree`` hold (they then only give each joint's
    ``joint_points``, the nearest point): the same object gives the same rig at any point count.

    bones:       bone count target (default 24). Humanoid and quadruped shapes get their 21 role bones when the
                 target allows at least 21; other shapes get at most this many bones along their chains.
    prune_scale: a leaf branch is pruned when its tip's ball lies inside the ball of a node nearer the root scaled
                 by this factor (larger prunes more).
    tolerance:   chains without a role are cut at bends until every point lies within tolerance * its radius of
                 its bone (in position and radius).
    roles:       try the humanoid / quadruped body plans (a guess from the shape's five main extremities: a molar
                 with four roots passes for a quadruped); False gives neutral chains.
    detail:      pass a list to receive an ``AutorigResult`` appended to it.
    kind:        force a template, one of ``KINDS``: "humanoid", "quadruped", "winged", "hand" or "chains" (None: the
                 best fit). A forced body plan is built whatever its score; ValueError when the shape has no
                 extremities for it (five for a humanoid, quadruped or winged body; six for a hand: a wrist and five
                 fingers). A winged body's wings get an arm's bones (shoulder, upper_arm, forearm, hand: a bird's
                 humerus, radius and ulna, hand).
    up:          the world's up direction in the volume's frame (x, y, z), when known (e.g. the scene's +Z). A
                 humanoid's spine must then point up and a quadruped's limbs down. None: inferred.
    own_scale:   False rigs ``points`` and ``tree`` themselves (the rig then depends on how many points were kept):
                 for thin, fragmented objects (bones without flesh) whose thin parts autorig's own skeleton, at 1%
                 of the voxels, loses.
    markers:     {name: (x, y, z) world point} for any of ``MARKER_NAMES`` (``{"chin": p, "wrist.L": p, ...}``):
                 points the user marked on the object. Each must lie nearest the limb (or head, or pelvis) its name
                 gives in the body plan chosen, and the marked joints move to them (a chin: the head joint; a
                 groin: the hips' root; a knee or elbow marked on one side only sets the other's at the same
                 share of its limb). With markers a body plan always wins over neutral chains; VolrigError when none meets them.
    plan_weights: the body-plan penalties' weights (``PLAN_TERMS`` then chains' score; None: the fitted ones,
                 ``PLAN_WEIGHTS``, or ``bone_plan_weights()`` for a plan read from the bone), for fitting and
                 cross-validating them.
    bone:        the scan's bone tissue (a bool Volume or array on the mask's grid, z, y, x), when known: a
                 humanoid's or quadruped's limb joints then move to the articulations the bones show
                 (``volrig.bones.rig_to_bones``; ``rig.bone_joints`` says which moved, and how). When the
                 flesh is missing (``BARE_BONE_SHARE`` of the outer surface or more is bone), the body plan is read
                 from the bone grown into a body (``volrig.bones.bone_body``), its head the skull (the thickest
                 end: ``bone_plan_weights``), and ``rig.note`` says so. None: the rig from the outer shape alone.
    When no body plan fits, the rig is neutral chains and ``rig.note`` says so.
    """
    return autorig_fit(points, tree, mask, bones=bones, prune_scale=prune_scale, tolerance=tolerance, roles=roles,
                       progress=progress, detail=detail, kind=kind, up=up, own_scale=own_scale, markers=markers,
                       plan_weights=plan_weights, bone=bone)[0]


def autorig_fit(points: SkeletonPoints, tree: SkeletonTree, mask, bones: Optional[int] = None,
                prune_scale: float = 1.5, tolerance: float = 0.35, roles: bool = True, progress: ProgressFn = None,
                detail: Optional[list] = None, kind: Optional[str] = None, up=None, own_scale: bool = True,
                markers: Optional[dict] = None, plan_weights=None, bone=None):
    """``autorig`` (the same arguments), returning (rig, ``volrig.bones.BonesFit`` or None without ``bone``): the
    fit's segments are what ``pipeline.rig_skeleton`` binds rigidly."""
    ijk, radii = _point_arrays(points)
    arr = _mask_for(points, mask)
    if not isinstance(tree, SkeletonTree):
        raise TypeError(f"tree must be a SkeletonTree (from skeleton_tree), got {type(tree).__name__}")
    if len(tree.component) != len(points):
        raise VolrigError(f"the tree has {len(tree.component)} points but {len(points)} points were given")
    if up is not None:  # bones, kind and up are checked by the core
        up = tuple(float(u) for u in np.asarray(up, dtype=np.float64).reshape(3))
    plan = _Plan(arr, points, ijk, radii, tree.edges, own_scale)
    if bone is not None:
        _mask_for(points, bone)  # the same geometry as the skeleton's
        plan = _plan_from_bones(plan, bone)
    weights = plan.weights if plan_weights is None else plan_weights
    d = _volrig.autorig(plan.mask, points.spacing, points.origin, plan.ijk, plan.radii, plan.edges, int(bones or 0),
                        float(prune_scale), float(tolerance), bool(roles), kind or "", up, bool(plan.own_scale),
                        progress, _markers(markers), [] if weights is None else [float(w) for w in weights],
                        detail is not None)
    d["joint_points"] = plan.joint_points(d["joint_points"])
    if detail is not None:
        detail.append(AutorigResult(d["kept"], int(d["root"]), d["nodes"], d["node_radius"], d["node_edges"],
                                    d["node_kept"], list(d["reading_kind"]), d["reading_features"],
                                    float(d["chains_fit"]), d["reading_leaves"]))
    rig = Rig(d["joints"], d["bones"], d["names"], d["parents"], d["kind"], d["joint_points"], float(d["fit"]),
              np.asarray(d["up"]), float(d["up_confidence"]), d["runner_up"], float(d["runner_up_fit"]),
              "; ".join(n for n in (plan.note, d["note"]) if n))
    if bone is None:
        return rig, None
    from .bones import rig_to_bones  # the bones' module builds on Rig
    fit = rig_to_bones(rig, bone, like_shape=arr.shape)
    return fit.rig, fit


@dataclass
class _Plan:
    """What autorig reads the body plan from: the mask, and the skeleton points and tree given with it."""
    mask: np.ndarray
    points: SkeletonPoints
    ijk: np.ndarray
    radii: np.ndarray
    edges: np.ndarray
    own_scale: bool
    note: str = ""
    user_points: Optional[SkeletonPoints] = None  # set when the plan's points are not the caller's
    weights: Optional[List[float]] = None  # the plan weights when not the fitted ones (bone_plan_weights)

    def joint_points(self, jp: np.ndarray) -> np.ndarray:
        """The rig's joint points as indices into the caller's points (the nearest of them; -1 stays)."""
        if self.user_points is None:
            return jp
        out = np.full(len(jp), -1, dtype=np.int64)
        theirs = self.user_points.centers
        for k, p in enumerate(jp):
            if p >= 0 and len(theirs):
                d = theirs - self.points.centers[p]
                out[k] = int(np.argmin(np.einsum("ij,ij->i", d, d)))
        return out


#: Skeleton points the grown bone is rigged with (autorig rigs its own skeleton of it: these only place
#: ``joint_points``, mapped back to the caller's points).
_BONE_BODY_POINTS = 2000


def _plan_from_bones(plan: _Plan, bone) -> _Plan:
    """``plan``, or, when the flesh is missing (``BARE_BONE_SHARE`` of the outer surface or more is bone), the
    bone grown into a body (``volrig.bones.bone_body``) rigged at autorig's own scale."""
    from .bones import bare_bone_share, bone_body  # the bones' module builds on Rig
    from .skeleton import skeletonize
    from .tree import skeleton_tree
    share = bare_bone_share(plan.mask, bone)
    if share < BARE_BONE_SHARE:
        return plan
    body, radius, _ = bone_body(bone)
    pts = skeletonize(body).top(_BONE_BODY_POINTS)
    ijk, radii = _point_arrays(pts)
    note = f"body plan from the bones ({share:.0%} of the surface is bare bone; the bone grown by {radius:.1f} mm)"
    return _Plan(_mask_for(pts, body), pts, ijk, radii, skeleton_tree(pts, body).edges, True, note, plan.points,
                 bone_plan_weights())


def _markers(markers) -> dict:
    """``markers`` as {name: (x, y, z) floats}; names and finiteness are checked by the core."""
    if not markers:
        return {}
    if not isinstance(markers, dict):
        raise TypeError(f"markers must be a dict of name -> (x, y, z), got {type(markers).__name__}")
    out = {}
    for name, p in markers.items():
        q = np.asarray(p, dtype=np.float64).reshape(-1)
        if q.shape != (3,):
            raise VolrigError(f"marker {name!r} must be a point (x, y, z), got {np.shape(p)}")
        out[str(name)] = tuple(float(v) for v in q)
    return out


@dataclass
class Binding:
    """Skeleton points bound to bones.

    bone:        (N,) int32 owning bone of each point (the heaviest in smooth mode).
    weights:     (N, B) scipy.sparse CSR matrix of weights (rows sum to 1): one-hot in rigid mode; up to three
                 bones per point in smooth mode. Without scipy, a ``volrig._optional.CSR`` holding the same arrays
                 (``data``, ``indices``, ``indptr``; ``tocsr``, ``tocsc``, ``to_scipy``).
    mode:        "rigid" or "smooth".
    unreachable: (N,) bool: points that no bone reaches inside the object (bound to the nearest bone in a straight
                 line instead; e.g. fragments separate from the rigged part).
    bone_names:  the rig's bone names, for reference.
    rigid:       None, or the tissue that must not bend (bool, on the mask's grid, z, y, x) the binding was made
                 with (``bind(..., rigid=)``): deforming draws it as a rigid layer (``volrig.rigid_layer``).
    rigid_whole: every 26-connected component of ``rigid`` moves whole, with the bone that carries most of it in the
                 rest frame (a rig from the bones: its segments, parted, ``volrig.pipeline.rig_skeleton(bone=)``).
                 False: each rigid voxel moves with the bone whose sphere covers it at rest.
    """

    bone: np.ndarray
    weights: "object"
    mode: str
    unreachable: np.ndarray
    bone_names: List[str] = field(default_factory=list)
    rigid: Optional[np.ndarray] = None
    rigid_whole: bool = False

    def __len__(self) -> int:
        return len(self.bone)

    def points_of(self, bone) -> np.ndarray:
        """Indices of the points owned by ``bone`` (an index or a name)."""
        b = self.bone_names.index(bone) if isinstance(bone, str) else int(bone)
        return np.flatnonzero(self.bone == b)

    def reassign(self, points, bone) -> "Binding":
        """A copy with ``points`` (indices or a boolean mask) bound to ``bone`` (index or name) alone, as weight
        painting does."""
        b = self.bone_names.index(bone) if isinstance(bone, str) else int(bone)
        nb = self.weights.shape[1]
        if not 0 <= b < nb:
            raise IndexError(f"bone {b} out of range (the rig has {nb} bones)")
        idx = np.asarray(points)
        idx = np.flatnonzero(idx) if idx.dtype == np.bool_ else idx.astype(np.int64).reshape(-1)
        if len(idx) and (idx.min() < 0 or idx.max() >= len(self.bone)):
            raise IndexError(f"point indices must lie in 0..{len(self.bone) - 1}")
        data, cols, indptr = _canonical(self.weights)
        rows = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
        painted = np.zeros(len(indptr) - 1, dtype=bool)
        painted[idx] = True
        keep = ~painted[rows]
        w = _optional.csr_from_coo(np.concatenate([data[keep], np.ones(int(painted.sum()), data.dtype)]),
                                   np.concatenate([rows[keep], np.flatnonzero(painted)]),
                                   np.concatenate([cols[keep], np.full(int(painted.sum()), b, cols.dtype)]),
                                   self.weights.shape, dtype=np.float32)
        owner = self.bone.copy()
        owner[idx] = b
        unreachable = self.unreachable.copy()
        unreachable[idx] = False
        return Binding(owner, w, self.mode, unreachable, list(self.bone_names), self.rigid, self.rigid_whole)

    def groups(self):
        """The weights bone by bone, as vertex groups hold them: a list over bones of (point indices int64,
        weights float32), only non-zero weights."""
        w = self.weights.tocsc()
        w.eliminate_zeros()
        return [(w.indices[w.indptr[b]:w.indptr[b + 1]].astype(np.int64),
                 w.data[w.indptr[b]:w.indptr[b + 1]].astype(np.float32)) for b in range(w.shape[1])]

    @classmethod
    def from_groups(cls, groups, bone_names: Sequence[str], count: int, fallback: Optional["Binding"] = None) \
            -> "Binding":
        """The binding painted weights describe (the inverse of ``groups``).

        groups:     mapping bone name -> (point indices, weights), e.g. read from vertex groups; names that are
                    not bones are ignored, bones without a group get no weight.
        bone_names: the rig's bones, in order; count: the number of points.
        fallback:   the binding to keep for points left without any weight (else they are an error); its rigid
                    tissue is kept too.
        Rows are normalised to sum to 1; the owner is the heaviest bone; mode is "rigid" when every point has one
        bone, else "smooth".
        """
        names = [str(n) for n in bone_names]
        rows, cols, vals = [], [], []
        for b, name in enumerate(names):
            if name not in groups:
                continue
            idx, w = groups[name]
            idx = np.asarray(idx, dtype=np.int64).reshape(-1)
            w = np.asarray(w, dtype=np.float64).reshape(-1)
            if len(idx) != len(w):
                raise VolrigError(f"group {name!r}: {len(idx)} indices but {len(w)} weights")
            if len(idx) and (idx.min() < 0 or idx.max() >= count):
                raise IndexError(f"group {name!r} refers to points outside 0..{count - 1}")
            if not np.isfinite(w).all() or (w < 0).any():
                raise VolrigError(f"group {name!r} has negative or non-finite weights")
            keep = w > 0
            rows.append(idx[keep])
            cols.append(np.full(int(keep.sum()), b, dtype=np.int64))
            vals.append(w[keep])
        nb = len(names)
        cat = (lambda parts, dt: np.concatenate(parts) if parts else np.zeros(0, dt))
        rows, cols, vals = cat(rows, np.int64), cat(cols, np.int64), cat(vals, np.float64)
        total = np.bincount(rows, weights=vals, minlength=count) if count else np.zeros(0)
        empty = np.flatnonzero(total <= 0)
        unreachable = np.zeros(count, dtype=bool)
        if len(empty):
            if fallback is None:
                raise VolrigError(f"{len(empty)} of {count} points have no weight on any bone")
            if len(fallback) != count or fallback.weights.shape[1] != nb:
                raise VolrigError(f"the fallback binding ({fallback.weights.shape}) does not match {count} points "
                                 f"and {nb} bones")
            fdata, fcols, findptr = _canonical(fallback.weights)
            frows = np.repeat(np.arange(count), np.diff(findptr))
            take = np.isin(frows, empty)
            rows, cols = np.concatenate([rows, frows[take]]), np.concatenate([cols, fcols[take].astype(np.int64)])
            vals = np.concatenate([vals, fdata[take].astype(np.float64)])
            unreachable[empty] = fallback.unreachable[empty]
        data, indices, indptr = _optional.coo_arrays(vals, rows, cols, (count, nb))
        per_row = np.diff(indptr)
        row_of = np.repeat(np.arange(count), per_row)
        total = np.bincount(row_of, weights=data, minlength=count)
        data = (data * (1.0 / total)[row_of]).astype(np.float32)
        w = _optional.csr_matrix(data, indices, indptr, (count, nb), dtype=np.float32)
        # the heaviest bone of each row, the first (lowest column) of equal ones
        order = np.lexsort((-data, row_of))
        owner = indices[order[indptr[:-1]]].astype(np.int32) if count else np.zeros(0, np.int32)
        mode = "rigid" if (per_row <= 1).all() else "smooth"
        return cls(owner, w, mode, unreachable, names, None if fallback is None else fallback.rigid,
                   fallback is not None and fallback.rigid_whole)


def _canonical(weights):
    """(data, column indices, indptr) of a CSR weights matrix (scipy's or a CSR), rows sorted by column and
    duplicates summed, as scipy's ``sum_duplicates`` leaves them."""
    w = weights.tocsr()
    rows = np.repeat(np.arange(w.shape[0]), np.diff(w.indptr))
    return _optional.coo_arrays(np.asarray(w.data), rows, np.asarray(w.indices), w.shape)


def weights_matrix(weight_bones: np.ndarray, weights: np.ndarray, bone_count: int):
    """(N, B) CSR matrix from up to three (bone, weight) pairs per point (bone -1 = unused)."""
    n = len(weight_bones)
    rows = np.repeat(np.arange(n), weight_bones.shape[1])
    cols = weight_bones.reshape(-1)
    vals = weights.reshape(-1)
    keep = cols >= 0
    return _optional.csr_from_coo(vals[keep], rows[keep], cols[keep], (n, bone_count), dtype=np.float32)


def bind(points: SkeletonPoints, rig: Rig, mask, mode: str = "rigid", progress: ProgressFn = None,
         rigid=None) -> Binding:
    """Binds every skeleton point to the bone that owns it.

    The owner is the bone nearest by geodesic distance inside the object: along a straight line to the bone's
    closest point when that line stays inside the object, otherwise along the contained neighbour graph from points
    that have one (so a hand resting on a thigh binds to the arm). ``mode="smooth"`` adds weights across each joint:
    within one radius of the joint plane the neighbouring bone takes up to half (summing to 1 with the owner).

    ``rigid``: tissue that must not bend (a bool Volume or array on the mask's grid; ``rigid_tissue`` makes one
    from label values or a value range of the source). Points on it move with one bone alone (weight 1): a
    26-connected rigid component wholly with the bone holding 90% of its points' ball volume, one spanning joints
    (bones touching in the label map; other bones' points past the joint region, more than two ball radii or a
    quarter of their bone beyond the joint's plane, holding 1% of its ball volume) point by point with each point's
    own bone. Only soft tissue blends.
    """
    ijk, radii = _point_arrays(points)
    arr = _mask_for(points, mask)
    rigid_arr = None
    if rigid is not None:
        rigid_arr = _mask_for(points, rigid)
        if rigid_arr.shape != arr.shape:
            raise VolrigError(f"rigid tissue of shape {rigid_arr.shape} does not lie on the mask's grid {arr.shape}")
    bone, wb, w, unreachable = _volrig.bind(arr, points.spacing, points.origin, ijk, radii, rig.joints, rig.bones,
                                            rig.names, rig.parents, mode, progress, rigid_arr)
    return Binding(bone, weights_matrix(wb, w, len(rig.bones)), mode, unreachable, list(rig.names),
                   _rigid_kept(rigid, rigid_arr))


def _rigid_kept(rigid, arr: Optional[np.ndarray]) -> Optional[np.ndarray]:
    """The rigid tissue a binding keeps: the caller's bool array itself (not copied: a Visible Human at 1 mm is
    480 MB), None when there is none."""
    if arr is None or not arr.any():
        return None
    given = rigid.array if isinstance(rigid, Volume) else np.asarray(rigid)
    return given if given.dtype == np.bool_ and given.flags.c_contiguous else arr != 0


def rigid_tissue(source: Volume, labels=None, value_range=None) -> Volume:
    """The voxels of ``source`` that must not bend, as a bool Volume for ``bind(..., rigid=...)``: those whose value
    is one of ``labels`` (a label map's bone codes, e.g. the Visible Human's 84 and 92), or lies in
    ``value_range`` = (low, high) inclusive (a CT's bone, e.g. (300, 3000) HU). Exactly one of the two."""
    if (labels is None) == (value_range is None):
        raise VolrigError("rigid_tissue: give labels or value_range (one of them)")
    arr = np.asarray(source.array)
    if labels is not None:
        values = np.asarray(list(labels))
        if values.size == 0:
            raise VolrigError("rigid_tissue: no labels given")
        out = np.isin(arr, values)
    else:
        lo, hi = (float(v) for v in value_range)
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise VolrigError(f"rigid_tissue: value_range must be finite with low <= high, got {value_range}")
        out = (arr >= lo) & (arr <= hi)
    return source.like(out)

"""Issue 16's acceptance criteria for volrig.autorig, on the shared subjects (volrig_support.subjects).

Default run: phantom at scales 0.5 and 1, the meshes, the Visible Human at 4 and 2 mm, the 24 rotations of the
phantom. VOLRIG_SLOW=1 adds the phantom at scale 2, the Visible Human at 1 mm and the 24 rotations of the meshes.
Criteria the current autorig does not meet yet are marked xfail (strict=False) with the reason; remove the mark
when it is met.
Skeletons are computed once per subject (module-scoped cache).
"""
import inspect
import os

import numpy as np
import pytest

from conftest import SHARED_DATA

import volrig
from volrig_support import subjects as S

SLOW = os.environ.get("VOLRIG_SLOW") == "1"
slow = pytest.mark.skipif(not SLOW, reason="slow: set VOLRIG_SLOW=1")
needs_data = pytest.mark.skipif(not SHARED_DATA.exists(),
                                reason=f"real data not available: {SHARED_DATA} (../shared/data beside the checkout)")

RIGIFY = ["hips", "spine", "chest", "neck", "head"] + [f"{b}.{s}" for s in "LR" for b in (
    "shoulder", "upper_arm", "forearm", "hand", "pelvis", "thigh", "shin", "foot")]
LIMB_JOINTS = S.LIMB_JOINTS
POINTS = 15000


def xfail(why):
    return pytest.mark.xfail(strict=False, reason=f"issue 16: {why}")


def autorig(pts, tree, mask, up=None):
    """volrig.autorig, passing up= only when it accepts it."""
    if up is not None and "up" in inspect.signature(volrig.autorig).parameters:
        return volrig.autorig(pts, tree, mask, up=np.asarray(up, dtype=np.float64))
    return volrig.autorig(pts, tree, mask)


_CACHE = {}


def subject(name, **kw):
    """A subject and its skeleton, computed once per test module run."""
    key = (name, tuple(sorted(kw.items())))
    if key not in _CACHE:
        if name.startswith("vhm") or name in S.MESHES:
            if not SHARED_DATA.exists():
                pytest.skip(f"real data not available: {SHARED_DATA}")
        s = S.load_subject(name, **kw)
        _CACHE[key] = (s, volrig.skeletonize(s.mask))
    return _CACHE[key]


def rig_of(name, points=POINTS, **kw):
    """The subject, its skeleton and its rig from ``points`` skeleton points (the subject's up passed), cached."""
    s, sk = subject(name, **kw)
    key = ("rig", name, points, tuple(sorted(kw.items())))
    if key not in _CACHE:
        pts = sk.top(points)
        _CACHE[key] = autorig(pts, volrig.skeleton_tree(pts, s.mask), s.mask, s.up)
    return s, sk, _CACHE[key]


@pytest.fixture(scope="module", autouse=True)
def _free_cache():
    yield
    _CACHE.clear()


def limb_error(s, sk, rig, name):
    """Distance from the rig's joint to the reference joint, in local radii (inf when the bone is missing)."""
    q = S.rig_joint(rig, name)
    if q is None:
        return np.inf
    return float(np.linalg.norm(q - s.joints[name])) / S.local_radius(sk.dt, s.mask, s.joints[name])


# ---- the phantom -------------------------------------------------------------------------------------------------

def phantom_cases(failing):
    """(scale, points) cases; those in ``failing`` marked xfail (the current autorig misses them)."""
    cases = [(0.5, n) for n in (5000, 15000, 40000, 100000)] + [(1.0, n) for n in (5000, 40000, 100000)]
    out = [pytest.param(*c, marks=xfail(f"phantom {c[0]} with {c[1]} points: {failing[c]}")) if c in failing
           else c for c in cases]
    return out + [pytest.param(2.0, n, marks=slow) for n in (5000, 100000)]


@pytest.mark.parametrize("scale,points", phantom_cases({}))
def test_phantom_humanoid_with_rigify_bones(scale, points):
    s, sk, rig = rig_of("phantom", points, scale=scale)
    assert rig.kind == "humanoid"
    assert sorted(rig.names) == sorted(RIGIFY)


@pytest.mark.parametrize("scale,points", phantom_cases({}))
def test_phantom_elbows_and_knees_within_a_limb_radius(scale, points):
    s, sk, rig = rig_of("phantom", points, scale=scale)
    errors = {n: limb_error(s, sk, rig, n) for n in ("elbow.L", "elbow.R", "knee.L", "knee.R")}
    assert max(errors.values()) <= 1.0, errors


# ---- rotations ---------------------------------------------------------------------------------------------------

def rotation_failures(name, points=POINTS, **kw):
    """For each of the 24 rotations: problems with the rig of the rotated mask (matching up passed) and the kind
    with up=None."""
    s, sk, rig0 = rig_of(name, points, **kw)
    bad = []
    for k, m in enumerate(S.rotations24()):
        vol, to_rot = S.rotate_mask(s.mask, m)
        pts = volrig.skeletonize(vol).top(points)
        tree = volrig.skeleton_tree(pts, vol)
        rig = autorig(pts, tree, vol, m @ s.up)
        worst = S.rig_difference(rig0, rig, to_rot, lambda p: S.local_radius(sk.dt, s.mask, p, S.SAME_JOINT_VOXELS))
        if rig.kind != s.kind or worst > 0.5:
            bad.append(f"rotation {k}: {rig.kind}, {len(rig)} bones, {worst:.2f} radii off")
        free = autorig(pts, tree, vol, None)
        if free.kind != s.kind:
            bad.append(f"rotation {k}, up=None: {free.kind}")
    return bad


@pytest.mark.parametrize("name", [
    "phantom",
    pytest.param("cow", marks=slow),
    pytest.param("knight", marks=slow),
    pytest.param("hand", marks=slow),
    pytest.param("horse", marks=slow),
    pytest.param("camel", marks=slow),
    pytest.param("arm", marks=slow),
    pytest.param("lion", marks=[slow, xfail("9/24 rotations give the lion head's rig (a thin shell: chains); "
                                            "with up=None none is called chains")]),
])
def test_24_rotations_give_the_same_rig_rotated(name):
    bad = rotation_failures(name, scale=0.5) if name == "phantom" else rotation_failures(name)
    assert not bad, "; ".join(bad[:8]) + (f" (+{len(bad) - 8} more)" if len(bad) > 8 else "")


# ---- meshes ------------------------------------------------------------------------------------------------------

def test_knight_humanoid_head_up():
    s, sk, rig = rig_of("knight")
    assert rig.kind == "humanoid"
    head = rig.bones[rig.names.index("head")]
    assert (rig.joints[head[1]] - rig.joints[head[0]]) @ s.up > 0
    assert rig.joints[head[1]] @ s.up >= (rig.joints @ s.up).max() - 1e-9, "the head is not the top"


def leaf_tails(rig):
    """Tails of the bones without children."""
    parents = set(int(p) for p in rig.parents if p >= 0)
    return np.array([rig.joints[rig.bones[b][1]] for b in range(len(rig)) if b not in parents])


def tgf_errors(s, sk, rig):
    """Each TGF joint's distance to the nearest rig joint, in local radii."""
    return np.array([np.linalg.norm(rig.joints - p, axis=1).min() / S.local_radius(sk.dt, s.mask, p)
                     for p in s.joints.values()])


def fingertips(s):
    """The TGF joints that end a chain (degree 1, not the root joint j0)."""
    deg = np.bincount(s.bones.ravel(), minlength=len(s.joints))
    return [f"j{i}" for i in range(1, len(s.joints)) if deg[i] == 1]


def test_hand_five_finger_chains_and_joints():
    s, sk, rig = rig_of("hand")
    assert rig.kind == "hand" and len(rig) == 16, rig
    tips = fingertips(s)
    assert len(tips) == 5
    leaves = leaf_tails(rig)
    chosen = set()
    for t in tips:
        p = s.joints[t]
        d = np.linalg.norm(leaves - p, axis=1) / S.local_radius(sk.dt, s.mask, p)
        k = int(np.argmin(d))
        assert d[k] <= 2.0 and k not in chosen, f"no chain of its own ends at finger tip {t}"
        chosen.add(k)
    errors = tgf_errors(s, sk, rig)
    assert (errors <= 2.0).mean() >= 0.9, f"{(errors <= 2.0).sum()}/{len(errors)} joints within 2 local radii"


@xfail("arm joints: 4 of arm.tgf's 5 within 1 local radius, the last 1.5")
def test_arm_joints_on_tgf():
    s, sk, rig = rig_of("arm")
    errors = tgf_errors(s, sk, rig)
    assert errors.max() <= 1.0, f"TGF joint errors in local radii: {np.round(errors, 2)}"


@pytest.mark.parametrize("name", [
    "cow",
    pytest.param("horse", marks=xfail("horse_quad.obj has no tail (a round rump): the criterion cannot hold on it")),
    "camel",
])
def test_quadruped_head_at_head_end_and_tail_chain(name):
    s, sk, rig = rig_of(name)
    bad = S.quadruped_problems(s, rig)
    assert not bad, f"{name}: " + "; ".join(bad)


COW_120 = pytest.mark.xfail(strict=False, reason="the cow at 120 voxels is read back to front (since the weights "
                            "fitted with the cross-section flatness, 2026-12-07; the camel at 240, read back to front "
                            "before, is right since); docs/rig.md, Known limits")


@pytest.mark.parametrize("name, voxels", [(n, v) for n in ("cow", "horse", "camel") for v in (120, 240)
                                          if (n, v) != ("cow", 120)] + [pytest.param("cow", 120, marks=COW_120)])
def test_quadruped_kind_and_head_end_at_other_voxel_sizes(name, voxels):
    """The kind must not depend on the voxel size (issue 16: an elephant was humanoid at one size and quadruped at
    another); the tail too, where the mesh has one."""
    s, sk, rig = rig_of(name, voxels=voxels)
    bad = [b for b in S.quadruped_problems(s, rig) if name != "horse" or "tail" not in b]
    assert not bad, f"{name} at {voxels} voxels: " + "; ".join(bad)


def test_lion_is_only_a_head():
    """lion.off is a head (a bust open at the neck), not a quadruped: issue 16's lion criterion cannot hold on it;
    this checks the shape really is head-only (longest extent < 1.5x the shortest), so the subject is known."""
    s, _ = subject("lion")
    ext = np.ptp(np.argwhere(s.mask.array), axis=0)
    assert ext.max() < 1.5 * ext.min()


# ---- the Visible Human -------------------------------------------------------------------------------------------

_VHM_JOINTS = {}


def vhm_rig(mm):
    s, sk, rig = rig_of(f"vhm{mm}", joints=False)
    if mm not in _VHM_JOINTS:
        _VHM_JOINTS[mm] = S.visible_human_joints(S.visible_human_labels(mm))
    s.joints = _VHM_JOINTS[mm]
    return s, sk, rig


VHM = [4, 2, pytest.param(1, marks=slow)]


@needs_data
@pytest.mark.parametrize("mm", VHM)
def test_vhm_humanoid_with_separate_arm_chains(mm):
    s, sk, rig = vhm_rig(mm)
    assert rig.kind == "humanoid"
    # The 21 Rigify bones and nothing else: the curled fingers of a hand resting on the pelvis go with the hand
    # (a humanoid's parts at its hands are chains only when they stick out farther than the hand is long).
    assert sorted(rig.names) == sorted(RIGIFY), sorted(set(rig.names) ^ set(RIGIFY))
    for side in "LR":
        chain, b = [], rig.names.index(f"hand.{side}")
        while b >= 0:
            chain.append(rig.names[b])
            b = int(rig.parents[b])
        assert chain[:4] == [f"{n}.{side}" for n in ("hand", "forearm", "upper_arm", "shoulder")], chain
        assert "pelvis" not in " ".join(chain) and "thigh" not in " ".join(chain), chain
        # nothing of the body hangs from the hand (joined to the pelvis?)
        hand = rig.names.index(f"hand.{side}")
        assert not [rig.names[k] for k in range(len(rig)) if int(rig.parents[k]) == hand]
        # the chain runs down its own arm (not round the arm-pelvis loop): elbow and wrist within 10 cm
        for joint in ("elbow", "wrist"):
            d = np.linalg.norm(S.rig_joint(rig, f"{joint}.{side}") - s.joints[f"{joint}.{side}"])
            assert d <= 100.0, f"{joint}.{side} is {d:.0f} mm from the bone-derived one"


@needs_data
@pytest.mark.parametrize("mm", VHM)
def test_vhm_limb_joints_within_two_local_radii(mm):
    """Every limb joint within two local radii of the bone-derived one; wrists (at their neck, the hands resting on
    the pelvis) and ankles (above the heel) within 3 cm."""
    s, sk, rig = vhm_rig(mm)
    radii = {name: S.local_radius(sk.dt, s.mask, s.joints[name]) for name in LIMB_JOINTS}
    errors = {name: float(np.linalg.norm(S.rig_joint(rig, name) - s.joints[name])) for name in LIMB_JOINTS}
    assert all(errors[n] <= 2.0 * radii[n] for n in LIMB_JOINTS), {n: round(errors[n] / radii[n], 2) for n in errors}
    for side in "LR":
        for joint in ("wrist", "ankle"):
            assert errors[f"{joint}.{side}"] <= 30.0, f"{joint}.{side}: {errors[f'{joint}.{side}']:.0f} mm"


@needs_data
@pytest.mark.parametrize("mm", VHM)
def test_vhm_limb_joints_within_3cm_of_bone_joints(mm):
    s, sk, rig = vhm_rig(mm)
    errors = {}
    for name in LIMB_JOINTS:
        q = S.rig_joint(rig, name)
        errors[name] = np.inf if q is None else round(float(np.linalg.norm(q - s.joints[name])), 1)
    assert max(errors.values()) <= 30.0, errors


@needs_data
def test_vhm_same_rig_across_resolutions():
    resolutions = (4, 2, 1) if SLOW else (4, 2)
    rigs = {mm: vhm_rig(mm)[2] for mm in resolutions}
    ref = rigs[resolutions[-1]]
    for mm, rig in rigs.items():
        assert rig.kind == ref.kind and sorted(rig.names) == sorted(ref.names), f"{mm} mm: {rig.kind} {rig.names}"
        for n, (h, t) in zip(ref.names, ref.bones):
            b = rig.bones[rig.names.index(n)]
            d = np.linalg.norm(rig.joints[b] - ref.joints[[h, t]], axis=1).max()
            assert d <= 30.0, f"{n} differs by {d:.0f} mm between {mm} mm and {resolutions[-1]} mm"

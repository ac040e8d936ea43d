"""autorig's choices on the phantom: kind forcing, a given or inferred up direction, the fit and the runner-up,
the same rig whatever the point count, and the same rig (rotated) under axis-aligned rotations."""
import itertools

import numpy as np
import pytest

import volrig
from volrig.rig import autorig
from volrig.tree import skeleton_tree
from volrig.volume import Volume

ROLE_BONES = {"hips", "spine", "chest", "neck", "head"} | {
    f"{b}.{s}" for s in "LR" for b in ("shoulder", "upper_arm", "forearm", "hand", "pelvis", "thigh", "shin", "foot")}
LIMB_JOINTS = (("elbow", "upper_arm", "forearm"), ("knee", "thigh", "shin"))


def joint_errors(ph, rig, transform=lambda p: p):
    """Distance of each elbow and knee from the phantom's, in units of the limb's radius there."""
    radius = {s.name: s.radius_a for s in ph.segments}
    out = {}
    for side in "LR":
        for joint, bone, seg in LIMB_JOINTS:
            got = rig.tails()[rig.index(f"{bone}.{side}")]
            out[f"{joint}.{side}"] = np.linalg.norm(got - transform(ph.joints[f"{joint}.{side}"])) / radius[f"{seg}.{side}"]
    return out


@pytest.fixture(scope="module")
def half(phantom_half):
    mask = volrig.segment(phantom_half.volume)
    sk = volrig.skeletonize(mask)
    pts = sk.top(15000)
    return phantom_half, mask, sk, pts, skeleton_tree(pts, mask)


def test_fit_runner_up_and_inferred_up_are_reported(half):
    ph, mask, sk, pts, tree = half
    rig = autorig(pts, tree, mask)
    assert rig.kind == "humanoid" and set(rig.names) == ROLE_BONES
    assert 0.8 <= rig.fit <= 1.0
    # The runner-up: the phantom read as a quadruped (no up given: nothing says its limbs do not hang down) or chains.
    assert rig.runner_up in ("quadruped", "chains") and 0.0 <= rig.runner_up_fit < rig.fit
    assert rig.up @ [0, 0, 1] > 0.99 and rig.up_confidence > 0.5  # the phantom stands along +z


def test_kind_is_forced_and_checked(half):
    ph, mask, sk, pts, tree = half
    chains = autorig(pts, tree, mask, kind="chains")
    assert chains.kind == "chains" and all(n.startswith("chain") for n in chains.names)
    assert autorig(pts, tree, mask, kind="humanoid").kind == "humanoid"
    quad = autorig(pts, tree, mask, kind="quadruped")  # forced: built whatever its score
    assert quad.kind == "quadruped" and set(quad.names) == ROLE_BONES
    with pytest.raises(ValueError, match="kind must be one of 'humanoid', 'quadruped', 'winged', 'hand', 'chains'"):
        autorig(pts, tree, mask, kind="dragon")
    assert "hand" in volrig.rig.KINDS
    # The phantom has five extremities, a hand needs six: a clear error, no crash.
    with pytest.raises(ValueError, match="no hand fits this shape"):
        autorig(pts, tree, mask, kind="hand")
    with pytest.raises(ValueError, match="up must be"):
        autorig(pts, tree, mask, up=(0, 0, 0))


def test_a_given_up_is_used_and_rules_out_an_upside_down_body(half):
    ph, mask, sk, pts, tree = half
    rig = autorig(pts, tree, mask, up=(0, 0, 2))
    assert rig.kind == "humanoid" and rig.up_confidence == 1.0
    np.testing.assert_allclose(rig.up, [0, 0, 1])
    # Told that up is -z, no humanoid reading of the phantom has its spine pointing up: not a humanoid.
    assert autorig(pts, tree, mask, up=(0, 0, -1)).kind != "humanoid"


def test_a_small_object_y_cannot_be_forced_into_a_body_plan():
    mask = np.zeros((60, 40, 40), np.uint8)
    mask[5:55, 17:23, 17:23] = 1
    mask[30:36, 17:23, 5:35] = 1
    pts = volrig.skeletonize(mask).at(0.3)
    with pytest.raises(ValueError, match="no humanoid body plan fits"):
        autorig(pts, skeleton_tree(pts, mask), mask, kind="humanoid")


def rotations():
    """The 24 axis-aligned rotations as (permutation, signs): new axis i = signs[i] * old axis perm[i]."""
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1, -1), repeat=3):
            R = np.zeros((3, 3))
            for i in range(3):
                R[i, perm[i]] = signs[i]
            if np.linalg.det(R) > 0:
                yield perm, signs, R


def rotate(mask, perm, signs):
    """The mask [z, y, x] rotated: (x, y, z) -> R (x, y, z), shifted back into the grid."""
    a = np.asarray(mask).transpose(2, 1, 0).transpose(perm)  # [x, y, z] then permuted
    for i, s in enumerate(signs):
        if s < 0:
            a = np.flip(a, axis=i)
    return np.ascontiguousarray(a.transpose(2, 1, 0))


def up_name(rot):
    u = rot[2] @ [0, 0, 1]
    i = int(np.argmax(np.abs(u)))
    return "up=" + ("+" if u[i] > 0 else "-") + "xyz"[i]


# One rotation per up direction (the six faces), each with the matching up and with up inferred.
SIX = [next(r for r in rotations() if np.allclose(r[2] @ [0, 0, 1], u)) for u in np.vstack([np.eye(3), -np.eye(3)])]


@pytest.mark.parametrize("rot", SIX, ids=up_name)
def test_rotating_the_phantom_rotates_its_rig(half, rot):
    ph, mask, sk, pts, tree = half
    perm, signs, R = rot
    arr = rotate(mask.array, perm, signs)
    new_dims = np.abs(R) @ np.asarray(mask.array.shape[::-1], float)  # (x, y, z)
    offset = np.where(R.sum(axis=1) < 0, new_dims - 1, 0)  # flipped axes shift back into the grid

    def transform(p):
        return R @ np.asarray(p) + offset

    vol = Volume(arr, mask.spacing, mask.origin)
    rpts = volrig.skeletonize(vol).top(15000)
    rtree = skeleton_tree(rpts, vol)
    up = R @ [0, 0, 1]
    for given in (up, None):
        rig = autorig(rpts, rtree, vol, up=given)
        assert rig.kind == "humanoid" and set(rig.names) == ROLE_BONES
        errs = joint_errors(ph, rig, transform)
        assert max(errs.values()) <= 1.0, errs
        # .L is still the character's left
        left = R @ [1, 0, 0]
        assert (rig.tails()[rig.index("hand.L")] - rig.tails()[rig.index("hand.R")]) @ left > 0
        assert rig.up @ up > 0.95


@pytest.fixture(scope="module")
def full():
    ph = volrig.phantom.humanoid(1.0)
    mask = volrig.segment(ph.volume)
    return ph, mask, volrig.skeletonize(mask)


def test_the_phantom_at_scale_1_gets_the_same_rig_whatever_the_point_count(full, half):
    ph, mask, sk = full
    rigs = []
    for n in (5000, 20000, 100000):
        pts = sk.top(n)
        rig = autorig(pts, skeleton_tree(pts, mask), mask)
        assert rig.kind == "humanoid" and set(rig.names) == ROLE_BONES, n
        assert max(joint_errors(ph, rig).values()) <= 1.0, (n, joint_errors(ph, rig))
        assert 0 <= rig.joint_points.max() < n
        rigs.append(rig)
    for r in rigs[1:]:
        assert r.names == rigs[0].names
        np.testing.assert_allclose(r.joints, rigs[0].joints)

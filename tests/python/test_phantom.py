"""The procedural humanoid phantom: grid, anatomy, symmetry, separation of the limbs, determinism.

Run: PYTHONPATH=python /usr/bin/python3 -m pytest tests/python/test_phantom.py
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from volrig import phantom
from volrig.phantom import BACKGROUND, BONE, FLESH, SKIN

CUBE = np.ones((3, 3, 3), bool)
JOINTS = ["hips", "spine", "chest", "neck", "head", "head_top"] + [
    f"{j}.{s}" for j in ("shoulder", "elbow", "wrist", "hand_tip", "hip", "knee", "ankle", "toe") for s in "LR"]
TORSO = ("chest", "abdomen", "pelvis")


@pytest.fixture(scope="module")
def full():
    return phantom.humanoid(scale=1.0)


@pytest.fixture(params=["half", "full"])
def ph(request, phantom_half, full):
    return phantom_half if request.param == "half" else full


def voxel(ph, name):
    """[z, y, x] index of a joint."""
    v = np.rint(ph.joints[name] / np.asarray(ph.volume.spacing)).astype(int)
    return v[2], v[1], v[0]


def test_dims_and_geometry(phantom_half, full):
    assert full.volume.dims == (290, 169, 940)
    assert full.volume.array.shape == (940, 169, 290)
    assert phantom_half.volume.dims == (145, 85, 470)
    for p in (full, phantom_half):
        assert p.volume.array.dtype == np.uint8
        assert p.volume.spacing == (1.0, 1.0, 1.0)
        assert p.volume.origin == (0.0, 0.0, 0.0)


def test_spacing_scales_world_units():
    a = phantom.humanoid(scale=0.25)
    b = phantom.humanoid(scale=0.25, spacing=2.5)
    np.testing.assert_array_equal(a.volume.array, b.volume.array)
    assert b.volume.spacing == (2.5, 2.5, 2.5)
    for name in JOINTS:
        np.testing.assert_allclose(b.joints[name], 2.5 * a.joints[name])
    sa, sb = a.segment("thigh.L"), b.segment("thigh.L")
    assert sb.radius_a == pytest.approx(2.5 * sa.radius_a)
    np.testing.assert_array_equal(a.segment_mask("thigh.L"), b.segment_mask("thigh.L"))
    with pytest.raises(ValueError):
        phantom.humanoid(scale=0)


def test_intensities(ph):
    assert set(np.unique(ph.volume.array).tolist()) == {BACKGROUND, SKIN, FLESH, BONE}


def test_proportions_fill_the_grid(full):
    a = full.volume.array
    body = a > 0
    zs = np.nonzero(body.any(axis=(1, 2)))[0]
    assert 905 <= zs.max() <= 925          # head top near 915
    assert 5 <= zs.min() <= 25             # soles near 15
    for side in "LR":
        xs = np.nonzero(full.segment_mask(f"hand.{side}").any(axis=(0, 1)))[0]
        assert xs.min() >= 15 and xs.max() <= 275
    fraction = body.mean()
    assert 0.20 <= fraction <= 0.30, fraction  # a real body is not thin
    assert 0.05 < (a == BONE).sum() / body.sum() < 0.25


def test_joints_present_and_inside_the_body(ph):
    assert set(JOINTS) <= set(ph.joints)
    a = ph.volume.array
    for name in JOINTS:
        assert a[voxel(ph, name)] >= FLESH, name  # flesh or bone, not skin or background


def test_bone_strictly_inside_flesh(ph):
    a = ph.volume.array
    bone = a == BONE
    outside = a < FLESH  # skin and background
    assert not (ndimage.binary_dilation(bone, CUBE) & outside).any()


def test_mirror_symmetry(ph):
    a = ph.volume.array
    np.testing.assert_array_equal(a, a[:, :, ::-1])
    width = (a.shape[2] - 1) * ph.volume.spacing[0]
    for name in JOINTS:
        if name.endswith(".L"):
            left, right = ph.joints[name], ph.joints[name[:-2] + ".R"]
            assert left[0] > width / 2  # .L is +x, the character's left (it faces -y)
            np.testing.assert_allclose([width - left[0], left[1], left[2]], right, atol=1e-9)


def test_segment_masks_mirror(phantom_half):
    ph = phantom_half
    for seg in ph.segments:
        if seg.name.endswith(".L"):
            np.testing.assert_array_equal(ph.segment_mask(seg.name)[:, :, ::-1], ph.segment_mask(seg.name[:-2] + ".R"))


def crop(mask: np.ndarray, pad: int):
    """Slices of the bounding box of `mask` grown by `pad` voxels."""
    idx = np.nonzero(mask)
    return tuple(slice(max(int(i.min()) - pad, 0), int(i.max()) + pad + 1) for i in idx)


def test_arms_clear_of_torso_and_legs(ph):
    torso = np.zeros(ph.volume.array.shape, bool)
    for name in TORSO + ("thigh.L", "thigh.R"):
        torso |= ph.segment_mask(name)
    scale = ph.volume.dims[0] / 290
    min_gap = max(2.0, 6 * scale)  # a visible gap at the elbow and hand: ~6 voxels * scale
    arms = {}
    for side in "LR":
        arm = np.zeros_like(torso)
        for part in ("upper_arm", "forearm", "hand"):
            arm |= ph.segment_mask(f"{part}.{side}")
        arms[side] = arm
        box = crop(arm, int(np.ceil(min_gap)) + 2)
        # the whole arm (upper arm included) stays clear: its 1-voxel dilation does not meet the torso
        assert not (ndimage.binary_dilation(arm[box], CUBE) & torso[box]).any(), side
        gap = ndimage.distance_transform_edt(~torso[box])
        lower = ph.segment_mask(f"forearm.{side}")[box] | ph.segment_mask(f"hand.{side}")[box]
        assert gap[lower].min() >= min_gap, gap[lower].min()
    box = crop(arms["L"], 2)
    assert not (ndimage.binary_dilation(arms["L"][box], CUBE) & arms["R"][box]).any()


def test_legs_apart_below_the_crotch(ph):
    a = ph.volume.array
    left = ph.segment_mask("thigh.L") | ph.segment_mask("shin.L") | ph.segment_mask("foot.L")
    right = ph.segment_mask("thigh.R") | ph.segment_mask("shin.R") | ph.segment_mask("foot.R")
    pelvis = ph.segment_mask("pelvis")
    crotch = np.nonzero(pelvis.any(axis=(1, 2)))[0].min()  # lowest slice of the pelvis
    hip_z = voxel(ph, "hip.L")[0]
    assert crotch < hip_z
    below = slice(0, crotch)
    assert not (ndimage.binary_dilation(left[below], CUBE) & right[below]).any()
    # and nothing else bridges them: below the crotch each slice's centre column is empty
    cx = (a.shape[2] - 1) / 2
    centre = a[below, :, int(np.floor(cx)):int(np.ceil(cx)) + 1]
    assert not centre.any()


def test_elbows_and_knees_between_their_neighbours(ph):
    for side in "LR":
        for upper, mid, lower in (("shoulder", "elbow", "wrist"), ("hip", "knee", "ankle")):
            a, m, b = (ph.joints[f"{j}.{side}"] for j in (upper, mid, lower))
            assert b[2] < m[2] < a[2], (upper, mid, lower)
            ab = b - a
            t = float((m - a) @ ab / (ab @ ab))
            assert 0.3 < t < 0.7
            off_line = np.linalg.norm(m - (a + t * ab))
            assert off_line < 0.15 * np.linalg.norm(ab)  # nearly straight limbs
        assert ph.joints[f"hand_tip.{side}"][2] < ph.joints[f"wrist.{side}"][2]
        assert ph.joints[f"toe.{side}"][1] < ph.joints[f"ankle.{side}"][1]  # toes point forward (-y)
    assert ph.joints["head_top"][2] > ph.joints["head"][2] > ph.joints["neck"][2] > ph.joints["chest"][2] \
        > ph.joints["spine"][2] > ph.joints["hips"][2]


def test_segments_and_masks(phantom_half):
    ph = phantom_half
    names = {s.name for s in ph.segments}
    for part in ("upper_arm", "forearm", "hand", "thigh", "shin", "foot"):
        assert {f"{part}.L", f"{part}.R"} <= names
    seg = ph.segment("upper_arm.L")
    assert (seg.joint_a, seg.joint_b) == ("shoulder.L", "elbow.L")
    assert seg.radius_a > seg.radius_b > 0
    m = ph.segment_mask("upper_arm.L")
    assert m.dtype == bool and m.shape == ph.volume.array.shape
    assert m[voxel(ph, "shoulder.L")] and m[voxel(ph, "elbow.L")]
    assert not m[voxel(ph, "wrist.L")]
    assert (ph.volume.array[m] > 0).all()  # the capsule is part of the body
    # voxel count against the cone-sphere's volume (frustum plus two half balls: close for a slight taper)
    ra, rb = seg.radius_a, seg.radius_b
    length = np.linalg.norm(ph.joints["elbow.L"] - ph.joints["shoulder.L"])
    expected = np.pi * length * (ra * ra + ra * rb + rb * rb) / 3 + 2 / 3 * np.pi * (ra ** 3 + rb ** 3)
    assert abs(m.sum() / expected - 1) < 0.05
    for e in ph.ellipsoids:
        em = ph.segment_mask(e.name)
        assert abs(em.sum() / (4 / 3 * np.pi * np.prod(e.radii)) - 1) < 0.03, e.name
    with pytest.raises(KeyError):
        ph.segment_mask("tail")


def test_deterministic(phantom_half):
    again = phantom.humanoid(scale=0.5)
    np.testing.assert_array_equal(again.volume.array, phantom_half.volume.array)
    for name in JOINTS:
        np.testing.assert_array_equal(again.joints[name], phantom_half.joints[name])
    assert again.segments == phantom_half.segments


def test_skeleton_fraction_scipy(phantom_half):
    """Euclidean thinness skeleton at TP 0.3, computed with scipy alone: about 2% of the object voxels."""
    mask = phantom_half.volume.array > 0
    dt = ndimage.distance_transform_edt(np.pad(mask, 1))[1:-1, 1:-1, 1:-1]
    kernel = np.ones((3, 3, 3))
    kernel[1, 1, 1] = 0
    mnt = ndimage.convolve(dt, kernel, mode="constant", cval=0.0) / 26
    kept = np.count_nonzero(mask & (dt - mnt > 0.3)) / mask.sum()
    assert 0.015 < kept < 0.025, kept

"""Autorig on real data: the frog (../shared/data/frogtissue) and the libigl arm mesh (../shared/data/meshes)."""
import numpy as np
import pytest

import volrig
from conftest import shared


def frog_rig(**kw):
    vol = volrig.load(str(shared("frogtissue/frogtissue.mhd")))
    mask = volrig.segment(vol)
    pts = volrig.skeletonize(mask).top(40000)
    # Organs and thin bones without flesh: the 40,000 points kept hold the thin leg bones (autorig's own skeleton,
    # 1% of the voxels, loses them: see docs/rig.md, Known limits).
    return volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask, own_scale=False, **kw)


@pytest.mark.xfail(strict=False, reason="issue 16: bones without flesh touch each other at their joints: the "
                   "level-set tree, cutting loops at weak links (right for bodies with skin), keeps the wrong "
                   "contacts; the frog comes out as chains (forced to a quadruped, its front feet land among the "
                   "hind legs)")
def test_frog_gets_four_legs_a_spine_and_a_head():
    rig = frog_rig()
    assert rig.kind == "quadruped"  # its legs do not point away from its head
    tip = lambda name: rig.tails()[rig.index(name)]  # noqa: E731
    # the frog lies along +x: snout near x = 470, hind feet at x < 200, front feet beside the trunk
    assert tip("head")[0] > 400
    for side in "LR":
        assert tip(f"foot.{side}")[0] < 200
        assert 230 < tip(f"hand.{side}")[0] < 380 and abs(tip(f"hand.{side}")[1] - 230) > 80
        for limb in (("upper_arm", "forearm", "hand"), ("thigh", "shin", "foot")):
            assert all(f"{b}.{side}" in rig.names for b in limb)
    assert {"hips", "spine", "chest"} <= set(rig.names)


def test_libigl_arm_joints_are_found():
    v, f = volrig.read_mesh(str(shared("meshes/arm.obj")))
    joints, edges = volrig.read_tgf(str(shared("meshes/arm.tgf")))
    mask = volrig.voxelize(v, f, 0.01)
    pts = volrig.skeletonize(mask).top(4000)
    # Lying along x in a scene whose up is +z, as the add-on passes it (without up, its shoulder end and fingers
    # pass for a small humanoid: benchmarks/fit_plan_weights.py, arm (no up)).
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask, up=(0, 0, 1))
    assert rig.kind == "chains"  # an arm with five fingers is no body plan
    assert "no body plan fits" in rig.note
    dt = volrig.distance_transform(mask)
    sp, org = np.asarray(mask.spacing), np.asarray(mask.origin)
    for j in joints:
        ijk = np.rint((j - org) / sp).astype(int)[::-1]
        lo, hi = np.maximum(ijk - 3, 0), ijk + 4
        local_radius = dt[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]].max()
        nearest = np.linalg.norm(rig.joints - j, axis=1).min()
        assert local_radius > 0.02
        assert nearest <= 2 * local_radius, (j, nearest, local_radius)
    # a rig, not a joint per voxel: the arm and five fingers need few bones
    assert len(rig) <= 24


def test_a_thin_shell_is_rigged_from_the_points_given():
    # lion.off is a head open at the back: voxelized as it is, only its shell (about 3,000 voxels) is object, and
    # autorig's own skeleton of it has no branch; autorig then rigs the points given instead of failing.
    v, f = volrig.read_mesh(str(shared("meshes/lion.off")))
    mask = volrig.voxelize(v, f, float(np.ptp(v, axis=0).max()) / 160)
    assert mask.array.sum() < 5000
    pts = volrig.skeletonize(mask).top(15000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask)
    assert len(rig) >= 4
    assert set(rig.joint_points[rig.joint_points >= 0]) <= set(range(len(pts)))

"""volrig_support.subjects: the shared rigging subjects and the Visible Human's bone-derived reference joints."""
import os

import numpy as np
import pytest

from conftest import shared

SLOW = os.environ.get("VOLRIG_SLOW") == "1"
NAMES = [f"{j}.{s}" for s in "LR" for j in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")]


@pytest.fixture(scope="module")
def vhm_joints():
    """Bone-derived joints at 4 and 2 mm (and 1 mm with VOLRIG_SLOW=1)."""
    shared("visible-human/austinman_4mm_labels.nii.gz")
    from volrig_support import subjects
    return {mm: subjects.visible_human_joints(subjects.visible_human_labels(mm))
            for mm in ((4, 2, 1) if SLOW else (4, 2))}


def test_vhm_joints_agree_across_resolutions(vhm_joints):
    ref = vhm_joints[2]
    assert sorted(ref) == sorted(NAMES)
    for mm, joints in vhm_joints.items():
        for name in NAMES:
            d = np.linalg.norm(joints[name] - ref[name])
            assert d < 10.0, f"{name} at {mm} mm is {d:.1f} mm from the 2 mm one"


def test_vhm_joints_anatomy(vhm_joints):
    for mm, j in vhm_joints.items():
        for base in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle"):
            left, right = j[base + ".L"], j[base + ".R"]
            assert left[0] > right[0] + 100, f"{base}: left not on +x at {mm} mm"
            mirrored = np.array([left[0] - right[0], left[1] - right[1], left[2] - right[2]])
            # symmetric: same height and depth within a few cm (the cadaver's pose is not perfectly symmetric)
            assert abs(mirrored[2]) < 40 and abs(mirrored[1]) < 40, f"{base} asymmetric at {mm} mm: {mirrored}"
        for s in "LR":
            z = {b: j[f"{b}.{s}"][2] for b in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")}
            # heights for a 1.8 m man standing, arms bent with the hands on the pelvis (mm above the soles)
            assert 1450 < z["shoulder"] < 1650 and 1150 < z["elbow"] < 1350 and 950 < z["wrist"] < 1200
            assert 880 < z["hip"] < 1050 and 450 < z["knee"] < 600 and 60 < z["ankle"] < 200
            for a, m, b in (("shoulder", "elbow", "wrist"), ("hip", "knee", "ankle")):
                pa, pm, pb = (j[f"{n}.{s}"] for n in (a, m, b))
                t = (pm - pa) @ (pb - pa) / ((pb - pa) @ (pb - pa))
                assert 0.2 < t < 0.8, f"{m}.{s} not between {a} and {b} at {mm} mm"
            # segment lengths (mm): humerus ~300-370, forearm ~230-290, femur ~420-500, tibia ~360-450
            L = lambda a, b: np.linalg.norm(j[f"{a}.{s}"] - j[f"{b}.{s}"])  # noqa: E731
            assert 280 < L("shoulder", "elbow") < 380 and 200 < L("elbow", "wrist") < 300
            assert 400 < L("hip", "knee") < 520 and 340 < L("knee", "ankle") < 460


def test_vhm_joints_need_bone():
    from volrig import Volume
    from volrig_support import subjects
    with pytest.raises(ValueError, match="no bone"):
        subjects.visible_human_joints(Volume(np.zeros((4, 4, 4), np.uint8), (1, 1, 1), (0, 0, 0)))


def test_mesh_subjects_voxelize_to_size():
    shared("meshes/cow.off")
    from volrig_support import subjects
    for name in ("cow", "hand"):
        s = subjects.mesh_subject(name)
        assert 150 <= max(s.mask.array.shape) <= 175
        assert s.mask.array.sum() > 50000, f"{name} voxelized nearly empty"
    hand = subjects.mesh_subject("hand")
    assert len(hand.joints) == 21 and hand.bones.shape == (20, 2)
    assert np.isclose(np.linalg.norm(hand.up), 1)


def test_hole_capping_closes_an_open_off_mesh(tmp_path):
    from volrig_support import subjects
    p = tmp_path / "box.off"
    # a unit cube without its top face: five quads; the hole is capped by a fan
    v = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
    f = "4 0 3 2 1\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n"
    p.write_text(f"OFF\n8 5 0\n{v}{f}")
    verts, faces = __import__("volrig").read_mesh(str(p))
    assert verts.shape == (8, 3) and faces.shape == (10, 3)
    v2, f2 = subjects._close_holes(verts, faces)
    assert v2.shape == (9, 3) and f2.shape == (14, 3)
    np.testing.assert_allclose(v2[8], [0.5, 0.5, 1.0])
    from volrig import voxelize
    mask = voxelize(v2, f2, voxel_size=0.1)
    assert mask.array.sum() == 10 * 10 * 10


def test_hole_capping_welds_a_slit_first():
    """A mesh cut open along a seam (camel_b.obj: duplicated vertices along a slit) is closed by welding, not
    capped by a fan across the body."""
    from volrig_support import subjects
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    quads = [[0, 3, 2, 1], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7], [4, 5, 6, 7]]
    # the top face on copies of its corners: a slit all round it
    v = np.vstack([v, v[4:]])
    quads[5] = [8, 9, 10, 11]
    faces = np.array([[q[0], q[i], q[i + 1]] for q in quads for i in (1, 2)])
    v2, f2 = subjects._close_holes(v, faces)
    assert v2.shape == (8, 3) and f2.shape == (12, 3)
    from volrig import voxelize
    mask = voxelize(v2, f2, voxel_size=0.1)
    assert mask.array.sum() == 10 * 10 * 10


def test_rig_joint_maps_reference_names():
    from volrig import Rig
    from volrig_support import subjects
    rig = Rig(joints=[[0, 0, 0], [0, 0, -1], [0, 0, -2]], bones=[[0, 1], [1, 2]], names=["upper_arm.L",
                                                                                       "forearm.L"])
    np.testing.assert_allclose(subjects.rig_joint(rig, "elbow.L"), [0, 0, -1])
    np.testing.assert_allclose(subjects.rig_joint(rig, "shoulder.L"), [0, 0, 0])
    assert subjects.rig_joint(rig, "knee.L") is None


def test_rotate_mask_maps_points_exactly():
    from volrig import Volume
    from volrig_support import subjects
    mask = Volume(np.zeros((5, 4, 3), bool), (1.0, 2.0, 3.0), (10.0, 0.0, 0.0))
    mask.array[4, 3, 2] = True   # x=2, y=3, z=4
    p = np.array([10 + 2 * 1.0, 3 * 2.0, 4 * 3.0])
    rots = subjects.rotations24()
    assert len(rots) == 24 and len({m.tobytes() for m in rots}) == 24
    for m in rots:
        vol, to_turned = subjects.rotate_mask(mask, m)
        z, y, x = np.argwhere(vol.array)[0]
        np.testing.assert_allclose(to_turned(p), np.array([x, y, z]) * np.asarray(vol.spacing))


def test_rig_difference_pairs_bones():
    from volrig import Rig
    from volrig_support import subjects
    a = Rig(joints=[[0, 0, 0], [0, 0, 10], [0, 5, 15]], bones=[[0, 1], [1, 2]], names=["chain0", "chain0.001"],
            kind="chains")
    b = Rig(joints=[[0, 5, 15], [0, 0, 10], [0, 0, 0]], bones=[[1, 0], [2, 1]], names=["chain0", "chain0.001"],
            kind="chains")  # the same bones, listed the other way round
    same = subjects.rig_difference(a, b, lambda p: p, lambda p: 2.0)
    assert same == 0.0
    shifted = Rig(joints=b.joints + [0, 0, 3], bones=b.bones, names=b.names, kind="chains")
    assert subjects.rig_difference(a, shifted, lambda p: p, lambda p: 2.0) == 1.5
    humanoid = Rig(joints=a.joints, bones=a.bones, names=["upper_arm.L", "forearm.L"], kind="humanoid")
    swapped = Rig(joints=a.joints, bones=a.bones, names=["forearm.L", "upper_arm.L"], kind="humanoid")
    assert subjects.rig_difference(humanoid, swapped, lambda p: p, lambda p: 2.0) > 1
    assert subjects.rig_difference(a, humanoid, lambda p: p, lambda p: 2.0) == float("inf")

"""The one-click rig on a fixed sample of the shared characters (issue 53), judged by the aggregate the field uses,
never by one subject: the share of body plans right and the mean CD-J2J against the reference skeletons
(volrig_support.characters: RigNet's metric, x 100, longest side 1), and the same with five markers taken from the
reference skeletons. Fails when the aggregate regresses. benchmarks/rig_characters.py prints the whole set."""
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import SHARED_DATA

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from rig_characters import reference_markers  # noqa: E402
from volrig_support import characters as C  # noqa: E402

pytestmark = pytest.mark.skipif(not (SHARED_DATA / "characters" / "index.json").exists(),
                                reason=f"real data not available: {SHARED_DATA / 'characters'}")

#: A fixed sample: humanoids at rest and posed, a winged one, a fish, a quadruped, shapes without skeletons, and a
#: sculpture that is no animal.
SAMPLE = ("15b2fcc8-3115-50e7-b201-d73f4e71b4f1", "916674f6-7b1d-5f0e-a562-8c27ed4cd4f9",
          "e45edd83-7d6c-5543-9be3-6b3e5b000437", "7baedcf7-a499-55a3-97e5-aa50dce00c05", "11814_ori", "2982_ori",
          "8210_ori", "smith_ori", "rignet8333_arms_up", "rignet8333_sitting", "dog", "beast", "fertility")
#: The aggregate measured last (2026-12-07: 12/13 plans, J2J 5.01, with markers 3.04; 5.10 and 3.64 before straight
#: legs were told by their bend, limbs started on their own side and the groin and chin placed their joints; 5.31
#: and 4.01 before the
#: head, hands and feet ended where the references end them, 5.80 and 4.28 before extra chains by size, matched
#: legs and raised hips); these characters are among those the weights were fitted to, so
#: this guards against regressions: the leave-one-out figures are benchmarks/rig_characters.py's. A regression
#: beyond these fails.
PLANS_RIGHT = 12
MEAN_J2J = 5.1
MARKED_J2J = 3.2


@pytest.fixture(scope="module")
def sample():
    return C.characters(SAMPLE)


def test_plans_and_joints_over_the_sample(sample):
    right, d = 0, []
    for s in sample:
        rig = s.rig()
        right += rig.kind == C.plan_label(s.plan)
        if s.reference is not None:
            d.append(C.rig_distances(rig.joints, rig.bones, *s.reference, s.vertices()))
    d = np.array(d)
    print(f"plans {right}/{len(sample)}, mean J2J {d[:, 0].mean():.2f} J2B {d[:, 1].mean():.2f} "
          f"B2B {d[:, 2].mean():.2f} over {len(d)}")
    assert right >= PLANS_RIGHT
    assert d[:, 0].mean() <= MEAN_J2J


def test_five_markers_give_humanoids_and_closer_joints(sample):
    d = []
    for s in sample:
        if s.plan != "humanoid" or s.reference is None:
            continue
        marks = reference_markers(*s.reference, s.up)
        rig = s.rig(markers={k: tuple(v) for k, v in marks.items()})
        assert rig.kind == "humanoid", s.name
        d.append(C.rig_distances(rig.joints, rig.bones, *s.reference, s.vertices()))
    d = np.array(d)
    print(f"with markers: mean J2J {d[:, 0].mean():.2f} over {len(d)}")
    assert d[:, 0].mean() <= MARKED_J2J


def test_rig_distances_is_the_chamfer_of_the_joint_sets():
    """The metric on a case worked by hand: two joints 0.1 apart along the longest side 1 -> J2J 10."""
    v = np.array([[0, 0, 0], [1, 0.5, 0.5]], float)
    a = np.array([[0.2, 0.2, 0.2], [0.8, 0.2, 0.2]])
    b = a + [0.1, 0, 0]
    j2j, j2b, b2b = C.rig_distances(a, [[0, 1]], b, [[0, 1]], v)
    assert j2j == pytest.approx(10.0)
    # Joints against the other bone: each set has one end over the other's bone (0) and one 0.1 beyond it (10).
    assert j2b == pytest.approx(5.0)
    assert 0 < b2b < j2b  # the bones overlap over 0.5 of their 0.6


def test_reference_markers_are_found_along_the_up_the_skeleton_stands_along():
    """A stick T-pose standing along +z, its file's up said to be +y (the arms' axis): read along +y its "feet" would
    be two fingers of one hand forking in the palm, so the markers are found along +z, the first axis its legs reach
    down a quarter of its height along; read along +z as given, the same markers."""
    J = np.array([[0, 0, 0], [0, 0, 4], [0, 0, 6], [0, 0, 7],            # groin, chest, chin, crown
                  [0, 3, 4], [0, 3.5, 4.3], [0, 3.5, 3.7],              # left arm: wrist, two fingers
                  [0, -3, 4], [0, -3.5, 4.3], [0, -3.5, 3.7],           # right arm
                  [0, 0.5, -2.5], [0, 0.5, -5], [0, -0.5, -2.5], [0, -0.5, -5]], float)  # knees, feet
    bones = [[0, 1], [1, 2], [2, 3], [1, 4], [4, 5], [4, 6], [1, 7], [7, 8], [7, 9], [0, 10], [10, 11], [0, 12],
             [12, 13]]
    told = reference_markers(J, bones, (0, 1, 0))
    right = reference_markers(J, bones, (0, 0, 1))
    assert told.keys() == right.keys()
    assert all(np.allclose(told[k], right[k]) for k in told)
    assert np.allclose(right["chin"], J[2]) and np.allclose(right["groin"], J[0])
    assert {tuple(right["wrist.L"]), tuple(right["wrist.R"])} == {tuple(J[4]), tuple(J[7])}


def test_a_crouching_boys_big_head_is_his_head():
    """The crouching boy (shapes/boy.obj, arms out): his head, the thickest part, sits on the shoulders with its
    ball reaching into theirs. It stayed the tree's root and no extremity, so his right hand was read as the head
    and his left arm ran down a leg (fit 0.71). Now the head is a leaf like a mouse's: head above the shoulders,
    each hand out on its own side."""
    s = C.characters(["boy"])[0]
    rig = s.rig()
    assert rig.kind == "humanoid" and rig.fit > 0.9, (rig.kind, rig.fit)
    J = np.asarray(rig.joints)
    up = np.asarray(s.up, float)

    def end(bone, k):
        return J[rig.bones[rig.names.index(bone)][k]]

    assert end("head", 1) @ up > max(end("upper_arm.L", 0) @ up, end("upper_arm.R", 0) @ up)
    v = s.vertices()
    hands = [end("hand.L", 1), end("hand.R", 1)]
    width = np.ptp(v[:, 0])
    assert abs(hands[0][0] - hands[1][0]) > 0.6 * width  # the hands at the two ends of the arm span


def test_characters_turned_as_blender_imports_them_keep_their_plans():
    """Blender's OBJ import turns a character ((x, y, z) -> (x, -z, y)): the same shape on another voxel lattice.
    The bird 17872 came out as neutral chains (its wings and legs meet the trunk a node apart: a spine of 3 nodes
    for 3 bones, so its winged rig was dropped though it scored best) and the sitting figure with five markers had
    no rig at all (its head sits on its shoulders: a head path of 2 nodes for the neck and head). The chest now
    moves along the trunk so both paths have their nodes (body_plan.cpp, trunk_split)."""
    bird, sitting = (C.turned(s) for s in C.characters(["17872_ori", "rignet8333_sitting"]))
    assert bird.rig().kind == "winged"
    markers = reference_markers(*sitting.reference, sitting.up)
    assert markers is not None
    assert sitting.rig(markers={k: tuple(v) for k, v in markers.items()}).kind == "humanoid"


def test_turned_is_the_same_character_in_another_frame():
    sub = C.characters(["dog"])[0]
    t = C.turned(sub)
    assert np.allclose(t.mesh[0], sub.mesh[0] @ C.BLENDER_IMPORT.T) and np.array_equal(t.mesh[1], sub.mesh[1])
    assert np.allclose(C.BLENDER_IMPORT @ np.asarray(sub.up, float), t.up)
    assert np.isclose(np.linalg.det(C.BLENDER_IMPORT), 1.0)  # a turn, no mirror: left stays left

"""Markers (issue 53): joints the user points at guide autorig's body plan and place those joints
(``autorig(..., markers=)``, ``rig_skeleton``, ``rig_mesh``, ``volrig rig --markers``), and ``ray_marker`` turns a
click's ray into the point half-way through the part it crosses."""
import json

import numpy as np
import pytest

import volrig
from volrig import pipeline
from volrig_support import subjects as S


@pytest.fixture(scope="module")
def stride():
    """A capsule humanoid mid-stride, its skeleton and tree."""
    s = S.capsule_subject("stride", 0.8)
    pts = volrig.skeletonize(s.mask).top(15000)
    return s, pts, volrig.skeleton_tree(pts, s.mask)


def test_ray_marker_is_half_way_through_the_first_part_it_crosses():
    a = np.zeros((20, 30, 40), bool)  # z, y, x
    a[5:15, 10:20, 4:10] = True  # a block x 4..9
    a[5:15, 10:20, 20:36] = True  # a second block farther along +x
    mask = volrig.Volume(a, spacing=(2.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0))
    p = volrig.ray_marker(mask, origin=(-10.0, 15.0, 10.0), direction=(1.0, 0.0, 0.0))
    assert p is not None
    assert p[0] == pytest.approx(2 * 6.5, abs=1.0)  # the first block, x 4..9 voxels at 2 units: its middle
    assert p[1] == pytest.approx(15.0) and p[2] == pytest.approx(10.0)
    back = volrig.ray_marker(mask, origin=(100.0, 15.0, 10.0), direction=(-1.0, 0.0, 0.0))
    assert back[0] == pytest.approx(2 * 27.5, abs=1.0)  # from the other side: the second block
    assert volrig.ray_marker(mask, origin=(-10.0, 2.0, 10.0), direction=(1.0, 0.0, 0.0)) is None  # misses
    assert volrig.ray_marker(mask, origin=(-10.0, 15.0, 10.0), direction=(-1.0, 0.0, 0.0)) is None  # away
    with pytest.raises(ValueError, match="direction"):
        volrig.ray_marker(mask, origin=(0, 0, 0), direction=(0, 0, 0))


def test_markers_choose_the_plan_and_place_their_joints(stride):
    s, pts, tree = stride
    mid = 0.5 * (s.joints["shoulder.L"] + s.joints["shoulder.R"])
    marks = {"chin": mid + [0, 0, 12 * 0.8], "wrist.L": s.joints["wrist.L"], "wrist.R": s.joints["wrist.R"],
             "knee.L": s.joints["knee.L"], "groin": 0.5 * (s.joints["hip.L"] + s.joints["hip.R"]) - [0, 0, 8]}
    rig = volrig.autorig(pts, tree, s.mask, markers=marks, up=(0, 0, 1))
    assert rig.kind == "humanoid" and rig.note == ""
    for name in ("wrist.L", "wrist.R", "knee.L"):  # marked joints sit on their markers, sides as marked
        assert np.linalg.norm(S.rig_joint(rig, name) - marks[name]) < 1e-6, name
    heads = rig.heads()
    assert np.linalg.norm(heads[rig.names.index("head")] - marks["chin"]) < 1e-6  # a chin is the head joint
    assert np.linalg.norm(heads[rig.names.index("hips")] - marks["groin"]) < 1e-6  # a groin the hips' root


def _share(rig, side):
    """Where the knee lies between hip and ankle on one side (0 at the hip, 1 at the ankle)."""
    hip, knee = rig.heads()[rig.names.index("thigh" + side)], rig.tails()[rig.names.index("thigh" + side)]
    ankle = rig.tails()[rig.names.index("shin" + side)]
    return float(np.dot(knee - hip, ankle - hip) / np.dot(ankle - hip, ankle - hip))


def test_a_knee_marked_on_one_side_sets_the_other_at_the_same_share_of_its_leg(stride):
    s, pts, tree = stride
    plain = volrig.autorig(pts, tree, s.mask, up=(0, 0, 1))
    hip = plain.heads()[plain.names.index("thigh.L")]
    ankle = plain.tails()[plain.names.index("shin.L")]
    knee = hip + 0.35 * (ankle - hip)  # a knee marked well above the rig's own
    rig = volrig.autorig(pts, tree, s.mask, up=(0, 0, 1), markers={"knee.L": knee})
    assert np.linalg.norm(S.rig_joint(rig, "knee.L") - knee) < 1e-6
    assert _share(rig, ".L") == pytest.approx(0.35, abs=1e-6)
    assert abs(_share(plain, ".R") - 0.35) > 0.05  # the other knee was elsewhere ...
    assert _share(rig, ".R") == pytest.approx(0.35, abs=1e-6)  # ... and now matches
    both = volrig.autorig(pts, tree, s.mask, up=(0, 0, 1),
                          markers={"knee.L": knee, "knee.R": S.rig_joint(plain, "knee.R")})
    assert np.linalg.norm(S.rig_joint(both, "knee.R") - S.rig_joint(plain, "knee.R")) < 1e-6  # both marked: as marked


def test_markers_swap_sides_when_they_say_so(stride):
    s, pts, tree = stride
    swapped = {"wrist.L": s.joints["wrist.R"], "wrist.R": s.joints["wrist.L"]}
    rig = volrig.autorig(pts, tree, s.mask, markers=swapped, up=(0, 0, 1))
    assert np.linalg.norm(S.rig_joint(rig, "wrist.L") - s.joints["wrist.R"]) < 1e-6
    plain = volrig.autorig(pts, tree, s.mask, up=(0, 0, 1))
    left = plain.tails()[plain.names.index("hand.L")]
    marked_left = rig.tails()[rig.names.index("hand.L")]
    assert np.linalg.norm(left - marked_left) > 10  # the arm named left is the other arm now


def test_bad_markers_are_refused_clearly(stride):
    s, pts, tree = stride
    with pytest.raises(volrig.VolrigError, match="unknown marker 'elbow'.*elbow.L"):
        volrig.autorig(pts, tree, s.mask, markers={"elbow": (0, 0, 0)})
    with pytest.raises(volrig.VolrigError, match="not a finite point"):
        volrig.autorig(pts, tree, s.mask, markers={"knee.L": (0, np.nan, 0)})
    with pytest.raises(volrig.VolrigError, match="cannot guide kind 'hand'"):
        volrig.autorig(pts, tree, s.mask, markers={"knee.L": (0, 0, 0)}, kind="hand")
    with pytest.raises(volrig.VolrigError, match="must be a point"):
        volrig.autorig(pts, tree, s.mask, markers={"knee.L": (0, 0)})
    with pytest.raises(TypeError, match="dict"):
        volrig.autorig(pts, tree, s.mask, markers=[("knee.L", (0, 0, 0))])
    assert "wrist.L" in volrig.MARKER_NAMES and "chin" in volrig.MARKER_NAMES


def test_plan_weights_are_checked(stride):
    s, pts, tree = stride
    from volrig.rig import PLAN_TERMS
    with pytest.raises(volrig.VolrigError, match=f"{len(PLAN_TERMS) + 1} values"):
        volrig.autorig(pts, tree, s.mask, plan_weights=[1.0])
    w = [1.0] * (len(PLAN_TERMS) + 1)
    w[PLAN_TERMS.index("mirror_legs")] = -1
    with pytest.raises(volrig.VolrigError, match="'mirror_legs' must be >= 0"):
        volrig.autorig(pts, tree, s.mask, plan_weights=w)
    # Chains scoring below every reading: no body plan fits, and the rig says so.
    w = [0.0] * (len(PLAN_TERMS) + 1)
    w[-1] = -100.0
    rig = volrig.autorig(pts, tree, s.mask, plan_weights=w)
    assert rig.kind == "chains" and "no body plan fits" in rig.note
    assert "no body plan fits" in pipeline.describe_rig(rig)


def test_cli_rig_takes_markers(tmp_path, stride):
    s, _, _ = stride
    vol = tmp_path / "figure.nrrd"
    volrig.Volume(s.mask.array.astype(np.uint8), spacing=s.mask.spacing, origin=s.mask.origin).save(vol)
    marks = tmp_path / "markers.json"
    marks.write_text(json.dumps({"knee.L": [float(x) for x in s.joints["knee.L"]]}))
    from volrig.cli import main
    out = tmp_path / "figure.vrig"
    assert main(["rig", str(vol), "--lo", "1", "--up", "+z", "--markers", str(marks), "-o", str(out)]) == 0
    rig = volrig.load_rig(str(out)).rig
    assert np.linalg.norm(S.rig_joint(rig, "knee.L") - s.joints["knee.L"]) < 1e-6
    marks.write_text("[1, 2]")
    assert main(["rig", str(vol), "--lo", "1", "--markers", str(marks), "-o", str(out)]) == 2


def test_wrists_above_the_knees_make_a_humanoid_below_them_a_quadruped(stride):
    s, pts, tree = stride
    marks = {n: s.joints[n] for n in ("wrist.L", "wrist.R", "knee.L")}
    assert volrig.autorig(pts, tree, s.mask, markers=marks, up=(0, 0, 1)).kind == "humanoid"
    dog = S.capsule_quadruped_subject(0)
    dpts = volrig.skeletonize(dog.mask).top(15000)
    dtree = volrig.skeleton_tree(dpts, dog.mask)
    marks = {n: dog.joints[n] for n in ("wrist.L", "wrist.R", "knee.L")}  # front feet below the hind knees
    rig = volrig.autorig(dpts, dtree, dog.mask, markers=marks, up=(0, 0, 1))
    assert rig.kind == "quadruped"
    assert np.linalg.norm(S.rig_joint(rig, "wrist.L") - dog.joints["wrist.L"]) < 1e-6

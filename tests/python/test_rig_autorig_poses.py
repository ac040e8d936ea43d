"""autorig on a humanoid of capsules (volrig_support.subjects.capsule_subject) in poses it was not developed on
(knees apart, feet wide, a stride, a T-pose, arms up), drawn 110 to 240 voxels tall: the limbs are 7 to 17 voxels
across, where the medial axis' radii step by the distance transform's fractions of a voxel. Every limb joint must
land within 1.5 limb radii of the true one (the arm at 0.6 is 6.6 voxels across: its elbow comes within 1.4 radii).
Before the knee's and the ankle's necks had to stand out of that noise (kNeckNoise), a 5% wobble of a plain
cylinder passed for one: ankles came out two radii up the shin, knees and hips a thigh radius high."""
import numpy as np
import pytest

import volrig
from volrig_support import subjects as S

#: the limb radius (figure units) each reference joint is judged by
LIMB = {"shoulder": "upper_arm", "elbow": "upper_arm", "hip": "thigh", "knee": "thigh", "ankle": "shin"}


@pytest.mark.parametrize("scale", [0.6, 0.9, 1.15])
@pytest.mark.parametrize("pose", ["down", "knees_apart", "wide", "stride", "tpose", "armsup"])
def test_limb_joints_within_a_limb_radius_and_a_half(pose, scale):
    subject = S.capsule_subject(pose, scale)
    mask = subject.mask
    pts = volrig.skeletonize(mask).top(15000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask)
    assert rig.kind == "humanoid" and rig.up @ subject.up > 0.97
    for name, truth in subject.joints.items():
        base = name.split(".")[0]
        if base == "wrist":  # a capsule hand as thin as its forearm has no wrist to find
            continue
        radius = S.CAPSULE_RADII[LIMB[base]]
        error = np.linalg.norm(S.rig_joint(rig, name) - truth) / scale
        assert error <= 1.5 * radius, f"{name}: {error:.1f} from the true joint (limb radius {radius})"


def test_capsule_subject():
    s = S.capsule_subject("stride", 0.5)
    assert s.kind == "humanoid" and s.mask.array.dtype == bool and s.mask.array.any()
    assert set(s.joints) == set(S.LIMB_JOINTS)
    knee_l, knee_r = s.joints["knee.L"], s.joints["knee.R"]
    assert knee_l[1] < knee_r[1] and knee_l[0] > knee_r[0]  # the left knee forward (-y), at +x
    inside = s.mask.array[tuple(np.round(np.array([s.joints[n] for n in S.LIMB_JOINTS])[:, ::-1]).astype(int).T)]
    assert inside.all()  # every joint inside the figure
    assert S.load_subject("capsules_tpose", scale=0.5).mask.array.shape[2] > s.mask.array.shape[2]
    with pytest.raises(KeyError, match="sitting"):
        S.capsule_subject("sitting")
    with pytest.raises(ValueError, match="positive"):
        S.capsule_subject("down", 0)


@pytest.mark.parametrize("tail, scale", [(t, s) for t in (0, 15, 25, 40, 70) for s in (0.8, 1.2)])
def test_capsule_quadruped_head_forward_and_tail_behind(tail, scale):
    """A dog of capsules: quadruped, its head bone at its head and, with a tail, a tail chain behind. At 1.2 the
    thickest node (the tree's root) lies in the rump behind the hips, which no template bone holds: the tail's chain
    now goes on from there to the nearest held node (extras.cpp, path_to_held) instead of being dropped."""
    s = S.capsule_quadruped_subject(tail, scale)
    pts = volrig.skeletonize(s.mask).top(15000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, s.mask), s.mask)
    bad = [b for b in S.quadruped_problems(s, rig) if tail or "tail bones" not in b]
    assert not bad, f"tail {tail} at {scale}: " + "; ".join(bad)


def _fan_tailed_dog(scale, radius=3.5, length=40.0, fan=18.0):
    """The capsule dog without its tail, given a blunt tail (a cylinder ``radius`` thick, ``length`` long, up and
    back from the rump) ending in a fan of feathers: a flat plate one voxel thick, widening from the tail's width to
    2 x (radius + 0.7 fan) over ``fan``. Returns the mask, the tail's end (voxels) and its direction."""
    s = S.capsule_quadruped_subject(0, scale)
    m = np.pad(s.mask.array, ((0, int(30 * scale)), (0, int(50 * scale)), (0, 0)))  # room behind and above
    shift = s.joints["hip.L"] / scale - np.array([9, 30, 40.0])  # figure units to the mask's (before scaling)
    d = np.array([0, 37, 14]) / np.hypot(37, 14)
    end = np.array([0, 30, 48.0]) + length * d
    z, y, x = np.indices(m.shape).astype(float)
    p = np.stack([x, y, z], -1) / scale - shift - end
    along = p @ d
    m |= (along >= -length) & (along <= 0) & (np.linalg.norm(p - along[..., None] * d, axis=-1) <= radius)
    normal = np.cross(d, [1.0, 0, 0]) / np.linalg.norm(np.cross(d, [1.0, 0, 0]))
    m |= (along >= 0) & (along <= fan) & (np.abs(p[..., 0]) <= radius + 0.7 * along) & (np.abs(p @ normal) * scale <= 0.6)
    return volrig.Volume(m), (end + shift) * scale, d


@pytest.mark.parametrize("scale", [1.0, 1.5, 2.0])
def test_a_tail_ending_in_a_fan_ends_where_the_fan_starts(scale):
    """A tail ending in a flat fan (a bird's tail feathers, a fish's fin): the level-set tree runs along the sheet
    and round its border, and the tail chain used to end at a corner of the fan (16 units to the side, 18 out). It
    ends where the fan starts now, on the tail's line (extras.cpp, before_fringe)."""
    vol, end, d = _fan_tailed_dog(scale)
    pts = volrig.skeletonize(vol).top(15000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, vol), vol, up=(0, 0, 1))
    assert rig.kind == "quadruped"
    tails = [b for b, n in zip(rig.bones, rig.names) if n.startswith("tail")]
    assert len(tails) >= 2
    off = (np.asarray(rig.joints)[tails[-1][1]] - end) / scale
    assert abs(off[0]) < 2.0, f"the tail ends {off[0]:.1f} units to the side of its line"
    assert -5.0 < off @ d < 5.0, f"the tail ends {off @ d:.1f} units along from the fan's start"


@pytest.mark.parametrize("scale, up", [(1.0, (0, 0, 1)), (1.0, None), (0.7, (0, 0, 1))])
def test_capsule_bird_is_winged(scale, up):
    """A bird of capsules (volrig_support.subjects.capsule_bird_subject; no subject the plan weights were fitted
    to): two flat wings held out, two legs, a head. The winged plan, its wings on the wings (each wing's bones
    between its shoulder and its tip, on its own side) and its legs on the legs (each knee within 2.5 leg radii of
    the true one); no extra chain branches off a wing (a sheet's medial axis branches along its edges)."""
    s = S.capsule_bird_subject(scale)
    pts = volrig.skeletonize(s.mask).top(15000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, s.mask), s.mask, up=up)
    assert rig.kind == "winged", (rig.kind, rig.runner_up)
    joints = np.asarray(rig.joints)
    centre = 0.5 * (s.joints["shoulder.L"] + s.joints["shoulder.R"])
    for side in "LR":
        tip = joints[rig.bones[rig.names.index("hand." + side), 1]]
        true_tip = s.joints["wingtip." + side]
        assert np.linalg.norm(tip - true_tip) < 0.25 * np.linalg.norm(true_tip - centre), side
        knee = joints[rig.bones[rig.names.index("shin." + side), 0]]
        assert np.linalg.norm(knee - s.joints["knee." + side]) / scale < 2.5 * 3.5, side
    assert not [n for n in rig.names if n.startswith(("chain.shoulder", "chain.upper_arm", "chain.forearm",
                                                      "chain.hand"))]


def test_a_body_lying_across_the_given_up_is_rigged_as_it_lies():
    """A standing figure given an up across it (+y: a character modelled lying down, or its up mislabelled): no
    humanoid or quadruped reading stands along that up (their terms for a spine not up and limbs not down, and the
    winged and hand biases, raised to 100 to make that certain), so chains would win; instead the reading without up, clear of
    chains by the weights' margin, is taken, with its own up and a note saying the given up was overruled. With that
    reading's score raised to within the margin, chains stay."""
    from volrig.rig import PLAN_TERMS, PLAN_WEIGHTS
    s = S.capsule_subject("wide", 0.6)
    pts = volrig.skeletonize(s.mask).top(15000)
    tree = volrig.skeleton_tree(pts, s.mask)
    w = list(PLAN_WEIGHTS)
    for term in ("bias_winged", "bias_hand", "h_spine_not_up", "q_limbs_not_down"):
        w[PLAN_TERMS.index(term)] = 100.0
    rig = volrig.autorig(pts, tree, s.mask, up=(0, 1, 0), plan_weights=w)
    assert rig.kind == "humanoid" and rig.up @ s.up > 0.97, (rig.kind, rig.up)
    assert "given up" in rig.note and rig.runner_up == "chains"
    free = volrig.autorig(pts, tree, s.mask, plan_weights=w)  # the reading without up, joint for joint
    assert free.kind == "humanoid" and free.fit > 0.9 and free.note == "" and np.allclose(rig.joints, free.joints)
    # The same reading within the margin of chains (fit = 1 / (1 + exp(score - chains)): the humanoid's bias raised
    # until its score lies 0.5 below chains') leaves chains, saying no plan fits.
    w[PLAN_TERMS.index("bias_humanoid")] += np.log(free.fit / (1 - free.fit)) - 0.5
    w[PLAN_TERMS.index("bias_quadruped")] = 100.0
    assert volrig.autorig(pts, tree, s.mask, plan_weights=w).fit == pytest.approx(1 / (1 + np.exp(-0.5)), abs=1e-6)
    rig = volrig.autorig(pts, tree, s.mask, up=(0, 1, 0), plan_weights=w)
    assert rig.kind == "chains" and "no body plan fits" in rig.note


def test_markers_on_a_body_lying_across_the_given_up_rig_it_as_it_lies():
    """The same figure given +y with markers on its wrists and a knee (a user clicking a character modelled lying
    down): the markers are hard constraints, not a reason to keep the up. Under +y its wrists lie no higher than
    its knee, so a quadruped was read along +y; now the reading without up, keeping the markers, wins as without
    them: a humanoid standing along z, the note saying so, its wrists and knee on the markers."""
    s = S.capsule_subject("wide", 0.6)
    pts = volrig.skeletonize(s.mask).top(15000)
    tree = volrig.skeleton_tree(pts, s.mask)
    marks = {name: s.joints[name] for name in ("wrist.L", "wrist.R", "knee.L")}
    rig = volrig.autorig(pts, tree, s.mask, up=(0, 1, 0), markers=marks)
    assert rig.kind == "humanoid" and rig.up @ s.up > 0.97 and "given up overruled" in rig.note, (rig.kind, rig.up)
    joints = np.asarray(rig.joints)
    for name, bone, end in (("wrist.L", "hand.L", 0), ("wrist.R", "hand.R", 0), ("knee.L", "shin.L", 0)):
        assert np.allclose(joints[rig.bones[rig.names.index(bone)][end]], marks[name]), name


def test_a_weak_reading_along_the_given_up_is_overruled_a_clear_one_kept():
    """The same figure given +y, with a humanoid reading under that up scoring 0.3 below chains (the weight of the
    spine not pointing up chosen so; fit 0.57): not clear of chains by the weights' margin (1), while the reading
    without up is (fit > 0.9, standing along z), so the up is overruled. Scoring 1.5 below chains, the reading
    under the given up is kept as it is."""
    from volrig.rig import PLAN_TERMS, PLAN_WEIGHTS
    s = S.capsule_subject("wide", 0.6)
    pts = volrig.skeletonize(s.mask).top(15000)
    tree = volrig.skeleton_tree(pts, s.mask)
    w = np.array(PLAN_WEIGHTS, float)
    for term in ("bias_winged", "bias_hand", "bias_quadruped"):
        w[PLAN_TERMS.index(term)] = 100.0
    spine = PLAN_TERMS.index("h_spine_not_up")
    detail = []
    volrig.autorig(pts, tree, s.mask, up=(0, 1, 0), plan_weights=list(w), detail=detail)
    F = np.asarray(detail[0].reading_features, float)
    F = F[[k == "humanoid" for k in detail[0].reading_kind]]
    chains = w[-1]

    def weighted(below):  # w with the spine's weight making the best humanoid reading under +y score chains - below
        lo, hi = 0.0, 100.0
        for _ in range(60):
            w[spine] = (lo + hi) / 2
            lo, hi = (w[spine], hi) if (F @ w[:-1]).min() < chains - below else (lo, w[spine])
        return list(w)

    weak = weighted(0.3)
    rig = volrig.autorig(pts, tree, s.mask, up=(0, 1, 0), plan_weights=weak)
    assert rig.kind == "humanoid" and "given up" in rig.note and rig.up @ s.up > 0.97, (rig.note, rig.up)
    clear = weighted(1.5)
    rig = volrig.autorig(pts, tree, s.mask, up=(0, 1, 0), plan_weights=clear)
    assert rig.kind == "humanoid" and rig.note == "" and np.allclose(rig.up, (0, 1, 0))
    assert rig.fit == pytest.approx(1 / (1 + np.exp(-1.5)), abs=1e-3)

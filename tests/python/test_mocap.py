"""Motion capture: the BVH reader through Python, forward kinematics, bone maps and retargeting onto volrig rigs,
with CMU subject 131 (../shared/data/bvh) driving the phantom's automatic rig, and the CLI.

Run: PYTHONPATH=python /usr/bin/python3 -m pytest tests/python/test_mocap.py
"""
from __future__ import annotations

import json
import os
import random

import numpy as np
import pytest

import volrig
from volrig import mocap
from conftest import shared
from test_cli import run

#: BVH (Y up, facing +Z) -> volrig world (Z up, facing -Y): +90 degrees about X, written out independently here.
Y_UP = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])


def write(path, text):
    path.write_text(text)
    return path


def points(m, pts):
    """Applies (F, B, 4, 4) matrices to (B, 3) rest points -> (F, B, 3)."""
    return np.einsum("fbij,bj->fbi", m, np.c_[pts, np.ones(len(pts))])[..., :3]


# ---- small clips written here -----------------------------------------------------------------------------------

CHAIN = """HIERARCHY
ROOT root
{{
  OFFSET 1 2 3
  CHANNELS 6 Xposition Yposition Zposition {root_order}
  JOINT a
  {{
    OFFSET 0 2 0
    CHANNELS 3 {order}
    JOINT b
    {{
      OFFSET 1.5 0 0.5
      CHANNELS 3 Xrotation Zrotation Yrotation
      End Site
      {{
        OFFSET 0 0 1
      }}
    }}
  }}
}}
MOTION
Frames: {count}
Frame Time: 0.04
{rows}
"""


def chain_clip(tmp_path, rows, order="Zrotation Xrotation Yrotation", root_order="Zrotation Yrotation Xrotation"):
    text = CHAIN.format(order=order, root_order=root_order, count=len(rows),
                        rows="\n".join(" ".join(f"{v:.10g}" for v in r) for r in rows))
    return mocap.read_bvh(write(tmp_path / "chain.bvh", text))


def test_euler_channels_multiply_left_to_right(tmp_path):
    # a's channels Zrotation Xrotation: Rz(90) @ Rx(90) takes b's offset (1.5, 0, 0.5) to ...
    rows = [[0, 0, 0, 0, 0, 0, 90, 90, 0, 0, 0, 0]]
    m = chain_clip(tmp_path, rows, order="Zrotation Xrotation Yrotation")
    pos, rot = m.forward_kinematics()
    # Rx(90): (1.5, 0, 0.5) -> (1.5, -0.5, 0); Rz(90): -> (0.5, 1.5, 0); plus a at (1, 4, 3)
    np.testing.assert_allclose(pos[0, 2], [1.5, 5.5, 3.0], atol=1e-12)
    # listed the other way round: Rx(90) @ Rz(90): Rz: (0, 1.5, 0.5); Rx: (0, -0.5, 1.5)
    m2 = chain_clip(tmp_path, [[0, 0, 0, 0, 0, 0, 90, 90, 0, 0, 0, 0]], order="Xrotation Zrotation Yrotation")
    pos2, _ = m2.forward_kinematics()
    np.testing.assert_allclose(pos2[0, 2], [1.0, 3.5, 4.5], atol=1e-12)
    # the End Site rides on b's rotation: b turns 90 degrees about its X, the (0, 0, 1) tip goes to -Y
    m3 = chain_clip(tmp_path, [[0, 0, 0, 0, 0, 0, 0, 0, 0, 90, 0, 0]])
    p3, r3 = m3.forward_kinematics()
    np.testing.assert_allclose(m3.end_site_positions(p3, r3)[0, 0], [2.5, 4.0, 3.5 - 0.0] + np.array([0, -1, 0]),
                               atol=1e-12)
    # the root's position channels add to its OFFSET; rotations are right-handed (Z by +90: x -> y)
    m4 = chain_clip(tmp_path, [[10, 20, 30, 90, 0, 0, 0, 0, 0, 0, 0, 0]])
    p4, r4 = m4.forward_kinematics()
    np.testing.assert_allclose(p4[0, 0], [11, 22, 33])
    np.testing.assert_allclose(r4[0, 0] @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(p4[0, 1], [11 - 2, 22, 33], atol=1e-12)


def test_position_channels_on_joints(tmp_path):
    text = """HIERARCHY
ROOT pelvis
{
  OFFSET 1 2 3
  CHANNELS 6 Zrotation Yrotation Xrotation Xposition Yposition Zposition
  JOINT spine
  {
    OFFSET 0 10 0
    CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  }
}
MOTION
Frames: 1
Frame Time: 0.5
90 0 0 1 1 1 0.5 0 0 0 0 0
"""
    m = mocap.read_bvh(write(tmp_path / "p.bvh", text))
    pos, _ = m.forward_kinematics()
    # translations apply in the parent's frame, before the joint's own rotation, whatever their place in the list
    np.testing.assert_allclose(pos[0, 0], [2, 3, 4])
    np.testing.assert_allclose(pos[0, 1], [2 - 10, 3 + 0.5, 4], atol=1e-12)
    assert m.fps == 2.0 and m.channels[1][0] == "Xposition"


# ---- CMU subject 131 ----------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def walk():
    return volrig.read_bvh(shared("bvh/131_01.bvh"))


@pytest.fixture(scope="module")
def hop():
    return volrig.read_bvh(shared("bvh/131_03.bvh"))


def test_cmu_131_parses(walk, hop):
    for m, frames in ((walk, 994), (hop, 1102)):
        assert len(m.names) == 31 and m.frame_count == frames and m.frames.shape == (frames, 96)
        assert m.frame_time == pytest.approx(1 / 120, rel=1e-4) and round(m.fps) == 120
        assert m.names[0] == "Hips" and m.parents[0] == -1 and (m.parents[1:] < np.arange(1, 31)).all()
        assert len(m.end_parents) == 7 and m.channels[0][:3] == ("Xposition", "Yposition", "Zposition")
    assert walk.channels[walk.index("LeftShoulder")] == ("Zrotation", "Xrotation", "Yrotation")
    assert walk.frames[0, :3].tolist() == [5.23, 16.9002, -33.8986]
    with pytest.raises(KeyError, match="LeftUpLeg.*joints: Hips, LHipJoint"):
        walk.index("LeftUpLeg")


def test_forward_kinematics_matches_scipy(walk):
    from scipy.spatial.transform import Rotation
    frames = [0, 137, 400, 993]
    pos, rot = walk.forward_kinematics(frames)
    cols = walk.columns()
    for k, f in enumerate(frames):
        g, p = {}, {}
        for j, (par, chans) in enumerate(zip(walk.parents, walk.channels)):
            values = walk.frames[f, cols[j]:cols[j] + len(chans)]
            rot_names = [c[0] for c in chans if c.endswith("rotation")]
            angles = [v for c, v in zip(chans, values) if c.endswith("rotation")]
            local = Rotation.from_euler("".join(rot_names), angles, degrees=True)  # upper case: intrinsic
            t = walk.offsets[j] + np.array([dict(zip(chans, values)).get(a + "position", 0.0) for a in "XYZ"])
            g[j] = local if par < 0 else g[par] * local
            p[j] = t if par < 0 else p[par] + g[par].apply(t)
            np.testing.assert_allclose(rot[k, j], g[j].as_matrix(), atol=1e-12)
            np.testing.assert_allclose(pos[k, j], p[j], atol=1e-9)
    # segments keep their lengths
    full, _ = walk.forward_kinematics()
    for j in range(1, 31):
        d = np.linalg.norm(full[:, j] - full[:, walk.parents[j]], axis=1)
        np.testing.assert_allclose(d, np.linalg.norm(walk.offsets[j]), atol=1e-9)


# ---- bone maps --------------------------------------------------------------------------------------------------

def test_body_roles_of_common_naming_schemes():
    rigify = ["hips", "spine", "chest", "neck", "head"] + [f"{b}.{s}" for s in "LR" for b in (
        "shoulder", "upper_arm", "forearm", "hand", "pelvis", "thigh", "shin", "foot")]
    roles = mocap.body_roles(rigify)
    assert len(roles) == 21 and all(role == name for role, name in roles.items())

    cmu = ["Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "RHipJoint", "RightUpLeg",
           "RightLeg", "RightFoot", "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head", "LeftShoulder",
           "LeftArm", "LeftForeArm", "LeftHand", "LeftFingerBase", "LThumb", "RightShoulder", "RightArm",
           "RightForeArm", "RightHand"]
    r = mocap.body_roles(cmu)
    assert (r["hips"], r["spine"], r["chest"], r["neck"], r["head"]) == ("Hips", "LowerBack", "Spine1", "Neck", "Head")
    assert (r["pelvis.L"], r["thigh.L"], r["shin.L"], r["foot.L"]) == ("LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot")
    assert (r["shoulder.R"], r["upper_arm.R"], r["forearm.R"], r["hand.R"]) == (
        "RightShoulder", "RightArm", "RightForeArm", "RightHand")

    mixamo = ["mixamorig:Hips", "mixamorig:Spine", "mixamorig:Spine1", "mixamorig:Spine2", "mixamorig:Neck",
              "mixamorig:Head", "mixamorig:LeftShoulder", "mixamorig:LeftArm", "mixamorig:LeftForeArm",
              "mixamorig:LeftHand", "mixamorig:LeftUpLeg", "mixamorig:LeftLeg", "mixamorig:LeftFoot"]
    r = mocap.body_roles(mixamo)
    assert (r["spine"], r["chest"], r["upper_arm.L"], r["shin.L"]) == (
        "mixamorig:Spine", "mixamorig:Spine2", "mixamorig:LeftArm", "mixamorig:LeftLeg")
    assert "pelvis.L" not in r and "thigh.R" not in r

    other = ["pelvis", "l_thigh", "l_calf", "l_foot", "R_Thigh", "r.calf", "Foot_R", "l_clavicle", "l_upperarm",
             "l_forearm", "l_hand", "lfemur", "spine_01", "neck_01", "head"]
    r = mocap.body_roles(other)
    assert (r["hips"], r["thigh.L"], r["shin.L"], r["foot.L"]) == ("pelvis", "l_thigh", "l_calf", "l_foot")
    assert (r["thigh.R"], r["shin.R"], r["foot.R"]) == ("R_Thigh", "r.calf", "Foot_R")
    assert (r["shoulder.L"], r["upper_arm.L"], r["spine"], r["neck"]) == (
        "l_clavicle", "l_upperarm", "spine_01", "neck_01")
    poser = ["hip", "abdomen", "chest", "neck", "head", "lCollar", "lShldr", "lForeArm", "lHand", "lThigh", "lShin",
             "lFoot"]
    r = mocap.body_roles(poser)
    assert (r["hips"], r["spine"], r["chest"], r["shoulder.L"], r["upper_arm.L"], r["shin.L"]) == (
        "hip", "abdomen", "chest", "lCollar", "lShldr", "lShin")
    # lowerback / leg are not a left "owerback" / "eg"
    assert mocap.body_roles(["lowerback", "leg"]) == {"spine": "lowerback"}


def test_default_bone_map_for_cmu_and_its_checks(walk, phantom_rig, tmp_path):
    m = volrig.default_bone_map(walk, phantom_rig)
    assert m == {"Hips": "hips", "lowerback": "spine", "Chest2": "chest", "lowerneck": "neck", "Head": "head",
                 "LeftCollar": "shoulder.L", "LeftShoulder": "upper_arm.L", "LeftElbow": "forearm.L",
                 "lhand": "hand.L", "LHipJoint": "pelvis.L", "LeftHip": "thigh.L", "LeftKnee": "shin.L",
                 "LeftAnkle": "foot.L", "RightCollar": "shoulder.R", "RightShoulder": "upper_arm.R",
                 "RightElbow": "forearm.R", "rhand": "hand.R", "RHipJoint": "pelvis.R", "RightHip": "thigh.R",
                 "RightKnee": "shin.R", "RightAnkle": "foot.R"}
    path = tmp_path / "map.json"
    volrig.save_bone_map(path, m)
    assert volrig.load_bone_map(path) == m and json.loads(path.read_text()) == m
    with pytest.raises(ValueError, match="unknown BVH joint 'LeftUpLeg'.*Hips, LHipJoint"):
        mocap.check_bone_map({"LeftUpLeg": "thigh.L"}, walk, phantom_rig)
    with pytest.raises(ValueError, match="unknown rig bone 'thigh_L'.*'LeftHip'.*hips, spine"):
        mocap.check_bone_map({"LeftHip": "thigh_L"}, walk, phantom_rig)
    with pytest.raises(ValueError, match="'thigh.L' is mapped from both 'LeftHip' and 'RightHip'"):
        mocap.check_bone_map({"LeftHip": "thigh.L", "RightHip": "thigh.L"}, walk, phantom_rig)
    with pytest.raises(TypeError, match="names"):
        mocap.check_bone_map({"LeftHip": 3}, walk, phantom_rig)
    with pytest.raises(ValueError, match="empty"):
        volrig.animate(phantom_rig, walk, bone_map={})
    (tmp_path / "bad.json").write_text("[1, 2]")
    with pytest.raises(ValueError, match="bad.json: a bone map is a JSON object"):
        volrig.load_bone_map(tmp_path / "bad.json")
    (tmp_path / "bad2.json").write_text("{oops")
    with pytest.raises(ValueError, match="bad2.json: not a JSON bone map"):
        volrig.load_bone_map(tmp_path / "bad2.json")
    chains = volrig.Rig(joints=[[0, 0, 0], [0, 0, 1], [0, 0, 2]], bones=[[0, 1], [1, 2]], names=["chain0", "chain1"])
    with pytest.raises(ValueError, match="share no body roles; pass bone_map"):
        volrig.default_bone_map(walk, chains)
    with pytest.raises(ValueError, match="no leg .* pass scale="):
        volrig.animate(chains, walk, bone_map={"Hips": "chain0"})
    assert volrig.animate(chains, walk, frames=[0, 1], bone_map={"Hips": "chain0"}, scale=2.0).shape == (2, 2, 4, 4)


# ---- the phantom driven by the walk ----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def phantom_points_and_rig(phantom_half):
    mask = volrig.segment(phantom_half.volume)
    pts = volrig.skeletonize(mask).top(15000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask, alpha=0.9), mask)
    assert rig.kind == "humanoid" and len(rig) == 21
    return pts, rig


@pytest.fixture(scope="module")
def phantom_rig(phantom_points_and_rig):
    return phantom_points_and_rig[1]


def leg_length(rig):
    return float(np.linalg.norm(rig.tails()[rig.index("thigh.L")] - rig.heads()[rig.index("thigh.L")])
                 + np.linalg.norm(rig.tails()[rig.index("shin.L")] - rig.heads()[rig.index("shin.L")]))


def clip_scale(rig, motion):
    """Rig units per BVH unit from the legs (the phantom's are equal): hip-to-ankle along the chain."""
    bvh = np.mean([np.linalg.norm(motion.offsets[motion.index(k)]) + np.linalg.norm(motion.offsets[motion.index(a)])
                   for k, a in (("LeftKnee", "LeftAnkle"), ("RightKnee", "RightAnkle"))])
    return leg_length(rig) / bvh


@pytest.fixture(scope="module")
def walk_matrices(phantom_rig, walk):
    return volrig.animate(phantom_rig, walk)


def test_matrices_are_rigid_keep_lengths_and_joints(phantom_rig, walk_matrices):
    rig, m = phantom_rig, walk_matrices
    assert m.shape == (994, 21, 4, 4) and m.dtype == np.float64 and np.isfinite(m).all()
    r = m[..., :3, :3]
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-10)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-10)
    np.testing.assert_array_equal(m[..., 3, :], np.broadcast_to([0, 0, 0, 1.0], m[..., 3, :].shape))
    heads, tails = points(m, rig.heads()), points(m, rig.tails())
    np.testing.assert_allclose(np.linalg.norm(tails - heads, axis=2),
                               np.broadcast_to(np.linalg.norm(rig.tails() - rig.heads(), axis=1), (994, 21)),
                               atol=1e-9)
    children = [(b, p) for b, p in enumerate(rig.parents) if p >= 0]
    connected = [(b, p) for b, p in children if rig.bones[b, 0] == rig.bones[p, 1]]
    assert len(children) == 20 and len(connected) == 18  # the pelvis bones start at the hips' head
    for b, p in children:
        # a child's head stays where its parent carries it: on the parent's tail when connected
        np.testing.assert_allclose(heads[:, b], points(m[:, [p]], rig.heads()[[b]])[:, 0], atol=1e-9)
        if (b, p) in connected:
            np.testing.assert_allclose(heads[:, b], tails[:, p], atol=1e-9)
    # the pose moves: knees bend, arms swing (not a rest-pose stub)
    knee = heads[:, rig.index("shin.L")]
    assert np.ptp(knee, axis=0).max() > 0.2 * leg_length(rig)


def test_ankles_alternate_with_the_clips_steps(phantom_rig, walk, walk_matrices):
    from scipy.signal import find_peaks
    rig = phantom_rig
    pos, _ = walk.forward_kinematics()
    scale = clip_scale(rig, walk)
    heads = points(walk_matrices, rig.heads())
    bvh = {s: pos[:, walk.index(j), 1] for s, j in (("L", "LeftAnkle"), ("R", "RightAnkle"))}
    ours = {s: heads[:, rig.index(f"foot.{s}"), 2] for s in "LR"}
    # steps: each swing of an ankle at least 2 BVH units (11 cm) above its neighbourhood, in frame order
    steps = sorted((int(f), s) for s in "LR" for f in find_peaks(bvh[s], prominence=2.0)[0])
    assert len(steps) >= 6
    matched = []
    for f, s in steps:
        other = "R" if s == "L" else "L"
        lo, hi = max(f - 5, 1), min(f + 6, len(ours[s]) - 1)
        g = lo + int(np.argmax(ours[s][lo:hi]))
        assert lo < g < hi - 1, f"the rig's {s} ankle has no swing peak near BVH frame {f}"
        assert ours[s][g] > ours[other][g] + scale, f"frame {g}: the swinging rig ankle is not the higher one"
        matched.append((g, s))
    # the clip's step period (between swings of alternate feet) and the rig's agree
    alternate = [(a, b) for (a, sa), (b, sb) in zip(steps, steps[1:]) if sa != sb]
    rig_alternate = [(a, b) for (a, sa), (b, sb) in zip(matched, matched[1:]) if sa != sb]
    assert len(alternate) >= 4
    period = np.median([b - a for a, b in alternate])
    assert 40 <= period <= 100  # 0.33 - 0.83 s per step at 120 fps
    assert abs(np.median([b - a for a, b in rig_alternate]) - period) <= 3
    # and the left-minus-right ankle height follows the clip's throughout
    assert np.corrcoef(bvh["L"] - bvh["R"], ours["L"] - ours["R"])[0, 1] > 0.9


def test_feet_stay_on_the_floor_and_root_in_place(phantom_rig, walk, walk_matrices):
    rig = phantom_rig
    heads = points(walk_matrices, rig.heads())
    pos, _ = walk.forward_kinematics()
    leg = leg_length(rig)
    floor = min(pos[:, walk.index("LeftAnkle"), 1].min(), pos[:, walk.index("RightAnkle"), 1].min())
    for s, joint in (("L", "LeftAnkle"), ("R", "RightAnkle")):
        ankle = pos[:, walk.index(joint)]
        speed = np.r_[0, np.linalg.norm(np.diff(ankle[:, [0, 2]], axis=0), axis=1) / walk.frame_time]
        contact = (ankle[:, 1] < floor + 0.3) & (speed < 5.0)  # within 1.7 cm of the floor, below 0.3 m/s
        assert contact.sum() > 100
        rest = rig.heads()[rig.index(f"foot.{s}"), 2]
        err = np.abs(heads[contact, rig.index(f"foot.{s}"), 2] - rest)
        assert err.max() < 0.06 * leg, f"{s} ankle off the floor by {err.max():.1f} at a contact frame"
        assert np.median(err) < 0.02 * leg
    # in place: the root's head never leaves its rest spot horizontally
    root = int(np.flatnonzero(rig.parents < 0)[0])
    np.testing.assert_allclose(heads[:, root, :2], np.broadcast_to(rig.heads()[root, :2], (994, 2)), atol=1e-9)


def test_travel_scales_the_root_path_and_frames_split_alike(phantom_rig, walk, walk_matrices):
    rig = phantom_rig
    travel = volrig.animate(rig, walk, root_motion="travel")
    root = int(np.flatnonzero(rig.parents < 0)[0])
    pos, _ = walk.forward_kinematics()
    shift = points(travel, rig.heads())[:, root] - points(walk_matrices, rig.heads())[:, root]
    bvh_shift = (Y_UP @ (pos[:, 0] - pos[0, 0]).T).T
    scale = clip_scale(rig, walk)
    np.testing.assert_allclose(shift[:, :2], scale * bvh_shift[:, :2], atol=1e-9)
    np.testing.assert_allclose(shift[:, 2], 0.0, atol=1e-9)
    assert np.linalg.norm(shift[-1, :2]) > 2 * leg_length(rig)  # the walk goes somewhere
    # farm split: any frame range gives those frames' matrices
    part = volrig.animate(rig, walk, frames=range(500, 548), root_motion="travel")
    np.testing.assert_allclose(part, travel[500:548], atol=1e-12)
    np.testing.assert_allclose(volrig.animate(rig, walk, frames=[7, 3]), walk_matrices[[7, 3]], atol=1e-12)
    with pytest.raises(IndexError, match="0..993"):
        volrig.animate(rig, walk, frames=[994])
    with pytest.raises(ValueError, match="root_motion"):
        volrig.animate(rig, walk, root_motion="fly")
    with pytest.raises(ValueError, match="up_axis"):
        volrig.animate(rig, walk, up_axis="x")


def test_hop_lifts_the_rig(phantom_rig, hop):
    rig = phantom_rig
    m = volrig.animate(rig, hop)
    heads, tails = points(m, rig.heads()), points(m, rig.tails())
    np.testing.assert_allclose(np.linalg.norm(tails - heads, axis=2),
                               np.broadcast_to(np.linalg.norm(rig.tails() - rig.heads(), axis=1), heads.shape[:2]),
                               atol=1e-9)
    pos, _ = hop.forward_kinematics()
    lower_ankle = np.minimum(pos[:, hop.index("LeftAnkle"), 1], pos[:, hop.index("RightAnkle"), 1])
    ours = np.minimum(heads[:, rig.index("foot.L"), 2], heads[:, rig.index("foot.R"), 2])
    # the rig's lower foot leaves the floor exactly when and as far as the hopper's (scaled)
    np.testing.assert_allclose(ours - ours.min(), (lower_ankle - lower_ankle.min()) * clip_scale(rig, hop), atol=1e-9)
    assert np.ptp(ours) > 0.3 * leg_length(rig)  # the hops leave the floor


# ---- exactness on skeletons built here --------------------------------------------------------------------------

def test_a_rig_shaped_like_the_clip_reproduces_it(tmp_path):
    rng = np.random.default_rng(6)
    rows = np.c_[rng.uniform(-5, 5, (20, 3)), rng.uniform(-180, 180, (20, 9))]
    m = chain_clip(tmp_path, rows.tolist())
    pos, rot = m.forward_kinematics()
    rest, rest_ends = m.rest_positions()
    # the same skeleton as a Z-up rig: root -> a -> b -> tip
    joints = (Y_UP @ np.r_[rest, rest_ends].T).T
    rig = volrig.Rig(joints=joints, bones=[[0, 1], [1, 2], [2, 3]], names=["root", "a", "b"])
    out = volrig.animate(rig, m, bone_map={"root": "root", "a": "a", "b": "b"}, root_motion="travel", scale=1.0)
    tips = m.end_site_positions(pos, rot)[:, 0]
    expect = (Y_UP @ (np.concatenate([pos, tips[:, None]], axis=1) - pos[:1, :1]).reshape(-1, 3).T).T
    got = np.concatenate([points(out, rig.heads()), points(out, rig.tails())[:, -1:]], axis=1) - joints[0]
    np.testing.assert_allclose(got.reshape(-1, 3), expect, atol=1e-9)
    # a Z-up clip (up_axis="z") against the same rig built without turning it
    rig_z = volrig.Rig(joints=np.r_[rest, rest_ends], bones=[[0, 1], [1, 2], [2, 3]], names=["root", "a", "b"])
    out_z = volrig.animate(rig_z, m, bone_map={"root": "root", "a": "a", "b": "b"}, root_motion="travel",
                           up_axis="z", scale=2.0)
    got_z = points(out_z, rig_z.tails())[:, -1] - rest[0]
    # bone geometry does not scale, only the root path does: tip = root shift * 2 + rotated rest offsets
    rel = m.end_site_positions(pos, rot)[:, 0] - pos[:, 0]
    np.testing.assert_allclose(got_z, 2.0 * (pos[:, 0] - pos[0, 0]) + rel, atol=1e-9)


T_POSE = """HIERARCHY
ROOT Hips
{{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT LeftArm
  {{
    OFFSET 1 0 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT LeftForeArm
    {{
      OFFSET 3 0 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      End Site
      {{
        OFFSET 3 0 0
      }}
    }}
  }}
}}
MOTION
Frames: 2
Frame Time: 0.1
0 10 0 0 0 0 0 0 0 0 0 0
0 10 0 0 0 0 -90 0 0 {elbow} 0 0
"""


def test_rest_pose_alignment_t_pose_clip_on_a_hanging_arm(tmp_path):
    # The clip rests in a T-pose (arm along +X); frame 1 lowers the arm (-90 about Z) and bends the elbow 90
    # degrees, the forearm back out sideways.
    m = mocap.read_bvh(write(tmp_path / "t.bvh", T_POSE.format(elbow=90)))
    # The rig's arm hangs down (-Z) at rest, as scans do.
    rig = volrig.Rig(joints=[[0, 0, 0], [1, 0, 0], [1, 0, -3], [1, 0, -6]], bones=[[0, 1], [1, 2], [2, 3]],
                     names=["shoulder.L", "upper_arm.L", "forearm.L"])
    bone_map = {"Hips": "shoulder.L", "LeftArm": "upper_arm.L", "LeftForeArm": "forearm.L"}
    out = volrig.animate(rig, m, bone_map=bone_map, scale=1.0)
    heads, tails = points(out, rig.heads()), points(out, rig.tails())
    direction = (tails - heads) / np.linalg.norm(tails - heads, axis=2)[..., None]
    # BVH rest frame: the rig's arm is swung onto the clip's T-pose (+X)
    np.testing.assert_allclose(direction[0, 1], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(direction[0, 2], [1, 0, 0], atol=1e-12)
    # frame 1: the upper arm hangs down like the clip's; the forearm points where the clip's does (Y_UP of it)
    pos, rot = m.forward_kinematics()
    clip_forearm = Y_UP @ (m.end_site_positions(pos, rot)[1, 0] - pos[1, 2]) / 3
    np.testing.assert_allclose(direction[1, 1], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(direction[1, 2], clip_forearm, atol=1e-12)
    assert abs(clip_forearm[2]) < 1e-12  # bent 90 degrees: horizontal
    # unmapped bones follow their parent rigidly
    out2 = volrig.animate(rig, m, bone_map={"Hips": "shoulder.L", "LeftArm": "upper_arm.L"}, scale=1.0)
    np.testing.assert_allclose(out2[:, 2], out2[:, 1], atol=1e-12)


# ---- broken files -----------------------------------------------------------------------------------------------

GOOD = CHAIN.format(order="Zrotation Xrotation Yrotation", root_order="Zrotation Yrotation Xrotation", count=2,
                    rows="0 0 0 0 0 0 0 0 0 0 0 0\n1 2 3 4 5 6 7 8 9 10 11 12")


@pytest.mark.parametrize("edit, message", [
    (lambda t: t[:t.index("JOINT b")], "the file ends"),
    (lambda t: t[:-10], "line 22: Frames: 2 frames of 12 channels need at least 47 bytes but only 41 follow"),
    (lambda t: t.replace("1 2 3 4 5 6 7 8 9 10 11 12", "1 2 3 4 5 6 7 8 9 10 11"),
     "line 25: frame 1 has 11 numbers but the hierarchy has 12 channels"),
    (lambda t: t.replace("CHANNELS 3 Xrotation Zrotation Yrotation", "CHANNELS 4 Xrotation Zrotation Yrotation"),
     "line 13: CHANNELS of JOINT 'b' declares 4 channels but names 3"),
    (lambda t: t.replace("7 8 9", "7 eight 9"), "line 25: frame 1, channel 7 .'a' Xrotation.: 'eight' is not a number"),
    (lambda t: t.replace("Xrotation Zrotation", "Xrotation Qrotation"), "line 13: .*unknown channel 'Qrotation'"),
    (lambda t: t.replace("Frames: 2", "Frames: 2000000000"), "line 22: Frames: 2,000,000,000 frames of 12 channels"),
    (lambda t: t[:t.index("MOTION")], "the file ends before MOTION"),
    (lambda t: t.replace("MOTION", "MOTON"), "line 21: unexpected 'MOTON'"),
    (lambda t: t.replace("Frame Time: 0.04", "Frame Time: -1"), "line 23: Frame Time: '-1' must be a positive"),
    (lambda t: t.replace("ROOT root", "ROOT a"), "line 6: joint name 'a' is used twice .first on line 2."),
    (lambda t: "\0" + t, "line 1: binary data"),
])
def test_broken_files_raise_clear_errors(tmp_path, edit, message):
    p = write(tmp_path / "broken.bvh", edit(GOOD))
    with pytest.raises(volrig.FileFormatError, match="^" + str(p).replace(".", r"\.") + ": .*" + message):
        volrig.read_bvh(p)
    with pytest.raises(volrig.FileFormatError):
        volrig.animate(volrig.Rig([[0, 0, 0], [0, 0, 1]], [[0, 1]], ["root"]), p, scale=1.0)


def test_missing_file():
    with pytest.raises(FileNotFoundError, match="nope.bvh"):
        volrig.read_bvh("/nonexistent/nope.bvh")


def test_random_truncation_and_corruption_only_raise_file_format_errors(tmp_path):
    sources = [GOOD.encode()]
    try:
        sources.append(shared("bvh/131_01.bvh").read_bytes()[:40000])  # hierarchy and ~45 frames
    except pytest.skip.Exception:
        pass
    rnd = random.Random(6)
    path = tmp_path / "damaged.bvh"
    outcomes = {"read": 0, "refused": 0}
    for trial in range(400):
        data = bytearray(rnd.choice(sources))
        if trial % 2:
            data = data[:rnd.randrange(len(data))]
        for _ in range(rnd.randrange(0, 4)):
            at = rnd.randrange(len(data)) if data else 0
            kind = rnd.randrange(3)
            if kind == 0 and data:
                data[at] = rnd.randrange(256)
            elif kind == 1:
                del data[at:at + rnd.randrange(1, 20)]
            else:
                data[at:at] = rnd.choice([b"{", b"}", b" ", b"\n", b"nan", b"-", b"1e400", b"JOINT x", b"\0"])
        path.write_bytes(bytes(data))
        try:
            m = volrig.read_bvh(path)
            assert np.isfinite(m.frames).all() and m.frames.shape == (m.frame_count, sum(map(len, m.channels)))
            outcomes["read"] += 1
        except volrig.FileFormatError as e:
            assert str(e).startswith(str(path) + ": ")
            outcomes["refused"] += 1
    assert outcomes["refused"] > 100 and outcomes["read"] > 0


# ---- command line -----------------------------------------------------------------------------------------------

def test_cli_animate(tmp_path, phantom_points_and_rig, walk, walk_matrices):
    pts, phantom_rig = phantom_points_and_rig
    rig_file = tmp_path / "phantom.vrig"
    volrig.save_rig(rig_file, pts, rig=phantom_rig)
    out = tmp_path / "walk.npz"
    r = run("animate", rig_file, walk.source, "-o", out, "--frames", "1-48", "--save-map", tmp_path / "map.json")
    assert r.returncode == 0, r.stderr
    assert "48 frames" in r.stdout
    d = np.load(out)
    np.testing.assert_allclose(d["matrices"], walk_matrices[:48], atol=1e-12)
    assert d["frames"].tolist() == list(range(48)) and list(d["bone_names"]) == phantom_rig.names
    assert json.loads(str(d["bone_map"])) == volrig.default_bone_map(walk, phantom_rig)
    assert float(d["frame_time"]) == walk.frame_time and str(d["root_motion"]) == "in_place"
    # an edited map comes back in: without the arms mapped they follow the shoulders
    edited = {k: v for k, v in json.loads((tmp_path / "map.json").read_text()).items() if "arm" not in v}
    (tmp_path / "legs.json").write_text(json.dumps(edited))
    r = run("animate", rig_file, walk.source, "-o", out, "--frames", "100-101", "--map", tmp_path / "legs.json",
            "--root", "travel")
    assert r.returncode == 0, r.stderr
    d = np.load(out)
    np.testing.assert_allclose(d["matrices"], volrig.animate(phantom_rig, walk, frames=[99, 100], bone_map=edited,
                                                             root_motion="travel"), atol=1e-12)
    shoulder = phantom_rig.index("shoulder.L")
    np.testing.assert_allclose(d["matrices"][:, phantom_rig.index("upper_arm.L")], d["matrices"][:, shoulder])
    assert [f for f in os.listdir(tmp_path) if ".tmp" in f] == []
    # clear errors, exit code 2, no traceback, the output untouched
    before = out.read_bytes()
    for args, words in [(("--frames", "0-5"), "frames 1-994"), (("--frames", "a-b"), "FIRST-LAST"),
                        (("--map", tmp_path / "missing.json"), "missing.json")]:
        r = run("animate", rig_file, walk.source, "-o", out, *args)
        assert r.returncode == 2 and words in r.stderr and "Traceback" not in r.stderr, r.stderr
    bad = write(tmp_path / "bad.bvh", GOOD.replace("7 8 9", "7 x 9"))
    r = run("animate", rig_file, bad, "-o", out)
    assert r.returncode == 2 and "bad.bvh: line 25" in r.stderr and "Traceback" not in r.stderr
    assert out.read_bytes() == before


def _vdb_active(path, grid):
    return next(g["active_voxels"] for g in volrig._volrig.vdb_grids(str(path)) if g["name"] == grid)


def test_cli_bake_mocap_writes_a_vdb_sequence_without_blender(tmp_path, walk, monkeypatch):
    ph = volrig.phantom.humanoid(0.3)
    src = tmp_path / "phantom.nrrd"
    ph.volume.save(src)
    mask = volrig.segment(ph.volume)
    pts = volrig.skeletonize(mask).top(6000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask)
    assert rig.kind == "humanoid"
    binding = volrig.bind(pts, rig, mask, mode="smooth")
    rig_file = tmp_path / "phantom.vrig"
    volrig.save_rig(rig_file, pts, rig=rig, binding=binding, source=str(src))
    out = tmp_path / "frames"
    # BVH frames 1, 31, 61 (every 30th of the 120 fps walk) -> files 1, 2, 3
    r = run("bake-mocap", src, rig_file, walk.source, "-o", out, "--frames", "1-61", "--step", 30)
    assert r.returncode == 0, r.stderr
    assert "3 of 3 frames" in r.stdout and r.stderr.count("bake-mocap: ") == 3 and "3/3 BVH frame 61" in r.stderr
    assert "3/3 frames, " in r.stderr and " frames/s" in r.stderr  # the progress bar
    files = [out / f"phantom_{k:04d}.vdb" for k in (1, 2, 3)]
    assert sorted(os.listdir(out)) == [f.name for f in files]  # nothing else (no temporary files left)
    assert {g["name"] for g in volrig._volrig.vdb_grids(str(files[0]))} == {"density", "bone"}

    deformer = volrig.Deformer(ph.volume, pts, binding)
    rest = int(np.count_nonzero(deformer.frame(volrig.rest_pose(len(rig)), mode="linear").bone.array))
    assert rest > 0.9 * np.count_nonzero(mask.array)
    # the walk's hips swing the pelvis bones out of the spheres they overlap at rest: with the hips at the legs'
    # fork (autorig's hip_on_thigh_line) 5.3% more voxels at BVH frame 1 (its legs spread widest), 1.0-1.5% at 31, 61
    counts = [_vdb_active(f, "bone") for f in files]
    for c in counts:
        assert abs(c - rest) <= 0.06 * rest, (c, rest)
    bones = [volrig.load(str(f), grid="bone") for f in files]
    for a, b in [(0, 1), (1, 2), (0, 2)]:
        assert bones[a].array.shape != bones[b].array.shape or not np.array_equal(bones[a].array, bones[b].array)
    # each file is the Deformer's frame for volrig.animate's matrices of that BVH frame
    m = volrig.animate(rig, walk, frames=[30])[0]
    expected = deformer.frame(m, mode="linear")
    np.testing.assert_array_equal(bones[1].array, expected.bone.array)
    np.testing.assert_allclose(bones[1].origin, expected.bone.origin, atol=1e-9)
    density = volrig.load(str(files[1]), grid="density").array
    np.testing.assert_allclose(density, expected.values.array, rtol=1e-3, atol=1e-3 * float(ph.volume.array.max()))

    # a farm splits the range: another machine baking BVH frame 31 alone writes the same file 2
    part = tmp_path / "part"
    r = run("bake-mocap", src, rig_file, walk.source, "-o", part, "--frames", "20-40", "--step", 30, "--name",
            "phantom", "--mode", "linear", "--lattice-tables")  # (accepted; one frame builds none: too short to pay)
    assert r.returncode == 0, r.stderr
    assert os.listdir(part) == ["phantom_0002.vdb"]
    np.testing.assert_array_equal(volrig.load(str(part / "phantom_0002.vdb"), grid="bone").array, bones[1].array)
    r = run("bake-mocap", src, rig_file, walk.source, "-o", part, "--frames", "31", "--step", 30, "--name",
            "phantom", "--skip-existing")
    assert r.returncode == 0 and "exists, skipped" in r.stderr and "0 of 1 frames" in r.stdout
    # the bake's lattice tables (in process, the FolderBake watched): none by default, whatever the length; with
    # --lattice-tables at the first frame of a bake of 16 frames, none in one of a single frame
    from volrig import cli, pipeline
    made = []

    class Watched(pipeline.FolderBake):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            made.append(self.deformer.lattice_after)

    monkeypatch.setattr(pipeline, "FolderBake", Watched)
    for k, (frames, flag) in enumerate((("1-16", []), ("1-16", ["--lattice-tables"]), ("31", ["--lattice-tables"]))):
        assert cli.main(["bake-mocap", str(src), str(rig_file), walk.source, "-o", str(tmp_path / f"watched{k}"),
                         "--frames", frames, "--name", "phantom"] + flag) == 0
    assert made == [-1, 0, -1]
    # --plain-blend: the smooth blend without the bend model and the contact planes
    plain = tmp_path / "plain"
    r = run("bake-mocap", src, rig_file, walk.source, "-o", plain, "--frames", "31", "--step", 30, "--name",
            "phantom", "--plain-blend")
    assert r.returncode == 0, r.stderr
    np.testing.assert_array_equal(volrig.load(str(plain / "phantom_0002.vdb"), grid="bone").array,
                                  deformer.frame(m, mode="linear", keep_volume=False).bone.array)

    # clear errors: exit 2, no traceback
    bare = tmp_path / "bare.vrig"
    volrig.save_rig(bare, pts, rig=rig)
    for args, words in [((src, bare, walk.source), "no binding"),
                        ((src, rig_file, walk.source, "--step", 0), "--step"),
                        ((src, rig_file, walk.source, "--frames", "2-20", "--step", 30), "step 30"),
                        ((src, rig_file, walk.source, "--frames", "0-5"), "frames 1-994"),
                        ((tmp_path / "none.nrrd", rig_file, walk.source), "none.nrrd")]:
        r = run("bake-mocap", *args, "-o", tmp_path / "err")
        assert r.returncode == 2 and words in r.stderr and "Traceback" not in r.stderr, (args, r.stderr)


def test_basis_matrices_rebuild_blenders_pose_chain(phantom_rig, walk_matrices):
    # Blender: pose_bone.matrix = parent.matrix @ (parent rest^-1 @ rest) @ matrix_basis; it must give M @ rest
    rig, m = phantom_rig, walk_matrices[::200]
    basis = rig.basis_matrices(m)
    rest = rig.rest_matrices
    for b, p in enumerate(rig.parents):
        parent = m[:, p] @ rest[p] if p >= 0 else np.eye(4)
        local_rest = np.linalg.inv(rest[p]) @ rest[b] if p >= 0 else rest[b]
        np.testing.assert_allclose(parent @ local_rest @ basis[:, b], m[:, b] @ rest[b], atol=1e-9)
    r = basis[..., :3, :3]
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-9)
    np.testing.assert_allclose(basis[..., 3, :], np.broadcast_to([0, 0, 0, 1.0], basis[..., 3, :].shape))
    np.testing.assert_allclose(rig.basis_matrices(volrig.rest_pose(len(rig))), volrig.rest_pose(len(rig)), atol=1e-12)
    with pytest.raises(ValueError, match="shape"):
        rig.basis_matrices(np.eye(4))

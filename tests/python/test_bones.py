"""Rigs from a scan's bones (issue 54): ``autorig(..., bone=)``, ``volrig.bones``, ``rig_skeleton(bone=)``.

The Visible Human (AustinMan labels at 4 and 2 mm) against references built from its tissue table's names, in the
test only: the joints the bone tissue ("Bone..." rows) shows (``volrig_support.subjects.visible_human_joints``: a
section profile along each long bone, the femoral and humeral heads as the thickest bone) and each knee's menisci
("Meniscus"). The frog (label 13, skeleton). Synthetic phantoms: tests/native/test_rig_bones.cpp."""
import csv

import numpy as np
import pytest

import volrig
from volrig.bones import bone_segments, rig_to_bones, separated
from volrig.pipeline import rig_skeleton

from conftest import shared
from volrig_support import subjects as S

LIMB_JOINTS = [f"{j}.{s}" for s in "LR" for j in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")]
TOLERANCE = {4: 30.0, 2: 15.0}  # mm: a joint from the bones within this of the reference
_CACHE = {}


def tissue_codes():
    """Tissue name -> code, from the Visible Human's own table."""
    path = shared("visible-human/austinman_tissues.tsv")
    with open(path, newline="") as f:
        return {row["tissue"]: int(row["value"]) for row in csv.DictReader(f, delimiter="\t")}


def vhm(mm):
    """Labels, body mask, bone mask (every "Bone..." tissue), skeleton points, tree and the outer-shape rig."""
    shared(f"visible-human/austinman_{mm}mm_labels.nii.gz")
    if mm not in _CACHE:
        codes = tissue_codes()
        labels = S.visible_human_labels(mm)
        a = np.asarray(labels.array)
        bone = labels.like(np.isin(a, [c for n, c in codes.items() if n.startswith("Bone")]))
        mask = labels.like(a > 0)
        pts = volrig.skeletonize(mask).top(15000)
        tree = volrig.skeleton_tree(pts, mask)
        plain = volrig.autorig(pts, tree, mask, up=(0, 0, 1))
        _CACHE[mm] = dict(labels=labels, mask=mask, bone=bone, pts=pts, tree=tree, plain=plain, codes=codes)
    return _CACHE[mm]


@pytest.fixture(scope="module", autouse=True)
def _free_cache():
    yield
    _CACHE.clear()


def from_bones(mm):
    v = vhm(mm)
    if "rig" not in v:
        v["rig"] = volrig.autorig(v["pts"], v["tree"], v["mask"], up=(0, 0, 1), bone=v["bone"])
        v["reference"] = S.visible_human_joints(v["labels"])
    return v


def menisci(v):
    """Centroid of each side's menisci (+x is the body's left), from the tissue named Meniscus."""
    lab = np.asarray(v["labels"].array)
    z, y, x = np.nonzero(lab == v["codes"]["Meniscus"])
    p = np.stack([x, y, z], axis=1) * np.asarray(v["labels"].spacing) + np.asarray(v["labels"].origin)
    mid = float(np.median(p[:, 0]))
    return {"L": p[p[:, 0] > mid].mean(axis=0), "R": p[p[:, 0] <= mid].mean(axis=0)}


@pytest.mark.parametrize("mm", [4, 2])
def test_vhm_limb_joints_at_the_bones_articulations(mm):
    v = from_bones(mm)
    rig, ref = v["rig"], v["reference"]
    errors = {n: round(float(np.linalg.norm(S.rig_joint(rig, n) - ref[n])), 1) for n in LIMB_JOINTS}
    assert max(errors.values()) <= TOLERANCE[mm], errors
    for side in "LR":
        hip, knee, ankle = (S.rig_joint(rig, f"{j}.{side}") for j in ("hip", "knee", "ankle"))
        assert hip[2] > knee[2] + 300 and knee[2] > ankle[2] + 300, (hip, knee, ankle)
        d = np.linalg.norm(knee - menisci(v)[side])
        assert d <= TOLERANCE[mm], f"knee.{side} {d:.0f} mm from its menisci"
    # the bones moved every limb joint of the Visible Human: the report says which, how and from where
    moved = {j.name: j for j in rig.bone_joints}
    assert sorted(moved) == sorted(LIMB_JOINTS)
    for name, j in moved.items():
        assert j.moved and j.how in ("contact", "ball", "thickest", "section"), j
        assert np.allclose(rig.joints[j.joint], j.after) and np.allclose(v["plain"].joints[j.joint], j.before)
        assert j.child_segment > 0 or j.parent_segment > 0  # a hand without a segment of its own: the forearm


@pytest.mark.parametrize("mm", [4, 2])
def test_vhm_bones_improve_on_the_outer_shape(mm):
    """Summed over the twelve limb joints, the bones' joints lie nearer the reference than the outer shape's."""
    v = from_bones(mm)
    ref = v["reference"]
    err = lambda rig: sum(float(np.linalg.norm(S.rig_joint(rig, n) - ref[n])) for n in LIMB_JOINTS)  # noqa: E731
    assert err(v["rig"]) < 0.6 * err(v["plain"]), (err(v["rig"]), err(v["plain"]))


@pytest.mark.parametrize("step,least", [(2, 12), (3, 11), (4, 12)], ids=["4mm", "6mm", "8mm"])
def test_vhm_on_slices_far_apart(step, least):
    """An anisotropic scan: the 2 mm Visible Human with every `step`-th axial slice kept (slices 4, 6 and 8 mm
    apart), against the full grid's reference joints: at least `least` of the 12 limb joints within 30 mm (issue 54
    asks 11 up to 8 mm: at 8 mm the left wrist, its hand resting on the pelvis, stays 32 mm short). At 4 and 6 mm the
    left ankle's talus fuses with the tibia and its contact with the forefoot is the next joint down, 35-50 mm low
    (11 of 12 before 2026-12-07); the valley left in the tibia's segment just above it is the ankle. At 8 mm the left
    ankle's section lay in the foot, 82 mm low (10 of 12 before): its shin 14% longer than the right one, whose
    thighs agree, it is sought again at the right shin's length (bilateral symmetry). Since the bone is interpolated
    between its slices (2026-12-07 afternoon) 8 mm has 12 (the left wrist 32 -> 8 mm) and 6 mm 11, one fewer: the
    right ankle's contact is the next joint down again (10 -> 33 mm, 31 mm low) and fused_end finds no valley above
    it (not examined further); across the phases of 6 mm slices the worst grid went 4 -> 8 (benchmarks/RESULTS.md,
    the phase sweep)."""
    full = vhm(2)
    a = np.asarray(full["labels"].array)[::step]
    sp = full["labels"].spacing
    labels = volrig.Volume(a, (sp[0], sp[1], sp[2] * step), full["labels"].origin)
    mask, bone = labels.like(a > 0), labels.like(np.isin(a, S.BONE_LABELS))
    pts = volrig.skeletonize(mask).top(15000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask, up=(0, 0, 1), bone=bone)
    ref = from_bones(2)["reference"]
    errors = {n: round(float(np.linalg.norm(S.rig_joint(rig, n) - ref[n])), 1) for n in LIMB_JOINTS}
    assert sum(e <= 30 for e in errors.values()) >= least, errors


def thinned(labels, step, phase):
    """Every `step`-th axial slice of a label Volume from slice `phase` (benchmarks/bench_bones.py --phases)."""
    a = np.ascontiguousarray(np.asarray(labels.array)[phase::step])
    sp, o = labels.spacing, labels.origin
    return volrig.Volume(a, (sp[0], sp[1], sp[2] * step), (o[0], o[1], o[2] + phase * sp[2]))


def worst_phase(arms, legs, step):
    """The posed (or standing: arms None) 2 mm Visible Human with every `step`-th slice kept, rigged from its bones
    at each of the `step` phases: (limb joints within 30 mm, the phase in mm, the errors) at the worst phase, and
    the counts per phase."""
    v = vhm(2)
    if arms is None:
        body, ref = v["labels"], v.setdefault("joints", S.visible_human_joints(v["labels"]))
    else:
        body, ref = posed_vhm(arms, legs)
    counts = []
    for phase in range(step):
        labels = thinned(body, step, phase)
        a = labels.array
        mask, bone = labels.like(a > 0), labels.like(np.isin(a, S.BONE_LABELS))
        pts = volrig.skeletonize(mask).top(15000)
        rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask, up=(0, 0, 1), bone=bone)
        errors = {n: round(float(np.linalg.norm(S.rig_joint(rig, n) - ref[n])), 1) for n in LIMB_JOINTS}
        counts.append((sum(e <= 30 for e in errors.values()), phase * 2, errors))
    _CACHE.setdefault("phases", {})[(arms, legs, step)] = [c[2] for c in counts]
    return min(counts, key=lambda c: c[0]), [c[0] for c in counts]


@pytest.mark.parametrize("arms,legs", [(None, None), (90, 0), (150, 15)], ids=["standing", "t-pose", "arms-raised"])
def test_vhm_on_8mm_slices_at_every_phase(arms, legs):
    """Issue 54's 11 of 12 limb joints within 30 mm on slices 8 mm apart, whatever the slices' phase: the 2 mm
    Visible Human (standing, T-pose, arms raised and legs apart, posed by its own rig) with every fourth slice kept
    from the first, second, third and fourth; the worst phase counts. Before the bone was interpolated between its
    slices (rig_detail::refine_slices, 2026-12-07) the worst phases were 10 (standing), 7 (T-pose) and 11 (arms
    raised); now 11, 11 and 11 (benchmarks/RESULTS.md, the phase sweep).

    The elbows, too, lie between their bones' ends: the median of the eight (two per phase) within 20 mm. On the
    interpolated slices the olecranon fuses with the humerus and the contact with the forearm is only the part
    still apart, in front of the joint; before the elbow was centred between the facing ends (2026-12-08) the
    T-pose's and the raised arms' medians were 24.2 and 26.5 mm (20-29 mm at 12 of their 16 elbows), now 18.3 and
    17.3 (standing 10.2 -> 7.0). And every shoulder within 20 mm at every phase: a sphere whose centre lies outside
    the humerus' own segment had faced the acromion, not the glenoid, and stood (standing at phase 2 mm, the T-pose
    at 6 mm, arms raised at 6 mm) 33, 44 and 77 mm off; those now take the head's thickest bone (at most 11 mm)."""
    worst, counts = worst_phase(arms, legs, 4)
    assert worst[0] >= 11, f"phase {worst[1]} mm: {worst[2]}; counts per phase {counts}"
    phases = _CACHE["phases"][(arms, legs, 4)]
    elbows = [e[n] for e in phases for n in ("elbow.L", "elbow.R")]
    assert np.median(elbows) <= 20.0, elbows
    shoulders = [e[n] for e in phases for n in ("shoulder.L", "shoulder.R")]
    assert max(shoulders) <= 20.0, shoulders


@pytest.mark.parametrize("arms,legs", [(90, 0), (150, 15)], ids=["t-pose", "arms-raised"])
def test_vhm_on_6mm_slices_at_every_phase(arms, legs):
    """The same on slices 6 mm apart, at each of their three phases, posed (standing keeps 12 at every phase).
    Before the wrists and ankles were sought along their parent bone's shaft and a fused head's thickest bone was
    climbed to (2026-12-08) the T-pose kept 8 of 12 at phase 2 mm (its outer shape's ankles on the toes and in the
    foot, its right hip 92 mm low on the femur's neck, a wrist out on the hand) and arms raised 10 at 4 mm (a wrist
    the hand's bones could not place, its outer shape 62 mm out; a hip on the trochanters); now 12 and 11."""
    worst, counts = worst_phase(arms, legs, 3)
    assert worst[0] >= 11, f"phase {worst[1]} mm: {worst[2]}; counts per phase {counts}"


def test_vhm_hips_below_the_knees_are_repaired():
    """Issue 54's failure: an outer-shape rig with the hips below the knees (thighs touching) and the elbows 9 cm
    too high. The bones put every limb joint back: a knee between the femur's and the tibia's facing ends, a hip at
    the femur's end away from the knee, where the head's sphere is fitted."""
    v = from_bones(2)
    plain, ref = v["plain"], v["reference"]
    joints = plain.joints.copy()
    for side in "LR":
        hip, knee = (int(plain.bones[plain.index(f"{b}.{side}")][0]) for b in ("thigh", "shin"))
        elbow = int(plain.bones[plain.index(f"forearm.{side}")][0])
        at = joints[knee].copy()
        joints[hip], joints[knee] = at + [0, 0, -60], at + [0, 0, 150]
        joints[elbow] += [0, 0, 90]
    bad = volrig.Rig(joints, plain.bones, plain.names, plain.parents, plain.kind)
    assert all(S.rig_joint(bad, f"hip.{s}")[2] < S.rig_joint(bad, f"knee.{s}")[2] for s in "LR")
    rig = rig_to_bones(bad, v["bone"]).rig
    errors = {n: round(float(np.linalg.norm(S.rig_joint(rig, n) - ref[n])), 1) for n in LIMB_JOINTS}
    assert max(errors.values()) <= TOLERANCE[2], errors
    for side in "LR":
        assert S.rig_joint(rig, f"hip.{side}")[2] > S.rig_joint(rig, f"knee.{side}")[2] + 300


def test_vhm_topology_and_other_joints_kept():
    v = from_bones(4)
    rig, plain = v["rig"], v["plain"]
    assert rig.names == plain.names and np.array_equal(rig.bones, plain.bones)
    assert np.array_equal(rig.parents, plain.parents) and rig.kind == plain.kind and rig.fit == plain.fit
    moved = {j.joint for j in rig.bone_joints if j.moved}
    ends = {int(plain.bones[plain.index(f"{b}.{s}")][1]) for b in ("hand", "foot") for s in "LR"}
    changed = set(np.flatnonzero(np.abs(rig.joints - plain.joints).max(axis=1) > 0).tolist())
    assert changed <= moved | ends and moved <= changed
    for b in ("hand", "foot"):  # end joints keep their bone's direction and length
        for s in "LR":
            k = plain.index(f"{b}.{s}")
            assert np.allclose(np.diff(rig.joints[rig.bones[k]], axis=0), np.diff(plain.joints[plain.bones[k]], axis=0))
    assert (rig.joint_points[sorted(moved)] == -1).all()


def test_without_bone_the_outer_shape_rig_is_unchanged():
    v = vhm(4)
    again = volrig.autorig(v["pts"], v["tree"], v["mask"], up=(0, 0, 1), bone=None)
    plain = v["plain"]
    assert again.bone_joints is None
    assert np.array_equal(again.joints, plain.joints) and np.array_equal(again.bones, plain.bones)
    assert np.array_equal(again.joint_points, plain.joint_points) and again.names == plain.names


def test_bad_bone_masks_are_refused_clearly():
    v = vhm(4)
    with pytest.raises(volrig.VolrigError, match="same grid"):
        volrig.autorig(v["pts"], v["tree"], v["mask"], bone=np.zeros((4, 4, 4), bool))
    with pytest.raises(volrig.VolrigError, match="bone mask is empty"):
        volrig.autorig(v["pts"], v["tree"], v["mask"], bone=v["mask"].like(np.zeros(v["mask"].array.shape, bool)))
    with pytest.raises(volrig.VolrigError, match="empty"):
        bone_segments(np.zeros((5, 5, 5), bool))


def test_bone_segments_part_the_long_bones():
    v = vhm(2)
    segs, sizes = bone_segments(v["bone"])
    lab = np.asarray(segs.array)
    bone = np.asarray(v["bone"].array)
    assert np.array_equal(lab > 0, bone & (lab > 0)) and len(sizes) == lab.max()
    assert (lab > 0).sum() >= 0.97 * bone.sum()  # the bone, less the bits thinner than the opening
    ref = S.visible_human_joints(v["labels"])

    def at(p, r=20.0):
        """The segment with the most voxels within r mm of p."""
        c = np.rint((p - np.asarray(segs.origin)) / np.asarray(segs.spacing)).astype(int)[::-1]
        k = int(np.ceil(r / min(segs.spacing)))
        box = lab[c[0] - k:c[0] + k + 1, c[1] - k:c[1] + k + 1, c[2] - k:c[2] + k + 1]
        counts = np.bincount(box[box > 0])
        return int(np.argmax(counts)) if len(counts) else 0
    for side in "LR":  # the femur's middle and the tibia's are different segments
        hip, knee, ankle = ref[f"hip.{side}"], ref[f"knee.{side}"], ref[f"ankle.{side}"]
        femur, tibia = at(0.5 * (hip + knee)), at(0.5 * (knee + ankle))
        assert femur > 0 and tibia > 0 and femur != tibia


@pytest.mark.parametrize("child,joint", [("shin.L", "knee.L"), ("forearm.R", "elbow.R"), ("thigh.R", "hip.R")],
                         ids=["knee", "elbow", "hip"])
def test_a_joint_bent_90_degrees_moves_each_segment_with_its_own_bone(child, joint):
    """The rig and the rigid layer agree: each bone segment binds wholly to its rig bone. A knee, an elbow or a hip
    bent 90 degrees: every voxel of the child's segment in the rigid layer moves with the child bone (the rigid
    layer's piece of it is the segment moved by the child's matrix) and no voxel of the segment across the joint
    (femur, humerus, pelvis) does: that one moves wholly with one other bone."""
    from test_rigid_layer import piece_moved
    v = vhm(2)
    if "rigged" not in v:
        v["rigged"] = (rig_skeleton(v["pts"], v["mask"], up=(0, 0, 1), rigid=v["bone"], bone=v["bone"]),
                       rig_to_bones(v["plain"], v["bone"]))
    r, fit = v["rigged"]
    assert np.allclose(fit.rig.joints, r.rig.joints)
    lab = np.asarray(fit.segments.array)
    rigid = r.binding.rigid
    assert r.binding.rigid_whole and np.array_equal(rigid, separated(fit.segments, v["bone"]))
    across = next(j.parent_segment for j in fit.joints if j.name == joint)
    assert fit.bone_segment[child] and across and fit.bone_segment[child] != across
    moved = (lab == fit.bone_segment[child]) & rigid
    held = (lab == across) & rigid
    assert moved.sum() >= 0.98 * (lab == fit.bone_segment[child]).sum() and held.any()
    d = volrig.Deformer(v["labels"], v["pts"], r.binding)
    pose = r.rig.pose({child: ([1, 0, 0], 90)})
    d.frame(pose, mode="rigid", sampling="nearest", values=False)
    cb = r.rig.index(child)
    carried = np.zeros(lab.shape, np.int16)
    for p in d._layer.pieces:
        x, y, z = p.box[:3]
        sz, sy, sx = p.voxels.shape
        carried[z:z + sz, y:y + sy, x:x + sx][p.voxels > 0] = p.bone + 1
    assert (carried[moved] == cb + 1).all(), np.unique(carried[moved], return_counts=True)
    assert len(np.unique(carried[held])) == 1 and carried[held][0] not in (0, cb + 1), np.unique(carried[held])
    # the child's pieces, moved by its matrix, land where its segment moved rigidly lands
    spacing, origin = v["labels"].spacing, v["labels"].origin
    m = np.asarray(pose[cb])
    z, y, x = np.nonzero(moved)
    q = ((np.stack([x, y, z], axis=1) * spacing + origin) @ m[:3, :3].T + m[:3, 3] - origin) / spacing
    want = set(map(tuple, np.floor(q + 0.5).astype(int).tolist()))
    got = set()
    for p in d._layer.pieces:
        if p.bone == cb:
            got |= set(map(tuple, piece_moved(p, m, spacing, origin).tolist()))
    assert len(want & got) >= 0.97 * len(want)
    assert np.linalg.norm(r.rig.joints[r.rig.bones[cb][1]] - fit.rig.joints[fit.rig.bones[cb][1]]) == 0


def posed_vhm(arms, legs):
    v = vhm(2)
    if "rigged" not in v:
        v["rigged"] = (rig_skeleton(v["pts"], v["mask"], up=(0, 0, 1), rigid=v["bone"], bone=v["bone"]),
                       rig_to_bones(v["plain"], v["bone"]))
    ref = S.visible_human_joints(v["labels"])
    return S.posed_visible_human(v["labels"], v["rigged"][0], arms, legs, {n: ref[n] for n in LIMB_JOINTS})


@pytest.mark.parametrize("arms,legs,slices", [(150, 15, 1), (90, 0, 1), (150, 15, 4), (90, 0, 4)],
                         ids=["arms-raised-legs-apart", "t-pose", "arms-raised-8mm-slices", "t-pose-8mm-slices"])
def test_a_posed_body_rigs_from_its_bones(arms, legs, slices):
    """Standing bodies unlike the one the rules were written on (issue 54): the Visible Human posed by its own rig,
    arms raised or straight out, legs apart, then rigged again from scratch. Humanoid, and every limb joint within
    15 mm of where its bones put it at 2 mm; with slices 8 mm apart, 11 of 12 within 30 mm. The outer shape alone
    misses by 29-39 mm on average (shoulders out on a raised arm, hips high on the flank of legs apart). The T-pose
    on 8 mm slices: its left humerus and forearm fuse into one segment while the outer shape's shoulder lies 214 mm
    in on the chest and its elbow 86 mm short; the elbow is sought along the limb from that segment's own far end
    (9 of 12 before 2026-12-07: elbow 88 mm, shoulder 190 mm off)."""
    posed, ref = posed_vhm(arms, legs)
    a = np.asarray(posed.array)[::slices]
    posed = volrig.Volume(a, (posed.spacing[0], posed.spacing[1], posed.spacing[2] * slices), posed.origin)
    codes = tissue_codes()
    bone = posed.like(np.isin(a, [c for n, c in codes.items() if n.startswith("Bone")]))
    mask = posed.like(a > 0)
    pts = volrig.skeletonize(mask).top(15000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask, up=(0, 0, 1), bone=bone)
    assert rig.kind == "humanoid"
    errors = {n: round(float(np.linalg.norm(S.rig_joint(rig, n) - ref[n])), 1) for n in LIMB_JOINTS}
    if slices == 1:
        assert max(errors.values()) <= 15.0, errors
    else:
        assert sum(e <= 30.0 for e in errors.values()) >= 11, errors


def frog():
    vol = volrig.load(str(shared("frogtissue/frogtissue.mhd")))
    mask = volrig.segment(vol)
    pts = volrig.skeletonize(mask).top(40000)
    return vol, mask, pts, volrig.skeleton_tree(pts, mask), volrig.rigid_tissue(vol, labels=[13])


LIMBS = {"leg": ("thigh", "shin", "foot"), "arm": ("upper_arm", "forearm", "hand")}
LIMB_JOINTS_OF = {"leg": ("hip", "knee", "ankle"), "arm": ("shoulder", "elbow", "wrist")}


def test_the_frog_rigs_from_its_bones():
    """The frog's labels hold organs and bones, no skin: 47% of its outer surface is bare bone, so the body plan is
    read from the bone (label 13) grown into a body. Each limb chain then runs on its own limb's bones: the four
    limbs' bone segments are disjoint, their middle joints lie within 5 mm of bone, the legs hang from the end away from the
    head, and left and right lie on either side of the spine; with up given (its limbs below its trunk) or not."""
    vol, mask, pts, tree, bone = frog()
    assert volrig.bones.bare_bone_share(mask, bone) > volrig.rig.BARE_BONE_SHARE
    for up in (None, (0, 0, -1)):  # (its limbs below its trunk: read back to front before the skull was the head)
        _check_frog_rig(volrig.autorig(pts, tree, mask, bone=bone, up=up), bone)


def _check_frog_rig(rig, bone):
    assert rig.kind in ("humanoid", "quadruped") and rig.note.startswith("body plan from the bones"), rig.note
    b = np.asarray(bone.array).astype(bool)
    to_bone = volrig.distance_transform(bone.like(~b))  # mm to the nearest bone voxel
    segs, names = {}, []
    for limb, parts in LIMBS.items():
        for side in "LR":
            name = f"{limb}.{side}"
            chain = {f"{p}.{side}" for p in parts}
            segs[name] = {j.child_segment for j in rig.bone_joints
                          if j.name == f"{j.name.partition('.')[0]}.{side}" and j.child_segment
                          and j.name.partition(".")[0] in LIMB_JOINTS_OF[limb]}
            middle = S.rig_joint(rig, ("knee." if limb == "leg" else "elbow.") + side)
            ijk = np.round((middle - np.asarray(bone.origin)) / np.asarray(bone.spacing)).astype(int)[::-1]
            assert to_bone[tuple(ijk)] <= 5.0, (name, middle)  # within the grown bone (3.6 mm)
            assert chain <= set(rig.names)
            names.append(name)
    for x in names:
        assert segs[x], x
        for y in names:
            if x < y:
                assert not segs[x] & segs[y], (x, y, segs)
    head = rig.joints[rig.bones[rig.index("head")][0]]
    hips = rig.joints[rig.bones[rig.index("hips")][0]]
    axis = (head - hips) / np.linalg.norm(head - hips)
    for side in "LR":
        knee, elbow = S.rig_joint(rig, "knee." + side), S.rig_joint(rig, "elbow." + side)
        assert (knee - hips) @ axis < (elbow - hips) @ axis  # the legs nearer the hips' end than the arms
    across = np.cross(axis, S.rig_joint(rig, "knee.L") - hips)
    assert across @ np.cross(axis, S.rig_joint(rig, "knee.R") - hips) < 0  # legs either side of the spine

def _segment_distance(p, a, b):
    d = b - a
    t = np.clip((p - a) @ d / (d @ d), 0, 1)
    return float(np.linalg.norm(p - (a + t * d)))


@pytest.mark.parametrize("tail, spacing", [(4, 1.0), (14, 1.0), (14, 0.1)])
def test_a_small_quadruped_rigs_from_its_bones_with_each_leg_on_its_own_bones(tail, spacing):
    """Issue 54's small four-legged vertebrate: bones and organs, no skin, the skull thicker than the trunk. The
    body plan is read from the bone grown into a body (its thickest node, the skull, an end on a neck: a leaf like
    the feet, so five extremities); it is a quadruped, up given or not, and each leg's knee or elbow lies on its own
    leg's bones. With a tail longer than its trunk (a mouse's) too: the tail sticks out furthest but is thin, and
    the plan read from bones takes the skull, the thickest end, for the head (bone_plan_weights; before, such a
    body was rigged back to front, its tail the head). At 0.1 mm voxels it is mouse-sized (3.5 mm its skeleton's size,
    the cube root of its bone's volume): the opening, least segment and reach scale with it (an adult's 4 mm opening
    eroded the whole skeleton and autorig(bone=) failed), and the limb joints still come from its bones."""
    labels, legs = S.bones_only_quadruped(tail=tail)
    labels = volrig.Volume(np.asarray(labels.array), (spacing,) * 3, (0.0, 0.0, 0.0))
    mask = volrig.segment(labels)
    bone = volrig.rigid_tissue(labels, labels=[13])
    pts = volrig.skeletonize(mask).top(40000)
    tree = volrig.skeleton_tree(pts, mask)
    for up in ((0, 0, 1), None):
        rig = volrig.autorig(pts, tree, mask, bone=bone, up=up)
        assert rig.kind == "quadruped" and rig.note.startswith("body plan from the bones"), (up, rig.kind, rig.note)
        assert sum(j.moved for j in rig.bone_joints) >= 10, [(j.name, j.why) for j in rig.bone_joints]
        for joint, leg in (("elbow", "front"), ("knee", "hind")):
            for side in "LR":
                p = S.rig_joint(rig, f"{joint}.{side}") / spacing  # in voxels, as the legs' bones are given
                dist = {name: min(_segment_distance(p, a, b) for a, b in segs) for name, segs in legs.items()}
                assert min(dist, key=dist.get) == f"{leg}.{side}", (joint, side, dist)
                assert dist[f"{leg}.{side}"] < 6.0  # within the grown bone of its own leg (voxels)

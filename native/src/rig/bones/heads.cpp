// rig/bones/heads.cpp: rig_to_bones' heads in their sockets (hips, shoulders: the head's sphere, its contact
// with the socket, the thickest bone) and the seeds a long bone's shaft gives a head, a wrist or an ankle the
// outer shape put off its bones.
#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include "rig/bones/fitter.hpp"

namespace volrig::rig_detail {

/// A head the outer shape put nearer its limb's middle joint (knee, elbow: bone db's head) than half its long
/// bone's length (a hip below the knee) starts again at the long bone's end away from that joint.
bool Fitter::seed_ball(BoneJoint& j, int cb, int db) {
    const SegmentEnds e = segment_ends(g_, members_[static_cast<std::size_t>(j.child_segment)]);
    if (!e.found) return false;
    const P3 k = head(db);
    const P3 far = norm(sub(e.a, k)) > norm(sub(e.b, k)) ? e.a : e.b;
    const double bone_length = norm(sub(far, k));
    if (norm(sub(head(cb), k)) >= 0.5 * bone_length) return false;
    // a femur about as long as the tibia, a humerus as the forearm: else the segment is not this limb's
    if (bone_length < 0.5 * length(db) || bone_length > 2.0 * length(db)) return false;
    move(j, cb, far, "seed");
    return true;
}

/// Where a head lies by its long bone's shaft: up the shaft from its hinge (the bone's principal axis over its
/// voxels within kShaftReach of its expected length of the hinge), at that length, the limb's proportions against
/// the bone below (an upper arm 0.56 / 0.44 of the forearm, a thigh as long as the shin). The bone's far end is no
/// guide: a humerus fused with the scapula at the voxel size ends at the spine.
constexpr double kShaftReach = 0.6, kShaftSlack = 0.25, kShaftWindow = 0.4;
constexpr double kShaftAgree = 0.7071;  // cos 45 degrees: a distal seed's shaft against the outer shape's bone
std::optional<Fitter::ShaftHead> Fitter::shaft_head(std::int32_t s, int db) const {
    const std::string distal = out_.rig.names[db];
    const double along = along_of(distal.substr(0, distal.size() - 2));
    if (along <= 0 || along >= 1) return std::nullopt;
    const double expect = along / (1 - along) * length(db);
    const std::optional<P3> at = along_shaft(s, head(db), expect);
    return at ? std::optional<ShaftHead>(ShaftHead{*at, expect}) : std::nullopt;
}

/// Where the shaft of segment s puts the far end of a long bone from its hinge k: the principal axis of the
/// segment's voxels within kShaftReach of `expect` (mm) of k, at `expect` on their side of k.
std::optional<P3> Fitter::along_shaft(std::int32_t s, const P3& k, double expect) const {
    const Patch p = patch_of(g_, out_.segments.labels, s, k, kShaftReach * expect);
    if (p.pos.size() < 8) return std::nullopt;
    P3 c{0, 0, 0};
    const P3 axis = principal_axis(p.pos, c);
    const double sign = dot(sub(c, k), axis) >= 0 ? 1.0 : -1.0;
    return add(k, {sign * expect * axis[0], sign * expect * axis[1], sign * expect * axis[2]});
}

/// Where a wrist or an ankle lies by its parent bone's shaft (shaft_head the other way): where the bones placed the
/// elbow or knee and the shoulder or hip above it, the forearm or shin is expected at the limb's proportions against
/// the bone above (0.44 / 0.56 of the upper arm, as long as the thigh), down the shaft of the segment the hinge found
/// beyond it. Nothing where those joints are not the bones' or the shaft runs more than 45 degrees (kShaftAgree)
/// off the outer shape's bone.
std::optional<P3> Fitter::distal_seed(const BoneJoint& j, int pb, int cb) const {
    const int up = out_.rig.parents[static_cast<std::size_t>(pb)];
    if (up < 0 || !placed_joint(out_.rig.bones[up][0])) return std::nullopt;
    const auto mid = std::find_if(out_.joints.begin(), out_.joints.end(),
                                  [&](const BoneJoint& k) { return k.joint == out_.rig.bones[pb][0] && k.how != "kept"; });
    if (mid == out_.joints.end()) return std::nullopt;
    const std::string& name = out_.rig.names[pb];
    const double share = along_of(name.substr(0, name.size() - 2));  // the elbow's or the knee's
    if (share <= 0 || share >= 1) return std::nullopt;
    const double expect = (1 - share) / share * length(up);
    const std::int32_t s = mid->child_segment > 0 ? mid->child_segment : j.parent_segment;
    const std::optional<P3> at = along_shaft(s, head(pb), expect);
    // a shaft across the outer shape's bone is some other bone's (the segment holds more than the forearm or shin)
    if (!at || dot(unit(sub(*at, head(pb))), unit(sub(head(cb), head(pb)))) < kShaftAgree) return std::nullopt;
    return at;
}

/// A wrist or an ankle sought where its parent's shaft puts it (distal_seed): at the parent segment's contact nearest
/// there when the outer shape's joint lies further than kShaftSlack of the expected length from it (a wrist out on
/// the hand: the carpals' contact lay outside its window); also along the limb straight down the shaft (the seed at
/// the proportions' share) when the outer joint lies kLimbRadius off the shaft's line (an ankle on the toes: the limb
/// ran across the foot) or nothing else placed it (`last`). Else it stays: the seed is the proportions', not the bones'.
bool Fitter::place_seeded(BoneJoint& j, int pb, int cb, double along, double w, bool last) {
    const std::optional<P3> seed = distal_seed(j, pb, cb);
    if (!seed) return false;
    const P3 k = head(pb), o = head(cb);
    const bool far = norm(sub(o, *seed)) > kShaftSlack * norm(sub(*seed, k));
    const P3 d = unit(sub(*seed, k)), v = sub(o, k);
    const double t = dot(v, d);
    const bool off_line = norm(sub(v, {t * d[0], t * d[1], t * d[2]})) > kLimbRadius * p_.scale;
    if (!last && !far && !off_line) return false;
    const BoneJoint before = j;
    const std::int64_t point = out_.rig.joint_points.empty() ? -1 : out_.rig.joint_points[static_cast<std::size_t>(j.joint)];
    move(j, cb, *seed, "seed");
    j.child_segment = segment_of(cb);
    j.parent_segment = segment_along(pb, 0.5, 0.95);
    bool done = j.parent_segment > 0 && j.parent_segment != j.child_segment && place_hinge(j, pb, cb, w);
    if (!done && (last || off_line) && j.parent_segment > 0) {
        j.child_segment = j.parent_segment;
        done = place_in_limb(j, pb, cb, along, true);
    }
    if (done) {
        j.why.clear();
        return true;
    }
    move(j, cb, before.to, before.how.c_str());
    j = before;
    if (!out_.rig.joint_points.empty()) out_.rig.joint_points[static_cast<std::size_t>(j.joint)] = point;
    return false;
}

/// A head the outer shape put off its long bone altogether (a raised arm's shoulder out on the arm, where the arm's
/// medial axis leaves the trunk) starts again where its shaft puts it; one further than kShaftSlack of the bone's
/// expected length from there (a hip high on the flank of legs held apart) is sought from where it is. Either way
/// its head is then sought within kShaftWindow of that length, not just near the outer shape's joint. Returns where
/// the shaft puts the head, or nothing when the outer shape's joint lies there.
std::optional<Fitter::ShaftHead> Fitter::seed_by_shaft(BoneJoint& j, int cb, int db, double w) {
    const auto e = shaft_head(j.child_segment, db);
    if (!e) return std::nullopt;
    const bool off = !near_segment(j.child_segment, head(cb), w);
    if (!off && norm(sub(head(cb), e->at)) <= kShaftSlack * e->length) return std::nullopt;
    if (off) move(j, cb, e->at, "seed");
    return e;
}

bool Fitter::place_ball(BoneJoint& j, int cb, int db, double w) {
    const BoneJoint* mid = hinge_of(j.name);
    const std::array<std::int32_t, 2> exclude{mid ? mid->child_segment : (db >= 0 ? segment_of(db) : 0),
                                             mirror_segment(cb)};
    bool seeded = db >= 0 && seed_ball(j, cb, db);
    std::optional<ShaftHead> shaft;
    if (seeded) w = window(norm(sub(head(cb), head(db))));  // the long bone's length
    else if (db >= 0 && (shaft = seed_by_shaft(j, cb, db, w)))
        w = std::max(w, kShaftWindow * shaft->length), seeded = true;
    if (!fit_ball(j, cb, exclude, w)) return false;
    for (int pass = 0; seeded && pass < 3 && j.how == "contact"; ++pass)  // from the socket, the head's sphere
        fit_ball(j, cb, exclude, w);
    // a socket far from where the shaft puts the head is another joint's (a sacroiliac joint where the femur fused
    // with its hemipelvis at the voxel size): the head is then that fused bone's thickest there. Whether the outer
    // shape's joint was near the shaft's head or not: a socket found near it may still be the wrong joint.
    if (!shaft && db >= 0 && !seeded) shaft = shaft_head(j.child_segment, db);
    if (shaft && norm(sub(head(cb), shaft->at)) > kShaftSlack * shaft->length) {
        const auto c = thickest(j.child_segment, shaft->at, w);
        if (!c) return false;
        j.parent_segment = 0;
        move(j, cb, *c, "thickest");
    }
    return true;
}

/// A ball joint from where bone cb's head lies now: the sphere of its head, else the contact with its socket, else
/// (no socket apart from it) its thickest bone.
bool Fitter::fit_ball(BoneJoint& j, int cb, const std::array<std::int32_t, 2>& exclude, double w) {
    const P3 at = head(cb);
    const Patch own = patch_of(g_, out_.segments.labels, j.child_segment, at, w);
    j.parent_segment = socket_of(j.child_segment, exclude, at, w, own);
    if (j.parent_segment == 0) {  // the head fused with its socket at this voxel size: its thickest bone
        const auto c = thickest(j.child_segment, at, w);
        if (c) move(j, cb, *c, "thickest");
        else j.why = "no bone of segment " + std::to_string(j.child_segment) + " near the joint";
        return c.has_value();
    }
    const Patch other = patch_of(g_, out_.segments.labels, j.parent_segment, at, w);
    const Contact k = contact_of(g_, own, other, p_.reach, cell_);
    // the head's surface facing its socket, a few voxels deep into the gap
    const Contact cap = contact_of(g_, own, other, p_.reach, std::max(3 * cell_, 6.0 * p_.scale));
    const Sphere s = fit_sphere(cap.a);

    const bool fits = s.radius >= 2 * cell_ && s.radius <= w && norm(sub(s.centre, k.centre)) <= 1.5 * s.radius;
    if (fits && segment_at(s.centre) == j.child_segment) {
        move(j, cb, s.centre, "ball");
        return true;
    }
    // a sphere whose centre lies outside the head's own bone is not that head's: its cap faced some other bone
    // than the socket (the 8 mm standing body's left shoulder took the acromion above the humeral head for it, the
    // centre 33 mm high); the head is then its thickest bone, as where it fused with its socket
    const auto c = fits ? thickest(j.child_segment, at, w) : std::nullopt;
    if (c) move(j, cb, *c, "thickest");
    else move(j, cb, k.centre, "contact");
    return true;
}

/// The thickest bone of segment s near c (thickest_point within w), climbed where it lies in the outer half of the
/// window (thicker bone may lie past the window's edge): sought again around what it found while that moves by more
/// than a voxel (at most kClimbSteps times), so that a head a window away from the outer shape's joint is reached (a
/// hip put 92 mm low, whose window held the femur's neck at most). One in the inner half is a local thickest at the
/// window's scale, and stays (climbing from there took a head fused with its socket to the fused mass, 21 mm off).
constexpr int kClimbSteps = 4;
std::optional<P3> Fitter::thickest(std::int32_t s, const P3& c, double w) const {
    std::optional<P3> at = thickest_point(g_, out_.segments.labels, s, c, w);
    if (!at || norm(sub(*at, c)) <= 0.5 * w) return at;
    for (int step = 0; step < kClimbSteps; ++step) {
        const std::optional<P3> next = thickest_point(g_, out_.segments.labels, s, *at, w);
        if (!next || norm(sub(*next, *at)) <= cell_) break;
        at = next;
    }
    return at;
}

}  // namespace volrig::rig_detail

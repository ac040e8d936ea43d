// rig/bones/bone_rig.cpp: a role-named rig's limb joints moved to the articulations its bone tissue shows
// (volrig/rig.hpp rig_to_bones): limb bones matched to segments; hinges at contacts, narrowest sections and along
// their limb, wrists and ankles by symmetry; segments split at them (heads.cpp: heads and shaft seeds).
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <optional>

#include "rig/autorig/templates.hpp"
#include "rig/bones/fitter.hpp"
#include "volrig/error.hpp"

namespace volrig::rig_detail {

const LimbJoint kLimbJoints[6] = {
    {"forearm", "upper_arm", "elbow", false, "", 0.56},
    {"upper_arm", "", "shoulder", true, "forearm", 0},
    {"hand", "forearm", "wrist", false, "", kArmProportions[2] / (kArmProportions[2] + kArmProportions[3] * kHandToKnuckles)},
    {"shin", "thigh", "knee", false, "", 0.5},
    {"thigh", "", "hip", true, "shin", 0},
    {"foot", "shin", "ankle", false, "", kLegProportions[2] / (kLegProportions[2] + kLegProportions[3] * kFootToBall)},
};

/// The share of its limb a hinge with child bone `child` lies at (kLimbJoints' along; 0 when none is known).
double along_of(const std::string& child) {
    for (const LimbJoint& lj : kLimbJoints)
        if (!lj.ball && child == lj.child) return lj.along;
    return 0.0;
}

BoneRig Fitter::run() {
    for (const char* sfx : {".L", ".R"})
        for (const LimbJoint& lj : kLimbJoints) place(lj, sfx);
    for (const LimbJoint& lj : kLimbJoints)
        if (!lj.ball && along_of(lj.parent) > 0) mirror_length(lj);  // wrists and ankles
    for (const LimbJoint& lj : kLimbJoints)
        if (!lj.ball && along_of(lj.parent) > 0) seed_kept(lj);
    out_.bone_segment.assign(out_.rig.bones.size(), 0);
    for (std::size_t b = 0; b < out_.rig.bones.size(); ++b) out_.bone_segment[b] = segment_of(static_cast<int>(b));
    check_rig(out_.rig);
    return std::move(out_);
}

void Fitter::place(const LimbJoint& lj, const std::string& sfx) {
    const int cb = bone(lj.child + sfx);
    const int pb = *lj.parent ? bone(lj.parent + sfx) : -1;
    if (cb < 0 || (*lj.parent && pb < 0)) return;
    BoneJoint j;
    j.joint = out_.rig.bones[cb][0];
    j.name = lj.name + sfx;
    j.from = j.to = head(cb);
    j.how = "kept";
    const double w = window(pb >= 0 ? std::min(length(cb), length(pb)) : length(cb));
    j.child_segment = segment_of(cb);
    // the parent's segment at the joint's end of it (a forearm parted mid-shaft where slices lie far apart: the
    // wrist's is the lower piece)
    j.parent_segment = pb >= 0 ? segment_along(pb, 0.5, 0.95) : 0;
    bool done = false;
    if (lj.ball) j.child_segment = hinge_segment(j.name, j.child_segment);
    if (!lj.ball && lj.along > 0 && j.parent_segment > 0 && place_seeded(j, pb, cb, lj.along, w, false)) done = true;
    else if (lj.ball && j.child_segment == 0) j.why = "no bone segment along " + out_.rig.names[cb];
    else if (lj.ball) done = place_ball(j, cb, *lj.distal ? bone(lj.distal + sfx) : -1, w);
    else if (j.parent_segment == 0) j.why = "no bone segment along " + out_.rig.names[pb];
    else if (j.parent_segment == j.child_segment) {  // near the outer shape's joint unless that is far off, and
        // along the limb; the limb first on slices interpolated (place_in_limb says why)
        const bool limb_first = interpolated() && lj.along > 0;
        done = (limb_first && place_in_limb(j, pb, cb, lj.along)) ||
               (!off_proportion(pb, cb, lj.along) && !bone_top(j, pb, cb, lj.along) && place_in_section(j, pb, cb, w)) ||
               (!limb_first && lj.along > 0 && place_in_limb(j, pb, cb, lj.along)) || reseed_shared(j, pb, cb, w);
    }
    else  // a child without a segment of its own: whatever meets the parent
        done = place_hinge(j, pb, cb, w) || (lj.along > 0 && hidden_in_parent(j, pb, cb, lj.along)) ||
               reseed_hinge(j, pb, cb, w);
    if (!done && j.why.empty()) j.why = "the bones show no articulation there";
    if (done && interpolated() && std::string(lj.name) == "elbow") centre_hinge(j, pb, cb);
    out_.joints.push_back(j);
}

/// How an elbow is centred on slices interpolated (centre_hinge): the parent's shaft from kCentreShaft[0] to
/// [1] windows behind the joint, the bone within kCentreRadius (mm, an adult's) of its line and kCentreDepth (mm)
/// of the joint on either side.
constexpr double kCentreShaft[2] = {0.5, 2.0};
constexpr double kCentreRadius = 35.0, kCentreDepth = 10.0;

/// An elbow placed on slices interpolated, moved across the parent's shaft to the midpoint of the bone's
/// two facing ends there: the centroids of every segment's voxels within kCentreDepth before and after the joint
/// along the shaft, within kCentreRadius of its line.
/// Where the interpolation bridged part of the joint space (a T-pose's olecranon fused with the humerus, whose
/// contact with the forearm then lies only in front) the contact's or the section's centre is the part still apart;
/// the facing ends are the whole articulation's, as the bone anatomy puts the joint. Not the knee: its facing ends
/// there would hold the patella, a bone in front of the joint (on the 8 mm sweep the knees moved 2-4 mm medially
/// and an ankle sought along the limb below one went 6 -> 40 mm).
void Fitter::centre_hinge(BoneJoint& j, int pb, int cb) {
    const P3 at = head(cb);
    const double w = window(std::min(length(cb), length(pb)));
    const Patch near = patch_of(g_, out_.segments.labels, j.parent_segment, at, kCentreShaft[1] * w);
    if (near.pos.size() < 8) return;
    P3 c{0, 0, 0};
    for (const P3& q : near.pos)
        for (int a = 0; a < 3; ++a) c[a] += q[a] / static_cast<double>(near.pos.size());
    const P3 d0 = unit(sub(at, c));  // from the parent's bone to the joint
    std::vector<P3> shaft;
    for (const P3& q : near.pos)
        if (const double t = -dot(sub(q, at), d0); t >= kCentreShaft[0] * w && t <= kCentreShaft[1] * w)
            shaft.push_back(q);
    if (shaft.size() < 8) return;
    P3 sc{0, 0, 0};
    P3 d = principal_axis(shaft, sc);
    if (dot(d, d0) < 0) d = {-d[0], -d[1], -d[2]};
    const double radius = kCentreRadius * p_.scale, depth = std::max(kCentreDepth * p_.scale, 2 * cell_);
    P3 sum[2] = {{0, 0, 0}, {0, 0, 0}};
    double n[2] = {0, 0};
    std::array<std::int64_t, 3> lo{}, hi{};
    box_of(g_, at, at, std::max(radius, depth), lo, hi);
    for_box(g_, lo, hi, [&](std::int64_t i, const P3& q) {
        if (out_.segments.labels[static_cast<std::size_t>(i)] <= 0) return;
        const P3 v = sub(q, at);
        const double t = dot(v, d);
        if (t == 0 || std::abs(t) > depth || norm(sub(v, {t * d[0], t * d[1], t * d[2]})) > radius) return;
        const int side = t > 0 ? 1 : 0;
        sum[side] = add(sum[side], q), n[side] += 1;
    });
    if (n[0] < 8 || n[1] < 8) return;
    const P3 mid = lerp({sum[0][0] / n[0], sum[0][1] / n[0], sum[0][2] / n[0]},
                        {sum[1][0] / n[1], sum[1][1] / n[1], sum[1][2] / n[1]}, 0.5);
    const std::string how = j.how;
    move(j, cb, mid, how.c_str());
}

/// How far from the joint the far end of a shared segment may lie, in the parent bone's expected length.
constexpr double kTopSpan[2] = {0.5, 2.0};

/// A hinge whose parent bone's head the outer shape put off their shared segment, and not from the bones (a
/// shoulder guessed inside the chest): the shared segment's far end from the child's tail (its principal axis'
/// end), when it lies between kTopSpan of the parent's expected length (the limb's proportions against the child
/// bone) from the joint; nothing otherwise.
std::optional<P3> Fitter::bone_top(const BoneJoint& j, int pb, int cb, double along) const {
    if (along <= 0 || along >= 1 || placed_joint(out_.rig.bones[pb][0])) return std::nullopt;
    const double w = window(std::min(length(cb), length(pb)));
    if (near_segment(j.child_segment, head(pb), w)) return std::nullopt;
    const SegmentEnds e = segment_ends(g_, members_[static_cast<std::size_t>(j.child_segment)]);
    if (!e.found) return std::nullopt;
    const P3 far = norm(sub(e.a, tail(cb))) > norm(sub(e.b, tail(cb))) ? e.a : e.b;
    const double expect = along / (1 - along) * length(cb), span = norm(sub(far, head(cb)));
    if (span < kTopSpan[0] * expect || span > kTopSpan[1] * expect) return std::nullopt;
    return far;
}

/// Bilateral symmetry (a wrist's or an ankle's pair): where the forearms or shins, measured between the joints
/// placed, differ by more than kMirrorSlack while the bones above them (upper arms, thighs) agree within it, one of
/// the two distal joints is off (a left ankle whose outer shape lay in the foot and whose section lies in the foot's
/// bones, 82 mm low on 8 mm slices). Each side's narrowest section is sought along its parent bone at either side's
/// length (all segments within kMirrorWindow of that length around it): the length whose two valleys are deeper
/// together is the joint's, and the other side's joint moves to its section there when its own valley there is
/// deeper than at its own length (its segments stay as they were split).
constexpr double kMirrorSlack = 0.05, kMirrorWindow = 0.1;
void Fitter::mirror_length(const LimbJoint& lj) {
    BoneJoint* side[2] = {nullptr, nullptr};
    for (BoneJoint& k : out_.joints)
        if (k.name == std::string(lj.name) + ".L") side[0] = &k;
        else if (k.name == std::string(lj.name) + ".R") side[1] = &k;
    if (!side[0] || !side[1]) return;
    const bool kept[2] = {side[0]->how == "kept", side[1]->how == "kept"};
    if (kept[0] && kept[1]) return;
    int pb[2], cb[2];
    for (int s = 0; s < 2; ++s) {
        const std::string sfx = s == 0 ? ".L" : ".R";
        pb[s] = bone(lj.parent + sfx), cb[s] = bone(lj.child + sfx);
        if (pb[s] < 0 || cb[s] < 0) return;
    }
    const double len[2] = {length(pb[0]), length(pb[1])};
    const int up[2] = {out_.rig.parents[pb[0]], out_.rig.parents[pb[1]]};  // the bones above (upper arm, thigh)
    if (up[0] < 0 || up[1] < 0 ||
        std::abs(length(up[0]) - length(up[1])) > kMirrorSlack * std::min(length(up[0]), length(up[1])))
        return;
    if (!kept[0] && !kept[1] && std::abs(len[0] - len[1]) <= kMirrorSlack * std::min(len[0], len[1])) return;
    // each side's section at either length: the length whose sections are deeper on both sides is the joint's
    Section at[2][2];  // [side][length]
    double score[2] = {0, 0};
    for (int s = 0; s < 2; ++s)
        for (int l = 0; l < 2; ++l) {
            const P3 axis = axis_of(pb[s]), c = add(head(pb[s]), {len[l] * axis[0], len[l] * axis[1], len[l] * axis[2]});
            const double half = kMirrorWindow * len[l];
            Patch p;
            for (const auto& [t, count] : segments_near(c, half)) {
                const Patch q = patch_of(g_, out_.segments.labels, t, c, 2 * half);
                p.pos.insert(p.pos.end(), q.pos.begin(), q.pos.end());
                p.surface.insert(p.surface.end(), q.surface.begin(), q.surface.end());
                p.index.insert(p.index.end(), q.index.begin(), q.index.end());
            }
            at[s][l] = narrowest_section(p, c, axis, half, slab_along(axis));
            score[l] += at[s][l].found ? at[s][l].share : 0;
        }
    // a side the bones did not place (a hand without a segment of its own, its outer shape's wrist far out) takes
    // its section at the other side's length; else the length whose sections are deeper
    const int l = kept[0] ? 1 : kept[1] ? 0 : score[0] >= score[1] ? 0 : 1;
    const int s = 1 - l;  // the side whose length lost
    if (kept[s]) {
        if (!at[s][l].found) return;
        move(*side[s], cb[s], at[s][l].centre, "section");
        side[s]->why.clear();
        return;
    }
    if (!at[s][l].found || at[s][l].share <= at[s][s].share) return;
    move(*side[s], cb[s], at[s][l].centre, "section");
}

/// A wrist or an ankle still where the outer shape put it after the symmetry check: sought where its parent's
/// shaft puts it (place_seeded, `last`: a raised hand whose bones do not reach the outer shape's wrist).
void Fitter::seed_kept(const LimbJoint& lj) {
    for (BoneJoint& j : out_.joints) {
        const std::string sfx = j.name.substr(j.name.size() - 2);
        const int pb = bone(lj.parent + sfx), cb = bone(lj.child + sfx);
        if (j.name != lj.name + sfx || j.how != "kept" || j.parent_segment <= 0 || pb < 0 || cb < 0) continue;
        place_seeded(j, pb, cb, lj.along, window(std::min(length(cb), length(pb))), true);
    }
}

P3 Fitter::axis_of(int b) const { return unit(sub(tail(b), head(b))); }

namespace {

/// How thick a section's slabs are along `axis` on voxels of `spacing`: the largest of the spacing times the axis'
/// share on each grid axis, at least the finest spacing.
double slab_of(const std::array<double, 3>& spacing, const P3& axis) {
    double slab = std::min({spacing[0], spacing[1], spacing[2]});
    for (int a = 0; a < 3; ++a) slab = std::max(slab, std::abs(axis[a]) * spacing[a]);
    return slab;
}

}  // namespace

/// How thick a section's slabs are along `axis`: a voxel's longest extent along it (its spacing times the axis'
/// share on each grid axis, the largest), at least the finest spacing. On a grid with slices 8 mm apart a slab
/// along the slices' normal is 8 mm thick: thinner slabs would fall between the slices and read as valleys.
double Fitter::slab_along(const P3& axis) const { return slab_of(g_.spacing, axis); }

/// slab_along for the scan's own voxels where the grid interpolates between its slices: a valley thinner than a
/// slice there is the interpolation's (fused_end on a raised arm's humerus took the olecranon fossa, a thin plate
/// of bone between two slices, for a bone fused on to its end, and pulled the elbow 30 mm up the humerus).
double Fitter::slab_sampled(const P3& axis) const { return slab_of(sampled_, axis); }

bool Fitter::place_in_section(BoneJoint& j, int pb, int cb, double w) {
    const P3 axis = axis_of(pb), at = head(cb);
    const Section s = narrowest_section(patch_of(g_, out_.segments.labels, j.child_segment, at, 1.5 * w), at, axis, w,
                                        slab_along(axis));
    if (!s.found) {
        j.why = "one segment spans the joint without a narrower section";
        return false;
    }
    split(j.child_segment, cb, s.centre, axis);
    j.child_segment = static_cast<std::int32_t>(out_.segments.sizes.size());
    move(j, cb, s.centre, "section");
    return true;
}

/// A knee or an elbow whose parent's segment runs on into the child bone's first stretch (slices too far apart to
/// part them there: the humerus fused with the top of the forearm), where the bones show no contact near the outer
/// shape's joint, itself where the limb's proportions put it: the joint is sought inside the parent's segment along
/// the limb (place_in_limb).
bool Fitter::off_proportion(int pb, int cb, double along) const {
    const double upper = length(pb), share = upper / std::max(upper + length(cb), 1e-9);
    return along > 0 && std::abs(share - along) > kLimbBand;
}

bool Fitter::hidden_in_parent(BoneJoint& j, int pb, int cb, double along) {
    // Only where the outer shape's joint sits where the limb's proportions put it: a joint far off (a knee guessed
    // 15 cm too high sits inside the femur) is the reseed's to repair.
    if (off_proportion(pb, cb, along) || segment_along(cb, 0.05, 0.3) != j.parent_segment) return false;
    const std::int32_t child = j.child_segment;
    j.child_segment = j.parent_segment;
    if (place_in_limb(j, pb, cb, along)) return true;
    j.child_segment = child;
    return false;
}

/// A knee, an elbow, a wrist or an ankle whose two bones run through one segment (slices too far apart to show the
/// joint space): sought along the whole limb, from the parent's head through the outer shape's joint to the child's tail, within kLimbBand of the share
/// its proportions put the joint at and kLimbRadius of the limb (limb_section: its deepest valley, else its bulge,
/// the condyles and the plateau or the epicondyles), where the segment is split. On slices interpolated it is
/// tried before the search near the outer shape's joint: the interpolation bridges the joint spaces the slices
/// missed, so valleys near that joint are the bone's shape, not a joint (the outer shape's knee of legs held apart
/// lies 60 mm off, and its window's deepest valley 100 mm up the femur), while the limb's proportions hold for any
/// adult's limb. Where the grid is the scan's own, a valley near a joint the outer shape placed well is the finer
/// guide (on the 4 mm labels a talus fused with the tibia: its valley 1 mm from the ankle, the limb's bulge 28 mm).
bool Fitter::place_in_limb(BoneJoint& j, int pb, int cb, double along, bool seeded) {
    const std::optional<P3> far = seeded ? std::nullopt : bone_top(j, pb, cb, along);
    const P3 top = far ? *far : head(pb);
    // seeded (place_seeded): the limb runs straight on past the seed, which lies at the share `along` of it
    const P3 d = sub(head(cb), top);
    const double f = (1 - along) / along;
    const P3 on = add(head(cb), {f * d[0], f * d[1], f * d[2]});
    const Limb limb{top, head(cb), seeded ? on : tail(cb), along - kLimbBand, along + kLimbBand};
    const double length = norm(sub(limb.k, limb.a)) + norm(sub(limb.b, limb.k));
    const P3 mid = lerp(limb.a, limb.b, 0.5);
    const P3 axis = unit(add(unit(sub(limb.k, limb.a)), unit(sub(limb.b, limb.k))));  // splits upper from lower
    const Patch p = patch_of(g_, out_.segments.labels, j.child_segment, mid, 0.5 * length + kLimbRadius * p_.scale);
    const Section s = limb_section(p, limb, kLimbRadius * p_.scale, slab_along(axis));
    if (!s.found) return false;
    const std::int32_t shared = j.child_segment;
    move(j, cb, s.centre, s.bulge ? "bulge" : "section");
    split(shared, cb, s.centre, axis);
    j.child_segment = static_cast<std::int32_t>(out_.segments.sizes.size());
    j.why.clear();
    return true;
}

/// The child's side of a hinge at `at`: its own segment and the other segments meeting the parent's patch there
/// that lie beyond the joint along the parent's axis (an ulna beside the radius, a talus under the tibia).
Patch Fitter::child_side(const BoneJoint& j, const Patch& parent, const P3& at, const P3& axis, double w) const {
    Patch out;
    for (const auto& [t, count] : segments_near(at, w)) {
        if (t == j.parent_segment || count < 8) continue;
        Patch p = patch_of(g_, out_.segments.labels, t, at, w);
        P3 c{0, 0, 0};
        for (const P3& q : p.pos)
            for (int a = 0; a < 3; ++a) c[a] += q[a] / static_cast<double>(p.pos.size());
        if (t != j.child_segment && dot(sub(c, at), axis) <= 0) continue;
        if (!contact_of(g_, p, parent, p_.reach, cell_).found) continue;
        out.pos.insert(out.pos.end(), p.pos.begin(), p.pos.end());
        out.surface.insert(out.surface.end(), p.surface.begin(), p.surface.end());
        out.index.insert(out.index.end(), p.index.begin(), p.index.end());
    }
    return out;
}

bool Fitter::place_hinge(BoneJoint& j, int pb, int cb, double w) {
    const P3 at = head(cb);
    const Patch parent = patch_of(g_, out_.segments.labels, j.parent_segment, at, w);
    const Patch child = child_side(j, parent, at, axis_of(pb), w);
    const Contact k = contact_of(g_, parent, child, p_.reach, std::max(1.5 * cell_, 4.0 * p_.scale));
    if (!k.found) {
        j.why = "no segment meets segment " + std::to_string(j.parent_segment) + " there";
        return false;
    }
    move(j, cb, k.centre, "contact");
    fused_beyond(j, pb, cb, w);
    return true;
}

/// How deep a valley in the parent's segment just before a hinge's contact must be (over its lower wall) to mark a
/// bone fused on to the parent's end (fused_end): the tibia and the talus fused on 8 mm slices leave 10-25%.
constexpr double kFusedValley = 0.1;

/// A hinge at a contact whose parent segment holds, within the window w behind it (along the parent bone), a valley
/// of at least kFusedValley and more bone between that valley and the contact (the talus and calcaneus joined to
/// the tibia where slices lie far apart, whose contact with the forefoot is the next joint down): the joint moves to
/// the valley, and the parent's segment is split there (the part beyond goes with the child bone).
void Fitter::fused_beyond(BoneJoint& j, int pb, int cb, double w) {
    const P3 at = head(cb), axis = axis_of(pb);
    const Patch p = patch_of(g_, out_.segments.labels, j.parent_segment, at, 1.5 * w);
    const Section s = fused_end(p, at, axis, w, w, 0.5 * w, slab_sampled(axis), kFusedValley);
    if (!s.found) return;
    split(j.parent_segment, cb, s.centre, axis);
    move(j, cb, s.centre, "section");
}

/// A hinge the outer shape put beyond the window of its bones' contact: started again between the facing ends of
/// the two segments (the parent's end nearer the child's centroid, and the child's nearer the parent's).
bool Fitter::reseed_hinge(BoneJoint& j, int pb, int cb, double w) {
    if (j.child_segment == 0) return false;
    const SegmentEnds p = segment_ends(g_, members_[static_cast<std::size_t>(j.parent_segment)]);
    const SegmentEnds c = segment_ends(g_, members_[static_cast<std::size_t>(j.child_segment)]);
    if (!p.found || !c.found) return false;
    const auto nearer = [](const SegmentEnds& e, const P3& q) { return norm(sub(e.a, q)) < norm(sub(e.b, q)) ? e.a : e.b; };
    const P3 pe = nearer(p, c.centroid), ce = nearer(c, p.centroid);
    const P3 seed{0.5 * (pe[0] + ce[0]), 0.5 * (pe[1] + ce[1]), 0.5 * (pe[2] + ce[2])};
    if (norm(sub(seed, head(cb))) > 0.5 * (length(pb) + length(cb))) return false;  // not this limb's bones
    const BoneJoint before = j;
    const std::int64_t point = out_.rig.joint_points.empty() ? -1 : out_.rig.joint_points[static_cast<std::size_t>(j.joint)];
    move(j, cb, seed, "seed");
    if (place_hinge(j, pb, cb, w)) {
        j.from = before.from;
        j.why.clear();
        return true;
    }
    move(j, cb, before.from, "kept");
    if (!out_.rig.joint_points.empty()) out_.rig.joint_points[static_cast<std::size_t>(j.joint)] = point;
    j.why = before.why;
    return false;
}

/// Parent and child bones run through one segment with no narrower section between (the outer shape's joint far
/// from the bones'): the child keeps it, and the parent takes the largest segment meeting it at its end nearer the
/// joint (a femur, not the patella or the fibula).
bool Fitter::reseed_shared(BoneJoint& j, int pb, int cb, double w) {
    const SegmentEnds e = segment_ends(g_, members_[static_cast<std::size_t>(j.child_segment)]);
    if (!e.found) return false;
    const P3 end = norm(sub(e.a, head(cb))) < norm(sub(e.b, head(cb))) ? e.a : e.b;
    const Patch own = patch_of(g_, out_.segments.labels, j.child_segment, end, w);
    std::int32_t other = 0;
    int most = 0;
    for (const auto& [t, count] : segments_near(end, w))
        if (t != j.child_segment && count > most &&
            contact_of(g_, own, patch_of(g_, out_.segments.labels, t, end, w), p_.reach, cell_).found)
            most = count, other = t;
    if (other == 0) return false;
    const std::string why = j.why;
    j.parent_segment = other;
    j.why.clear();
    if (reseed_hinge(j, pb, cb, w)) return true;
    j.why = why;
    return false;
}

/// Voxels of segment s beyond the plane (at, axis) and near bone cb become a new segment.
void Fitter::split(std::int32_t s, int cb, const P3& at, const P3& axis) {
    const double r = window(length(cb));
    // the child bone and the bones below it (a shin and its foot: a foot fused with the tibia goes with it)
    std::vector<int> below{cb};
    for (std::size_t k = 0; k < below.size(); ++k)
        for (std::size_t b = 0; b < out_.rig.parents.size(); ++b)
            if (out_.rig.parents[b] == below[k]) below.push_back(static_cast<int>(b));
    const auto fresh = static_cast<std::int32_t>(out_.segments.sizes.size() + 1);
    std::int64_t moved = 0;
    for (const int b : below) {
        std::array<std::int64_t, 3> lo{}, hi{};
        box_of(g_, head(b), tail(b), r, lo, hi);
        for_box(g_, lo, hi, [&](std::int64_t i, const P3& q) {
            std::int32_t& l = out_.segments.labels[static_cast<std::size_t>(i)];
            if (l == s && dot(sub(q, at), axis) > 0 && to_segment(q, head(b), tail(b)) <= r) l = fresh, ++moved;
        });
    }
    out_.segments.sizes[static_cast<std::size_t>(s - 1)] -= moved;
    out_.segments.sizes.push_back(moved);
    std::vector<std::int64_t>& from = members_[static_cast<std::size_t>(s)];
    std::vector<std::int64_t> gone;
    const auto kept = std::stable_partition(from.begin(), from.end(), [&](std::int64_t i) {
        return out_.segments.labels[static_cast<std::size_t>(i)] == s;
    });
    gone.assign(kept, from.end());
    from.erase(kept, from.end());
    members_.push_back(std::move(gone));
}

/// Moves the head of bone cb to `to`; an end bone (its tail no bone's head) keeps its direction and length.
void Fitter::move(BoneJoint& j, int cb, const P3& to, const char* how) {
    auto& rig = out_.rig;
    const P3 d = sub(to, rig.joints[static_cast<std::size_t>(j.joint)]);
    rig.joints[static_cast<std::size_t>(j.joint)] = to;
    const std::int32_t t = rig.bones[cb][1];
    const bool end = std::none_of(rig.bones.begin(), rig.bones.end(), [&](const auto& b) { return b[0] == t; });
    if (end)
        for (int k = 0; k < 3; ++k) rig.joints[static_cast<std::size_t>(t)][k] += d[k];
    if (!rig.joint_points.empty()) rig.joint_points[static_cast<std::size_t>(j.joint)] = -1;
    j.to = to;
    j.how = how;
}

}  // namespace volrig::rig_detail

namespace volrig {

namespace {

BoneRig fit_on(const Grid& grid, const std::array<double, 3>& sampled, const std::uint8_t* bone, const Rig& rig,
              const BoneRigOptions& opt) {
    using namespace rig_detail;
    const std::vector<std::int64_t> voxels = bone_voxels(grid, bone);
    const BoneParams p = bone_params(grid, opt, voxels.size());
    return Fitter(grid, sampled, p, rig, segments_of(grid, voxels, p), voxels).run();
}

}  // namespace

BoneRig rig_to_bones(const Grid& grid, const std::uint8_t* bone, const Rig& rig, const BoneRigOptions& opt) {
    check_rig(rig);
    // slices far apart: fitted on the bone interpolated between them (rig_detail::Refined says why), the segments
    // given back on the scan's own grid
    const std::optional<rig_detail::Refined> fine = rig_detail::refine_slices(grid, bone);
    if (!fine) return fit_on(grid, grid.spacing, bone, rig, opt);
    BoneRig out = fit_on(fine->grid, grid.spacing, fine->bone.data(), rig, opt);
    out.segments = rig_detail::on_slices(*fine, grid, out.segments);
    return out;
}

}  // namespace volrig

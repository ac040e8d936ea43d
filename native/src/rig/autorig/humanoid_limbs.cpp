// rig/autorig/humanoid_limbs.cpp: where a humanoid's limb joints go when its medial axis does not show them: an arm
// fused with the trunk, a hip above the legs' fork, a straight knee (see templates.hpp).
#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "rig/autorig/templates.hpp"

namespace volrig::rig_detail {

std::optional<std::size_t> deepest_dip(const Chain4& chain, std::size_t lo, std::size_t hi, double voxel) {
    std::vector<double> after(hi - lo + 2, 0.0);  // after[k - lo]: the widest sample beyond k up to hi
    for (std::size_t k = hi; k > lo; --k) after[k - 1 - lo] = std::max(after[k - lo], chain[k][3]);
    std::optional<std::size_t> best;
    double best_rise = 0, before = 0;
    for (std::size_t k = lo; k <= hi; before = std::max(before, chain[k][3]), ++k) {
        const double wide = std::min(before, after[k - lo]), rise = wide / chain[k][3];
        if (widens(wide, chain[k][3], voxel) && rise >= best_rise) {
            best_rise = rise;
            best = k;
        }
    }
    return best;
}

namespace {

/// The line through points (least squares): their centroid and principal direction.
std::pair<Vec, Vec> line_through(const std::vector<Vec>& points) {
    Vec mean = Vec::Zero();
    for (const Vec& p : points) mean += p / static_cast<double>(points.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const Vec& p : points) cov += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    return {mean, eig.eigenvectors().col(2)};
}

/// The neck of a limb's chain within kNeckWindow of its radius (arc length) around sample `at` (deepest_dip there);
/// else none.
std::optional<std::size_t> narrowest_near(const Chain4& chain, std::size_t at, double voxel) {
    const double window = kNeckWindow * chain[at][3];
    const std::vector<double> arc = arc_of(chain);
    std::size_t lo = at, hi = at;
    while (lo > 0 && arc[at] - arc[lo - 1] <= window) --lo;
    while (hi + 1 < chain.size() && arc[hi + 1] - arc[at] <= window) ++hi;
    return deepest_dip(chain, lo, hi, voxel);
}

}  // namespace

std::size_t own_start(const Chain4& chain) {
    const std::size_t n = chain.size();
    if (n < 3) return 0;
    std::vector<double> beyond(n, 0.0);  // the largest radius of the samples after k
    for (std::size_t k = n - 1; k-- > 0;) beyond[k] = std::max(beyond[k + 1], chain[k + 1][3]);
    const std::vector<double> arc = arc_of(chain);
    std::size_t own = 0;
    for (std::size_t k = 0; k + 1 < n && arc[k] <= 0.5 * arc.back(); ++k)
        if (chain[k][3] > kTrunkJump * beyond[k]) own = k + 1;
    return own;
}

namespace {

constexpr int kCornerSteps = 4;

/// The shoulder joint from the visible upper arm's samples (from the top down): up the body (`body_up`) to the
/// object's surface (at most `limit`), then into the corner under the top and the outer side (`radius` in from
/// each, kCornerSteps alternating steps), front to back midway or `radius` behind the front (`front`, when given)
/// whichever lies further forward; none unless their line runs along `body_up`.
std::optional<Vec> shoulder_up_line(const RigContext& c, const std::vector<Vec>& upper, const Vec& body_up,
                                    const Vec& front, const Vec& chest, double radius, double limit) {
    if (upper.size() < 3) return std::nullopt;
    auto [mean, dir] = line_through(upper);
    if (dir.dot(upper.front() - upper.back()) < 0) dir = -dir;  // towards the trunk
    if (std::abs(dir.dot(body_up)) < kFusedAlongSpine) return std::nullopt;  // a girdle across the body
    const Vec rise = dir.dot(body_up) > 0 ? body_up : Vec(-body_up);
    // From the top of the visible upper arm: centred (a radius inside the outer side, midway front to back: the
    // visible axis leans out, its inner side being trunk), up to the shoulder's top and a radius back in, centred
    // again there.
    Vec at = mean + (upper.front() - mean).dot(dir) * dir;
    // The body's frame, fixed once (a frame following the point would turn with it): out from the chest across
    // the body, ahead towards the front (without a front: across both).
    Vec out = perp(at - chest, rise).normalized();
    if (front.norm() > 0) out = rise.cross(front).normalized() * (rise.cross(front).dot(out) < 0 ? -1.0 : 1.0);
    const Vec ahead = front.norm() > 0 ? Vec(perp(front, rise).normalized()) : Vec(rise.cross(out));
    auto centre = [&] {
        at += std::clamp(c.reach_inside(at, out, 0.0, 2.0 * radius) - radius, -radius, radius) * out;
        // Front to back: midway, or a radius behind the front where the shoulder is deeper than the arm is thick
        // (the shoulder blade behind the joint); midway without a front.
        const double ahead_reach = c.reach_inside(at, ahead, 0.0, 4.0 * radius);
        const double middle = 0.5 * (ahead_reach - c.reach_inside(at, -ahead, 0.0, 4.0 * radius));
        at += (front.norm() > 0 ? std::max(middle, ahead_reach - radius) : middle) * ahead;
    };
    centre();
    at += std::max(0.0, c.reach_inside(at, rise, 0.0, limit) - radius) * rise;
    centre();
    for (int k = 0; k < kCornerSteps; ++k) {  // into the corner: a radius below the top, a radius in from the side
        at += std::clamp(c.reach_inside(at, rise, 0.0, 2.0 * radius) - radius, -radius, radius) * rise;
        centre();
    }
    return at;
}

/// Upper arm, forearm and hand cut by proportional_fit over the shoulder joint and the own samples; cuts into the
/// chain (chest, own, elbow, wrist, tip), or none.
std::vector<std::size_t> fused_cuts(const Chain4& chain, std::size_t own, const Vec& shoulder) {
    Chain4 rest{Eigen::Vector4d(shoulder.x(), shoulder.y(), shoulder.z(), chain[own][3])};
    rest.insert(rest.end(), chain.begin() + static_cast<std::ptrdiff_t>(own), chain.end());
    const std::vector<double> ratios(kArmProportions.begin() + 1, kArmProportions.end());
    const Fit fit = proportional_fit(rest, ratios, chain.back()[3]);
    if (fit.cuts.size() != 4 || fit.cuts[1] < 2) return {};
    std::vector<std::size_t> cuts{0, own};
    for (std::size_t k = 1; k < 4; ++k) cuts.push_back(own + fit.cuts[k] - 1);
    return cuts;
}

std::vector<Vec> positions_of(const Chain4& chain, std::size_t from, std::size_t to) {
    std::vector<Vec> out;
    for (std::size_t k = from; k <= to && k < chain.size(); ++k) out.push_back(chain[k].head<3>());
    return out;
}

}  // namespace

std::optional<FusedArm> fused_arm(const RigContext& c, const Chain4& chain, const Vec& body_up, const Vec& front) {
    const std::size_t own = own_start(chain);
    if (own == 0 || own + 3 >= chain.size()) return std::nullopt;
    const std::vector<double> arc = arc_of(chain);
    const double r0 = chain[own][3], limit = 0.5 * (arc.back() - arc[own]);
    const Vec chest = chain.front().head<3>();
    // First the line of the visible top (kFusedTopRadii), then, once the elbow is known, of the whole visible
    // upper arm.
    std::size_t top_end = own;
    while (top_end + 1 < chain.size() && arc[top_end + 1] - arc[own] <= kFusedTopRadii * r0) ++top_end;
    std::optional<Vec> shoulder = shoulder_up_line(c, positions_of(chain, own, top_end), body_up, front, chest, r0, limit);
    if (!shoulder) return std::nullopt;
    std::vector<std::size_t> cuts = fused_cuts(chain, own, *shoulder);
    if (cuts.empty()) return std::nullopt;
    if (const auto better = shoulder_up_line(c, positions_of(chain, own, cuts[2]), body_up, front, chest, r0, limit)) {
        if (auto again = fused_cuts(chain, own, *better); !again.empty()) {
            shoulder = better;
            cuts = std::move(again);
        }
    }
    return FusedArm{own, *shoulder, cuts};
}

void shoulder_on_top(const RigContext& c, Rig& rig, const Chain4& arm, std::size_t top, std::size_t elbow,
                     const std::string& upper_arm, const Vec& body_up, const Vec& front) {
    const std::int32_t b = bone_index(rig, upper_arm);
    if (b < 0 || elbow <= top + 2) return;
    double radius = 0;
    for (std::size_t k = top; k <= elbow; ++k) radius += arm[k][3] / static_cast<double>(elbow - top + 1);
    const double length = (bone_end(rig, static_cast<std::size_t>(b), 0) - bone_end(rig, static_cast<std::size_t>(b), 1)).norm();
    if (const auto at = shoulder_up_line(c, positions_of(arm, top, elbow), body_up, front, arm.front().head<3>(), radius, length))
        move_joint(rig, rig.bones[static_cast<std::size_t>(b)][0], *at);
}

void place_fused_shoulder(Rig& rig, const std::string& upper_arm, const Vec& shoulder) {
    const std::int32_t b = bone_index(rig, upper_arm);
    if (b >= 0) move_joint(rig, rig.bones[static_cast<std::size_t>(b)][0], shoulder);
}

void hip_on_thigh_line(Rig& rig, const std::string& thigh) {
    const std::int32_t t = bone_index(rig, thigh), h = bone_index(rig, "hips");
    if (t < 0 || h < 0) return;
    const std::int32_t head = rig.bones[static_cast<std::size_t>(t)][0];
    const Vec knee = bone_end(rig, static_cast<std::size_t>(t), 1), hip = bone_end(rig, static_cast<std::size_t>(t), 0);
    const double length = (hip - knee).norm();
    if (length == 0) return;
    const Vec dir = (hip - knee) / length;
    const double along = (bone_end(rig, static_cast<std::size_t>(h), 0) - knee).dot(dir);
    if (along > length) move_joint(rig, head, knee + along * dir);
}

void straight_knee(const RigContext& c, Rig& rig, const std::vector<std::uint32_t>& leg, const std::string& sfx) {
    const std::int32_t thigh = bone_index(rig, "thigh" + sfx), shin = bone_index(rig, "shin" + sfx);
    if (thigh < 0 || shin < 0 || leg.empty()) return;
    const Vec hip = bone_end(rig, static_cast<std::size_t>(thigh), 0);
    const Vec ankle = bone_end(rig, static_cast<std::size_t>(shin), 1);
    const double length = (ankle - hip).norm();
    if (length == 0) return;
    const Vec dir = (ankle - hip) / length;
    const Chain4 chain = c.samples(leg);
    // The leg's axis between hip and ankle: straight when no node strays kStraightLegBend of their distance off
    // the hip-ankle line.
    double worst = -1;  // none between hip and ankle
    for (const auto& q : chain) {
        const Vec v = q.head<3>() - hip;
        if (v.dot(dir) > 0 && v.dot(dir) < length) worst = std::max(worst, perp(v, dir).norm());
    }
    if (worst < 0 || worst > kStraightLegBend * length) return;
    const double share = kLegProportions[1] / (kLegProportions[1] + kLegProportions[2]);
    // On the axis: the node nearest the proportional point along the line.
    std::size_t best = 0;
    auto off = [&](std::size_t k) { return std::abs((chain[k].head<3>() - hip).dot(dir) - share * length); };
    for (std::size_t k = 1; k < chain.size(); ++k)
        if (off(k) < off(best)) best = k;
    const std::optional<std::size_t> neck = narrowest_near(chain, best, c.grid.min_spacing());
    const Vec knee = chain[neck ? *neck : best].head<3>();
    move_joint(rig, rig.bones[static_cast<std::size_t>(thigh)][1], knee);
    // A knee found at its neck is the anatomical one: the hip goes up the thigh's line to the thigh's proportion
    // of the knee's height above the sole, when the legs' fork left it shorter. The sole, not the ankle: where the
    // ankle joint lies in a foot pointed down is less certain than how far the leg reaches below the knee.
    if (!neck) return;
    const Vec down = (ankle - knee).normalized();
    double height = 0;
    for (const auto& q : chain) height = std::max(height, (q.head<3>() - knee).dot(down) + q[3]);
    lengthen_proximal(c, rig, static_cast<std::size_t>(thigh), kThighToKneeHeight * height);
}

void heel_ankle(const RigContext& c, Rig& rig, const std::vector<std::uint32_t>& leg, const std::string& sfx) {
    const std::int32_t shin = bone_index(rig, "shin" + sfx);
    if (shin < 0 || leg.size() < 4) return;
    const Vec knee = bone_end(rig, static_cast<std::size_t>(shin), 0), ankle = bone_end(rig, static_cast<std::size_t>(shin), 1);
    const Chain4 chain = c.samples(leg);
    const std::vector<double> arc = arc_of(chain);
    const std::size_t bend = nearest_sample(chain, ankle);  // the axis node at the rig's ankle
    std::size_t heel = bend;  // the widest node within kNeckWindow radii of it
    for (std::size_t k = 0; k < chain.size(); ++k)
        if (std::abs(arc[k] - arc[bend]) <= kNeckWindow * chain[bend][3] && chain[k][3] > chain[heel][3]) heel = k;
    const Vec middle = 0.5 * (knee + ankle);  // the neck: the narrowest node from mid-shin to the heel
    const std::size_t from = nearest_sample(chain, middle);
    std::size_t neck = heel;
    for (std::size_t k = from; k < heel; ++k)
        if (chain[k][3] < chain[neck][3]) neck = k;
    if (neck == heel || !widens(chain[heel][3], chain[neck][3], c.grid.min_spacing()))
        return;  // no neck above a wider heel
    const double half = 0.5 * (arc[neck] + arc[heel]);
    std::size_t at = neck;
    while (at < heel && arc[at + 1] <= half) ++at;
    move_joint(rig, rig.bones[static_cast<std::size_t>(shin)][1], chain[at].head<3>());
}

void wrist_at_neck(const RigContext& c, Rig& rig, const std::vector<std::uint32_t>& arm, const std::string& sfx) {
    const std::int32_t forearm = bone_index(rig, "forearm" + sfx);
    if (forearm < 0 || arm.size() < 4) return;
    const Vec wrist = bone_end(rig, static_cast<std::size_t>(forearm), 1);
    const Chain4 chain = c.samples(arm);
    const std::vector<double> arc = arc_of(chain);
    const std::size_t at = nearest_sample(chain, wrist);  // the axis node at the rig's wrist
    std::optional<std::size_t> best;
    // No noise floor here (see kNeckNoise): a hand resting on the pelvis widens the mask beyond the wrist by
    // less than that at the Visible Human's 2 mm, and the wrist must also be the narrowest node of its window.
    const double voxel = 0.0;
    for (std::size_t k = 1; k + 1 < chain.size(); ++k) {
        const double window = kNeckWindow * chain[k][3];
        double before = 0, after = 0;
        bool lowest = true;
        for (std::size_t j = 0; j < chain.size(); ++j) {
            if (std::abs(arc[j] - arc[k]) > window || j == k) continue;
            lowest = lowest && chain[j][3] >= chain[k][3];
            (j < k ? before : after) = std::max(j < k ? before : after, chain[j][3]);
        }
        if (lowest && widens(before, chain[k][3], voxel) && widens(after, chain[k][3], voxel) &&
            (!best || std::abs(arc[k] - arc[at]) < std::abs(arc[*best] - arc[at])))
            best = k;
    }
    if (best) move_joint(rig, rig.bones[static_cast<std::size_t>(forearm)][1], chain[*best].head<3>());
}

namespace {

/// Joint `end` of bone `name` moved between the heads of bones `left` and `right`: midway across and at their
/// height along body_up; unchanged front to back.
void between(Rig& rig, const std::string& name, int end, const std::string& left, const std::string& right,
             const Vec& body_up) {
    const std::int32_t b = bone_index(rig, name), lb = bone_index(rig, left), rb = bone_index(rig, right);
    if (b < 0 || lb < 0 || rb < 0) return;
    const Vec l = bone_end(rig, static_cast<std::size_t>(lb), 0), r = bone_end(rig, static_cast<std::size_t>(rb), 0);
    if ((l - r).norm() == 0) return;
    const Vec across = (l - r).normalized(), up = perp(body_up, across).normalized();
    const Vec at = bone_end(rig, static_cast<std::size_t>(b), end), to = 0.5 * (l + r) - at;
    move_joint(rig, rig.bones[static_cast<std::size_t>(b)][static_cast<std::size_t>(end)],
               at + to.dot(across) * across + to.dot(up) * up);
}

}  // namespace

namespace {

/// The arc length of each piece of a fit.
std::vector<double> piece_lengths(const Chain4& chain, const Fit& f) {
    const std::vector<double> arc = arc_of(chain);
    std::vector<double> out;
    for (std::size_t j = 0; j + 1 < f.cuts.size(); ++j) out.push_back(arc[f.cuts[j + 1]] - arc[f.cuts[j]]);
    return out;
}

/// Each length after the first over their sum (the first: the root's bone, which the fork sets).
std::vector<double> distal_shares(const std::vector<double>& lengths) {
    double sum = 0;
    for (std::size_t j = 1; j < lengths.size(); ++j) sum += lengths[j];
    std::vector<double> out;
    for (std::size_t j = 1; j < lengths.size(); ++j) out.push_back(sum > 0 ? lengths[j] / sum : 0.0);
    return out;
}

}  // namespace

void match_limb_fits(const RigContext& c, const std::vector<std::uint32_t> (&limb)[2], Fit (&fit)[2],
                     const std::vector<double>& prior) {
    Chain4 chain[2];
    std::vector<double> length[2], share[2];
    for (int s = 0; s < 2; ++s) {
        chain[s] = c.samples(limb[s]);
        length[s] = piece_lengths(chain[s], fit[s]);
        if (length[s].size() != prior.size()) return;
        share[s] = distal_shares(length[s]);
    }
    double mismatch = 0;
    for (std::size_t j = 0; j < share[0].size(); ++j) mismatch = std::max(mismatch, std::abs(share[0][j] - share[1][j]));
    if (mismatch <= kLimbMismatch) return;
    const std::vector<double> expected = distal_shares(prior);
    auto off = [&](const std::vector<double>& sh) {
        double sum = 0;
        for (std::size_t j = 0; j < sh.size(); ++j) sum += std::abs(std::log(std::max(sh[j], 1e-9) / expected[j]));
        return sum;
    };
    const int bad = off(share[0]) > off(share[1]) ? 0 : 1;
    // The root's bone (pelvis, shoulder) keeps its cut: the fork set it, not a bend.
    const std::size_t root = fit[bad].cuts[1];
    const Chain4 distal(chain[bad].begin() + static_cast<std::ptrdiff_t>(root), chain[bad].end());
    const Fit again = proportional_fit(distal, std::vector<double>(length[1 - bad].begin() + 1, length[1 - bad].end()),
                                       0.0, kMatchWeight * kProportionWeight);
    if (again.cuts.size() + 1 != fit[bad].cuts.size()) return;
    for (std::size_t j = 0; j < again.cuts.size(); ++j) fit[bad].cuts[j + 1] = root + again.cuts[j];
}

void raise_low_hips(const RigContext& c, Rig& rig, const std::vector<std::uint32_t> (&leg)[2],
                    const std::string (&sfx)[2], const Vec& body_up) {
    const std::int32_t neck = bone_index(rig, "neck");
    std::int32_t thigh[2], shin[2];
    for (int s = 0; s < 2; ++s) {
        thigh[s] = bone_index(rig, "thigh" + sfx[s]);
        shin[s] = bone_index(rig, "shin" + sfx[s]);
        if (thigh[s] < 0 || shin[s] < 0 || leg[s].empty()) return;
    }
    if (neck < 0) return;
    const Chain4 chain[2] = {c.samples(leg[0]), c.samples(leg[1])};
    double sole = std::numeric_limits<double>::infinity(), hip = 0;
    for (int s = 0; s < 2; ++s) {
        for (const auto& q : chain[s]) sole = std::min(sole, q.head<3>().dot(body_up) - q[3]);
        hip += 0.5 * bone_end(rig, static_cast<std::size_t>(thigh[s]), 0).dot(body_up);
    }
    const double neck_height = bone_end(rig, static_cast<std::size_t>(neck), 0).dot(body_up) - sole;
    const double least = sole + kLeastHipHeight * neck_height;
    if (hip >= least) return;
    const double share = kLegProportions[1] / (kLegProportions[1] + kLegProportions[2]);
    for (int s = 0; s < 2; ++s) {
        const auto t = static_cast<std::size_t>(thigh[s]);
        const Vec head = bone_end(rig, t, 0) + (least - hip) * body_up;
        move_joint(rig, rig.bones[t][0], head);
        const Vec want = head + share * (bone_end(rig, static_cast<std::size_t>(shin[s]), 1) - head);
        move_joint(rig, rig.bones[t][1], chain[s][nearest_sample(chain[s], want)].head<3>());
    }
}

void level_hips(Rig& rig, const Vec& body_up) {
    const std::int32_t l = bone_index(rig, "thigh.L"), r = bone_index(rig, "thigh.R");
    if (l < 0 || r < 0) return;
    const Vec hl = bone_end(rig, static_cast<std::size_t>(l), 0), hr = bone_end(rig, static_cast<std::size_t>(r), 0);
    const double half = 0.5 * (hr - hl).dot(body_up);
    move_joint(rig, rig.bones[static_cast<std::size_t>(l)][0], hl + half * body_up);
    move_joint(rig, rig.bones[static_cast<std::size_t>(r)][0], hr - half * body_up);
}

void centre_chest(Rig& rig, const Vec& body_up) {
    between(rig, "chest", 1, "upper_arm.L", "upper_arm.R", body_up);
    between(rig, "hips", 0, "thigh.L", "thigh.R", body_up);
}

void recut_spine(Rig& rig, Chain4 spine) {
    const std::int32_t h = bone_index(rig, "hips"), s = bone_index(rig, "spine"), c = bone_index(rig, "chest");
    if (h < 0 || s < 0 || c < 0 || spine.size() < 4) return;
    spine.front().head<3>() = bone_end(rig, static_cast<std::size_t>(h), 0);
    spine.back().head<3>() = bone_end(rig, static_cast<std::size_t>(c), 1);
    const Fit fit = trunk_fit(spine);
    if (fit.cuts.size() != 4) return;
    move_joint(rig, rig.bones[static_cast<std::size_t>(s)][0], spine[fit.cuts[1]].head<3>());
    move_joint(rig, rig.bones[static_cast<std::size_t>(c)][0], spine[fit.cuts[2]].head<3>());
}

void place_head(const RigContext& c, Rig& rig, const Chain4& head, const Vec& body_up) {
    const std::int32_t h = bone_index(rig, "head"), n = bone_index(rig, "neck");
    if (h < 0 || n < 0 || head.empty()) return;
    const auto hb = static_cast<std::size_t>(h);
    const Vec base = bone_end(rig, static_cast<std::size_t>(n), 0);
    // The top of the head: up from the head joint, at most four times the neck and head's extent.
    const double extent = (bone_end(rig, hb, 1) - base).norm() + (bone_end(rig, hb, 0) - base).norm();
    const Vec top = bone_end(rig, hb, 0) + c.reach_inside(bone_end(rig, hb, 0), body_up, 0.0, 4.0 * extent) * body_up;
    const double height = (top - base).dot(body_up);
    if (height <= 0) return;
    const double want = (1.0 - kHeadShare) * height;  // above the neck's base
    std::size_t at = 0;
    for (std::size_t k = 1; k < head.size(); ++k)
        if (std::abs((head[k].head<3>() - base).dot(body_up) - want) < std::abs((head[at].head<3>() - base).dot(body_up) - want))
            at = k;
    // Centred in the head's section at that height (the axis may run to the face or to the crown).
    Vec joint = head[at].head<3>();
    // Across the body (from the right shoulder to the left: the same axes whichever way the object is turned) and
    // front to back.
    const std::int32_t l = bone_index(rig, "upper_arm.L"), r = bone_index(rig, "upper_arm.R");
    Vec across = body_up.unitOrthogonal();
    if (l >= 0 && r >= 0)
        if (const Vec a = perp(bone_end(rig, static_cast<std::size_t>(l), 0) - bone_end(rig, static_cast<std::size_t>(r), 0), body_up);
            a.norm() > 0)
            across = a.normalized();
    for (const Vec& d : {across, Vec(body_up.cross(across))}) {
        const double limit = 2.0 * height;
        joint += 0.5 * (c.reach_inside(joint, d, 0.0, limit) - c.reach_inside(joint, -d, 0.0, limit)) * d;
    }
    move_joint(rig, rig.bones[hb][0], joint);
    move_joint(rig, rig.bones[hb][1], joint + kHeadTail * c.reach_inside(joint, body_up, 0.0, 2.0 * height) * body_up);
}

void end_hands_and_feet(Rig& rig) {
    std::vector<int> heads(rig.joints.size(), 0);
    for (const auto& b : rig.bones) ++heads[static_cast<std::size_t>(b[0])];
    for (const char* side : {".L", ".R"})
        for (const auto& [name, share] : {std::pair{"hand", kHandToKnuckles}, std::pair{"foot", kFootToBall}}) {
            const std::int32_t b = bone_index(rig, name + std::string(side));
            if (b < 0 || heads[static_cast<std::size_t>(rig.bones[static_cast<std::size_t>(b)][1])]) continue;
            const auto bb = static_cast<std::size_t>(b);
            const Vec head = bone_end(rig, bb, 0);
            move_joint(rig, rig.bones[bb][1], head + share * (bone_end(rig, bb, 1) - head));
        }
}

namespace {

/// The points of the two lines a + s u and b + t v closest to each other, midway; none when they are parallel.
std::optional<Vec> closest_between(const Vec& a, const Vec& u, const Vec& b, const Vec& v) {
    const double uv = u.dot(v), den = 1 - uv * uv;
    if (den < 1e-9) return std::nullopt;
    const Vec w = a - b;
    const double s = (uv * v.dot(w) - u.dot(w)) / den, t = (v.dot(w) - uv * u.dot(w)) / den;
    return 0.5 * (a + s * u + b + t * v);
}

}  // namespace

void bend_corner(const RigContext& c, Rig& rig, const std::vector<std::uint32_t>& limb, const std::string& proximal,
                 const std::string& distal) {
    const std::int32_t p = bone_index(rig, proximal), d = bone_index(rig, distal);
    if (p < 0 || d < 0 || limb.size() < 7) return;
    const Vec joint = bone_end(rig, static_cast<std::size_t>(p), 1);
    const Chain4 chain = c.samples(limb);
    const std::vector<double> arc = arc_of(chain);
    const std::size_t at = nearest_sample(chain, joint);  // the axis sample at the joint
    const double radius = chain[at][3];
    std::vector<Vec> before, after;  // each bone's axis, off the rounded bend
    for (std::size_t k = 0; k < chain.size(); ++k)
        if (std::abs(arc[k] - arc[at]) > kBendRound * radius) (k < at ? before : after).push_back(chain[k].head<3>());
    if (before.size() < 3 || after.size() < 3) return;
    auto [a, u] = line_through(before);
    auto [b, v] = line_through(after);
    if (u.dot(before.back() - before.front()) < 0) u = -u;  // both along the limb, outwards
    if (v.dot(after.back() - after.front()) < 0) v = -v;
    if (u.dot(v) > std::cos(kBendAngle)) return;  // straight: the axis shows the joint
    const std::optional<Vec> corner = closest_between(a, u, b, v);
    if (!corner) return;
    const double dist = (*corner - joint).norm();
    if (dist == 0) return;
    const Vec dir = (*corner - joint) / dist;
    // Towards the corner, at most a radius and staying half a radius inside the object.
    const double reach = c.reach_inside(joint, dir, 0.0, dist + radius) - 0.5 * radius;
    const double move = std::min({dist, radius, reach});
    if (move > 0) move_joint(rig, rig.bones[static_cast<std::size_t>(p)][1], joint + move * dir);
}

}  // namespace volrig::rig_detail

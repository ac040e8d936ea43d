// autorig/humanoid_limbs.cpp: where a humanoid's limb joints go when its medial axis does not show them: an arm
// fused with the trunk, a hip above the legs' fork, a straight knee (see templates.hpp).
#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "autorig/templates.hpp"

namespace volrig::rigging {

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

/// The sample of a limb's chain where it is narrowest within kNeckWindow of its radius (arc length) around sample
/// `at`, when the radius rises from there by kNeckRise on both sides within that window (a knee between thigh and
/// calf); else none.
std::optional<std::size_t> narrowest_near(const Chain4& chain, std::size_t at) {
    const double window = kNeckWindow * chain[at][3];
    const std::vector<double> arc = arc_of(chain);
    std::size_t lo = at, hi = at;
    while (lo > 0 && arc[at] - arc[lo - 1] <= window) --lo;
    while (hi + 1 < chain.size() && arc[hi + 1] - arc[at] <= window) ++hi;
    std::size_t m = lo;
    for (std::size_t k = lo; k <= hi; ++k)
        if (chain[k][3] < chain[m][3]) m = k;
    double before = 0, after = 0;
    for (std::size_t k = lo; k < m; ++k) before = std::max(before, chain[k][3]);
    for (std::size_t k = m + 1; k <= hi; ++k) after = std::max(after, chain[k][3]);
    const double rise = (1 + kNeckRise) * chain[m][3];
    if (before >= rise && after >= rise) return m;
    return std::nullopt;
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

/// The shoulder joint of a fused arm from the visible upper arm's samples (from the top down): up the body
/// (`body_up`) to the object's surface (at most `limit`), then `radius` back in, `radius` inside the surface away
/// from the chest and midway front to back; none unless their line runs along `body_up`.
std::optional<Vec> shoulder_up_line(const RigContext& c, const std::vector<Vec>& upper, const Vec& body_up,
                                    const Vec& chest, double radius, double limit) {
    if (upper.size() < 3) return std::nullopt;
    auto [mean, dir] = line_through(upper);
    if (dir.dot(upper.front() - upper.back()) < 0) dir = -dir;  // towards the trunk
    if (std::abs(dir.dot(body_up)) < kFusedAlongSpine) return std::nullopt;  // a girdle across the body
    const Vec rise = dir.dot(body_up) > 0 ? body_up : Vec(-body_up);
    // From the top of the visible upper arm: centred (a radius inside the outer side, midway front to back: the
    // visible axis leans out, its inner side being trunk), up to the shoulder's top and a radius back in, centred
    // again there.
    Vec at = mean + (upper.front() - mean).dot(dir) * dir;
    auto centre = [&] {
        const Vec out = perp(at - chest, rise).normalized(), ahead = rise.cross(out);
        at += std::clamp(c.reach_inside(at, out, 0.0, 2.0 * radius) - radius, -radius, radius) * out;
        const double front = c.reach_inside(at, ahead, 0.0, 4.0 * radius);
        at += 0.5 * (front - c.reach_inside(at, -ahead, 0.0, 4.0 * radius)) * ahead;
    };
    centre();
    at += std::max(0.0, c.reach_inside(at, rise, 0.0, limit) - radius) * rise;
    centre();
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

std::optional<FusedArm> fused_arm(const RigContext& c, const Chain4& chain, const Vec& body_up) {
    const std::size_t own = own_start(chain);
    if (own == 0 || own + 3 >= chain.size()) return std::nullopt;
    const std::vector<double> arc = arc_of(chain);
    const double r0 = chain[own][3], limit = 0.5 * (arc.back() - arc[own]);
    const Vec chest = chain.front().head<3>();
    // First the line of the visible top (kFusedTopRadii), then, once the elbow is known, of the whole visible
    // upper arm.
    std::size_t top_end = own;
    while (top_end + 1 < chain.size() && arc[top_end + 1] - arc[own] <= kFusedTopRadii * r0) ++top_end;
    std::optional<Vec> shoulder = shoulder_up_line(c, positions_of(chain, own, top_end), body_up, chest, r0, limit);
    if (!shoulder) return std::nullopt;
    std::vector<std::size_t> cuts = fused_cuts(chain, own, *shoulder);
    if (cuts.empty()) return std::nullopt;
    if (const auto better = shoulder_up_line(c, positions_of(chain, own, cuts[2]), body_up, chest, r0, limit)) {
        if (auto again = fused_cuts(chain, own, *better); !again.empty()) {
            shoulder = better;
            cuts = std::move(again);
        }
    }
    return FusedArm{own, *shoulder, cuts};
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
    // The leg's axis between hip and ankle: straight when no node strays kStraightLeg of the mean radius off the
    // hip-ankle line.
    double worst = 0, radius = 0;
    std::size_t count = 0;
    for (const auto& q : chain) {
        const Vec v = q.head<3>() - hip;
        if (v.dot(dir) <= 0 || v.dot(dir) >= length) continue;
        worst = std::max(worst, perp(v, dir).norm());
        radius += q[3];
        ++count;
    }
    if (count == 0 || worst > kStraightLeg * radius / static_cast<double>(count)) return;
    const double share = kLegProportions[1] / (kLegProportions[1] + kLegProportions[2]);
    // On the axis: the node nearest the proportional point along the line.
    std::size_t best = 0;
    auto off = [&](std::size_t k) { return std::abs((chain[k].head<3>() - hip).dot(dir) - share * length); };
    for (std::size_t k = 1; k < chain.size(); ++k)
        if (off(k) < off(best)) best = k;
    const std::optional<std::size_t> neck = narrowest_near(chain, best);
    const Vec knee = chain[neck ? *neck : best].head<3>();
    move_joint(rig, rig.bones[static_cast<std::size_t>(thigh)][1], knee);
    // A knee found at its neck is the anatomical one: the hip goes up the thigh's line to the thigh's proportion
    // of the shin, when the legs' fork left it shorter.
    if (neck)
        lengthen_proximal(c, rig, static_cast<std::size_t>(thigh), kLegProportions[1] / kLegProportions[2] * (ankle - knee).norm());
}

void heel_ankle(const RigContext& c, Rig& rig, const std::vector<std::uint32_t>& leg, const std::string& sfx) {
    const std::int32_t shin = bone_index(rig, "shin" + sfx);
    if (shin < 0 || leg.size() < 4) return;
    const Vec knee = bone_end(rig, static_cast<std::size_t>(shin), 0), ankle = bone_end(rig, static_cast<std::size_t>(shin), 1);
    const Chain4 chain = c.samples(leg);
    const std::vector<double> arc = arc_of(chain);
    std::size_t bend = 0;  // the axis node at the rig's ankle
    for (std::size_t k = 1; k < chain.size(); ++k)
        if ((chain[k].head<3>() - ankle).norm() < (chain[bend].head<3>() - ankle).norm()) bend = k;
    std::size_t heel = bend;  // the widest node within kNeckWindow radii of it
    for (std::size_t k = 0; k < chain.size(); ++k)
        if (std::abs(arc[k] - arc[bend]) <= kNeckWindow * chain[bend][3] && chain[k][3] > chain[heel][3]) heel = k;
    const Vec middle = 0.5 * (knee + ankle);  // the neck: the narrowest node from mid-shin to the heel
    std::size_t from = 0;
    for (std::size_t k = 1; k < chain.size(); ++k)
        if ((chain[k].head<3>() - middle).norm() < (chain[from].head<3>() - middle).norm()) from = k;
    std::size_t neck = heel;
    for (std::size_t k = from; k < heel; ++k)
        if (chain[k][3] < chain[neck][3]) neck = k;
    if (neck == heel || chain[heel][3] < (1 + kNeckRise) * chain[neck][3]) return;  // no neck above a wider heel
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
    std::size_t at = 0;  // the axis node at the rig's wrist
    for (std::size_t k = 1; k < chain.size(); ++k)
        if ((chain[k].head<3>() - wrist).norm() < (chain[at].head<3>() - wrist).norm()) at = k;
    std::optional<std::size_t> best;
    for (std::size_t k = 1; k + 1 < chain.size(); ++k) {
        const double window = kNeckWindow * chain[k][3], rise = (1 + kNeckRise) * chain[k][3];
        double before = 0, after = 0;
        bool lowest = true;
        for (std::size_t j = 0; j < chain.size(); ++j) {
            if (std::abs(arc[j] - arc[k]) > window || j == k) continue;
            lowest = lowest && chain[j][3] >= chain[k][3];
            (j < k ? before : after) = std::max(j < k ? before : after, chain[j][3]);
        }
        if (lowest && before >= rise && after >= rise &&
            (!best || std::abs(arc[k] - arc[at]) < std::abs(arc[*best] - arc[at])))
            best = k;
    }
    if (best) move_joint(rig, rig.bones[static_cast<std::size_t>(forearm)][1], chain[*best].head<3>());
}

void centre_chest(Rig& rig) {
    const std::int32_t chest = bone_index(rig, "chest"), left = bone_index(rig, "upper_arm.L"),
                       right = bone_index(rig, "upper_arm.R");
    if (chest < 0 || left < 0 || right < 0) return;
    const Vec l = bone_end(rig, static_cast<std::size_t>(left), 0), r = bone_end(rig, static_cast<std::size_t>(right), 0);
    if ((l - r).norm() == 0) return;
    const Vec across = (l - r).normalized();
    const std::int32_t j = rig.bones[static_cast<std::size_t>(chest)][1];
    const Vec at = bone_end(rig, static_cast<std::size_t>(chest), 1);
    move_joint(rig, j, at + (0.5 * (l + r) - at).dot(across) * across);
}

void head_up(const RigContext& c, Rig& rig, const Vec& body_up) {
    const std::int32_t h = bone_index(rig, "head");
    if (h < 0) return;
    const Vec base = bone_end(rig, static_cast<std::size_t>(h), 0), tip = bone_end(rig, static_cast<std::size_t>(h), 1);
    const double length = (tip - base).norm();
    if (length == 0 || (tip - base).dot(body_up) >= kHeadUp * length) return;
    const double reach = c.reach_inside(base, body_up, 0.0, 3.0 * length);
    if (reach > 0) move_joint(rig, rig.bones[static_cast<std::size_t>(h)][1], base + reach * body_up);
}

}  // namespace volrig::rigging

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

Vec joint_at(const Rig& rig, std::int32_t j) {
    const auto& p = rig.joints[static_cast<std::size_t>(j)];
    return Vec(p[0], p[1], p[2]);
}

void move_joint(Rig& rig, std::int32_t j, const Vec& q) {
    rig.joints[static_cast<std::size_t>(j)] = {q.x(), q.y(), q.z()};
    rig.joint_points[static_cast<std::size_t>(j)] = -1;
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

/// The shoulder joint of a fused arm from the visible upper arm's samples (from the top down): up their line to
/// the object's surface (at most `limit`), then `radius` back in; none unless the line runs along the spine.
std::optional<Vec> shoulder_up_line(const RigContext& c, const std::vector<Vec>& upper, const Vec& spine_dir,
                                    double radius, double limit) {
    if (upper.size() < 3) return std::nullopt;
    auto [mean, dir] = line_through(upper);
    if (dir.dot(upper.front() - upper.back()) < 0) dir = -dir;  // towards the trunk
    if (std::abs(dir.dot(spine_dir)) < kFusedAlongSpine) return std::nullopt;  // a girdle across the body
    const Vec from = mean + (upper.front() - mean).dot(dir) * dir;
    return from + std::max(0.0, c.reach_inside(from, dir, 0.0, limit) - radius) * dir;
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

std::optional<FusedArm> fused_arm(const RigContext& c, const Chain4& chain, const Vec& spine_dir) {
    const std::size_t own = own_start(chain);
    if (own == 0 || own + 3 >= chain.size()) return std::nullopt;
    const std::vector<double> arc = arc_of(chain);
    const double r0 = chain[own][3], limit = 0.5 * (arc.back() - arc[own]);
    // First the line of the visible top (kFusedTopRadii), then, once the elbow is known, of the whole visible
    // upper arm.
    std::size_t top_end = own;
    while (top_end + 1 < chain.size() && arc[top_end + 1] - arc[own] <= kFusedTopRadii * r0) ++top_end;
    std::optional<Vec> shoulder = shoulder_up_line(c, positions_of(chain, own, top_end), spine_dir, r0, limit);
    if (!shoulder) return std::nullopt;
    std::vector<std::size_t> cuts = fused_cuts(chain, own, *shoulder);
    if (cuts.empty()) return std::nullopt;
    if (const auto better = shoulder_up_line(c, positions_of(chain, own, cuts[2]), spine_dir, r0, limit)) {
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
    const Vec knee = joint_at(rig, rig.bones[static_cast<std::size_t>(t)][1]), hip = joint_at(rig, head);
    const double length = (hip - knee).norm();
    if (length == 0) return;
    const Vec dir = (hip - knee) / length;
    const double along = (joint_at(rig, rig.bones[static_cast<std::size_t>(h)][0]) - knee).dot(dir);
    if (along > length) move_joint(rig, head, knee + along * dir);
}

void straight_knee(const RigContext& c, Rig& rig, const std::vector<std::uint32_t>& leg, const std::string& sfx) {
    const std::int32_t thigh = bone_index(rig, "thigh" + sfx), shin = bone_index(rig, "shin" + sfx);
    if (thigh < 0 || shin < 0) return;
    const std::int32_t knee = rig.bones[static_cast<std::size_t>(thigh)][1];
    const Vec hip = joint_at(rig, rig.bones[static_cast<std::size_t>(thigh)][0]);
    const Vec ankle = joint_at(rig, rig.bones[static_cast<std::size_t>(shin)][1]);
    const double length = (ankle - hip).norm();
    if (length == 0) return;
    const Vec dir = (ankle - hip) / length;
    // The leg's axis between hip and ankle: straight when no node strays kStraightLeg of the mean radius off the
    // hip-ankle line.
    double worst = 0, radius = 0;
    std::size_t count = 0;
    for (const std::uint32_t v : leg) {
        const double s = (c.tree.at(v) - hip).dot(dir);
        if (s <= 0 || s >= length) continue;
        worst = std::max(worst, perp(c.tree.at(v) - hip, dir).norm());
        radius += c.tree.radius(v);
        ++count;
    }
    if (count == 0 || worst > kStraightLeg * radius / static_cast<double>(count)) return;
    const double share = kLegProportions[1] / (kLegProportions[1] + kLegProportions[2]);
    // On the axis: the node nearest the proportional point along the line.
    std::uint32_t best = kNone;
    for (const std::uint32_t v : leg)
        if (best == kNone || std::abs((c.tree.at(v) - hip).dot(dir) - share * length) <
                                 std::abs((c.tree.at(best) - hip).dot(dir) - share * length))
            best = v;
    move_joint(rig, knee, c.tree.at(best));
}

}  // namespace volrig::rigging

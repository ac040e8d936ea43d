// rig/autorig/body_plan.cpp: the humanoid and quadruped templates: a scored discrete search over which extremities
// are head, legs and arms, then the role-named rig of the best (see templates.hpp).
#include <algorithm>
#include <array>
#include <cmath>

#include "rig/autorig/templates.hpp"

namespace volrig::rig_detail {

namespace {

/// How far two limb tips x, y (meeting at `base`) are from mirroring each other across the body's midplane: both
/// tips at the same place along the spine's line (through `pelvis` along `axis`) and at the same distance from it,
/// relative to the limbs' length. Straight-line measures: paths through a cluttered trunk wander.
double mirror(const NodeTree& t, std::uint32_t pelvis, const Vec& axis, std::uint32_t x, std::uint32_t y,
              std::uint32_t base) {
    const Vec px = t.at(x) - t.at(pelvis), py = t.at(y) - t.at(pelvis);
    const double tx = px.dot(axis), ty = py.dot(axis);
    const double rx = (px - tx * axis).norm(), ry = (py - ty * axis).norm();
    return (std::abs(tx - ty) + std::abs(rx - ry)) / std::max((t.at(x) - t.at(base)).norm() + (t.at(y) - t.at(base)).norm(), 1e-12);
}

/// A humanoid's arms hang from its chest and are shorter than its torso and legs: its hands stay well above its
/// feet along the spine (at mid-thigh when hanging, higher when raised). How far short of a quarter of the legs'
/// length above the feet they stay: 0 for a humanoid, about 0.25 or more for a quadruped's four feet on the
/// ground read as legs and arms.
double hands_at_feet(const NodeTree& t, std::uint32_t pelvis, const Vec& axis, const std::uint32_t (&legs)[2],
                     const std::uint32_t (&arms)[2]) {
    double feet = 0, hands = 0, leg_length = 0;
    for (int s = 0; s < 2; ++s) {
        feet += 0.5 * (t.at(legs[s]) - t.at(pelvis)).dot(axis);
        hands += 0.5 * (t.at(arms[s]) - t.at(pelvis)).dot(axis);
        leg_length += 0.5 * (t.at(legs[s]) - t.at(pelvis)).norm();
    }
    return std::max(0.0, kHandsAboveFeet - (hands - feet) / std::max(leg_length, 1e-12));
}

/// Where the limbs' left-right direction is taken: this share of the way out along each limb's path.
constexpr double kRootShare = 1.0 / 3.0;

/// Unit direction from a to b (zero when they coincide).
Vec unit(const Vec& a, const Vec& b) {
    const Vec d = b - a;
    return d.norm() > 0 ? Vec(d / d.norm()) : Vec::Zero();
}

/// How much a limb (base to tip) is a sheet: the median, over the nodes of its middle third (out of the trunk,
/// short of the hand or foot, which are flat on every animal), of how far their cross-section's width exceeds its
/// thickness (NodeTree::sheet - 1), over kSheetRatio - 1 and at most 1 (a round limb 0; a wing, a fin or a
/// flipper, flat along its whole length, 1).
constexpr double kSheetRatio = 4.0;
double flatness(const NodeTree& t, const std::vector<std::uint32_t>& path) {
    // The middle third: nodes [n/3, ceil(2n/3)), at least one.
    const std::size_t n = path.size(), lo = n / 3, hi = std::min(n, std::max(lo + 1, (2 * n + 2) / 3));
    return std::clamp((t.median_sheet(path, lo, hi) - 1.0) / (kSheetRatio - 1.0), 0.0, 1.0);
}

/// A reading's limb paths, computed once: legs from the pelvis, arms from the chest.
struct LimbPaths {
    std::vector<std::uint32_t> legs[2], arms[2];
    LimbPaths(const NodeTree& t, const Reading& r)
        : legs{t.path(r.pelvis, r.legs[0]), t.path(r.pelvis, r.legs[1])},
          arms{t.path(r.chest, r.arms[0]), t.path(r.chest, r.arms[1])} {}
};

/// The features every reading of five extremities shares, whatever its kind (plan_score.hpp).
PlanFeatures shared_features(const NodeTree& t, const Reading& r, const LimbPaths& p, double left_out,
                             double left_out_thickness, double object_extent) {
    PlanFeatures f{};
    const Vec axis = unit(t.at(r.pelvis), t.at(r.chest));
    f[kMirrorLegs] = mirror(t, r.pelvis, axis, r.legs[0], r.legs[1], r.pelvis);
    f[kMirrorArms] = mirror(t, r.pelvis, axis, r.arms[0], r.arms[1], r.chest);
    f[kLeftOut] = left_out;
    f[kHeadThin] = t.end_radius(r.head) < left_out_thickness ? 1.0 : 0.0;
    const Vec across_legs = perp(t.at(r.legs[0]) - t.at(r.legs[1]), axis).normalized();
    const Vec across_arms = perp(t.at(r.arms[0]) - t.at(r.arms[1]), axis).normalized();
    // The same at the limbs' roots (a third of the way out): their tips swing with the pose (a stride).
    auto root = [&](const std::vector<std::uint32_t>& path) { return t.point_along(path, kRootShare); };
    const Vec roots_legs = perp(root(p.legs[0]) - root(p.legs[1]), axis).normalized();
    const Vec roots_arms = perp(root(p.arms[0]) - root(p.arms[1]), axis).normalized();
    f[kRootsCross] = 1.0 - std::abs(roots_legs.dot(roots_arms));
    f[kPairsCross] = 1.0 - std::abs(across_legs.dot(across_arms));
    f[kHeadBehind] = std::max(0.0, -unit(t.at(r.chest), t.at(r.head)).dot(axis));
    double reach = 0;
    for (int s = 0; s < 2; ++s)
        reach += 0.25 * ((t.at(r.legs[s]) - t.at(r.pelvis)).norm() + (t.at(r.arms[s]) - t.at(r.chest)).norm());
    f[kLimbsShort] = std::max(0.0, 1.0 - reach / std::max((t.at(r.head) - t.at(r.chest)).norm(), 1e-12));
    const double leg = t.length(p.legs[0]) + t.length(p.legs[1]), arm = t.length(p.arms[0]) + t.length(p.arms[1]);
    f[kLimbRatio] = std::abs(std::log(std::max(leg, 1e-12) / std::max(arm, 1e-12)));
    f[kArmsFlat] = 0.5 * (flatness(t, p.arms[0]) + flatness(t, p.arms[1]));
    f[kLegsFlat] = 0.5 * (flatness(t, p.legs[0]) + flatness(t, p.legs[1]));
    f[kNarrowSpan] =
        std::max(0.0, 1.0 - t.extent({r.head, r.legs[0], r.legs[1], r.arms[0], r.arms[1]}) / std::max(object_extent, 1e-12));
    return f;
}

/// The humanoid reading's own features (plan_score.hpp).
void humanoid_features(const NodeTree& t, const Reading& r, const LimbPaths& p, const std::optional<Vec>& up,
                       PlanFeatures& f) {
    const Vec axis = unit(t.at(r.pelvis), t.at(r.chest));
    f[kBiasHumanoid] = 1;
    const double rl = 0.5 * (t.mean_radius(p.legs[0]) + t.mean_radius(p.legs[1]));
    const double ra = 0.5 * (t.mean_radius(p.arms[0]) + t.mean_radius(p.arms[1]));
    f[kHLegsThin] = std::max(0.0, (ra - rl) / std::max(ra, 1e-12));
    f[kHHandsLow] = hands_at_feet(t, r.pelvis, axis, r.legs, r.arms);
    const Vec legs = (0.5 * (t.at(r.legs[0]) + t.at(r.legs[1])) - t.at(r.pelvis)).normalized();
    f[kHLegsNotDown] = 0.5 * (1.0 + legs.dot(axis));
    if (up) f[kHSpineNotUp] = 0.5 * (1.0 - axis.dot(*up));  // without up, the reading's up is its spine: 0
}

/// The quadruped reading's own features (plan_score.hpp).
void quadruped_features(const NodeTree& t, const Reading& r, const std::optional<Vec>& up, PlanFeatures& f) {
    const Vec axis = unit(t.at(r.pelvis), t.at(r.chest));
    f[kBiasQuadruped] = 1;
    Vec limbs = Vec::Zero();
    for (int s = 0; s < 2; ++s) limbs += unit(t.at(r.pelvis), t.at(r.legs[s])) + unit(t.at(r.chest), t.at(r.arms[s]));
    const Vec legs = unit(t.at(r.pelvis), 0.5 * (t.at(r.legs[0]) + t.at(r.legs[1])));
    f[kQLegsAlong] = std::abs(legs.dot(axis));
    // Without up, the reading's own up: against its limbs' mean direction (how far they agree is what is left).
    const Vec u = up ? *up : (limbs.norm() > 0 ? Vec(-limbs.normalized()) : Vec::Zero());
    f[kQLimbsNotDown] = 0.5 * (1.0 + 0.25 * limbs.dot(u));
    f[kQSpineTilt] = std::abs(axis.dot(u));
}

/// The winged reading's own features (plan_score.hpp): its arms are wings, so their flatness is no penalty but
/// its lack is.
void winged_features(const NodeTree& t, const Reading& r, const std::optional<Vec>& up, PlanFeatures& f) {
    f[kBiasWinged] = 1;
    f[kWWingsRound] = 1.0 - f[kArmsFlat];
    f[kArmsFlat] = 0;
    if (up) f[kWLegsNotDown] = 0.5 * (1.0 + unit(t.at(r.pelvis), 0.5 * (t.at(r.legs[0]) + t.at(r.legs[1]))).dot(*up));
}

/// How many markers a reading breaks: a marker holds when the role it names (RoleMarker) is the one whose
/// extremity path from its base lies nearest to it (a groin: the pelvis nearer than the chest).
int broken_markers(const NodeTree& t, const Reading& r, const LimbPaths& p, const std::vector<RoleMarker>& markers) {
    if (markers.empty()) return 0;
    const std::vector<std::uint32_t> head = t.path(r.chest, r.head);
    const std::vector<std::uint32_t>* paths[5] = {&head, &p.legs[0], &p.legs[1], &p.arms[0], &p.arms[1]};
    int broken = 0;
    for (const RoleMarker& m : markers) {
        if (m.role == RoleMarker::Pelvis) {
            broken += (m.at - t.at(r.pelvis)).norm() > (m.at - t.at(r.chest)).norm();
            continue;
        }
        double d[5];
        for (int k = 0; k < 5; ++k) {
            d[k] = std::numeric_limits<double>::infinity();
            for (std::size_t i = 1; i < paths[k]->size(); ++i) d[k] = std::min(d[k], (m.at - t.at((*paths[k])[i])).norm());
        }
        const int nearest = static_cast<int>(std::min_element(d, d + 5) - d);
        const bool ok = m.role == RoleMarker::Head ? nearest == 0
                        : m.role == RoleMarker::Leg ? (nearest == 1 || nearest == 2)
                                                    : (nearest == 3 || nearest == 4);
        broken += !ok;
    }
    return broken;
}

/// Whether the arms hang between the head and the legs: where they meet lies nearer the head, along the tree, than
/// where the legs meet. Both templates are built so (the chest between the pelvis and the head); a reading whose
/// arms meet beyond its pelvis (seen from the head) reads the body back to front, its spine then the short side
/// branch to a girdle.
bool arms_between(const NodeTree& t, std::uint32_t head, std::uint32_t arms_meet, std::uint32_t pelvis) {
    return t.length(t.path(head, arms_meet)) < t.length(t.path(head, pelvis));
}

/// Every assignment of five extremities to head, legs, arms, read as a humanoid, a quadruped and a winged body; the best of
/// each kind kept in `best`, every reading appended to `all` when given.
void consider(const NodeTree& t, const std::array<std::uint32_t, 5>& leaf, double left_out, double left_out_thickness,
              const SearchInput& in, PlanSearch& best, std::vector<PlanReading>* all) {
    const double object_extent = t.extent(t.order());
    for (int h = 0; h < 5; ++h)
        for (int a = 0; a < 5; ++a)
            for (int b = a + 1; b < 5; ++b) {
                if (a == h || b == h) continue;
                int rest[2], n = 0;
                for (int i = 0; i < 5; ++i)
                    if (i != h && i != a && i != b) rest[n++] = i;
                Reading r{leaf[h], {leaf[a], leaf[b]}, {leaf[rest[0]], leaf[rest[1]]}, kNone, kNone};
                // The arms' meeting point may sit on a side branch (a shoulder girdle): the chest is where that
                // branch joins the spine.
                r.pelvis = t.median(r.legs[0], r.legs[1], r.head);
                const std::uint32_t arms_meet = t.median(r.arms[0], r.arms[1], r.head);
                r.chest = t.median(r.pelvis, arms_meet, r.head);
                if (r.pelvis == r.chest || !arms_between(t, r.head, arms_meet, r.pelvis)) continue;
                const LimbPaths paths(t, r);
                const int broken = broken_markers(t, r, paths, in.markers);
                const PlanFeatures shared = shared_features(t, r, paths, left_out, left_out_thickness, object_extent);
                for (const PlanKind kind : {PlanKind::Humanoid, PlanKind::Quadruped, PlanKind::Winged}) {
                    PlanFeatures f = shared;
                    if (kind == PlanKind::Humanoid) humanoid_features(t, r, paths, in.up, f);
                    else if (kind == PlanKind::Quadruped) quadruped_features(t, r, in.up, f);
                    else winged_features(t, r, in.up, f);
                    const double score = plan_score(f, in.weights);
                    Plan& slot = best.of(kind);
                    // Markers first (fewest broken), then the score.
                    if (broken < slot.broken || (broken == slot.broken && score < slot.score))
                        slot = Plan{r.head, {r.legs[0], r.legs[1]}, {r.arms[0], r.arms[1]}, score, broken};
                    if (all) all->push_back({plan_kind_name(kind), f, {r.head, r.legs[0], r.legs[1], r.arms[0], r.arms[1]}});
                }
            }
}

}  // namespace

Fit trunk_fit(const Chain4& spine) {
    if (spine.size() < kSpineProportions.size() + 1) return fit_chain(spine, 3);
    // Shares of the chord from the pelvis to the chest, not of the arc: the axis' wiggles differ between
    // resolutions.
    const Vec chord = (spine.back().head<3>() - spine.front().head<3>()).normalized();
    std::vector<double> along;
    for (const auto& q : spine) along.push_back((q.head<3>() - spine.front().head<3>()).dot(chord));
    double sum = 0;
    for (double r : kSpineProportions) sum += r;
    Fit fit;
    fit.cuts.push_back(0);
    double share = 0;
    for (std::size_t k = 0; k + 1 < kSpineProportions.size(); ++k) {
        share += kSpineProportions[k] / sum;
        std::size_t at = fit.cuts.back() + 1;  // the sample nearest that share of the chord, after the last cut
        while (at + 1 < spine.size() - (kSpineProportions.size() - 1 - k) &&
               std::abs(along[at + 1] - share * along.back()) < std::abs(along[at] - share * along.back()))
            ++at;
        fit.cuts.push_back(at);
    }
    fit.cuts.push_back(spine.size() - 1);
    return fit;
}

void restore_proximal(const RigContext& c, Rig& rig, const std::string& proximal, const std::string& distal,
                      double ratio) {
    const std::int32_t p = bone_index(rig, proximal), d = bone_index(rig, distal);
    if (p < 0 || d < 0) return;
    const Vec mid = bone_end(rig, static_cast<std::size_t>(p), 1);
    const double want = ratio * (bone_end(rig, static_cast<std::size_t>(d), 1) - mid).norm();
    if ((bone_end(rig, static_cast<std::size_t>(p), 0) - mid).norm() < kHiddenEnd * want)
        lengthen_proximal(c, rig, static_cast<std::size_t>(p), want);
}

std::vector<double> node_sheets(const RigContext& c) {
    const NodeTree& t = c.tree;
    std::vector<double> out(t.size(), 1.0);
    for (const std::uint32_t v : t.order()) {
        const std::uint32_t p = t.parent(v);
        const std::uint32_t q = p != kNone ? p : (t.children(v).empty() ? kNone : t.children(v)[0]);
        if (q == kNone || (t.at(v) - t.at(q)).norm() == 0) continue;
        out[v] = c.cross_section_ratio(t.at(v), (t.at(v) - t.at(q)).normalized(), kSectionRadii * t.radius(v));
    }
    return out;
}

bool spans_object(const NodeTree& t, const std::vector<std::uint32_t>& leaves) {
    return t.extent(leaves) >= 0.5 * t.extent(t.order());
}

PlanSearch search_plans(const NodeTree& t, const SearchInput& in, std::vector<PlanReading>* all) {
    PlanSearch best;
    const auto ext = t.extremities();
    if (ext.size() < 5) return best;
    // Five of the (up to) seven most significant leaves; ten with markers (they say which, even among fingers).
    const int m = static_cast<int>(std::min<std::size_t>(ext.size(), in.markers.empty() ? 7 : 10));
    double total = 0;
    // An extremity's weight: how far it sticks out times how thick it is at its end (a tail as long as the head
    // but thinner weighs less).
    auto weight = [&](std::size_t i) { return std::max(ext[i].first, 0.0) * t.end_radius(ext[i].second); };
    for (int i = 0; i < m; ++i) total += weight(static_cast<std::size_t>(i));
    for (int mask5 = 0; mask5 < (1 << m); ++mask5) {
        // Any five: a tail longer than the body may be left out (kLeftOut prices what is).
        if (__builtin_popcount(static_cast<unsigned>(mask5)) != 5) continue;
        std::array<std::uint32_t, 5> leaf{};
        double left_out = 0, left_out_thickness = 0;
        for (int i = 0, k = 0; i < m; ++i) {
            const auto& [significance, node] = ext[static_cast<std::size_t>(i)];
            if (mask5 & (1 << i)) {
                leaf[static_cast<std::size_t>(k++)] = node;
            } else {
                left_out += weight(static_cast<std::size_t>(i));
                left_out_thickness = std::max(left_out_thickness, t.end_radius(node));
            }
        }
        consider(t, leaf, total > 0 ? left_out / total : 0.0, left_out_thickness, in, best, all);
    }
    return best;
}

namespace {

/// A humanoid's joints the medial axis does not show, on one side: the shoulder, elbow, wrist, hip, knee and heel.
void place_hidden_joints(const RigContext& c, Rig& rig, const std::vector<std::uint32_t>& arm, const Fit& arm_fit,
                         const std::optional<FusedArm>& fused, const std::string& arm_sfx,
                         const std::vector<std::uint32_t>& leg, const Fit& leg_fit, const std::string& leg_sfx,
                         const Vec& body_up, const Vec& front) {
    if (fused) place_fused_shoulder(rig, "upper_arm" + arm_sfx, fused->shoulder);
    const auto& a = arm_fit.cuts;
    if (!fused) {
        restore_proximal(c, rig, "upper_arm" + arm_sfx, "forearm" + arm_sfx,
                         kArmProportions[1] / kArmProportions[2]);
        shoulder_on_top(c, rig, c.samples(arm), a[1], a[2], "upper_arm" + arm_sfx, body_up, front);
    }
    bend_corner(c, rig, std::vector<std::uint32_t>(arm.begin() + static_cast<std::ptrdiff_t>(a[1]),
                                                   arm.begin() + static_cast<std::ptrdiff_t>(a[3]) + 1),
                "upper_arm" + arm_sfx, "forearm" + arm_sfx);
    wrist_at_neck(c, rig, std::vector<std::uint32_t>(arm.begin() + static_cast<std::ptrdiff_t>(a[2]), arm.end()),
                  arm_sfx);
    hip_on_thigh_line(rig, "thigh" + leg_sfx);
    restore_proximal(c, rig, "thigh" + leg_sfx, "shin" + leg_sfx, kLegProportions[1] / kLegProportions[2]);
    const auto& k = leg_fit.cuts;
    straight_knee(c, rig, std::vector<std::uint32_t>(leg.begin() + static_cast<std::ptrdiff_t>(k[1]), leg.end()),
                  leg_sfx);
    heel_ankle(c, rig, std::vector<std::uint32_t>(leg.begin() + static_cast<std::ptrdiff_t>(k[2]), leg.end()),
               leg_sfx);
}

/// Where the feet point (forward): the sum of the legs' last bones (`leg`: the legs' nodes, `fit`: their cuts)
/// across `up`.
Vec feet_forward(const NodeTree& t, const std::vector<std::uint32_t> (&leg)[2], const Fit (&fit)[2], const Vec& up) {
    Vec forward = Vec::Zero();
    for (int s = 0; s < 2; ++s) {
        const auto& k = fit[s].cuts;
        forward += perp(t.at(leg[s][k[k.size() - 1]]) - t.at(leg[s][k[k.size() - 2]]), up);
    }
    return forward;
}

/// The body's mid-plane between a pair of limbs: the unit vector across `axis` from tip 1 to tip 0 (zero when they
/// line up along it) and the median offset along it of the spine's and the head's nodes (the nodes where the limbs
/// join may lie off the middle; the median holds).
std::pair<Vec, double> mid_plane(const NodeTree& t, const std::vector<std::uint32_t>& spine,
                                 const std::vector<std::uint32_t>& head, const std::uint32_t (&tips)[2],
                                 const Vec& axis) {
    Vec across = perp(t.at(tips[0]) - t.at(tips[1]), axis);
    if (across.norm() > 0) across.normalize();
    std::vector<double> off;
    for (const auto* nodes : {&spine, &head})
        for (std::uint32_t n : *nodes) off.push_back(t.at(n).dot(across));
    const auto half = off.begin() + static_cast<std::ptrdiff_t>(off.size() / 2);
    std::nth_element(off.begin(), half, off.end());
    return {across, *half};
}

/// The chest: `chest` (where the arms' paths meet the trunk), moved along the trunk from the pelvis to the head when
/// the spine (pelvis to chest: hips, spine, chest) or the head's path (chest to head: neck, head) has too few nodes
/// for its bones and the other can spare them. A bird's wings and legs may meet the trunk a node apart, a sitting
/// figure's head sit on its shoulders: the reading was scored, and its rig is now built instead of dropped (on the
/// shared characters turned as Blender imports them, 2026-12-08: a bird went to chains, a human to chains, and the
/// sitting figure with five markers had no rig at all). No rig that was built before changes.
std::uint32_t trunk_split(const NodeTree& t, std::uint32_t pelvis, std::uint32_t chest, std::uint32_t head) {
    const std::vector<std::uint32_t> trunk = t.path(pelvis, head);
    const auto at = std::find(trunk.begin(), trunk.end(), chest);
    if (at == trunk.end() || trunk.size() < 6) return chest;
    const auto i = static_cast<std::size_t>(at - trunk.begin());
    return trunk[std::clamp<std::size_t>(i, 3, trunk.size() - 3)];
}

}  // namespace

Candidate build_plan(const RigContext& c, const Plan& plan, PlanKind kind, double tolerance,
                     const std::optional<Vec>& up) {
    const bool humanoid = kind == PlanKind::Humanoid;
    const NodeTree& t = c.tree;
    const std::uint32_t H = plan.head;
    const std::uint32_t pelvis = t.median(plan.legs[0], plan.legs[1], H);
    const std::uint32_t chest = trunk_split(t, pelvis, t.median(pelvis, t.median(plan.arms[0], plan.arms[1], H), H), H);
    const std::vector<std::uint32_t> spine = t.path(pelvis, chest), head = t.path(chest, H);
    std::vector<std::uint32_t> leg[2], arm[2];
    Fit leg_fit[2], arm_fit[2];
    const Fit spine_fit = trunk_fit(c.samples(spine)), head_fit = fit_chain(c.samples(head), 2);
    bool ok = spine_fit.cuts.size() == 4 && head_fit.cuts.size() == 3;
    const Vec spine_dir = (t.at(chest) - t.at(pelvis)).normalized();
    std::optional<FusedArm> fused[2];
    const Vec body_up = up ? *up : spine_dir;  // limbs' sides lie across it
    const auto [across, mid] = mid_plane(t, spine, head, plan.legs, body_up);
    for (int k = 0; k < 2; ++k) {
        const double sign = k == 0 ? 1.0 : -1.0;  // the second leg's side is the other way across
        leg[k] = t.from_own_side(t.path(pelvis, plan.legs[k]), sign * across, sign * mid);
        leg_fit[k] = humanoid ? limb_fit(c.samples(leg[k]), false) : fit_chain(c.samples(leg[k]), 4);
        ok = ok && leg_fit[k].cuts.size() == 5;
    }
    if (ok && humanoid) match_limb_fits(c, leg, leg_fit, kLegProportions);
    if (!ok) return Candidate{};
    // Orientation: the spine points up (humanoid) or forward (quadruped); left = up x forward.
    Candidate out;
    Vec forward = Vec::Zero();
    if (humanoid) forward = feet_forward(t, leg, leg_fit, spine_dir);
    const Vec front = perp(forward, body_up).norm() > 0 ? Vec(perp(forward, body_up).normalized()) : Vec::Zero();
    for (int k = 0; k < 2; ++k) {
        arm[k] = t.path(chest, plan.arms[k]);
        if (kind == PlanKind::Winged) arm[k] = t.out_to_farthest(arm[k]);
        if (humanoid) fused[k] = fused_arm(c, c.samples(arm[k]), body_up, front);
        arm_fit[k] = fused[k] ? Fit{fused[k]->cuts, 0.0}
                              : humanoid ? limb_fit(c.samples(arm[k]), true) : fit_chain(c.samples(arm[k]), 4);
        ok = ok && arm_fit[k].cuts.size() == 5;
    }
    if (!ok) return Candidate{};

    if (humanoid) {
        out.up = spine_dir;
        const Vec legs = (0.5 * (t.at(plan.legs[0]) + t.at(plan.legs[1])) - t.at(pelvis)).normalized();
        out.up_confidence = std::clamp(-2.0 * legs.dot(spine_dir) - 1.0, 0.0, 1.0);
    } else if (kind == PlanKind::Winged) {
        // The legs hang down; forward is the spine's way across up (a bird's), or the feet's when the spine
        // stands up (a penguin's).
        const Vec legs = unit(t.at(pelvis), t.at(plan.legs[0])) + unit(t.at(pelvis), t.at(plan.legs[1]));
        out.up = up ? *up : (legs.norm() > 0 ? Vec(-legs.normalized()) : spine_dir);
        out.up_confidence = up ? 1.0 : std::clamp(legs.norm() / 2.0, 0.0, 1.0);
        forward = perp(spine_dir, out.up);
        if (forward.norm() < 0.5) forward = feet_forward(t, leg, leg_fit, out.up);
        if (forward.norm() == 0) forward = out.up.unitOrthogonal();
    } else {
        forward = spine_dir;
        Vec down = Vec::Zero();
        for (int s = 0; s < 2; ++s) {
            down += perp(t.at(plan.legs[s]) - t.at(pelvis), forward).normalized();
            down += perp(t.at(plan.arms[s]) - t.at(chest), forward).normalized();
        }
        out.up = -down.normalized();
        out.up_confidence = std::clamp(down.norm() / 4.0, 0.0, 1.0);
    }
    const Vec left = out.up.cross(forward.normalized());
    auto first_is_left = [&](const std::uint32_t (&pair)[2], std::uint32_t base) {
        return (t.at(pair[0]) - t.at(base)).dot(left) >= (t.at(pair[1]) - t.at(base)).dot(left);
    };
    const bool leg0_left = first_is_left(plan.legs, pelvis), arm0_left = first_is_left(plan.arms, chest);

    RigBuilder b(c);
    b.chain(spine, spine_fit.cuts, {"hips", "spine", "chest"});
    b.chain(head, head_fit.cuts, {"neck", "head"});
    for (int s = 0; s < 2; ++s) {
        const std::string sfx = ((s == 0) == arm0_left) ? ".L" : ".R";
        b.chain(arm[s], arm_fit[s].cuts, {"shoulder" + sfx, "upper_arm" + sfx, "forearm" + sfx, "hand" + sfx});
    }
    for (int s = 0; s < 2; ++s) {
        const std::string sfx = ((s == 0) == leg0_left) ? ".L" : ".R";
        b.chain(leg[s], leg_fit[s].cuts, {"pelvis" + sfx, "thigh" + sfx, "shin" + sfx, "foot" + sfx});
    }
    add_extra_chains(c, b, kind, tolerance);
    out.rig = b.finish(plan_kind_name(kind));
    if (humanoid)
        for (int s = 0; s < 2; ++s) {  // joints the medial axis does not show
            const std::string arm_sfx = ((s == 0) == arm0_left) ? ".L" : ".R", leg_sfx = ((s == 0) == leg0_left) ? ".L" : ".R";
            place_hidden_joints(c, out.rig, arm[s], arm_fit[s], fused[s], arm_sfx, leg[s], leg_fit[s], leg_sfx, body_up,
                                front);
        }
    if (humanoid) {
        std::string leg_sfx[2];
        for (int s = 0; s < 2; ++s) leg_sfx[s] = ((s == 0) == leg0_left) ? ".L" : ".R";
        raise_low_hips(c, out.rig, leg, leg_sfx, body_up);
        level_hips(out.rig, body_up);
        centre_chest(out.rig, body_up);
        recut_spine(out.rig, c.samples(spine));
        place_head(c, out.rig, c.samples(head), body_up);
        end_hands_and_feet(out.rig);
    }
    return out;
}

}  // namespace volrig::rig_detail

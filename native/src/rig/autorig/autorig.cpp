// autorig: from a skeleton-tree to an articulated skeleton (see volrig/rig.hpp). The stages, each in its own file:
//
// 0. coarse: the rig is made at autorig's own scale (kCoarseCells voxels along the object's longest extent), not
//    from the caller's points: a finer object is resampled (a coarse voxel is object when half its voxels are), a
//    coarser one only cropped; the 1% of its voxels of highest thinness score (more below that scale) and their
//    skeleton-tree replace the caller's points and tree. Any point count then gives the same rig (resolutions
//    resample to about the same object); the caller's points only name the point each joint sits on (the
//    nearest one). When that skeleton has no branch to rig (a thin shell), the caller's points are rigged.
//    AutorigOptions::own_scale = false rigs the caller's points instead.
// 1. shape_tree: the points that carry the shape are the scale axis (a point goes when its ball lies inside the
//    1.25x ball of a point at least twice as large: near-surface noise). They are joined by the tree's edges, by
//    contained cone edges reaching across each point's ball and by bridges between fragments; the part with the
//    largest ball volume is kept. Its level-set tree (bands of geodesic distance a fifth of the median radius
//    wide, split into connected pieces) follows the middle of each branch; node sizes follow the object's radii,
//    not the number of points kept.
// 2. node_tree: the nodes rooted at the largest-radius node; spurs pruned (a leaf branch goes when the leaf's ball
//    lies inside the ball, scaled by prune_scale, of a node between its junction and the root); a root at an end
//    of the tree (a head thicker than the trunk) moves to the first junction, its end a leaf; a path is rerooted
//    at its thicker end. Leaves are ranked by significance: how far each leaf's branch (in the longest-path
//    decomposition) sticks out of the balls from where it attaches up to the root (a branch that loops back into
//    the body from a thin node, as a thigh hung from a touching knee, is no extremity).
// 3. templates: body plans are fitted and scored. Humanoid and quadruped: a discrete search over assignments of
//    five of the seven most significant extremities to head, legs and arms, penalising pairs that do not mirror
//    each other across one midplane through the spine, significant extremities left out, a head not ahead of the
//    chest, and for a humanoid legs thinner than arms and hands as low as the feet; legs pointing away from the
//    head make a humanoid, otherwise a quadruped; a given up direction excludes humanoids whose spine does not
//    point up and quadrupeds whose limbs do not hang down. Parts left out that stick out of the body by a few of
//    their own radii become extra chains (a quadruped's tail behind its spine's start). Hand (hand.cpp): six of
//    the eight most significant extremities as a wrist and five fingers meeting on a palm, the thumb joining
//    farthest from the others' junction. Neutral chains: chains between branch points.
//    Every template that can be built is a candidate; body plans within their score limit win over chains; the
//    runner-up is reported, and AutorigOptions::kind forces one.
// 4. chain_fit and rig_builder: chains are cut into bones at bends by an optimal piecewise-linear fit in
//    (position, radius); a humanoid's limbs by one optimisation of bends and anatomical proportions together
//    (girdle, upper arm, forearm, hand; pelvis bone, thigh, shin, foot), the trunk at thirds of its chord. End
//    joints are extended along their bone to the object's surface.
// 5. humanoid_limbs: a humanoid's joints the medial axis does not show are placed by rules on the object itself
//    (walks along rays inside it): shoulders in the corner under the shoulder's top and outer side, bent elbows at
//    the corner of the bones' lines, knees at the leg's deepest dip, hips and chest between their joints, the
//    head bone up from 0.6 of the way down from the crown, half-way to it.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <tuple>

#include "rig/autorig/coarse.hpp"
#include "rig/autorig/templates.hpp"

namespace volrig {

namespace {

using rig_detail::Candidate;
using rig_detail::Vec;

void check_options(const PointSet& pts, const std::vector<std::array<std::uint32_t, 2>>& edges,
                   const AutorigOptions& opt) {
    if (!(opt.prune_scale >= 1.0 && std::isfinite(opt.prune_scale)))
        throw Error("autorig: prune_scale must be >= 1");
    if (!(opt.tolerance > 0 && std::isfinite(opt.tolerance))) throw Error("autorig: tolerance must be > 0");
    if (opt.bones < 0 || opt.bones > 10000) throw Error("autorig: bones must lie in 1..10000 (0 = default)");
    if (!opt.kind.empty() &&
        std::none_of(kAutorigKinds.begin(), kAutorigKinds.end(), [&](const char* k) { return opt.kind == k; })) {
        std::string known;
        for (const char* k : kAutorigKinds) known += std::string(known.empty() ? "'" : ", '") + k + "'";
        throw Error("autorig: kind must be one of " + known + ", got '" + opt.kind + "'");
    }
    if (opt.up) {
        const Vec u((*opt.up)[0], (*opt.up)[1], (*opt.up)[2]);
        if (!std::isfinite(u.norm()) || u.norm() == 0) throw Error("autorig: up must be a finite non-zero vector");
    }
    for (const auto& e : edges)
        if (e[0] >= pts.n || e[1] >= pts.n || e[0] == e[1])
            throw Error("autorig: tree edge (" + std::to_string(e[0]) + ", " + std::to_string(e[1]) +
                        ") is not between two of the " + std::to_string(pts.n) + " points");
    std::size_t parts = 0;
    forest_components(pts.n, edges, &parts);
    if (edges.size() + parts != pts.n) throw Error("autorig: the tree edges contain a cycle");
}

void check_markers(const AutorigOptions& opt) {
    if (opt.markers.empty()) return;
    if (opt.kind == "hand" || opt.kind == "winged" || opt.kind == "chains" || !opt.roles)
        throw Error("autorig: markers place a humanoid's or quadruped's joints; they cannot guide kind '" +
                    (opt.roles ? opt.kind : std::string("chains")) + "'");
    std::vector<std::string> seen;
    for (const auto& [name, at] : opt.markers) {
        rig_detail::marker_role(name);  // throws for an unknown name
        if (!std::isfinite(at[0]) || !std::isfinite(at[1]) || !std::isfinite(at[2]))
            throw Error("autorig: marker '" + name + "' is not a finite point");
        if (std::find(seen.begin(), seen.end(), name) != seen.end())
            throw Error("autorig: marker '" + name + "' is given twice");
        seen.push_back(name);
    }
}

/// What the templates read besides the tree: the up direction, the weights, the markers (in the tree's frame:
/// world - shift).
struct PlanInput {
    std::optional<Vec> up;
    const std::vector<double>& weights;
    std::vector<std::pair<std::string, Vec>> markers;
};

/// Whether a body plan of this kind and score is a candidate: below neutral chains' score when not forced (any
/// finite score with markers, which ask for a body plan), any finite score when forced.
bool admits(const AutorigOptions& opt, const PlanInput& in, const std::string& kind, double score) {
    const bool forced = opt.kind == kind;
    if (!(opt.kind.empty() || forced) || !std::isfinite(score)) return false;
    return forced || !in.markers.empty() || score < rig_detail::chains_score(in.weights);
}

/// Whether a built rig passes check_rig: a reading whose joints the rules placed on top of each other (a head
/// joint moved onto its tail) is no candidate.
bool consistent(const Rig& rig) {
    try {
        check_rig(rig);
        return true;
    } catch (const Error&) {
        return false;
    }
}

/// A built body plan: its fit from its score, the markers applied.
void finish_plan(Candidate& k, double score, const PlanInput& in) {
    k.score = score;
    k.fit = rig_detail::plan_fit(score, in.weights);
    if (!in.markers.empty() && !k.rig.bones.empty())
        rig_detail::apply_markers(k.rig, in.markers);
}

/// The body plan markers name, when they show it: a humanoid's wrists are above its knees along up (standing,
/// sitting, arms raised or out), a quadruped's front feet (its "wrists") below its hind knees. "" when the markers
/// hold no wrist or no knee, or up is not given.
std::string marked_kind(const PlanInput& in) {
    if (!in.up) return "";
    double wrist = 0, knee = 0;
    int nw = 0, nk = 0;
    for (const auto& [name, at] : in.markers) {
        if (name.rfind("wrist.", 0) == 0) wrist += at.dot(*in.up), ++nw;
        if (name.rfind("knee.", 0) == 0) knee += at.dot(*in.up), ++nk;
    }
    if (nw == 0 || nk == 0) return "";
    return wrist / nw > knee / nk ? "humanoid" : "quadruped";
}

/// Every reading scored, for fitting the weights (AutorigDetail): the body plans' and the hand's best.
void export_readings(std::vector<rig_detail::PlanReading> readings, const rig_detail::HandPlan& hand,
                     AutorigDetail& detail) {
    if (std::isfinite(hand.score)) {  // the hand's search ranks its readings by shape alone
        rig_detail::PlanReading r{"hand", {}, {hand.wrist}};
        r.features[rig_detail::kBiasHand] = 1;
        r.features[rig_detail::kHandShape] = hand.score;
        readings.push_back(r);
    }
    for (const auto& r : readings) {
        detail.reading_kind.push_back(r.kind);
        detail.reading_features.emplace_back(r.features.begin(), r.features.end());
        detail.reading_leaves.push_back(r.leaves);
    }
}

/// The body plans' candidates (humanoid, quadruped, winged, hand) that can be built, best first (the plan the markers
/// show, fewest markers broken, lowest score); every reading scored goes to `detail` when given.
std::vector<Candidate> plan_candidates(const rig_detail::RigContext& c, const AutorigOptions& opt,
                                       const PlanInput& in, AutorigDetail* detail) {
    std::vector<rig_detail::RoleMarker> roles;
    for (const auto& [name, at] : in.markers) roles.push_back({rig_detail::marker_role(name), at});
    std::vector<rig_detail::PlanReading> readings;
    const rig_detail::PlanSearch s =
        rig_detail::search_plans(c.tree, {in.up, in.weights, roles}, detail ? &readings : nullptr);
    // Best first: the plan the markers show (marked_kind), then the fewest markers broken, then the lowest score.
    const std::string marked = opt.kind.empty() ? marked_kind(in) : "";
    std::vector<std::pair<std::tuple<bool, int, double>, Candidate>> ranked;
    for (const auto kind : {rig_detail::PlanKind::Humanoid, rig_detail::PlanKind::Quadruped,
                            rig_detail::PlanKind::Winged}) {
        const rig_detail::Plan& plan = s.of(kind);
        const std::string name = rig_detail::plan_kind_name(kind);
        // Markers name a humanoid's or a quadruped's joints.
        if (kind == rig_detail::PlanKind::Winged && !in.markers.empty()) continue;
        if (admits(opt, in, name, plan.score)) {
            ranked.push_back({{!marked.empty() && marked != name, plan.broken, plan.score},
                              rig_detail::build_plan(c, plan, kind, opt.tolerance, in.up)});
            finish_plan(ranked.back().second, plan.score, in);
        }
    }
    const rig_detail::HandPlan hand = rig_detail::search_hand(c.tree);
    if (const double hs = rig_detail::hand_plan_score(hand, in.weights); in.markers.empty() && admits(opt, in, "hand", hs)) {
        ranked.push_back({{false, 0, hs}, rig_detail::hand_rig(c, hand)});
        ranked.back().second.score = hs;
        ranked.back().second.fit = rig_detail::plan_fit(hs, in.weights);
    }
    if (detail) export_readings(std::move(readings), hand, *detail);
    std::stable_sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::vector<Candidate> out;
    for (auto& [key, k] : ranked)
        if (!k.rig.bones.empty() && consistent(k.rig)) out.push_back(std::move(k));
    return out;
}

/// When no body plan is clear of chains by kUpOverruleMargin under the given up (`under_up`: the candidates found
/// with it, best first): the best body plan read without it, when that scores the margin below chains and below
/// every reading under the up, shows its own up clearly and lies across the given axis (more than 45 degrees off it
/// either way: a character modelled lying down, or its up mislabelled; a given up reversed still rules upside-down
/// readings out, as the weights' hard constraints ask). Marked up_overruled, with a note saying so; none otherwise.
/// Markers are kept: they constrain the reading without up as they did under it (a user's clicks on a body modelled
/// lying down are no reason to keep its up: under it the wrists lie no higher than the knees, which marked_kind
/// reads as a quadruped).
std::vector<Candidate> plan_without_up(const rig_detail::RigContext& c, const AutorigOptions& opt,
                                       const PlanInput& in, const std::vector<Candidate>& under_up) {
    const double chains = rig_detail::chains_score(in.weights), margin = rig_detail::kUpOverruleMargin;
    double best_under_up = chains;  // with markers the candidates are not ranked by score alone
    for (const Candidate& k : under_up) best_under_up = std::min(best_under_up, k.score);
    if (best_under_up <= chains - margin) return {};  // a clear reading under the up: the up holds
    const PlanInput free{std::nullopt, in.weights, in.markers};
    std::vector<Candidate> found = plan_candidates(c, opt, free, nullptr);
    if (found.empty()) return {};
    Candidate& k = found[0];
    if (!(k.score <= best_under_up - margin && k.up_confidence >= rig_detail::kUpOverruleClarity &&
          std::abs(k.up.normalized().dot(*in.up)) < std::sqrt(0.5)))
        return {};
    k.up_overruled = true;
    char along[64];
    std::snprintf(along, sizeof along, "(%.2f, %.2f, %.2f)", k.up.x(), k.up.y(), k.up.z());
    k.rig.note = "given up overruled; no body plan stands along it; rigged standing along " + std::string(along) +
                 "; check the up axis, or choose a plan";
    found.resize(1);
    return found;
}

/// The templates' candidates, best first: body plans within their limit (or forced, or meeting markers) by score
/// (read without up when no plan stands along it: plan_without_up), then chains (not with markers; left out when
/// two body plans precede them and no detail is asked for: autorig reads only the first two).
std::vector<Candidate> candidates(const rig_detail::RigContext& c, const AutorigOptions& opt, const PlanInput& in,
                                  AutorigDetail* detail) {
    const int target = opt.bones > 0 ? opt.bones : 24;
    std::vector<Candidate> out;
    if (opt.kind.empty() ? opt.roles && (target >= 21 || !in.markers.empty()) : opt.kind != "chains") {
        out = plan_candidates(c, opt, in, detail);
        if (opt.kind.empty() && in.up)
            if (std::vector<Candidate> free = plan_without_up(c, opt, in, out); !free.empty()) out = std::move(free);
    }
    if (!in.markers.empty() && out.empty())
        throw Error("autorig: the markers need a humanoid or quadruped body plan, and this shape has no five "
                    "extremities for one");
    // Chains come last, and the rig reads only the first two candidates (the rig and its runner-up): chains are built
    // when asked for, for the detail's chains_fit, or when fewer than two body plans stand before them.
    const bool want_chains =
        opt.kind == "chains" || (opt.kind.empty() && (detail || (in.markers.empty() && out.size() < 2)));
    if (want_chains) {
        Candidate chains = rig_detail::chain_rig(c, target, opt.tolerance);
        if (detail) detail->chains_fit = chains.rig.bones.empty() ? -1.0 : chains.fit;
        if (!chains.rig.bones.empty() && in.markers.empty()) {
            if (out.empty() && opt.kind.empty() && opt.roles && target >= 21)
                chains.rig.note = "no body plan fits; place markers or choose a plan";
            out.push_back(std::move(chains));
        }
    }
    if (out.empty() && opt.kind == "hand")
        throw Error("autorig: no hand fits this shape (it needs six extremities: five fingers meeting on a palm and a "
                    "wrist)");
    if (out.empty() && !opt.kind.empty() && opt.kind != "chains")
        throw Error("autorig: no " + opt.kind + " body plan fits this shape (it needs five extremities: head, two "
                    "arms, two legs, spread over the object)");
    return out;
}

Vec position(const Grid& g, const PointSet& pts, std::size_t i) {
    const auto p = point_position(g, pts, i);
    return Vec(p[0], p[1], p[2]);
}

/// Per position: the nearest of the caller's points (brute force: few positions).
std::vector<std::uint32_t> nearest_points(const Grid& g, const PointSet& pts, const std::vector<Vec>& at) {
    std::vector<std::uint32_t> out(at.size(), 0);
    std::vector<double> best(at.size(), std::numeric_limits<double>::infinity());
    for (std::size_t i = 0; i < pts.n; ++i) {
        const Vec p = position(g, pts, i);
        for (std::size_t k = 0; k < at.size(); ++k)
            if (const double d = (p - at[k]).squaredNorm(); d < best[k]) {
                best[k] = d;
                out[k] = static_cast<std::uint32_t>(i);
            }
    }
    return out;
}

/// What was kept, for the caller's points: a point is kept when the nearest node is (the nodes are few). Node
/// positions are `shift` away from the world.
void fill_detail(const Grid& g, const PointSet& pts, const rig_detail::LevelSetTree& lst,
                 const rig_detail::NodeTree& tree, const Vec& shift, AutorigDetail& d) {
    d.kept.assign(pts.n, 0);
    for (std::size_t i = 0; i < pts.n; ++i) {
        const Vec p = position(g, pts, i) - shift;
        double best = std::numeric_limits<double>::infinity();
        for (std::size_t k = 0; k < lst.centroid.size(); ++k)
            if (const double dk = (p - lst.centroid[k]).squaredNorm(); dk < best) {
                best = dk;
                d.kept[i] = tree.kept()[k];
            }
    }
    d.root = lst.centroid.empty() ? -1 : nearest_points(g, pts, {lst.centroid[tree.root()] + shift})[0];
    for (const Vec& c : lst.centroid) d.nodes.push_back({c.x() + shift.x(), c.y() + shift.y(), c.z() + shift.z()});
    d.node_radius = lst.radius;
    d.node_edges = lst.edges;
    d.node_kept = tree.kept();
}

/// Stages 1-3 on the points rigged (rg, rmask, rpts, redges; world = rg's positions + shift): every template's
/// candidate, best first, in rg's positions; `detail` (about the caller's grid g and points pts) filled on the way.
std::vector<Candidate> fit_templates(const Grid& rg, const std::uint8_t* rmask, const PointSet& rpts,
                                     const std::vector<std::array<std::uint32_t, 2>>& redges, const Vec& shift,
                                     const AutorigOptions& opt, const Progress& progress, const Grid& g,
                                     const PointSet& pts, AutorigDetail* detail) {
    const std::vector<double>& weights = rig_detail::plan_weights(opt.plan_weights);
    PlanInput in{std::nullopt, weights, {}};
    if (opt.up) in.up = Vec((*opt.up)[0], (*opt.up)[1], (*opt.up)[2]).normalized();
    for (const auto& [name, at] : opt.markers) in.markers.emplace_back(name, Vec(at[0], at[1], at[2]) - shift);
    report(progress, 0.3);
    const rig_detail::LevelSetTree lst = rig_detail::shape_tree(rg, rmask, rpts, redges, progress);
    report(progress, 0.5);
    rig_detail::NodeTree tree(lst.centroid, lst.radius, lst.edges);
    tree.prune(opt.prune_scale);
    tree.root_off_an_end();
    tree.root_path_at_thicker_end();
    report(progress, 0.7);
    if (detail) {
        *detail = AutorigDetail{};
        fill_detail(g, pts, lst, tree, shift, *detail);
    }
    const rig_detail::RigContext context{rg, rmask, rpts, tree, lst.rep};
    tree.set_sheet(rig_detail::node_sheets(context));
    return candidates(context, opt, in, detail);
}

}  // namespace

std::vector<std::string> autorig_plan_terms() {
    return {rig_detail::kPlanTermNames.begin(), rig_detail::kPlanTermNames.end()};
}

std::vector<double> autorig_fitted_weights() { return rig_detail::fitted_plan_weights(); }

Rig autorig(const Grid& g, const std::uint8_t* mask, const PointSet& pts,
            const std::vector<std::array<std::uint32_t, 2>>& edges, const AutorigOptions& opt,
            const Progress& progress, AutorigDetail* detail) {
    if (!pts.radius) throw Error("autorig: radii are required");
    check_points(g, mask, pts, "autorig");
    if (pts.n < 2) throw Error("autorig: needs at least 2 skeleton points, got " + std::to_string(pts.n));
    check_options(pts, edges, opt);
    check_markers(opt);
    rig_detail::plan_weights(opt.plan_weights);  // checks given weights

    // Autorig's own skeleton first; when it has no branch to rig (a thin shell, a few voxels), the caller's points.
    rig_detail::CoarseShape coarse;
    if (opt.own_scale) coarse = rig_detail::coarse_shape(g, mask);
    bool own = coarse.radius.size() >= 2;
    const Vec shift(coarse.offset[0], coarse.offset[1], coarse.offset[2]);
    std::vector<Candidate> found = own ? fit_templates(coarse.grid, coarse.mask.data(), coarse.points(), coarse.edges,
                                                       shift, opt, progress, g, pts, detail)
                                       : std::vector<Candidate>{};
    if (found.empty()) {
        own = false;
        found = fit_templates(g, mask, pts, edges, Vec::Zero(), opt, progress, g, pts, detail);
    }
    if (found.empty()) throw Error("autorig: the skeleton-tree has no branch to make a bone of");
    Rig rig = std::move(found[0].rig);
    if (own) {  // back to the world; joints sit on the caller's nearest points
        for (auto& j : rig.joints)
            for (int a = 0; a < 3; ++a) j[static_cast<std::size_t>(a)] += coarse.offset[static_cast<std::size_t>(a)];
        std::vector<Vec> on;
        for (std::size_t j = 0; j < rig.joints.size(); ++j)
            if (rig.joint_points[j] >= 0) on.emplace_back(rig.joints[j][0], rig.joints[j][1], rig.joints[j][2]);
        const std::vector<std::uint32_t> near = nearest_points(g, pts, on);
        for (std::size_t j = 0, k = 0; j < rig.joints.size(); ++j)
            if (rig.joint_points[j] >= 0) rig.joint_points[j] = near[k++];
    } else if (!opt.own_scale) {  // the caller's points rigged as asked: joints on them (the piece's point nearest
                                  // its centroid; a thin part's centroid can lie outside it), end joints aside
        for (std::size_t j = 0; j < rig.joints.size(); ++j)
            if (rig.joint_points[j] >= 0)
                rig.joints[j] = point_position(g, pts, static_cast<std::size_t>(rig.joint_points[j]));
    }
    rig.fit = found[0].fit;
    Vec up = found[0].up;
    rig.up_confidence = found[0].up_confidence;
    if (opt.up && !found[0].up_overruled) {
        up = Vec((*opt.up)[0], (*opt.up)[1], (*opt.up)[2]).normalized();
        rig.up_confidence = 1.0;
    }
    rig.up = {up.x(), up.y(), up.z()};
    if (found.size() > 1) {
        rig.runner_up = found[1].rig.kind;
        rig.runner_up_fit = found[1].fit;
    }
    check_rig(rig);
    report(progress, 1.0);
    return rig;
}

}  // namespace volrig

// rig/autorig/extras.cpp: the parts a body plan leaves out, kept as chains (see templates.hpp).
#include <algorithm>
#include <set>

#include "rig/autorig/templates.hpp"

namespace volrig::rig_detail {

namespace {

/// A bone-name base not yet used in the rig (base, base_2, base_3, ...).
std::string unused_base(const Rig& rig, const std::string& base) {
    auto used = [&](const std::string& b) {
        return std::any_of(rig.names.begin(), rig.names.end(), [&](const std::string& n) { return n.rfind(b, 0) == 0; });
    };
    std::string out = base;
    for (int k = 2; used(out); ++k) out = base + "_" + std::to_string(k);
    return out;
}

/// A quadruped's tail: a part hanging from the back of the trunk (hips, spine or pelvis) whose tip lies behind the
/// spine's start along the trunk (spine to chest). The tree may join the rump to the spine a little forward of the
/// hips, and hips may sit low when the hind legs touch.
bool is_tail(const Rig& rig, const std::string& owner, const Vec& tip) {
    if (owner != "hips" && owner != "spine" && owner.rfind("pelvis", 0) != 0) return false;
    const auto spine = static_cast<std::size_t>(bone_index(rig, "spine"));
    const Vec start = bone_end(rig, spine, 0);
    return (tip - start).dot(bone_end(rig, static_cast<std::size_t>(bone_index(rig, "chest")), 1) - start) < 0;
}

/// How far a part hanging from a humanoid's `owner` bone at `at` must stick out: the hand's (foot's) length when
/// the owner is a hand (foot), or its forearm (shin) with `at` within that length of the wrist (ankle); else 0.
double end_part_reach(const Rig& rig, const std::string& owner, const Vec& at) {
    const std::string side = owner.substr(std::min(owner.find('.'), owner.size()));  // ".L", ".R" or ""
    for (const auto& [end, limb] : {std::pair{"hand", "forearm"}, std::pair{"foot", "shin"}}) {
        const std::int32_t e = bone_index(rig, end + side);
        if (e < 0 || (owner != end + side && owner != limb + side)) continue;
        const Vec base = bone_end(rig, static_cast<std::size_t>(e), 0);
        const double length = (bone_end(rig, static_cast<std::size_t>(e), 1) - base).norm();
        if (owner == end + side || (at - base).norm() < length) return length;
    }
    return 0.0;
}

/// The tree path from `from` to the nearest node (fewest nodes between) a template bone holds; empty when none.
std::vector<std::uint32_t> path_to_held(const NodeTree& t, const RigBuilder& b, std::uint32_t from) {
    std::vector<std::uint32_t> best;
    for (std::uint32_t v : t.order()) {
        if (b.bone_of(v) < 0) continue;
        std::vector<std::uint32_t> p = t.path(from, v);
        if (best.empty() || p.size() < best.size()) best = std::move(p);
    }
    return best;
}

/// A fringe (before_fringe): nodes this many times thinner than the part's core...
constexpr double kFringeThinner = 3.0;
/// ...after the core has reached this many of its radii out of the body (a part, not a bump)...
constexpr double kFringeCoreReach = 2.0;
/// ...and flat: the median of their cross-sections' width over thickness (NodeTree::sheet; a round part 1-1.5).
constexpr double kFringeFlat = 2.0;

/// A part's path without the fringe at its end: where a part ends in a sheet a voxel or two thick (a bird's fan of
/// tail feathers, a fin, a fluke, a flat ear), the level-set tree runs along the sheet's middle or round its border
/// to a corner, nodes a few times thinner than the part's core, and out_to_farthest then ends the chain at that
/// corner. The path ends at its last core node instead, where the sheet starts (the rig's end joint then goes on to
/// the surface along the part, RigBuilder::finish). The core counts from where the part leaves the body's ball. On
/// the shared characters (2026-12-08) it moved only such ends: a bird's and a dragon's fanned tails, a dog's tail.
std::vector<std::uint32_t> before_fringe(const NodeTree& t, std::vector<std::uint32_t> path) {
    double core = 0;
    for (std::size_t k = 1; k + 1 < path.size(); ++k) {
        const double out = (t.at(path[k]) - t.at(path[0])).norm();
        if (out <= t.radius(path[0])) continue;  // still in the body
        core = std::max(core, t.radius(path[k]));
        if (core <= kFringeThinner * t.radius(path[k + 1]) || out <= kFringeCoreReach * core) continue;
        if (t.median_sheet(path, k + 1, path.size()) >= kFringeFlat) path.resize(k + 1);
        break;  // the first thinning decides: a round tip tapering stays whole
    }
    return path;
}

/// Whether a winged body's bone is one of its wings' (they carry the arm's names).
bool is_wing_bone(const std::string& name) {
    for (const char* prefix : {"shoulder.", "upper_arm.", "forearm.", "hand."})
        if (name.rfind(prefix, 0) == 0) return true;
    return false;
}

}  // namespace

void add_extra_chains(const RigContext& c, RigBuilder& b, PlanKind kind, double tolerance) {
    const bool quadruped = kind != PlanKind::Humanoid;  // tails named so; no hand or foot rule
    const NodeTree& t = c.tree;
    int added = 0;
    const double least_part = kExtraShare * t.box_size(t.order()).maxCoeff();  // of the body's longest side
    for (const auto& [significance, leaf] : t.extremities()) {
        if (added == kMaxExtraChains) break;
        if (b.bone_of(leaf) >= 0) continue;  // a template limb's tip
        // Up towards the root to the first node a template bone holds.
        std::vector<std::uint32_t> nodes{leaf};
        std::uint32_t at = leaf;
        while (t.parent(at) != kNone && b.bone_of(at) < 0) nodes.push_back(at = t.parent(at));
        if (b.bone_of(at) < 0) {  // the root is no template's (a rump behind the hips): on to the nearest held node
            const std::vector<std::uint32_t> on = path_to_held(t, b, at);
            if (!on.empty()) {
                nodes.insert(nodes.end(), on.begin() + 1, on.end());
                at = on.back();
            }
        }
        const std::int32_t holder = b.bone_of(at);
        // A part sticks out of the body by a few of its own radii (bumps and stubs are no parts), however thick
        // the body is where it attaches (a tail hanging down along the rump).
        nodes.pop_back();  // `at`: the body's
        if (holder < 0 || nodes.size() < 2 || significance < kExtraReach * t.mean_radius(nodes)) continue;
        nodes.push_back(at);
        std::reverse(nodes.begin(), nodes.end());
        nodes = t.out_to_farthest(before_fringe(t, std::move(nodes)));
        const bool tail = quadruped && is_tail(b.rig(), b.rig().names[static_cast<std::size_t>(holder)], t.at(leaf));
        const std::int32_t parent = tail ? holder : b.attach_bone(at, t.radius(at));
        const std::string& owner = b.rig().names[static_cast<std::size_t>(parent)];
        // A humanoid's fingers and toes go with its hand and foot: a part there is kept when it sticks out farther
        // than the hand (foot) is long (a sword held, not fingers curled against the pelvis).
        if (!quadruped && significance < end_part_reach(b.rig(), owner, t.at(at))) continue;
        if (kind == PlanKind::Winged && is_wing_bone(owner)) continue;
        const bool at_hand = !quadruped && (owner.rfind("forearm", 0) == 0 || owner.rfind("hand", 0) == 0);
        if (!at_hand && !tail && significance < least_part) continue;
        // Cut at bends, once it is kept.
        const Chain4 samples = c.samples(nodes);
        Fit fit;
        for (int pieces = 1; pieces <= 4; ++pieces) {
            fit = fit_chain(samples, pieces);
            if (fit.worst <= tolerance || static_cast<int>(fit.cuts.size()) - 1 < pieces) break;
        }
        if (fit.cuts.size() < 2) continue;
        const std::string base = unused_base(b.rig(), tail ? "tail" : "chain." + owner);
        b.chain(nodes, fit.cuts, numbered_names(base, fit.cuts.size() - 1), parent);
        ++added;
    }
}

}  // namespace volrig::rig_detail

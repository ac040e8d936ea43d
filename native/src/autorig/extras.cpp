// autorig/extras.cpp: the parts a body plan leaves out, kept as chains (see templates.hpp).
#include <algorithm>
#include <set>

#include "autorig/templates.hpp"

namespace volrig::rigging {

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

bool is_back_end(const std::string& bone) { return bone == "hips" || bone.rfind("pelvis", 0) == 0; }

}  // namespace

void add_extra_chains(const RigContext& c, RigBuilder& b, bool quadruped, double tolerance) {
    const NodeTree& t = c.tree;
    int added = 0;
    for (const auto& [significance, leaf] : t.extremities()) {
        if (added == kMaxExtraChains) break;
        if (b.bone_of(leaf) >= 0) continue;  // a template limb's tip
        // Up towards the root to the first node a template bone holds.
        std::vector<std::uint32_t> nodes{leaf};
        std::uint32_t at = leaf;
        while (t.parent(at) != kNone && b.bone_of(at) < 0) nodes.push_back(at = t.parent(at));
        const std::int32_t parent = b.bone_of(at);
        // A part: its tip lies beyond twice the radius where it attaches (bumps and stubs are no parts).
        if (parent < 0 || nodes.size() < 3 || (t.at(leaf) - t.at(at)).norm() < kExtraReach * t.radius(at)) continue;
        std::reverse(nodes.begin(), nodes.end());
        const Chain4 samples = c.samples(nodes);
        Fit fit;
        for (int pieces = 1; pieces <= 4; ++pieces) {
            fit = fit_chain(samples, pieces);
            if (fit.worst <= tolerance || static_cast<int>(fit.cuts.size()) - 1 < pieces) break;
        }
        if (fit.cuts.size() < 2) continue;
        const std::string& owner = b.rig().names[static_cast<std::size_t>(parent)];
        const std::string base = unused_base(b.rig(), quadruped && is_back_end(owner) ? "tail" : "chain." + owner);
        b.chain(nodes, fit.cuts, numbered_names(base, fit.cuts.size() - 1), parent);
        ++added;
    }
}

}  // namespace volrig::rigging

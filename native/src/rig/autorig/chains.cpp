// rig/autorig/chains.cpp: the neutral-chains template (see templates.hpp).
#include <algorithm>
#include <cmath>

#include "rig/autorig/templates.hpp"

namespace volrig::rig_detail {

namespace {

/// Key nodes of the subtree spanned by the root and the chosen leaves: the root, the leaves, and the nodes where
/// two or more chosen branches part. `in` marks the subtree.
std::vector<std::uint8_t> key_nodes(const NodeTree& t, const std::vector<std::uint32_t>& leaves,
                                    std::vector<std::uint8_t>& in) {
    in.assign(t.size(), 0);
    in[t.root()] = 1;
    for (std::uint32_t l : leaves)
        for (std::uint32_t v = l; v != kNone && !in[v]; v = t.parent(v)) in[v] = 1;
    std::vector<std::uint32_t> kids(t.size(), 0);
    for (std::uint32_t v = 0; v < t.size(); ++v)
        if (in[v] && v != t.root()) ++kids[t.parent(v)];
    std::vector<std::uint8_t> key(t.size(), 0);
    key[t.root()] = 1;
    for (std::uint32_t v = 0; v < t.size(); ++v)
        if (in[v] && kids[v] != 1) key[v] = 1;
    return key;
}

/// The chains (root outward) between key nodes over the most significant branches, as many as allow one bone
/// each within `target`.
std::vector<std::vector<std::uint32_t>> branch_chains(const NodeTree& t, int target) {
    std::vector<std::uint32_t> leaves;
    std::vector<std::uint8_t> in, key = key_nodes(t, leaves, in);
    for (const auto& [significance, leaf] : t.extremities()) {
        leaves.push_back(leaf);
        std::vector<std::uint8_t> in2;
        std::vector<std::uint8_t> key2 = key_nodes(t, leaves, in2);
        const long chains = std::count(key2.begin(), key2.end(), 1) - 1;
        if (chains > target && leaves.size() > 1) break;
        key = std::move(key2);
        in = std::move(in2);
    }
    std::vector<std::vector<std::uint32_t>> chains;
    for (std::uint32_t v : t.order()) {
        if (v == t.root() || !key[v] || !in[v]) continue;
        std::vector<std::uint32_t> c{v};
        for (std::uint32_t u = t.parent(v); u != kNone; u = t.parent(u)) {
            c.push_back(u);
            if (key[u]) break;
        }
        std::reverse(c.begin(), c.end());
        chains.push_back(std::move(c));
    }
    return chains;
}

}  // namespace

Candidate chain_rig(const RigContext& c, int target, double tolerance) {
    const auto chains = branch_chains(c.tree, target);
    if (chains.empty()) return Candidate{};  // a single node
    std::vector<Chain4> samples;
    for (const auto& ch : chains) samples.push_back(c.samples(ch));
    // Pieces per chain: the fewest within tolerance, then trimmed to the target by the smallest loss.
    std::vector<Fit> fits(chains.size());
    int total = 0;
    for (std::size_t k = 0; k < chains.size(); ++k) {
        for (int pieces = 1;; ++pieces) {
            fits[k] = fit_chain(samples[k], pieces);
            if (fits[k].worst <= tolerance || pieces >= 8 || static_cast<int>(fits[k].cuts.size()) - 1 < pieces) break;
        }
        total += static_cast<int>(fits[k].cuts.size()) - 1;
    }
    while (total > target) {
        std::size_t pick = chains.size();
        double least = std::numeric_limits<double>::infinity();
        for (std::size_t k = 0; k < chains.size(); ++k) {
            if (fits[k].cuts.size() <= 2) continue;
            const double w = fit_chain(samples[k], static_cast<int>(fits[k].cuts.size()) - 2).worst;
            if (w < least) {
                least = w;
                pick = k;
            }
        }
        if (pick == chains.size()) break;  // one bone per chain already
        fits[pick] = fit_chain(samples[pick], static_cast<int>(fits[pick].cuts.size()) - 2);
        --total;
    }
    RigBuilder b(c);
    double worst = 0;
    for (std::size_t k = 0; k < chains.size(); ++k) {
        b.chain(chains[k], fits[k].cuts, numbered_names("chain" + std::to_string(k), fits[k].cuts.size() - 1));
        worst = std::max(worst, fits[k].worst);
    }
    Candidate out;
    out.rig = b.finish("chains");
    out.fit = std::clamp(1.0 - worst, 0.0, 1.0);
    return out;
}

}  // namespace volrig::rig_detail

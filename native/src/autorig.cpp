// autorig: from a skeleton-tree to an articulated skeleton (see volrig/rig.hpp).
//
// 1. The tree component with most points is rooted at its largest-radius point.
// 2. Spurs are pruned: a leaf branch (leaf up to its first junction) goes when the leaf's ball lies inside the
//    ball, scaled by prune_scale, of the junction or of any node between it and the root. Repeated until stable.
//    Boundary noise and the rims of medial sheets go; limbs, whose tips lie far outside every ball of the trunk,
//    stay.
// 3. Each remaining leaf gets a persistence: the length of its branch in the longest-path decomposition of the
//    rooted tree. The most persistent leaves are the extremities.
// 4. With five or more extremities, the five most persistent are matched to a body plan (head, two arms, two
//    legs: the pair of legs and the pair of arms meet the head's path at two different points, pairs as
//    symmetric as possible). A humanoid's legs point away from its head; a quadruped's do not. Other shapes get
//    chains between branch points.
// 5. Chains are cut into bones at bends by an optimal piecewise-linear fit in (position, radius); role chains
//    into their role's number of bones, other chains into as few as keep every point within tolerance * radius.
//    End joints are extended along their bone to the object's surface.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <tuple>
#include <string>
#include <unordered_map>

#include "point_grid.hpp"
#include "volrig/rig.hpp"

namespace volrig {

namespace {

using Vec = Eigen::Vector3d;
constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

struct RootedTree {
    std::vector<std::uint32_t> parent;  // kNone for the root and for points outside the component
    std::vector<std::uint32_t> order;   // BFS order from the root (component points only)
    std::vector<std::uint32_t> depth;   // hops from the root
    std::vector<double> dist;           // path length from the root
    std::vector<std::vector<std::uint32_t>> children;
};

/// The level-set tree of one part of the skeleton: points binned by geodesic distance from the part's
/// largest-radius point (over the contained neighbour graph), each bin split into connected pieces; a piece is a
/// node (centroid, largest radius, representative point nearest the centroid) and pieces joined by graph edges
/// are linked, then reduced to a spanning tree by centroid distance. Unlike paths in the minimum spanning tree,
/// which wander inside a skeleton several voxels thick, the nodes follow the middle of each branch.
struct LevelSetTree {
    std::vector<Vec> centroid;
    std::vector<double> radius;
    std::vector<std::uint32_t> rep;
    std::vector<std::array<std::uint32_t, 2>> edges;
    std::vector<std::uint32_t> node_of_point;  // kNone outside the part
};

/// Scale-axis filter (after Giesen et al.'s scale axis transform): drops the points
/// whose ball lies inside the ball, scaled by kScaleAxis, of a point at least twice as large. Near-surface points
/// of a noisy boundary lie inside their limb's axis balls and go; axes and genuine sheets stay.
constexpr double kScaleAxis = 1.25;

std::vector<std::uint8_t> scale_axis(const Grid& g, const PointSet& pts) {
    const std::size_t n = pts.n;
    std::vector<Vec> pos(n);
    for (std::size_t i = 0; i < n; ++i) {
        const auto p = point_position(g, pts, i);
        pos[i] = Vec(p[0], p[1], p[2]);
    }
    std::vector<std::uint8_t> keep(n, 1);
    std::vector<std::uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(),
                     [&](std::uint32_t a, std::uint32_t b) { return pts.radius[a] > pts.radius[b]; });
    // Cells of a quarter of the largest radius: the largest balls scan about 10^3 cells.
    const double largest = order.empty() ? 1.0 : pts.radius[order[0]];
    std::array<std::int64_t, 3> cell;
    for (int a = 0; a < 3; ++a) cell[a] = std::max<std::int64_t>(1, std::llround(0.25 * largest / g.spacing[a]));
    const detail::PointGrid grid(g, pts, cell);
    for (std::uint32_t i : order) {
        if (!keep[i]) continue;  // inside a larger ball: what it would cover, that ball mostly covers
        const double reach_w = kScaleAxis * pts.radius[i];
        const std::int32_t* pi = pts.ijk + 3 * i;
        std::array<std::int64_t, 3> lo, hi;
        for (int a = 0; a < 3; ++a) {
            const std::int64_t v = pi[2 - a], reach = static_cast<std::int64_t>(std::ceil(reach_w / g.spacing[a]));
            lo[a] = std::max<std::int64_t>(0, v - reach) / cell[a];
            hi[a] = (v + reach) / cell[a];
        }
        grid.for_each_in_box(lo, hi, [&](std::uint32_t j) {
            if (j == i || !keep[j] || pts.radius[j] > 0.5f * pts.radius[i]) return;
            if ((pos[j] - pos[i]).norm() + pts.radius[j] <= reach_w) keep[j] = 0;
        });
    }
    return keep;
}

LevelSetTree level_set_tree(const Grid& g, const PointSet& pts, const SkeletonGraph& graph,
                            const std::vector<std::uint32_t>& component, double band) {
    const std::size_t n = pts.n;
    std::vector<Vec> pos(n);
    for (std::size_t i = 0; i < n; ++i) {
        const auto p = point_position(g, pts, i);
        pos[i] = Vec(p[0], p[1], p[2]);
    }
    std::uint32_t root = kNone;
    for (std::uint32_t i = 0; i < n; ++i)
        if (component[i] == 0 && (root == kNone || pts.radius[i] > pts.radius[root])) root = i;
    std::vector<double> dist(n, std::numeric_limits<double>::infinity());
    dist[root] = 0;
    std::vector<std::uint8_t> in_part(n);
    for (std::size_t i = 0; i < n; ++i) in_part[i] = component[i] == 0;
    shortest_paths(graph, dist, nullptr, &in_part);
    std::vector<std::int64_t> level(n, -1);
    for (std::size_t i = 0; i < n; ++i)
        if (std::isfinite(dist[i])) level[i] = static_cast<std::int64_t>(dist[i] / band);
    detail::DisjointSets sets(n);
    for (std::uint32_t v = 0; v < n; ++v)
        for (std::uint32_t e = graph.offsets[v]; e < graph.offsets[v + 1]; ++e) {
            const std::uint32_t w = graph.targets[e];
            if (level[v] >= 0 && level[v] == level[w]) sets.unite(v, w);
        }
    LevelSetTree t;
    t.node_of_point.assign(n, kNone);
    std::vector<std::uint32_t> node_of_root(n, kNone);
    std::vector<std::size_t> count;
    for (std::uint32_t i = 0; i < n; ++i) {
        if (level[i] < 0) continue;
        const std::uint32_t r = sets.find(i);
        if (node_of_root[r] == kNone) {
            node_of_root[r] = static_cast<std::uint32_t>(t.centroid.size());
            t.centroid.push_back(Vec::Zero());
            t.radius.push_back(0.0);
            t.rep.push_back(i);
            count.push_back(0);
        }
        const std::uint32_t k = node_of_root[r];
        t.node_of_point[i] = k;
        t.centroid[k] += pos[i];
        t.radius[k] = std::max(t.radius[k], static_cast<double>(pts.radius[i]));
        ++count[k];
    }
    for (std::size_t k = 0; k < t.centroid.size(); ++k) t.centroid[k] /= static_cast<double>(count[k]);
    for (std::uint32_t i = 0; i < n; ++i) {
        const std::uint32_t k = t.node_of_point[i];
        if (k != kNone && (pos[i] - t.centroid[k]).squaredNorm() < (pos[t.rep[k]] - t.centroid[k]).squaredNorm())
            t.rep[k] = i;
    }
    // Links between pieces, reduced to a spanning tree (Kruskal by centroid distance).
    std::vector<std::tuple<double, std::uint32_t, std::uint32_t>> links;
    for (std::uint32_t v = 0; v < n; ++v)
        for (std::uint32_t e = graph.offsets[v]; e < graph.offsets[v + 1]; ++e) {
            const std::uint32_t a = t.node_of_point[v], b = t.node_of_point[graph.targets[e]];
            if (a != kNone && b != kNone && a < b) links.emplace_back((t.centroid[a] - t.centroid[b]).norm(), a, b);
        }
    std::sort(links.begin(), links.end());
    links.erase(std::unique(links.begin(), links.end()), links.end());
    detail::DisjointSets nodes(t.centroid.size());
    for (const auto& [w, a, b] : links)
        if (nodes.unite(a, b)) t.edges.push_back({a, b});
    return t;
}

class Autorig {
public:
    Autorig(const Grid& g, const std::uint8_t* mask, const PointSet& pts, LevelSetTree&& nodes,
            const AutorigOptions& opt)
        : g_(g), mask_(mask), pts_(pts), opt_(opt), lst_(std::move(nodes)), pos_(lst_.centroid), rad_(lst_.radius),
          adj_(lst_.centroid.size()) {
        for (const auto& e : lst_.edges) {
            adj_[e[0]].push_back(e[1]);
            adj_[e[1]].push_back(e[0]);
        }
    }

    Rig run(const Progress& progress, AutorigDetail* detail) {
        std::uint32_t root = 0;
        for (std::uint32_t i = 0; i < pos_.size(); ++i)
            if (radius(i) > radius(root)) root = i;
        kept_.assign(pos_.size(), 1);
        reroot(root);
        report(progress, 0.2);
        prune();
        report(progress, 0.6);
        // A path (two ends): root it at its thicker end so that its bones run outward from there.
        bool is_path = kept_children(root_) <= 2;
        for (std::uint32_t v : t_.order)
            if (v != root_ && kept_children(v) > 1) is_path = false;
        if (is_path) {
            std::vector<std::uint32_t> ends = leaves_of();
            if (kept_children(root_) <= 1) ends.push_back(root_);
            if (ends.size() == 2) reroot(end_radius(ends[0]) >= end_radius(ends[1]) ? ends[0] : ends[1]);
        }
        if (detail) {
            detail->kept.assign(pts_.n, 0);
            for (std::size_t i = 0; i < pts_.n; ++i)
                detail->kept[i] = lst_.node_of_point[i] != kNone && kept_[lst_.node_of_point[i]];
            detail->root = lst_.rep[root_];
            for (const Vec& c : lst_.centroid) detail->nodes.push_back({c.x(), c.y(), c.z()});
            detail->node_radius = lst_.radius;
            detail->node_edges = lst_.edges;
            detail->node_kept = kept_;
        }
        Rig rig;
        const int target = opt_.bones > 0 ? opt_.bones : 24;
        if (opt_.roles && target >= 21 && !role_rig(rig)) rig = Rig{};
        if (rig.bones.empty()) chain_rig(rig, target);
        report(progress, 1.0);
        return rig;
    }

private:
    double radius(std::uint32_t i) const { return rad_[i]; }
    Vec at(std::uint32_t i) const { return pos_[i]; }

    // ---- rooted tree ----------------------------------------------------------------------------------------

    /// Roots the kept nodes at `root`: parent pointers, BFS order, depth and path length.
    void reroot(std::uint32_t root) {
        root_ = root;
        const std::size_t n = pos_.size();
        t_.parent.assign(n, kNone);
        t_.depth.assign(n, 0);
        t_.dist.assign(n, 0.0);
        t_.children.assign(n, {});
        t_.order.clear();
        t_.order.push_back(root);
        for (std::size_t k = 0; k < t_.order.size(); ++k) {
            const std::uint32_t v = t_.order[k];
            for (std::uint32_t w : adj_[v]) {
                if (!kept_[w] || w == t_.parent[v]) continue;
                t_.parent[w] = v;
                t_.depth[w] = t_.depth[v] + 1;
                t_.dist[w] = t_.dist[v] + (at(w) - at(v)).norm();
                t_.children[v].push_back(w);
                t_.order.push_back(w);
            }
        }
    }
    std::size_t kept_children(std::uint32_t v) const { return t_.children[v].size(); }
    std::vector<std::uint32_t> leaves_of() const {
        std::vector<std::uint32_t> l;
        for (std::uint32_t v : t_.order)
            if (v != root_ && t_.children[v].empty()) l.push_back(v);
        return l;
    }
    /// Mean radius of the few points nearest an end of a path (its thickness there).
    double end_radius(std::uint32_t end) const {
        double s = 0;
        int n = 0;
        for (std::uint32_t prev = kNone, cur = end; cur != kNone && n < 8; ++n) {
            s += radius(cur);
            std::uint32_t next = kNone;
            for (std::uint32_t w : adj_[cur])
                if (kept_[w] && w != prev) next = w;
            prev = cur;
            cur = next;
        }
        return n ? s / n : 0.0;
    }

    // ---- spur pruning ---------------------------------------------------------------------------------------

    void prune() {
        const double s = opt_.prune_scale;
        for (int pass = 0; pass < 10000; ++pass) {
            std::vector<std::uint32_t> leaves = leaves_of();
            std::vector<std::uint32_t> cut_below;  // the junction under which each pruned spur hangs
            std::vector<std::uint32_t> cut_leaf;
            for (std::uint32_t l : leaves) {
                // Walk to the junction (a node with two or more children, or the root).
                std::uint32_t j = t_.parent[l];
                while (j != root_ && t_.children[j].size() == 1) j = t_.parent[j];
                bool covered = false;
                for (std::uint32_t k = j; k != kNone && !covered; k = t_.parent[k])
                    covered = (at(l) - at(k)).norm() + radius(l) <= s * radius(k);
                if (covered) {
                    cut_below.push_back(j);
                    cut_leaf.push_back(l);
                }
            }
            if (cut_leaf.empty()) break;
            // Never cut every branch of a junction in one pass: the one whose tip reaches farthest stays.
            std::unordered_map<std::uint32_t, std::vector<std::size_t>> by_junction;
            for (std::size_t k = 0; k < cut_leaf.size(); ++k) by_junction[cut_below[k]].push_back(k);
            std::vector<std::uint8_t> spare(cut_leaf.size(), 0);
            for (auto& [j, ks] : by_junction) {
                if (ks.size() < t_.children[j].size()) continue;
                std::size_t best = ks[0];
                for (std::size_t k : ks)
                    if ((at(cut_leaf[k]) - at(j)).norm() > (at(cut_leaf[best]) - at(j)).norm()) best = k;
                spare[best] = 1;
            }
            bool changed = false;
            for (std::size_t k = 0; k < cut_leaf.size(); ++k) {
                if (spare[k]) continue;
                for (std::uint32_t v = cut_leaf[k]; v != cut_below[k]; v = t_.parent[v]) kept_[v] = 0;
                changed = true;
            }
            if (!changed) break;
            reroot(root_);
        }
    }

    // ---- persistence ------------------------------------------------------------------------------------------

    /// Leaves by descending significance: each leaf's branch in the longest-path decomposition of the rooted tree
    /// attaches at a node; the significance is how far the leaf lies outside that node's ball.
    std::vector<std::pair<double, std::uint32_t>> extremities() const {
        std::vector<double> height(pos_.size(), 0.0);
        std::vector<std::uint32_t> heavy(pos_.size(), kNone);
        for (auto it = t_.order.rbegin(); it != t_.order.rend(); ++it) {
            const std::uint32_t v = *it;
            for (std::uint32_t c : t_.children[v]) {
                const double h = height[c] + (at(c) - at(v)).norm();
                if (heavy[v] == kNone || h > height[v]) {
                    height[v] = h;
                    heavy[v] = c;
                }
            }
        }
        std::vector<std::pair<double, std::uint32_t>> out;
        for (std::uint32_t l : leaves_of()) {
            std::uint32_t t = l;
            while (t != root_ && heavy[t_.parent[t]] == t) t = t_.parent[t];
            const std::uint32_t top = t == root_ ? root_ : t_.parent[t];
            // How far the branch sticks out of the ball where it attaches (internal wandering does not count).
            out.emplace_back((at(l) - at(top)).norm() - radius(top), l);
        }
        std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
            return a.first != b.first ? a.first > b.first : a.second < b.second;
        });
        return out;
    }

    // ---- paths ------------------------------------------------------------------------------------------------

    std::uint32_t lca(std::uint32_t a, std::uint32_t b) const {
        while (t_.depth[a] > t_.depth[b]) a = t_.parent[a];
        while (t_.depth[b] > t_.depth[a]) b = t_.parent[b];
        while (a != b) {
            a = t_.parent[a];
            b = t_.parent[b];
        }
        return a;
    }
    /// The node on all three paths between a, b and c.
    std::uint32_t median(std::uint32_t a, std::uint32_t b, std::uint32_t c) const {
        const std::uint32_t x = lca(a, b), y = lca(b, c), z = lca(a, c);
        std::uint32_t m = x;
        if (t_.depth[y] > t_.depth[m]) m = y;
        if (t_.depth[z] > t_.depth[m]) m = z;
        return m;
    }
    /// Nodes of the path from a to b, both included.
    std::vector<std::uint32_t> path(std::uint32_t a, std::uint32_t b) const {
        const std::uint32_t m = lca(a, b);
        std::vector<std::uint32_t> up, down;
        for (std::uint32_t v = a; v != m; v = t_.parent[v]) up.push_back(v);
        up.push_back(m);
        for (std::uint32_t v = b; v != m; v = t_.parent[v]) down.push_back(v);
        up.insert(up.end(), down.rbegin(), down.rend());
        return up;
    }
    /// Diagonal of the bounding box of the given nodes' positions.
    double extent(const std::vector<std::uint32_t>& nodes) const {
        Vec lo = Vec::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
        for (std::uint32_t v : nodes) {
            lo = lo.cwiseMin(at(v));
            hi = hi.cwiseMax(at(v));
        }
        return nodes.empty() ? 0.0 : (hi - lo).norm();
    }
    double mean_radius(const std::vector<std::uint32_t>& p) const {
        double s = 0;
        for (std::uint32_t v : p) s += radius(v);
        return p.empty() ? 0.0 : s / static_cast<double>(p.size());
    }

    // ---- cutting a chain into bones -----------------------------------------------------------------------------

    struct Fit {
        std::vector<std::size_t> cuts;  // indices into the chain, first 0 and last size-1
        double worst = 0;               // largest deviation / radius
    };

    /// Optimal cut of `chain` into k pieces minimising the squared 4-D deviation (x, y, z, radius) of its points
    /// from each piece's chord (dynamic programming over at most 64 samples of the chain).
    Fit fit_chain(const std::vector<std::uint32_t>& chain, int k) const {
        const std::size_t n = chain.size();
        std::vector<std::size_t> sample;
        const std::size_t m = std::min<std::size_t>(n, 64);
        for (std::size_t s = 0; s < m; ++s) sample.push_back(m == 1 ? 0 : s * (n - 1) / (m - 1));
        k = std::max(1, std::min<int>(k, static_cast<int>(m) - 1));
        auto p4 = [&](std::size_t s) {
            const std::uint32_t v = chain[sample[s]];
            return Eigen::Vector4d(pos_[v].x(), pos_[v].y(), pos_[v].z(), radius(v));
        };
        auto deviation = [&](std::size_t a, std::size_t b, std::size_t s) {
            const Eigen::Vector4d pa = p4(a), d = p4(b) - pa, q = p4(s) - pa;
            const double len2 = d.squaredNorm();
            const double t = len2 > 0 ? std::clamp(q.dot(d) / len2, 0.0, 1.0) : 0.0;
            return (q - t * d).norm();
        };
        std::vector<double> cost(m * m, 0.0);
        for (std::size_t a = 0; a < m; ++a)
            for (std::size_t b = a + 1; b < m; ++b) {
                double c = 0;
                for (std::size_t s = a + 1; s < b; ++s) {
                    const double dv = deviation(a, b, s);
                    c += dv * dv;
                }
                cost[a * m + b] = c;
            }
        const double inf = std::numeric_limits<double>::infinity();
        std::vector<double> best((k + 1) * m, inf);
        std::vector<std::size_t> from((k + 1) * m, 0);
        best[0] = 0;
        for (int j = 1; j <= k; ++j)
            for (std::size_t b = 1; b < m; ++b)
                for (std::size_t a = 0; a < b; ++a) {
                    const double c = best[(j - 1) * m + a] + cost[a * m + b];
                    if (c < best[j * m + b]) {
                        best[j * m + b] = c;
                        from[j * m + b] = a;
                    }
                }
        Fit f;
        std::vector<std::size_t> cuts{m - 1};
        for (int j = k; j > 0; --j) cuts.push_back(from[j * m + cuts.back()]);
        std::reverse(cuts.begin(), cuts.end());
        for (std::size_t c = 0; c + 1 < cuts.size(); ++c)
            for (std::size_t s = cuts[c] + 1; s < cuts[c + 1]; ++s)
                f.worst = std::max(f.worst, deviation(cuts[c], cuts[c + 1], s) / std::max(radius(chain[sample[s]]), 1e-9));
        for (std::size_t c : cuts) f.cuts.push_back(sample[c]);
        return f;
    }

    /// Arc length along a chain's nodes, from its first node.
    std::vector<double> arc_of(const std::vector<std::uint32_t>& chain) const {
        std::vector<double> arc(chain.size(), 0.0);
        for (std::size_t k = 1; k < chain.size(); ++k) arc[k] = arc[k - 1] + (at(chain[k]) - at(chain[k - 1])).norm();
        return arc;
    }

    /// A joint expected at fraction `frac` of the arc from chain index a to b (plus `extra` length beyond b): the
    /// node deviating most from the chord a -> b (in position and radius) within a fifth of that length of the
    /// expected place, when it deviates by 0.15 of its radius (a clear bend), else the expected place itself.
    std::size_t place_joint(const std::vector<std::uint32_t>& chain, const std::vector<double>& arc, std::size_t a,
                            std::size_t b, double frac, double extra) const {
        const double len = arc[b] - arc[a] + extra, target = arc[a] + frac * len, w = 0.2 * len;
        auto index_at = [&](double x) {
            const auto it = std::lower_bound(arc.begin() + static_cast<std::ptrdiff_t>(a),
                                             arc.begin() + static_cast<std::ptrdiff_t>(b) + 1, x);
            return std::min<std::size_t>(static_cast<std::size_t>(it - arc.begin()), b);
        };
        auto p4 = [&](std::size_t k) {
            const Vec& p = at(chain[k]);
            return Eigen::Vector4d(p.x(), p.y(), p.z(), radius(chain[k]));
        };
        const Eigen::Vector4d pa = p4(a), d = p4(b) - pa;
        std::size_t best = std::clamp(index_at(target), a + 1, b - 1);
        double best_bend = 0.15;
        for (std::size_t c = std::max(a + 1, index_at(target - w)); c <= index_at(target + w) && c < b; ++c) {
            const Eigen::Vector4d q = p4(c) - pa;
            const double t = std::clamp(q.dot(d) / std::max(d.squaredNorm(), 1e-12), 0.0, 1.0);
            const double bend = (q - t * d).norm() / std::max(radius(chain[c]), 1e-9);
            if (bend > best_bend) {
                best_bend = bend;
                best = c;
            }
        }
        return best;
    }

    /// A humanoid limb: the strong bends by the piecewise-linear fit (an arm leaves the shoulder girdle; a leg
    /// leaves the pelvis and turns into the foot), then the weak ones (elbow and wrist; knee) near their
    /// Drillis-Contini proportions (upper arm : forearm : hand = 0.186 : 0.146 : 0.108 of the height, thigh and
    /// shin equal) and moved to a clear bend nearby.
    Fit limb_fit(const std::vector<std::uint32_t>& chain, bool arm) const {
        Fit f = fit_chain(chain, arm ? 2 : 3);
        if (f.cuts.size() != (arm ? 3u : 4u) || chain.size() < 8) return Fit{};
        const std::vector<double> arc = arc_of(chain);
        const std::size_t end = chain.size() - 1;
        if (arm) {
            const std::size_t sh = f.cuts[1];
            if (end - sh < 4) return Fit{};
            const double extra = radius(chain[end]);
            const std::size_t elbow = std::clamp(place_joint(chain, arc, sh, end, 0.186 / 0.44, extra), sh + 1, end - 2);
            // The wrist at its proportion of the whole arm, measured from the elbow now placed.
            const double whole = arc[end] - arc[sh] + extra;
            const double from_elbow = (0.332 / 0.44 * whole - (arc[elbow] - arc[sh])) / (arc[end] - arc[elbow] + extra);
            const std::size_t wrist =
                std::clamp(place_joint(chain, arc, elbow, end, from_elbow, extra), elbow + 1, end - 1);
            f.cuts = {0, sh, elbow, wrist, end};
        } else {
            const std::size_t hip = f.cuts[1], ankle = f.cuts[2];
            if (ankle - hip < 3) return Fit{};
            const std::size_t knee = std::clamp(place_joint(chain, arc, hip, ankle, 0.5, 0.0), hip + 1, ankle - 1);
            f.cuts = {0, hip, knee, ankle, end};
        }
        return f;
    }

    // ---- building the rig ----------------------------------------------------------------------------------------

    struct Builder {
        Rig rig;
        std::unordered_map<std::uint32_t, std::int32_t> joint_of_point;
        std::unordered_map<std::int32_t, std::int32_t> bone_ending_at;    // joint -> bone whose tail it is
        std::unordered_map<std::int32_t, std::int32_t> bone_starting_at;  // joint -> first bone with that head

        /// The joint on a node: at the node's representative skeleton point.
        std::int32_t joint(const Autorig& a, std::uint32_t node) {
            auto it = joint_of_point.find(node);
            if (it != joint_of_point.end()) return it->second;
            const std::int32_t j = static_cast<std::int32_t>(rig.joints.size());
            const std::uint32_t point = a.lst_.rep[node];
            rig.joints.push_back(point_position(a.g_, a.pts_, point));
            rig.joint_points.push_back(point);
            joint_of_point.emplace(node, j);
            return j;
        }
        /// Adds the bones of a chain cut at `cuts`, named names[0..]; returns the last bone.
        void chain(const Autorig& a, const std::vector<std::uint32_t>& nodes, const std::vector<std::size_t>& cuts,
                   const std::vector<std::string>& names) {
            std::int32_t prev = -1;
            const std::int32_t start = joint(a, nodes[cuts[0]]);
            if (auto it = bone_ending_at.find(start); it != bone_ending_at.end()) prev = it->second;
            else if (auto it2 = bone_starting_at.find(start); it2 != bone_starting_at.end()) prev = it2->second;
            for (std::size_t c = 0; c + 1 < cuts.size(); ++c) {
                const std::int32_t h = joint(a, nodes[cuts[c]]), t = joint(a, nodes[cuts[c + 1]]);
                const std::int32_t b = static_cast<std::int32_t>(rig.bones.size());
                rig.bones.push_back({h, t});
                rig.names.push_back(names[c]);
                rig.parents.push_back(prev);
                bone_ending_at.emplace(t, b);
                bone_starting_at.emplace(h, b);
                prev = b;
            }
        }
    };

    /// Moves each end joint (a tail no bone starts from) outward along its bone to the object's surface, up to
    /// twice the end point's radius.
    void extend_ends(Rig& rig) const {
        std::vector<int> heads(rig.joints.size(), 0);
        for (const auto& b : rig.bones) ++heads[static_cast<std::size_t>(b[0])];
        const double step = 0.5 * std::min({g_.spacing[0], g_.spacing[1], g_.spacing[2]});
        for (const auto& b : rig.bones) {
            const std::size_t t = static_cast<std::size_t>(b[1]);
            if (heads[t] || rig.joint_points[t] < 0) continue;
            const Vec head(rig.joints[b[0]][0], rig.joints[b[0]][1], rig.joints[b[0]][2]);
            const Vec tail(rig.joints[t][0], rig.joints[t][1], rig.joints[t][2]);
            const Vec dir = (tail - head).normalized();
            const double limit = 2.0 * pts_.radius[rig.joint_points[t]];
            double reach = 0;
            for (double s = step; s <= limit; s += step) {
                const Vec q = tail + s * dir;
                std::int64_t v[3];
                bool inside = true;
                for (int a = 0; a < 3; ++a) {
                    v[a] = std::llround((q[a] - g_.origin[a]) / g_.spacing[a]);
                    inside = inside && v[a] >= 0 && v[a] < g_.dims[a];
                }
                if (!inside || !mask_[g_.index(v[0], v[1], v[2])]) break;
                reach = s;
            }
            const Vec end = tail + reach * dir;
            rig.joints[t] = {end.x(), end.y(), end.z()};
            rig.joint_points[t] = -1;
        }
    }

    /// Humanoid / quadruped body plan over the five most persistent extremities; false when none fits.
    bool role_rig(Rig& out) const {
        const auto ext = extremities();
        if (ext.size() < 5) return false;
        // Five of the (up to) seven most significant leaves: head, two legs, two arms.
        const int m = static_cast<int>(std::min<std::size_t>(ext.size(), 7));
        double total = 0;
        for (int i = 0; i < m; ++i) total += std::max(ext[static_cast<std::size_t>(i)].first, 0.0);
        const double whole_extent = extent(t_.order);
        double best = std::numeric_limits<double>::infinity();
        std::uint32_t chosen[5] = {0, 0, 0, 0, 0};  // head, leg, leg, arm, arm
        std::uint32_t leaf[5];
        for (int mask5 = 0; mask5 < (1 << m); ++mask5) {
            // A body plan includes the two most prominent extremities.
            if (__builtin_popcount(static_cast<unsigned>(mask5)) != 5 || (mask5 & 3) != 3) continue;
            double left_out = 0;
            for (int i = 0, k = 0; i < m; ++i) {
                if (mask5 & (1 << i)) leaf[k++] = ext[static_cast<std::size_t>(i)].second;
                else left_out += std::max(ext[static_cast<std::size_t>(i)].first, 0.0);
            }
            const double leave_penalty = total > 0 ? left_out / total : 0.0;
            // A body spans the object: five fingers at the end of an arm are no body plan.
            if (extent(std::vector<std::uint32_t>(leaf, leaf + 5)) < 0.5 * whole_extent) continue;
        for (int h = 0; h < 5; ++h)
            for (int a = 0; a < 5; ++a)
                for (int b = a + 1; b < 5; ++b) {
                    if (a == h || b == h) continue;
                    int rest[2], r = 0;
                    for (int i = 0; i < 5; ++i)
                        if (i != h && i != a && i != b) rest[r++] = i;
                    const std::uint32_t H = leaf[h], A = leaf[a], B = leaf[b], C = leaf[rest[0]], D = leaf[rest[1]];
                    // The arms' meeting point may sit on a side branch (a shoulder girdle): the chest is where
                    // that branch joins the spine.
                    const std::uint32_t pelvis = median(A, B, H), chest = median(pelvis, median(C, D, H), H);
                    if (pelvis == chest) continue;
                    // A pair of limbs mirrors across the body's midplane: both tips sit at the same place along the
                    // spine's line (pelvis -> head) and at the same distance from it. Straight-line measures: paths
                    // through a cluttered trunk wander.
                    const Vec axis = (at(H) - at(pelvis)).normalized();
                    auto mirror = [&](std::uint32_t x, std::uint32_t y, std::uint32_t base) {
                        const Vec px = at(x) - at(pelvis), py = at(y) - at(pelvis);
                        const double tx = px.dot(axis), ty = py.dot(axis);
                        const double rx = (px - tx * axis).norm(), ry = (py - ty * axis).norm();
                        return (std::abs(tx - ty) + std::abs(rx - ry)) /
                               std::max((at(x) - at(base)).norm() + (at(y) - at(base)).norm(), 1e-12);
                    };
                    double score = mirror(A, B, pelvis) + mirror(C, D, chest) + leave_penalty;
                    const double rl = 0.5 * (mean_radius(path(pelvis, A)) + mean_radius(path(pelvis, B)));
                    const double ra = 0.5 * (mean_radius(path(chest, C)) + mean_radius(path(chest, D)));
                    if (rl < ra) score += 0.25;  // legs carry the body: thicker than arms
                    if (score < best) {
                        best = score;
                        chosen[0] = H;
                        chosen[1] = A;
                        chosen[2] = B;
                        chosen[3] = C;
                        chosen[4] = D;
                    }
                }
        }
        if (!std::isfinite(best) || best > 0.6) return false;
        const std::uint32_t H = chosen[0];
        std::uint32_t legs[2] = {chosen[1], chosen[2]}, arms[2] = {chosen[3], chosen[4]};
        const std::uint32_t pelvis = median(legs[0], legs[1], H);
        const std::uint32_t chest = median(pelvis, median(arms[0], arms[1], H), H);

        const std::vector<std::uint32_t> spine = path(pelvis, chest), head = path(chest, H);
        std::vector<std::uint32_t> leg_chain[2] = {path(pelvis, legs[0]), path(pelvis, legs[1])};
        std::vector<std::uint32_t> arm_chain[2] = {path(chest, arms[0]), path(chest, arms[1])};
        // A humanoid's legs point away from its head; a quadruped's hang below its spine.
        const Vec spine_dir = (at(chest) - at(pelvis)).normalized();
        const Vec leg_dir = (0.5 * (at(legs[0]) + at(legs[1])) - at(pelvis)).normalized();
        const bool humanoid = leg_dir.dot(spine_dir) < -0.5;

        const Fit spine_fit = fit_chain(spine, 3), head_fit = fit_chain(head, 2);
        Fit leg_fit[2], arm_fit[2];
        for (int k = 0; k < 2; ++k) {
            leg_fit[k] = humanoid ? limb_fit(leg_chain[k], false) : fit_chain(leg_chain[k], 4);
            arm_fit[k] = humanoid ? limb_fit(arm_chain[k], true) : fit_chain(arm_chain[k], 4);
        }
        if (spine_fit.cuts.size() != 4 || head_fit.cuts.size() != 3) return false;
        for (int k = 0; k < 2; ++k)
            if (leg_fit[k].cuts.size() != 5 || arm_fit[k].cuts.size() != 5) return false;

        // Orientation: the spine points up (humanoid) or forward (quadruped); left = up x forward.
        auto perp = [](const Vec& v, const Vec& axis) { return Vec(v - v.dot(axis) * axis); };
        Vec up, forward;
        if (humanoid) {
            up = spine_dir;
            forward = Vec::Zero();
            for (int s = 0; s < 2; ++s) {  // feet point forward: the last bone of each leg
                const auto& c = leg_fit[s].cuts;
                forward += perp(at(leg_chain[s][c[c.size() - 1]]) - at(leg_chain[s][c[c.size() - 2]]), up);
            }
        } else {
            forward = spine_dir;
            Vec down = Vec::Zero();
            for (int s = 0; s < 2; ++s) {
                down += perp(at(legs[s]) - at(pelvis), forward).normalized();
                down += perp(at(arms[s]) - at(chest), forward).normalized();
            }
            up = -down;
        }
        const Vec left = up.normalized().cross(forward.normalized());
        auto side = [&](std::uint32_t a, std::uint32_t b, std::uint32_t base) {  // true when a is the left one
            return (at(a) - at(base)).dot(left) >= (at(b) - at(base)).dot(left);
        };
        const bool leg0_left = side(legs[0], legs[1], pelvis), arm0_left = side(arms[0], arms[1], chest);

        Builder b;
        b.chain(*this, spine, spine_fit.cuts, {"hips", "spine", "chest"});
        b.chain(*this, head, head_fit.cuts, {"neck", "head"});
        for (int s = 0; s < 2; ++s) {
            const std::string sfx = ((s == 0) == arm0_left) ? ".L" : ".R";
            b.chain(*this, arm_chain[s], arm_fit[s].cuts,
                    {"shoulder" + sfx, "upper_arm" + sfx, "forearm" + sfx, "hand" + sfx});
        }
        for (int s = 0; s < 2; ++s) {
            const std::string sfx = ((s == 0) == leg0_left) ? ".L" : ".R";
            b.chain(*this, leg_chain[s], leg_fit[s].cuts, {"pelvis" + sfx, "thigh" + sfx, "shin" + sfx, "foot" + sfx});
        }
        b.rig.kind = humanoid ? "humanoid" : "quadruped";
        extend_ends(b.rig);
        out = std::move(b.rig);
        return true;
    }

    /// Chains between branch points, cut at bends; at most `target` bones.
    /// Key nodes of the subtree spanned by the root and the chosen leaves: the root, the leaves, and the nodes
    /// where two or more chosen branches part.
    std::vector<std::uint8_t> key_nodes(const std::vector<std::uint32_t>& leaves, std::vector<std::uint8_t>& in) const {
        in.assign(pos_.size(), 0);
        in[root_] = 1;
        for (std::uint32_t l : leaves)
            for (std::uint32_t v = l; v != kNone && !in[v]; v = t_.parent[v]) in[v] = 1;
        std::vector<std::uint32_t> kids(pos_.size(), 0);
        for (std::uint32_t v = 0; v < pos_.size(); ++v)
            if (in[v] && v != root_) ++kids[t_.parent[v]];
        std::vector<std::uint8_t> key(pos_.size(), 0);
        key[root_] = 1;
        for (std::uint32_t v = 0; v < pos_.size(); ++v)
            if (in[v] && (kids[v] != 1)) key[v] = 1;
        return key;
    }

    void chain_rig(Rig& out, int target) const {
        // The most significant branches, as many as the bone target allows one bone each.
        const auto ext = extremities();
        std::vector<std::uint32_t> leaves;
        std::vector<std::uint8_t> in, key;
        for (const auto& [significance, leaf] : ext) {
            leaves.push_back(leaf);
            std::vector<std::uint8_t> in2;
            const std::vector<std::uint8_t> key2 = key_nodes(leaves, in2);
            const long chains = std::count(key2.begin(), key2.end(), 1) - 1;
            if (chains > target && leaves.size() > 1) {
                leaves.pop_back();
                break;
            }
            key = key2;
            in = in2;
        }
        if (leaves.empty()) key = key_nodes(leaves, in);
        // Chains: from each key node (not the root) up to its nearest key ancestor, ordered outward from the root.
        std::vector<std::vector<std::uint32_t>> chains;
        for (std::uint32_t v : t_.order) {
            if (v == root_ || !key[v] || !in[v]) continue;
            std::vector<std::uint32_t> c{v};
            for (std::uint32_t u = t_.parent[v]; u != kNone; u = t_.parent[u]) {
                c.push_back(u);
                if (key[u]) break;
            }
            std::reverse(c.begin(), c.end());
            chains.push_back(std::move(c));
        }
        if (chains.empty()) return;  // a single point
        // Pieces per chain: the fewest within tolerance, then trimmed to the target by the smallest loss.
        std::vector<int> k(chains.size(), 1);
        std::vector<Fit> fits(chains.size());
        for (std::size_t c = 0; c < chains.size(); ++c) {
            for (;;) {
                fits[c] = fit_chain(chains[c], k[c]);
                if (fits[c].worst <= opt_.tolerance || k[c] >= 8 || static_cast<int>(fits[c].cuts.size()) - 1 < k[c])
                    break;
                ++k[c];
            }
        }
        int total = 0;
        for (const Fit& f : fits) total += static_cast<int>(f.cuts.size()) - 1;
        while (total > target) {
            std::size_t pick = chains.size();
            double least = std::numeric_limits<double>::infinity();
            for (std::size_t c = 0; c < chains.size(); ++c) {
                if (fits[c].cuts.size() <= 2) continue;
                const double w = fit_chain(chains[c], static_cast<int>(fits[c].cuts.size()) - 2).worst;
                if (w < least) {
                    least = w;
                    pick = c;
                }
            }
            if (pick == chains.size()) break;  // one bone per chain already
            fits[pick] = fit_chain(chains[pick], static_cast<int>(fits[pick].cuts.size()) - 2);
            --total;
        }
        Builder b;
        for (std::size_t c = 0; c < chains.size(); ++c) {
            std::vector<std::string> names;
            for (std::size_t p = 0; p + 1 < fits[c].cuts.size(); ++p) {
                std::string name = "chain" + std::to_string(c);
                if (p > 0) {
                    const std::string num = std::to_string(p);
                    name += "." + std::string(num.size() < 3 ? 3 - num.size() : 0, '0') + num;
                }
                names.push_back(std::move(name));
            }
            b.chain(*this, chains[c], fits[c].cuts, names);
        }
        b.rig.kind = "chains";
        extend_ends(b.rig);
        out = std::move(b.rig);
    }

    const Grid& g_;
    const std::uint8_t* mask_;
    const PointSet& pts_;
    AutorigOptions opt_;
    LevelSetTree lst_;
    const std::vector<Vec>& pos_;
    const std::vector<double>& rad_;
    std::vector<std::vector<std::uint32_t>> adj_;
    std::vector<std::uint8_t> kept_;
    std::uint32_t root_ = 0;
    RootedTree t_;
};

}  // namespace

Rig autorig(const Grid& g, const std::uint8_t* mask, const PointSet& pts,
            const std::vector<std::array<std::uint32_t, 2>>& edges, const AutorigOptions& opt,
            const Progress& progress, AutorigDetail* detail) {
    if (!pts.radius) throw Error("autorig: radii are required");
    check_points(g, mask, pts, "autorig");
    if (pts.n < 2) throw Error("autorig: needs at least 2 skeleton points, got " + std::to_string(pts.n));
    if (!(opt.prune_scale >= 1.0 && std::isfinite(opt.prune_scale)))
        throw Error("autorig: prune_scale must be >= 1");
    if (!(opt.tolerance > 0 && std::isfinite(opt.tolerance))) throw Error("autorig: tolerance must be > 0");
    if (opt.bones < 0 || opt.bones > 10000) throw Error("autorig: bones must lie in 1..10000 (0 = default)");
    for (const auto& e : edges)
        if (e[0] >= pts.n || e[1] >= pts.n || e[0] == e[1])
            throw Error("autorig: tree edge (" + std::to_string(e[0]) + ", " + std::to_string(e[1]) +
                        ") is not between two of the " + std::to_string(pts.n) + " points");
    std::size_t parts = 0;
    forest_components(pts.n, edges, &parts);
    if (edges.size() + parts != pts.n) throw Error("autorig: the tree edges contain a cycle");

    // The points that carry the shape: the scale axis, connected by the tree's edges among them and by contained
    // cone edges that may reach across each point's own ball.
    const std::vector<std::uint8_t> keep = scale_axis(g, pts);
    std::vector<std::uint32_t> sub_of(pts.n, kNone), point_of;
    std::vector<std::int32_t> sub_ijk;
    std::vector<float> sub_r;
    for (std::uint32_t i = 0; i < pts.n; ++i)
        if (keep[i]) {
            sub_of[i] = static_cast<std::uint32_t>(point_of.size());
            point_of.push_back(i);
            sub_ijk.insert(sub_ijk.end(), pts.ijk + 3 * i, pts.ijk + 3 * i + 3);
            sub_r.push_back(pts.radius[i]);
        }
    const PointSet sub{sub_ijk.data(), sub_r.data(), point_of.size()};
    std::vector<std::array<std::uint32_t, 2>> sub_edges = cone_edges(g, mask, sub, default_max_edge(g), true, {}, 0, 0);
    for (const auto& e : edges)
        if (keep[e[0]] && keep[e[1]])
            sub_edges.push_back({std::min(sub_of[e[0]], sub_of[e[1]]), std::max(sub_of[e[0]], sub_of[e[1]])});
    std::sort(sub_edges.begin(), sub_edges.end());
    sub_edges.erase(std::unique(sub_edges.begin(), sub_edges.end()), sub_edges.end());
    report(progress, 0.2);
    // Thin parts of a sparse skeleton break into fragments farther apart than E: join each fragment to its nearest
    // point elsewhere along a line inside the object, up to 8 E away.
    const double e0 = default_max_edge(g);
    const auto joins = bridge_components(g, mask, sub, sub_edges, 8.0 * e0, e0);
    sub_edges.insert(sub_edges.end(), joins.begin(), joins.end());
    report(progress, 0.3);
    const SkeletonGraph graph = graph_of_edges(g, sub, sub_edges);
    // The part to rig: the connected part with the largest ball volume, renumbered 0.
    std::size_t count = 0;
    std::vector<std::uint32_t> component = forest_components(sub.n, sub_edges, &count);
    std::vector<double> volume(count, 0.0);
    for (std::size_t i = 0; i < sub.n; ++i) volume[component[i]] += std::pow(static_cast<double>(sub_r[i]), 3);
    const std::uint32_t main = static_cast<std::uint32_t>(std::max_element(volume.begin(), volume.end()) - volume.begin());
    for (auto& c : component) c = c == main ? 0 : 1;
    // Level bands: a fifth of the median radius of the part, at least one voxel diagonal.
    std::vector<float> r;
    for (std::size_t i = 0; i < sub.n; ++i)
        if (component[i] == 0) r.push_back(sub_r[i]);
    std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2), r.end());
    const double voxel = std::sqrt(g.spacing[0] * g.spacing[0] + g.spacing[1] * g.spacing[1] + g.spacing[2] * g.spacing[2]);
    const double band = std::max(voxel, 0.2 * r[r.size() / 2]);
    LevelSetTree lst = level_set_tree(g, sub, graph, component, band);
    // Back to the caller's point indices.
    for (auto& p : lst.rep) p = point_of[p];
    std::vector<std::uint32_t> node_of_point(pts.n, kNone);
    for (std::size_t k = 0; k < sub.n; ++k) node_of_point[point_of[k]] = lst.node_of_point[k];
    lst.node_of_point = std::move(node_of_point);
    report(progress, 0.5);
    Autorig a(g, mask, pts, std::move(lst), opt);
    Rig rig = a.run(progress, detail);
    if (rig.bones.empty()) throw Error("autorig: the skeleton-tree has no branch to make a bone of");
    check_rig(rig);
    return rig;
}

}  // namespace volrig

// rig/autorig/shape_tree.cpp: scale axis, level-set tree, and autorig's first stage (see shape_tree.hpp).
#include "rig/autorig/shape_tree.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <tuple>

#include "common/point_grid.hpp"

namespace volrig::rig_detail {

namespace {

std::vector<Vec> positions(const Grid& g, const PointSet& pts) {
    std::vector<Vec> pos(pts.n);
    for (std::size_t i = 0; i < pts.n; ++i) {
        const auto p = point_position(g, pts, i);
        pos[i] = Vec(p[0], p[1], p[2]);
    }
    return pos;
}

/// Connected pieces of the points of one level (edges within a level), as nodes of `t`.
void level_pieces(const PointSet& pts, const std::vector<Vec>& pos, const SkeletonGraph& graph,
                  const std::vector<std::int64_t>& level, LevelSetTree& t) {
    const std::size_t n = pts.n;
    common_detail::DisjointSets sets(n);
    for (std::uint32_t v = 0; v < n; ++v)
        for (std::uint32_t e = graph.offsets[v]; e < graph.offsets[v + 1]; ++e) {
            const std::uint32_t w = graph.targets[e];
            if (level[v] >= 0 && level[v] == level[w]) sets.unite(v, w);
        }
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
        if (k == kNone) continue;
        if ((pos[i] - t.centroid[k]).squaredNorm() < (pos[t.rep[k]] - t.centroid[k]).squaredNorm()) t.rep[k] = i;
    }
}

}  // namespace

std::vector<std::uint8_t> scale_axis(const Grid& g, const PointSet& pts) {
    const std::size_t n = pts.n;
    const std::vector<Vec> pos = positions(g, pts);
    std::vector<std::uint8_t> keep(n, 1);
    std::vector<std::uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(),
                     [&](std::uint32_t a, std::uint32_t b) { return pts.radius[a] > pts.radius[b]; });
    // Cells of a quarter of the largest radius: the largest balls scan about 10^3 cells.
    const double largest = order.empty() ? 1.0 : pts.radius[order[0]];
    std::array<std::int64_t, 3> cell;
    for (int a = 0; a < 3; ++a) cell[a] = std::max<std::int64_t>(1, std::llround(0.25 * largest / g.spacing[a]));
    const common_detail::PointGrid grid(g, pts, cell);
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
            // (with a margin for rounding: grid distances meet the bound exactly, in any order of summing)
            if ((pos[j] - pos[i]).norm() + pts.radius[j] <= reach_w * (1 + 1e-9)) keep[j] = 0;
        });
    }
    return keep;
}

namespace {

// Where level_set_tree measures from: of the points as large as the largest (within kTiedRadius), those nearest
// (within kTiedRadius) to their centroid, at distance 0; the rest at infinity. Empty when no point is in the part.
// Chosen by geometry alone, so the same points in another order or rotated give the same sources; on a shape of
// one radius everywhere (a tube) this is its middle rather than every point.
std::vector<double> source_distances(const PointSet& pts, const std::vector<Vec>& pos,
                                     const std::vector<std::uint8_t>& in_part) {
    float largest = -1;
    for (std::uint32_t i = 0; i < pts.n; ++i)
        if (in_part[i]) largest = std::max(largest, pts.radius[i]);
    if (largest < 0) return {};
    std::vector<std::uint32_t> tied;
    Vec centre = Vec::Zero();
    for (std::uint32_t i = 0; i < pts.n; ++i)
        if (in_part[i] && pts.radius[i] >= (1.0 - kTiedRadius) * largest) {
            tied.push_back(i);
            centre += pos[i];
        }
    centre /= static_cast<double>(tied.size());
    double nearest = std::numeric_limits<double>::infinity();
    for (const std::uint32_t i : tied) nearest = std::min(nearest, (pos[i] - centre).norm());
    std::vector<double> dist(pts.n, std::numeric_limits<double>::infinity());
    const double tolerance = kTiedRadius * std::max(1.0, static_cast<double>(largest));
    for (const std::uint32_t i : tied)
        if ((pos[i] - centre).norm() <= nearest + tolerance) dist[i] = 0;
    return dist;
}

}  // namespace

LevelSetTree level_set_tree(const Grid& g, const PointSet& pts, const SkeletonGraph& graph,
                            const std::vector<std::uint8_t>& in_part, double band) {
    const std::size_t n = pts.n;
    const std::vector<Vec> pos = positions(g, pts);
    LevelSetTree t;
    std::vector<double> dist = source_distances(pts, pos, in_part);
    if (dist.empty()) {
        t.node_of_point.assign(n, kNone);
        return t;
    }
    shortest_paths(graph, dist, nullptr, &in_part);
    std::vector<std::int64_t> level(n, -1);
    for (std::size_t i = 0; i < n; ++i)
        // A distance a whole number of bands summed in another order may come out a bit under: nudged up.
        if (std::isfinite(dist[i])) level[i] = static_cast<std::int64_t>(dist[i] / band + 1e-9);
    level_pieces(pts, pos, graph, level, t);
    // Links between pieces, reduced to a spanning tree (Kruskal by centroid distance over the link's strength
    // squared): a link is as strong as the thickest graph edge joining the two pieces, relative to the thinner
    // piece (its smaller end radius over that piece's radius). Within a limb and where it grows out of the trunk
    // the axis runs on at the limb's own radius (about 1); where a limb only touches the body (a hand on the
    // pelvis, an arm against the trunk) the pieces meet through thin near-surface points: weak links, cut first
    // where they close a loop. (Limbs touching at the same geodesic level, knees together, share their level
    // pieces: no link to cut there.)
    std::map<std::pair<std::uint32_t, std::uint32_t>, double> strength;
    for (std::uint32_t v = 0; v < n; ++v)
        for (std::uint32_t e = graph.offsets[v]; e < graph.offsets[v + 1]; ++e) {
            const std::uint32_t w = graph.targets[e], a = t.node_of_point[v], b = t.node_of_point[w];
            if (a == kNone || b == kNone || a >= b) continue;
            const double s = std::min(pts.radius[v], pts.radius[w]) / std::min(t.radius[a], t.radius[b]);
            double& best = strength[{a, b}];
            best = std::max(best, s);
        }
    std::vector<std::tuple<double, std::uint32_t, std::uint32_t>> links;
    for (const auto& [ab, s] : strength) {
        const double weak = std::max(std::min(s, 1.0), kWeakestLink);
        links.emplace_back((t.centroid[ab.first] - t.centroid[ab.second]).norm() / (weak * weak), ab.first, ab.second);
    }
    std::sort(links.begin(), links.end());
    common_detail::DisjointSets nodes(t.centroid.size());
    for (const auto& [w, a, b] : links)
        if (nodes.unite(a, b)) t.edges.push_back({a, b});
    return t;
}

LevelSetTree shape_tree(const Grid& g, const std::uint8_t* mask, const PointSet& pts,
                        const std::vector<std::array<std::uint32_t, 2>>& tree_edges, const Progress& progress) {
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
    std::vector<std::array<std::uint32_t, 2>> edges = cone_edges(g, mask, sub, default_max_edge(g), true, {}, 0, 0);
    for (const auto& e : tree_edges)
        if (keep[e[0]] && keep[e[1]])
            edges.push_back({std::min(sub_of[e[0]], sub_of[e[1]]), std::max(sub_of[e[0]], sub_of[e[1]])});
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    report(progress, 0.2);
    // Thin parts of a sparse skeleton break into fragments farther apart than E: join each fragment to its nearest
    // point elsewhere along a line inside the object, up to 8 E away.
    const double e0 = default_max_edge(g);
    const auto joins = bridge_components(g, mask, sub, edges, 8.0 * e0, e0);
    edges.insert(edges.end(), joins.begin(), joins.end());
    report(progress, 0.3);
    const SkeletonGraph graph = graph_of_edges(g, sub, edges);
    // The part to rig: the connected part with the largest ball volume.
    std::size_t count = 0;
    const std::vector<std::uint32_t> component = forest_components(sub.n, edges, &count);
    std::vector<double> volume(count, 0.0);
    for (std::size_t i = 0; i < sub.n; ++i) volume[component[i]] += std::pow(static_cast<double>(sub_r[i]), 3);
    const auto main = static_cast<std::uint32_t>(std::max_element(volume.begin(), volume.end()) - volume.begin());
    std::vector<std::uint8_t> in_part(sub.n);
    std::vector<float> r;
    for (std::size_t i = 0; i < sub.n; ++i)
        if ((in_part[i] = component[i] == main)) r.push_back(sub_r[i]);
    std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2), r.end());
    const double voxel = std::sqrt(g.spacing[0] * g.spacing[0] + g.spacing[1] * g.spacing[1] + g.spacing[2] * g.spacing[2]);
    const double band = std::max(voxel, 0.2 * r[r.size() / 2]);
    LevelSetTree lst = level_set_tree(g, sub, graph, in_part, band);
    // Back to the caller's point indices.
    for (auto& p : lst.rep) p = point_of[p];
    std::vector<std::uint32_t> node_of_point(pts.n, kNone);
    for (std::size_t k = 0; k < sub.n; ++k) node_of_point[point_of[k]] = lst.node_of_point[k];
    lst.node_of_point = std::move(node_of_point);
    return lst;
}

}  // namespace volrig::rig_detail

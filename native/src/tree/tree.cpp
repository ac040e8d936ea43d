#include "volrig/tree.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <queue>
#include <string>
#include <tuple>

#include "common/point_grid.hpp"

namespace volrig {

using common_detail::DisjointSets;
using common_detail::PointGrid;

void check_points(const Grid& g, const std::uint8_t* mask, const PointSet& pts, const char* what) {
    check_grid(g, 1, std::numeric_limits<std::uint64_t>::max(), what);
    if (pts.n >= std::numeric_limits<std::uint32_t>::max())
        throw Error(std::string(what) + ": too many points (" + std::to_string(pts.n) + ")");
    for (std::size_t i = 0; i < pts.n; ++i) {
        const std::int32_t* p = pts.ijk + 3 * i;
        const bool inside = p[0] >= 0 && p[1] >= 0 && p[2] >= 0 && p[0] < g.dims[2] && p[1] < g.dims[1] &&
                            p[2] < g.dims[0];
        const std::string at = "point " + std::to_string(i) + " at [z, y, x] = [" + std::to_string(p[0]) + ", " +
                               std::to_string(p[1]) + ", " + std::to_string(p[2]) + "]";
        if (!inside) throw Error(std::string(what) + ": " + at + " lies outside the mask's grid");
        if (!mask[g.index(p[2], p[1], p[0])])
            throw Error(std::string(what) + ": " + at + " is not an object voxel of the mask");
        if (pts.radius && !(std::isfinite(pts.radius[i]) && pts.radius[i] >= 0))
            throw Error(std::string(what) + ": " + at + " has radius " + std::to_string(pts.radius[i]));
    }
}

std::array<double, 3> point_position(const Grid& g, const PointSet& pts, std::size_t i) {
    const std::int32_t* p = pts.ijk + 3 * i;
    return {g.origin[0] + g.spacing[0] * p[2], g.origin[1] + g.spacing[1] * p[1], g.origin[2] + g.spacing[2] * p[0]};
}

bool line_inside(const Grid& g, const std::uint8_t* mask, const std::int32_t* a, const std::int32_t* b) {
    // 3D Bresenham over (x, y, z), driven by the axis of largest extent; both end voxels are visited.
    std::int64_t p[3] = {a[2], a[1], a[0]};
    const std::int64_t q[3] = {b[2], b[1], b[0]};
    std::int64_t d[3], s[3];
    for (int k = 0; k < 3; ++k) {
        d[k] = std::abs(q[k] - p[k]);
        s[k] = q[k] > p[k] ? 1 : -1;
    }
    const int m = d[0] >= d[1] ? (d[0] >= d[2] ? 0 : 2) : (d[1] >= d[2] ? 1 : 2);
    const int u = (m + 1) % 3, v = (m + 2) % 3;
    std::int64_t eu = 2 * d[u] - d[m], ev = 2 * d[v] - d[m];
    auto inside = [&]() {
        return p[0] >= 0 && p[1] >= 0 && p[2] >= 0 && p[0] < g.dims[0] && p[1] < g.dims[1] && p[2] < g.dims[2] &&
               mask[g.index(p[0], p[1], p[2])] != 0;
    };
    for (std::int64_t step = 0; step <= d[m]; ++step) {
        if (!inside()) return false;
        if (eu > 0) {
            p[u] += s[u];
            eu -= 2 * d[m];
        }
        if (ev > 0) {
            p[v] += s[v];
            ev -= 2 * d[m];
        }
        eu += 2 * d[u];
        ev += 2 * d[v];
        p[m] += s[m];
    }
    return true;
}

double default_max_edge(const Grid& g) {
    return 4.0 * std::sqrt(g.spacing[0] * g.spacing[0] + g.spacing[1] * g.spacing[1] + g.spacing[2] * g.spacing[2]);
}

namespace {

double resolve_max_edge(const Grid& g, double e) {
    if (!std::isfinite(e) || e < 0) throw Error("skeleton_tree: max_edge must be positive (0 for the default)");
    return e > 0 ? e : default_max_edge(g);
}

/// Cone of a direction: the nearest of the 26 voxel directions (each component quantised at +-sin 22.5 deg).
int cone_of(double dx, double dy, double dz) {
    const double n = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double t = 0.38268343236508984 * n;
    auto q = [t](double c) { return c > t ? 2 : (c < -t ? 0 : 1); };
    return q(dx) + 3 * q(dy) + 9 * q(dz);
}

/// Runs body(begin, end) over [0, n) in parallel, in slices between which progress is reported from this thread.
template <class Body>
void sliced_parallel_for(std::size_t n, const Progress& progress, double p0, double p1, Body&& body) {
    const std::size_t slices = std::max<std::size_t>(1, std::min<std::size_t>(20, n / 4096));
    for (std::size_t s = 0; s < slices; ++s) {
        const std::size_t b = n * s / slices, e = n * (s + 1) / slices;
        tbb::parallel_for(tbb::blocked_range<std::size_t>(b, e, 256), [&](const tbb::blocked_range<std::size_t>& r) {
            body(r.begin(), r.end());
        });
        report(progress, p0 + (p1 - p0) * static_cast<double>(s + 1) / static_cast<double>(slices));
    }
}

using Pair = std::array<std::uint32_t, 2>;

}  // namespace

std::vector<std::array<std::uint32_t, 2>> cone_edges(const Grid& g, const std::uint8_t* mask, const PointSet& pts,
                                                     double e, bool ball_rule, const Progress& progress, double p0,
                                                     double p1) {
    // Cells of the plain reach e; a point scans the cells its reach touches (at most 3 e with the ball rule).
    const double cell_w = e;
    std::array<std::int64_t, 3> cell;
    for (int a = 0; a < 3; ++a) cell[a] = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::floor(cell_w / g.spacing[a])));
    const PointGrid grid(g, pts, cell);
    const double slack = 0.87 * std::max({g.spacing[0], g.spacing[1], g.spacing[2]});
    tbb::enumerable_thread_specific<std::vector<Pair>> local;
    sliced_parallel_for(pts.n, progress, p0, p1, [&](std::size_t b, std::size_t end) {
        auto& out = local.local();
        std::vector<std::pair<double, std::uint32_t>> cand;
        for (std::size_t i = b; i < end; ++i) {
            const std::int32_t* pi = pts.ijk + 3 * i;
            const double ri = ball_rule ? static_cast<double>(pts.radius[i]) : 0.0;
            const double reach = std::max(e, std::min(ri, 3.0 * e)), reach2 = reach * reach;
            std::array<std::int64_t, 3> lo, hi;
            for (int a = 0; a < 3; ++a) {
                const std::int64_t v = pi[2 - a], span = static_cast<std::int64_t>(std::ceil(reach / g.spacing[a]));
                lo[a] = std::max<std::int64_t>(0, v - span) / cell[a];
                hi[a] = (v + span) / cell[a];
            }
            cand.clear();
            grid.for_each_in_box(lo, hi, [&](std::uint32_t j) {
                if (j == i) return;
                const std::int32_t* pj = pts.ijk + 3 * j;
                const double dx = (pj[2] - pi[2]) * g.spacing[0], dy = (pj[1] - pi[1]) * g.spacing[1],
                             dz = (pj[0] - pi[0]) * g.spacing[2];
                const double d2 = dx * dx + dy * dy + dz * dz;
                if (d2 <= reach2) cand.emplace_back(d2, j);
            });
            std::sort(cand.begin(), cand.end());
            std::uint32_t closed = 0;  // bit per cone: a neighbour was found, or two lines failed
            std::uint8_t failures[27] = {};
            // Candidates equally near (up to rounding) are taken together: which of them closes a cone does not
            // depend on the order of the points (the same edges with the object turned or mirrored).
            for (std::size_t a = 0; a < cand.size() && closed != 0x7FFDFFFu;) {  // bit 13 (no direction) never set
                std::uint32_t closing = 0;
                for (const double near = cand[a].first * (1 + 1e-9); a < cand.size() && cand[a].first <= near; ++a) {
                    const auto [d2, j] = cand[a];
                    const std::int32_t* pj = pts.ijk + 3 * j;
                    const int k = cone_of((pj[2] - pi[2]) * g.spacing[0], (pj[1] - pi[1]) * g.spacing[1],
                                          (pj[0] - pi[0]) * g.spacing[2]);
                    if (closed & (1u << k)) continue;
                    // A line inside the point's own ball is inside the object.
                    if (std::sqrt(d2) + slack < ri || line_inside(g, mask, pi, pj)) {
                        closing |= 1u << k;
                        out.push_back(i < j ? Pair{static_cast<std::uint32_t>(i), j}
                                            : Pair{j, static_cast<std::uint32_t>(i)});
                    } else if (++failures[k] >= 2) {
                        closing |= 1u << k;
                    }
                }
                closed |= closing;
            }
        }
    });
    std::vector<Pair> edges;
    for (auto& v : local) edges.insert(edges.end(), v.begin(), v.end());
    tbb::parallel_sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    return edges;
}

namespace {

double distance(const Grid& g, const PointSet& pts, std::uint32_t i, std::uint32_t j) {
    const auto a = point_position(g, pts, i), b = point_position(g, pts, j);
    return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/// Nearest point (world distance) whose component differs from `comp[i]`, no farther than `max_dist`; with a
/// mask, the nearest whose line from i stays inside it (at most 64 lines tested). Returns (distance, index) or
/// (inf, n) when there is none.
std::pair<double, std::uint32_t> nearest_other(const Grid& g, const PointSet& pts, const PointGrid& grid,
                                               const std::vector<std::uint32_t>& comp, std::uint32_t i,
                                               const std::uint8_t* mask, double max_dist) {
    const auto c = grid.cell_of(pts.ijk + 3 * i);
    double ring_step = std::numeric_limits<double>::infinity();
    std::int64_t max_ring = 0;
    for (int a = 0; a < 3; ++a) {
        ring_step = std::min(ring_step, static_cast<double>(grid.cell()[a]) * g.spacing[a]);
        max_ring = std::max(max_ring, grid.cells()[a]);
    }
    if (std::isfinite(max_dist))
        max_ring = std::min<std::int64_t>(max_ring, static_cast<std::int64_t>(std::ceil(max_dist / ring_step)) + 1);
    const auto pi = point_position(g, pts, i);
    std::vector<std::pair<double, std::uint32_t>> pending;  // sorted by descending distance when popped
    int tests = 0;
    for (std::int64_t r = 0; r <= max_ring; ++r) {
        grid.for_each_in_ring(c, r, [&](std::uint32_t j) {
            if (comp[j] == comp[i]) return;
            const auto pj = point_position(g, pts, j);
            const double d = std::sqrt((pj[0] - pi[0]) * (pj[0] - pi[0]) + (pj[1] - pi[1]) * (pj[1] - pi[1]) +
                                       (pj[2] - pi[2]) * (pj[2] - pi[2]));
            if (d <= max_dist) pending.emplace_back(d, j);
        });
        // Every point not yet visited lies at least r cells away along some axis.
        const double sure = r == max_ring ? std::numeric_limits<double>::infinity() : static_cast<double>(r) * ring_step;
        std::sort(pending.begin(), pending.end(), std::greater<>());
        while (!pending.empty() && pending.back().first <= sure) {
            const auto [d, j] = pending.back();
            pending.pop_back();
            if (!mask || line_inside(g, mask, pts.ijk + 3 * i, pts.ijk + 3 * j)) return {d, j};
            if (++tests >= 64) return {std::numeric_limits<double>::infinity(), static_cast<std::uint32_t>(pts.n)};
        }
    }
    return {std::numeric_limits<double>::infinity(), static_cast<std::uint32_t>(pts.n)};
}

}  // namespace

SkeletonGraph skeleton_graph(const Grid& g, const std::uint8_t* mask, const PointSet& pts, double max_edge,
                             const Progress& progress) {
    check_points(g, mask, pts, "skeleton_graph");
    const double e = resolve_max_edge(g, max_edge);
    SkeletonGraph out = graph_of_edges(g, pts, cone_edges(g, mask, pts, e, false, progress, 0.0, 0.9));
    report(progress, 1.0);
    return out;
}

SkeletonGraph graph_of_edges(const Grid& g, const PointSet& pts, const std::vector<Pair>& edges) {
    SkeletonGraph out;
    out.offsets.assign(pts.n + 1, 0);
    for (const auto& p : edges) {
        ++out.offsets[p[0] + 1];
        ++out.offsets[p[1] + 1];
    }
    std::partial_sum(out.offsets.begin(), out.offsets.end(), out.offsets.begin());
    out.targets.resize(2 * edges.size());
    out.lengths.resize(2 * edges.size());
    std::vector<std::uint32_t> fill(out.offsets.begin(), out.offsets.end() - 1);
    for (const auto& p : edges) {
        const float len = static_cast<float>(distance(g, pts, p[0], p[1]));
        out.targets[fill[p[0]]] = p[1];
        out.lengths[fill[p[0]]++] = len;
        out.targets[fill[p[1]]] = p[0];
        out.lengths[fill[p[1]]++] = len;
    }
    return out;
}

void shortest_paths(const SkeletonGraph& graph, std::vector<double>& dist, std::vector<std::int32_t>* label,
                    const std::vector<std::uint8_t>* allowed) {
    using Item = std::pair<double, std::uint32_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
    for (std::uint32_t i = 0; i < dist.size(); ++i)
        if (std::isfinite(dist[i])) queue.push({dist[i], i});
    while (!queue.empty()) {
        const auto [d, v] = queue.top();
        queue.pop();
        if (d > dist[v]) continue;
        for (std::uint32_t e = graph.offsets[v]; e < graph.offsets[v + 1]; ++e) {
            const std::uint32_t w = graph.targets[e];
            const double nd = d + graph.lengths[e];
            if ((allowed && !(*allowed)[w]) || nd >= dist[w]) continue;
            dist[w] = nd;
            if (label) (*label)[w] = (*label)[v];
            queue.push({nd, w});
        }
    }
}

std::vector<std::uint32_t> forest_components(std::size_t n, const std::vector<Pair>& edges, std::size_t* count) {
    DisjointSets sets(n);
    for (const auto& p : edges) sets.unite(p[0], p[1]);
    // Roots ordered by descending size, ties by smallest member (the first point seen with that root).
    std::vector<std::uint32_t> first(n, std::numeric_limits<std::uint32_t>::max()), roots;
    for (std::uint32_t i = 0; i < n; ++i) {
        const std::uint32_t r = sets.find(i);
        if (first[r] == std::numeric_limits<std::uint32_t>::max()) {
            first[r] = i;
            roots.push_back(r);
        }
    }
    std::stable_sort(roots.begin(), roots.end(),
                     [&](std::uint32_t a, std::uint32_t b) { return sets.size_of(a) > sets.size_of(b); });
    std::vector<std::uint32_t> id(n, 0);
    for (std::size_t k = 0; k < roots.size(); ++k) first[roots[k]] = static_cast<std::uint32_t>(k);
    for (std::uint32_t i = 0; i < n; ++i) id[i] = first[sets.find(i)];
    if (count) *count = roots.size();
    return id;
}

std::vector<Pair> bridge_components(const Grid& g, const std::uint8_t* mask, const PointSet& pts,
                                    const std::vector<Pair>& edges, double max_dist, double cell_size) {
    // Boruvka: each round, every component but the one with most points contributes its closest pair to another
    // component (a safe spanning-tree edge by the cut property), until one is left or none can join.
    std::array<std::int64_t, 3> cell;
    for (int a = 0; a < 3; ++a) cell[a] = std::max<std::int64_t>(2, static_cast<std::int64_t>(cell_size / g.spacing[a]));
    const PointGrid grid(g, pts, cell);
    DisjointSets sets(pts.n);
    for (const auto& e : edges) sets.unite(e[0], e[1]);
    std::vector<Pair> all = edges, added;
    for (;;) {
        std::size_t count = 0;
        const std::vector<std::uint32_t> comp = forest_components(pts.n, all, &count);
        if (count <= 1) break;
        std::vector<std::pair<double, std::uint32_t>> best(pts.n);
        tbb::parallel_for(std::uint32_t{0}, static_cast<std::uint32_t>(pts.n), [&](std::uint32_t i) {
            best[i] = comp[i] == 0 ? std::pair<double, std::uint32_t>{std::numeric_limits<double>::infinity(), 0}
                                   : nearest_other(g, pts, grid, comp, i, mask, max_dist);
        });
        std::vector<std::tuple<double, std::uint32_t, std::uint32_t>> pick(
            count, {std::numeric_limits<double>::infinity(), 0, 0});
        for (std::uint32_t i = 0; i < pts.n; ++i) {
            auto& p = pick[comp[i]];
            if (best[i].first < std::get<0>(p)) p = {best[i].first, i, best[i].second};
        }
        std::sort(pick.begin(), pick.end());
        bool joined = false;
        for (const auto& [d, i, j] : pick) {
            if (!std::isfinite(d) || !sets.unite(i, j)) continue;
            const Pair e{std::min(i, j), std::max(i, j)};
            all.push_back(e);
            added.push_back(e);
            joined = true;
        }
        if (!joined) break;
    }
    return added;
}

SkeletonTree skeleton_tree(const Grid& g, const std::uint8_t* mask, const PointSet& pts, const TreeOptions& opt,
                           const Progress& progress) {
    if (!(opt.alpha >= 0.0 && opt.alpha <= 1.0)) throw Error("skeleton_tree: alpha must lie in [0, 1]");
    if (!pts.radius) throw Error("skeleton_tree: radii are required");
    check_points(g, mask, pts, "skeleton_tree");
    SkeletonTree t;
    t.max_edge = resolve_max_edge(g, opt.max_edge);
    std::vector<Pair> edges = cone_edges(g, mask, pts, t.max_edge, false, progress, 0.0, 0.8);

    auto weight = [&](std::uint32_t i, std::uint32_t j) {
        return opt.alpha * distance(g, pts, i, j) +
               (1.0 - opt.alpha) * std::abs(static_cast<double>(pts.radius[i]) - pts.radius[j]);
    };
    std::vector<std::tuple<double, std::uint32_t, std::uint32_t>> weighted(edges.size());
    tbb::parallel_for(std::size_t{0}, edges.size(), [&](std::size_t k) {
        weighted[k] = {weight(edges[k][0], edges[k][1]), edges[k][0], edges[k][1]};
    });
    edges = {};
    tbb::parallel_sort(weighted.begin(), weighted.end());
    report(progress, 0.85);

    DisjointSets sets(pts.n);
    for (const auto& [w, i, j] : weighted) {
        if (sets.unite(i, j)) {
            t.edges.push_back({i, j});
            t.weights.push_back(w);
            t.bridged.push_back(0);
        }
    }
    weighted = {};
    t.component = forest_components(pts.n, t.edges, &t.component_count);

    if (opt.bridge && t.component_count > 1) {
        const std::vector<Pair> added =
            bridge_components(g, nullptr, pts, t.edges, std::numeric_limits<double>::infinity(), t.max_edge);
        for (const auto& e : added) {
            t.edges.push_back(e);
            t.weights.push_back(weight(e[0], e[1]));
            t.bridged.push_back(1);
        }
        t.component = forest_components(pts.n, t.edges, &t.component_count);
    }
    report(progress, 1.0);
    return t;
}

}  // namespace volrig

// The rods of medial_surface.hpp: the curve skeleton as a graph, spurs pruned, traced into polylines with radii.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "medial/geometry.hpp"

namespace volrig::medial_detail {

namespace {

/// Index of a voxel in a sorted list, -1 when absent.
std::int64_t find(const std::vector<std::int64_t>& sorted, std::int64_t v) {
    const auto it = std::lower_bound(sorted.begin(), sorted.end(), v);
    return it != sorted.end() && *it == v ? static_cast<std::int64_t>(it - sorted.begin()) : -1;
}

/// The curve graph: curve and junction voxels, 26-adjacent, without the diagonal links a shorter two-step path
/// through a third voxel of the set replaces (so a digital curve is a chain, its corners no triangles).
std::vector<std::vector<std::int64_t>> curve_graph(const Grid& g, const std::vector<std::int64_t>& nodes) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    std::vector<std::vector<std::int64_t>> adj(nodes.size());
    tbb::parallel_for(std::size_t{0}, nodes.size(), [&](std::size_t k) {
        const std::int64_t i = nodes[k], x = i % nx, y = (i / nx) % ny, z = i / (nx * ny);
        auto node_at = [&](std::int64_t dx, std::int64_t dy, std::int64_t dz) -> std::int64_t {
            const std::int64_t X = x + dx, Y = y + dy, Z = z + dz;
            if (X < 0 || Y < 0 || Z < 0 || X >= g.dims[0] || Y >= g.dims[1] || Z >= g.dims[2]) return -1;
            return find(nodes, g.index(X, Y, Z));
        };
        for (std::int64_t dz = -1; dz <= 1; ++dz)
            for (std::int64_t dy = -1; dy <= 1; ++dy)
                for (std::int64_t dx = -1; dx <= 1; ++dx) {
                    if (!(dx || dy || dz)) continue;
                    const std::int64_t c = node_at(dx, dy, dz);
                    if (c < 0) continue;
                    const std::int64_t l2 = dx * dx + dy * dy + dz * dz;
                    bool redundant = false;
                    for (std::int64_t ez = -1; ez <= 1 && !redundant; ++ez)
                        for (std::int64_t ey = -1; ey <= 1 && !redundant; ++ey)
                            for (std::int64_t ex = -1; ex <= 1 && !redundant; ++ex) {
                                const std::int64_t fx = dx - ex, fy = dy - ey, fz = dz - ez;
                                if (!(ex || ey || ez) || std::abs(fx) > 1 || std::abs(fy) > 1 || std::abs(fz) > 1) continue;
                                if (!(fx || fy || fz)) continue;
                                if (ex * ex + ey * ey + ez * ez < l2 && fx * fx + fy * fy + fz * fz < l2 && node_at(ex, ey, ez) >= 0)
                                    redundant = true;
                            }
                    if (!redundant) adj[k].push_back(c);
                }
    });
    return adj;
}

/// Polylines of the curve graph between its ends and branch points (and around loops with neither).
std::vector<std::vector<std::int64_t>> trace(const std::vector<std::vector<std::int64_t>>& adj) {
    std::vector<std::vector<std::int64_t>> out;
    std::vector<std::vector<std::uint8_t>> used(adj.size());
    for (std::size_t k = 0; k < adj.size(); ++k) used[k].assign(adj[k].size(), 0);
    auto mark = [&](std::int64_t a, std::int64_t b) {
        for (std::size_t s = 0; s < adj[static_cast<std::size_t>(a)].size(); ++s)
            if (adj[static_cast<std::size_t>(a)][s] == b) used[static_cast<std::size_t>(a)][s] = 1;
    };
    auto walk = [&](std::int64_t start, std::size_t slot) {
        std::vector<std::int64_t> line{start};
        std::int64_t prev = start, cur = adj[static_cast<std::size_t>(start)][slot];
        mark(prev, cur);
        mark(cur, prev);
        line.push_back(cur);
        while (adj[static_cast<std::size_t>(cur)].size() == 2 && cur != start) {
            const auto& a = adj[static_cast<std::size_t>(cur)];
            const std::size_t s = a[0] == prev ? 1 : 0;
            if (used[static_cast<std::size_t>(cur)][s]) break;
            prev = cur;
            cur = a[s];
            mark(prev, cur);
            mark(cur, prev);
            line.push_back(cur);
        }
        out.push_back(std::move(line));
    };
    for (int loops = 0; loops < 2; ++loops)  // ends and branches first, then the loops left
        for (std::size_t k = 0; k < adj.size(); ++k) {
            if (loops == 0 && adj[k].size() == 2) continue;
            for (std::size_t s = 0; s < adj[k].size(); ++s)
                if (!used[k][s]) walk(static_cast<std::int64_t>(k), s);
        }
    return out;
}

/// Removes `k` from the curve graph.
void unlink(std::vector<std::vector<std::int64_t>>& adj, std::int64_t k) {
    for (std::int64_t n : adj[static_cast<std::size_t>(k)]) {
        auto& a = adj[static_cast<std::size_t>(n)];
        a.erase(std::remove(a.begin(), a.end(), k), a.end());
    }
    adj[static_cast<std::size_t>(k)].clear();
}

/// Prunes spurs: chains of curve voxels from a free end to a branch point or a junction (a rod's foot on a plate)
/// shorter than `t` (world units): bumps of a noisy boundary, below the scale t sets for plates too. A chain is
/// deleted from its free end one simple point at a time (stopping at any that is not), so the skeleton keeps its
/// topology; one pass, so the spurs of spurs are not eaten away.
void prune_spurs(const Grid& g, const std::vector<std::int64_t>& nodes, std::vector<std::vector<std::int64_t>>& adj,
                 std::vector<std::uint8_t>& cls, double t) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    auto centre = [&](std::int64_t k) {
        const std::int64_t i = nodes[static_cast<std::size_t>(k)];
        return at(g, double(i % nx), double((i / nx) % ny), double(i / (nx * ny)));
    };
    auto curve = [&](std::int64_t k) { return cls[static_cast<std::size_t>(nodes[static_cast<std::size_t>(k)])] == std::uint8_t(SkeletonClass::Curve); };
    for (std::size_t e = 0; e < adj.size(); ++e) {
        if (adj[e].size() != 1 || !curve(static_cast<std::int64_t>(e))) continue;
        std::vector<std::int64_t> chain{static_cast<std::int64_t>(e)};
        std::int64_t prev = chain[0], cur = adj[e][0];
        double length = 0;
        for (;;) {
            const P3 d = sub(centre(cur), centre(prev));
            length += std::sqrt(dot(d, d));
            if (adj[static_cast<std::size_t>(cur)].size() != 2 || !curve(cur) || length >= t) break;
            chain.push_back(cur);
            const auto& a = adj[static_cast<std::size_t>(cur)];
            const std::int64_t next = a[0] == prev ? a[1] : a[0];
            prev = cur;
            cur = next;
        }
        const bool foot = adj[static_cast<std::size_t>(cur)].size() >= 3 || !curve(cur);
        if (length >= t || !foot) continue;
        for (std::int64_t k : chain) {
            const std::int64_t i = nodes[static_cast<std::size_t>(k)];
            if (!is_simple(g, cls.data(), i % nx, (i / nx) % ny, i / (nx * ny))) break;
            cls[static_cast<std::size_t>(i)] = 0;
            unlink(adj, k);
        }
    }
}

}  // namespace

void add_rods(const Grid& g, std::vector<std::uint8_t>& cls, const std::vector<std::int64_t>& ft, double t,
              MedialSurface& out) {
    std::vector<std::int64_t> nodes;
    for (std::size_t i = 0; i < cls.size(); ++i)
        if (cls[i] == std::uint8_t(SkeletonClass::Curve) || cls[i] == std::uint8_t(SkeletonClass::Junction))
            nodes.push_back(static_cast<std::int64_t>(i));
    auto adj = curve_graph(g, nodes);
    prune_spurs(g, nodes, adj, cls, t);
    const auto lines = trace(adj);
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    for (const auto& line : lines) {
        // A chain shorter than t whose every voxel touches the surface runs along the surface (a seam the thinning
        // kept), not off it: not a rod.
        bool seam = true;
        double length = 0;
        for (std::size_t k = 0; k < line.size(); ++k) {
            const std::int64_t i = nodes[static_cast<std::size_t>(line[k])];
            seam = seam && cls[static_cast<std::size_t>(i)] == std::uint8_t(SkeletonClass::Junction);
            if (k == 0) continue;
            const std::int64_t j = nodes[static_cast<std::size_t>(line[k - 1])];
            const P3 d = sub(at(g, double(i % nx), double((i / nx) % ny), double(i / (nx * ny))),
                             at(g, double(j % nx), double((j / nx) % ny), double(j / (nx * ny))));
            length += std::sqrt(dot(d, d));
        }
        if (seam && length < t) continue;
        std::vector<P3> pts;
        std::vector<double> radii;
        for (std::int64_t k : line) {
            const std::int64_t i = nodes[static_cast<std::size_t>(k)];
            const P3 c = at(g, double(i % nx), double((i / nx) % ny), double(i / (nx * ny)));
            radii.push_back(boundary_distance(g, c, feature_centre(g, ft[static_cast<std::size_t>(i)])));
            pts.push_back({c[0] + g.origin[0], c[1] + g.origin[1], c[2] + g.origin[2]});
        }
        out.rods.push_back(std::move(pts));
        out.rod_radii.push_back(std::move(radii));
    }
}


}  // namespace volrig::medial_detail

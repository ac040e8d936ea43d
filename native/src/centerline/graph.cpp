// The object's voxel graph, Dijkstra over it, snapping points onto the object and finding its tips
// (volrig/centerline.hpp).
#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <string>

#include "centerline/detail.hpp"
#include "volrig/centerline.hpp"

namespace volrig {

VoxelGraph voxel_graph(const Grid& grid, const std::uint8_t* mask, const float* dt) {
    check_grid(grid, 1, ~std::uint64_t{0}, "mask");
    if (grid.voxel_count() >= std::numeric_limits<std::int32_t>::max())
        throw Error("mask: centerlines take grids of fewer than 2^31 voxels (crop the mask to the object first)");
    VoxelGraph g;
    g.grid = grid;
    g.dense_dt = dt;
    const std::int64_t n = grid.voxel_count();
    g.id.assign(static_cast<std::size_t>(n), -1);
    for (std::int64_t k = 0; k < n; ++k) {
        if (!mask[k]) continue;
        if (!std::isfinite(dt[k]) || dt[k] <= 0.0f)
            throw Error("mask: the distance transform is not positive and finite at object voxel " + std::to_string(k));
        g.id[static_cast<std::size_t>(k)] = static_cast<std::int32_t>(g.voxel.size());
        g.voxel.push_back(k);
        g.dt.push_back(dt[k]);
    }
    if (g.voxel.empty()) throw Error("mask: the mask is empty (no object voxel), so it has no centerline");
    return g;
}

namespace centerline_detail {

Neighbours neighbours(const Grid& grid) {
    Neighbours nb;
    for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                if (!dx && !dy && !dz) continue;
                nb.d.push_back({dx, dy, dz});
                nb.offset.push_back((static_cast<std::int64_t>(dz) * grid.dims[1] + dy) * grid.dims[0] + dx);
                const double lx = dx * grid.spacing[0], ly = dy * grid.spacing[1], lz = dz * grid.spacing[2];
                nb.length.push_back(std::sqrt(lx * lx + ly * ly + lz * lz));
            }
    return nb;
}

std::array<std::int64_t, 3> coords(const Grid& grid, std::int64_t lin) {
    const std::int64_t x = lin % grid.dims[0];
    const std::int64_t y = (lin / grid.dims[0]) % grid.dims[1];
    return {x, y, lin / (grid.dims[0] * grid.dims[1])};
}

Vec3d world(const Grid& grid, std::int64_t lin) {
    const auto c = coords(grid, lin);
    return {grid.origin[0] + grid.spacing[0] * c[0], grid.origin[1] + grid.spacing[1] * c[1],
            grid.origin[2] + grid.spacing[2] * c[2]};
}


std::int32_t thickest(const VoxelGraph& g) {
    return static_cast<std::int32_t>(std::max_element(g.dt.begin(), g.dt.end()) - g.dt.begin());
}

}  // namespace centerline_detail

using namespace centerline_detail;

void voxel_distances(const VoxelGraph& g, const std::vector<std::int32_t>& sources, double power,
                     std::vector<double>& dist, std::vector<std::int32_t>* pred, std::int32_t target) {
    const std::size_t n = g.size();
    const Neighbours nb = neighbours(g.grid);
    const double h = g.grid.min_spacing();
    std::vector<double> f(n, 1.0);
    if (power >= 0.0)
        for (std::size_t i = 0; i < n; ++i) f[i] = std::pow(h / g.dt[i], power);
    dist.assign(n, std::numeric_limits<double>::infinity());
    if (pred) pred->assign(n, -1);
    using Item = std::pair<double, std::int32_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> heap;
    for (std::int32_t s : sources) {
        dist[static_cast<std::size_t>(s)] = 0.0;
        heap.push({0.0, s});
    }
    const auto& dims = g.grid.dims;
    while (!heap.empty()) {
        const auto [d, a] = heap.top();
        heap.pop();
        if (d > dist[static_cast<std::size_t>(a)]) continue;
        if (a == target) break;
        const std::int64_t lin = g.voxel[static_cast<std::size_t>(a)];
        const auto c = coords(g.grid, lin);
        for (std::size_t k = 0; k < nb.offset.size(); ++k) {
            const std::int64_t x = c[0] + nb.d[k][0], y = c[1] + nb.d[k][1], z = c[2] + nb.d[k][2];
            if (x < 0 || y < 0 || z < 0 || x >= dims[0] || y >= dims[1] || z >= dims[2]) continue;
            const std::int32_t b = g.id[static_cast<std::size_t>(lin + nb.offset[k])];
            if (b < 0) continue;
            const double nd = d + nb.length[k] * 0.5 * (f[static_cast<std::size_t>(a)] + f[static_cast<std::size_t>(b)]);
            if (nd < dist[static_cast<std::size_t>(b)]) {
                dist[static_cast<std::size_t>(b)] = nd;
                if (pred) (*pred)[static_cast<std::size_t>(b)] = a;
                heap.push({nd, b});
            }
        }
    }
}

std::int32_t snap_to_object(const VoxelGraph& g, const Vec3d& p, double max_distance, const char* what) {
    const Grid& gr = g.grid;
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
        throw Error(std::string(what) + ": the point is not finite");
    std::array<std::int64_t, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
        const double f = (p[a] - gr.origin[a]) / gr.spacing[a];
        const double r = max_distance / gr.spacing[a];
        lo[a] = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::ceil(f - r)));
        hi[a] = std::min<std::int64_t>(gr.dims[a] - 1, static_cast<std::int64_t>(std::floor(f + r)));
    }
    double best = max_distance * max_distance;
    std::int32_t found = -1;
    for (std::int64_t z = lo[2]; z <= hi[2]; ++z)
        for (std::int64_t y = lo[1]; y <= hi[1]; ++y)
            for (std::int64_t x = lo[0]; x <= hi[0]; ++x) {
                const std::int32_t id = g.id[static_cast<std::size_t>(gr.index(x, y, z))];
                if (id < 0) continue;
                const double dx = gr.origin[0] + gr.spacing[0] * x - p[0];
                const double dy = gr.origin[1] + gr.spacing[1] * y - p[1];
                const double dz = gr.origin[2] + gr.spacing[2] * z - p[2];
                const double d2 = dx * dx + dy * dy + dz * dz;
                if (d2 <= best) {
                    best = d2;
                    found = id;
                }
            }
    if (found < 0)
        throw Error(std::string(what) + ": the point (" + std::to_string(p[0]) + ", " + std::to_string(p[1]) + ", " +
                    std::to_string(p[2]) + ") is not on the object (no object voxel within " +
                    std::to_string(max_distance) + " world units)");
    return found;
}

std::int32_t centerline_detail::tip_centre(const VoxelGraph& g, const std::vector<double>& dist, std::int32_t tip) {
    const double w = std::max({g.grid.spacing[0], g.grid.spacing[1], g.grid.spacing[2]});
    const double limit = dist[static_cast<std::size_t>(tip)] - w;
    const Neighbours nb = neighbours(g.grid);
    const auto& dims = g.grid.dims;
    std::vector<std::int32_t> piece{tip};
    std::vector<std::uint8_t> mark(g.size(), 0);
    mark[static_cast<std::size_t>(tip)] = 1;
    Vec3d sum{0, 0, 0};
    for (std::size_t q = 0; q < piece.size(); ++q) {
        const std::int64_t lin = g.voxel[static_cast<std::size_t>(piece[q])];
        const Vec3d p = world(g.grid, lin);
        for (int a = 0; a < 3; ++a) sum[a] += p[a];
        const auto c = coords(g.grid, lin);
        for (std::size_t k = 0; k < nb.offset.size(); ++k) {
            const std::int64_t x = c[0] + nb.d[k][0], y = c[1] + nb.d[k][1], z = c[2] + nb.d[k][2];
            if (x < 0 || y < 0 || z < 0 || x >= dims[0] || y >= dims[1] || z >= dims[2]) continue;
            const std::int32_t b = g.id[static_cast<std::size_t>(lin + nb.offset[k])];
            if (b < 0 || mark[static_cast<std::size_t>(b)] || !(dist[static_cast<std::size_t>(b)] >= limit)) continue;
            mark[static_cast<std::size_t>(b)] = 1;
            piece.push_back(b);
        }
    }
    for (auto& s : sum) s /= static_cast<double>(piece.size());
    double best = std::numeric_limits<double>::infinity();
    std::int32_t centre = tip;
    for (std::int32_t id : piece) {
        const Vec3d p = world(g.grid, g.voxel[static_cast<std::size_t>(id)]);
        const double d2 = (p[0] - sum[0]) * (p[0] - sum[0]) + (p[1] - sum[1]) * (p[1] - sum[1]) +
                          (p[2] - sum[2]) * (p[2] - sum[2]);
        if (d2 < best) {
            best = d2;
            centre = id;
        }
    }
    return centre;
}

std::int32_t far_tip(const VoxelGraph& g, const std::vector<double>& dist) {
    std::int32_t far = -1;
    double best = -1.0;
    for (std::size_t i = 0; i < dist.size(); ++i)
        if (std::isfinite(dist[i]) && dist[i] > best) {
            best = dist[i];
            far = static_cast<std::int32_t>(i);
        }
    return tip_centre(g, dist, far);
}

}  // namespace volrig

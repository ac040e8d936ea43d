// Pore network extraction: the open-faced distance transform, the seeds, and the whole pipeline.
#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "pores_internal.hpp"

namespace volrig::pores_detail {

namespace {

/// Whether voxel (x, y, z) of DT value d is not below any of its 26 neighbours.
bool is_local_max(const Grid& g, const PoreSpace& dt, std::int64_t x, std::int64_t y, std::int64_t z, float d) {
    for (std::int64_t dz = -1; dz <= 1; ++dz)
        for (std::int64_t dy = -1; dy <= 1; ++dy)
            for (std::int64_t dx = -1; dx <= 1; ++dx) {
                const std::int64_t u = x + dx, v = y + dy, w = z + dz;
                if (u < 0 || v < 0 || w < 0 || u >= g.dims[0] || v >= g.dims[1] || w >= g.dims[2]) continue;
                if (dt[g.index(u, v, w)] > d) return false;
            }
    return true;
}

/// Whether the plateau of voxel i (its 26-connected voxels of equal DT) has a neighbour of higher DT: a ridge or a
/// saddle, not a maximum. Stops at the first such neighbour (the walls' plateaus are large); when there is none,
/// `seen` holds the whole plateau.
bool plateau_rises(const Grid& g, const PoreSpace& dt, std::int64_t i, std::unordered_set<std::int64_t>& seen) {
    const float d = dt[i];
    const std::int64_t nx = g.dims[0], nxy = g.dims[0] * g.dims[1];
    std::vector<std::int64_t> stack{i};
    seen.insert(i);
    while (!stack.empty()) {
        const std::int64_t v = stack.back();
        stack.pop_back();
        const std::int64_t x = v % nx, y = (v / nx) % g.dims[1], z = v / nxy;
        for (std::int64_t dz = -1; dz <= 1; ++dz)
            for (std::int64_t dy = -1; dy <= 1; ++dy)
                for (std::int64_t dx = -1; dx <= 1; ++dx) {
                    const std::int64_t u = x + dx, w = y + dy, s = z + dz;
                    if (u < 0 || w < 0 || s < 0 || u >= g.dims[0] || w >= g.dims[1] || s >= g.dims[2]) continue;
                    const std::int64_t j = g.index(u, w, s);
                    if (dt[j] > d) return true;
                    if (dt[j] == d && seen.insert(j).second) stack.push_back(j);
                }
    }
    return false;
}

/// The local maxima of the DT (voxels not below any neighbour, on plateaus that do not rise), largest first (ties
/// in scan order).
std::vector<std::int64_t> local_maxima(const Grid& g, const PoreSpace& dt) {
    const std::int64_t nz = g.dims[2];
    std::vector<std::vector<std::int64_t>> per_slice(static_cast<std::size_t>(nz));
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t z = r.begin(); z != r.end(); ++z)
            for (std::int64_t y = 0; y < g.dims[1]; ++y)
                for (std::int64_t x = 0; x < g.dims[0]; ++x) {
                    const std::int64_t i = g.index(x, y, z);
                    if (dt[i] > 0 && is_local_max(g, dt, x, y, z, dt[i]))
                        per_slice[static_cast<std::size_t>(z)].push_back(i);
                }
    });
    std::vector<std::int64_t> out;
    std::unordered_set<std::int64_t> flat;  // voxels of the plateaus found not to rise
    for (auto& s : per_slice)
        for (const std::int64_t i : s) {
            if (!flat.count(i)) {
                std::unordered_set<std::int64_t> mine;  // fresh: a cleared set keeps its buckets, and clearing
                                                        // costs them
                if (plateau_rises(g, dt, i, mine)) continue;
                flat.insert(mine.begin(), mine.end());
            }
            out.push_back(i);
        }
    std::stable_sort(out.begin(), out.end(), [&dt](std::int64_t a, std::int64_t b) { return dt[a] > dt[b]; });
    return out;
}

}  // namespace

std::vector<std::int64_t> pore_seeds(const PoreSpace& dt) {
    const Grid& g = dt.grid;
    const std::vector<std::int64_t> cand = local_maxima(g, dt);
    if (cand.empty()) return {};
    // Buckets of kept seeds, cells at least as wide as the largest ball on every axis: a ball holding a candidate's
    // centre has its seed in the candidate's cell or a neighbouring one.
    const double rmax = dt[cand.front()];
    std::array<std::int64_t, 3> cell{};
    for (int a = 0; a < 3; ++a)
        cell[a] = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(rmax / g.spacing[a])));
    auto key = [](std::int64_t cx, std::int64_t cy, std::int64_t cz) { return (cz * 1000003 + cy) * 1000003 + cx; };
    std::unordered_map<std::int64_t, std::vector<std::int64_t>> buckets;
    std::vector<std::int64_t> kept;
    const std::int64_t nx = g.dims[0], nxy = g.dims[0] * g.dims[1];
    for (const std::int64_t c : cand) {
        const std::int64_t x = c % nx, y = (c / nx) % g.dims[1], z = c / nxy;
        const std::int64_t cx = x / cell[0], cy = y / cell[1], cz = z / cell[2];
        bool inside = false;
        for (std::int64_t dz = -1; dz <= 1 && !inside; ++dz)
            for (std::int64_t dy = -1; dy <= 1 && !inside; ++dy)
                for (std::int64_t dx = -1; dx <= 1 && !inside; ++dx) {
                    const auto it = buckets.find(key(cx + dx, cy + dy, cz + dz));
                    if (it == buckets.end()) continue;
                    for (const std::int64_t s : it->second) {
                        const double ex = static_cast<double>(s % nx - x) * g.spacing[0];
                        const double ey = static_cast<double>((s / nx) % g.dims[1] - y) * g.spacing[1];
                        const double ez = static_cast<double>(s / nxy - z) * g.spacing[2];
                        const double r = dt[s];
                        if (ex * ex + ey * ey + ez * ez <= r * r) {
                            inside = true;
                            break;
                        }
                    }
                }
        if (inside) continue;
        kept.push_back(c);
        buckets[key(cx, cy, cz)].push_back(c);
    }
    return kept;
}

}  // namespace volrig::pores_detail

namespace volrig {

PoreNetwork extract_pore_network(const Grid& grid, const std::uint8_t* mask, const Progress& progress,
                                 bool keep_regions) {
    check_grid(grid, 1, std::numeric_limits<std::uint64_t>::max(), "pore_network");
    pores_detail::PoreSpace space(grid, mask);
    const std::int64_t pore = space.index.count();
    if (pore == 0) throw Error("pore_network: the mask has no pore voxel");
    if (pore == grid.voxel_count()) throw Error("pore_network: the mask has no solid voxel (every voxel is pore)");
    pores_detail::pore_distance(space, mask, progress_span(progress, 0.0, 0.4));
    report(progress, 0.4);
    std::vector<std::int64_t> seeds = pores_detail::pore_seeds(space);
    report(progress, 0.5);
    const pores_detail::Regions regions = pores_detail::flood_regions(space, seeds, progress_span(progress, 0.5, 0.9));
    PoreNetwork net = pores_detail::measure_network(space, regions, seeds.size());
    net.pore_voxels = pore;
    if (keep_regions) net.regions = pores_detail::dense_labels(space, regions);
    report(progress, 1.0);
    return net;
}

}  // namespace volrig

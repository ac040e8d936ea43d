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
#include "volrig/distance.hpp"

namespace volrig::pores_detail {

namespace {

/// Mirrors index i of [-w, n + w) into [0, n) (w <= n).
inline std::int64_t mirror(std::int64_t i, std::int64_t n) {
    if (i < 0) return -1 - i;
    if (i >= n) return 2 * n - 1 - i;
    return i;
}

/// Whether voxel (x, y, z) of DT value d is not below any of its 26 neighbours.
bool is_local_max(const Grid& g, const float* dt, std::int64_t x, std::int64_t y, std::int64_t z, float d) {
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
bool plateau_rises(const Grid& g, const float* dt, std::int64_t i, std::unordered_set<std::int64_t>& seen) {
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
std::vector<std::int64_t> local_maxima(const Grid& g, const float* dt) {
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
    std::unordered_set<std::int64_t> flat, mine;  // voxels of the plateaus found not to rise; one plateau's
    for (auto& s : per_slice)
        for (const std::int64_t i : s) {
            if (!flat.count(i)) {
                mine.clear();
                if (plateau_rises(g, dt, i, mine)) continue;
                flat.insert(mine.begin(), mine.end());
            }
            out.push_back(i);
        }
    std::stable_sort(out.begin(), out.end(), [dt](std::int64_t a, std::int64_t b) { return dt[a] > dt[b]; });
    return out;
}

}  // namespace

std::vector<float> open_distance(const Grid& g, const std::uint8_t* mask, const Progress& progress) {
    std::array<std::int64_t, 3> w{};
    Grid pg = g;
    for (int a = 0; a < 3; ++a) {
        w[a] = std::min<std::int64_t>(8, g.dims[a]);
        pg.dims[a] = g.dims[a] + 2 * w[a];
    }
    std::vector<float> dt(static_cast<std::size_t>(pg.voxel_count()));
    {
        std::vector<std::uint8_t> padded(static_cast<std::size_t>(pg.voxel_count()));
        tbb::parallel_for(std::int64_t{0}, pg.dims[2], [&](std::int64_t z) {
            const std::int64_t sz = mirror(z - w[2], g.dims[2]);
            for (std::int64_t y = 0; y < pg.dims[1]; ++y) {
                const std::int64_t sy = mirror(y - w[1], g.dims[1]);
                for (std::int64_t x = 0; x < pg.dims[0]; ++x)
                    padded[static_cast<std::size_t>(pg.index(x, y, z))] =
                        mask[g.index(mirror(x - w[0], g.dims[0]), sy, sz)] ? 1 : 0;
            }
        });
        euclidean_distance_transform(pg, padded.data(), dt.data(), progress);
    }
    // Crop in place: a voxel's padded index is never below its cropped one, so a forward copy is safe.
    for (std::int64_t z = 0; z < g.dims[2]; ++z)
        for (std::int64_t y = 0; y < g.dims[1]; ++y)
            std::copy_n(dt.begin() + pg.index(w[0], y + w[1], z + w[2]), g.dims[0], dt.begin() + g.index(0, y, z));
    dt.resize(static_cast<std::size_t>(g.voxel_count()));
    dt.shrink_to_fit();  // before the region labels are allocated, so the peak stays the padded transform's
    return dt;
}

std::vector<std::int64_t> pore_seeds(const Grid& g, const float* dt) {
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
    const std::int64_t n = grid.voxel_count();
    std::int64_t pore = 0;
    for (std::int64_t i = 0; i < n; ++i) pore += mask[i] ? 1 : 0;
    if (pore == 0) throw Error("pore_network: the mask has no pore voxel");
    if (pore == n) throw Error("pore_network: the mask has no solid voxel (every voxel is pore)");
    const std::vector<float> dt = pores_detail::open_distance(grid, mask, progress_span(progress, 0.0, 0.4));
    report(progress, 0.4);
    std::vector<std::int64_t> seeds = pores_detail::pore_seeds(grid, dt.data());
    report(progress, 0.5);
    std::vector<std::int32_t> labels =
        pores_detail::flood_regions(grid, dt.data(), seeds, progress_span(progress, 0.5, 0.9));
    PoreNetwork net = pores_detail::measure_network(grid, dt.data(), labels, seeds.size());
    net.pore_voxels = pore;
    if (keep_regions) net.regions = std::move(labels);
    report(progress, 1.0);
    return net;
}

}  // namespace volrig

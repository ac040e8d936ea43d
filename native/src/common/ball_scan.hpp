// common/ball_scan.hpp (internal): visiting the voxels of many open balls row by row, one z slice per task.
//
// Used by reconstruct (the union of the balls): the balls are bucketed by the z slices they touch, so each slice is
// written by one task without races, and each ball is walked as x-runs [x0, x1] of rows y at slice z. (Local
// thickness uses row_half_width for its ball tables and paints its own way: medial/thickness.cpp.)
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "volrig/reconstruct.hpp"

namespace volrig::common_detail {

/// Largest |dx| such that offset (dx, dy, dz) lies in the open ball of radius r (lim_sq = open_ball_limit_sq(r)
/// for Euclidean), or -1.
inline std::int64_t row_half_width(Metric metric, double r, double lim_sq, std::int64_t dy, std::int64_t dz,
                                   const std::array<double, 3>& sp) {
    if (metric == Metric::Chamfer345) {
        const auto R = static_cast<std::int64_t>(std::ceil(r)) - 1;  // chamfer length <= R  <=>  < r
        const std::int64_t ay = dy < 0 ? -dy : dy, az = dz < 0 ? -dz : dz;
        const std::int64_t m = std::max(ay, az), S = ay + az;
        // |dx| > m: length 3|dx| + S;  |dx| <= m: length 2m + |dx| + S.
        const std::int64_t tb = (R - S) >= 0 ? (R - S) / 3 : -1;
        if (tb > m) return tb;
        const std::int64_t ta = std::min(m, R - 2 * m - S);
        return ta >= 0 ? ta : -1;
    }
    const double rest = lim_sq - static_cast<double>(dy * dy) * sp[1] * sp[1] - static_cast<double>(dz * dz) * sp[2] * sp[2];
    if (rest <= 0) return -1;
    const double sx2 = sp[0] * sp[0];
    auto t = static_cast<std::int64_t>(std::floor(std::sqrt(rest / sx2)));
    while (t >= 0 && static_cast<double>(t * t) * sx2 >= rest) --t;
    while (static_cast<double>((t + 1) * (t + 1)) * sx2 < rest) ++t;
    return t;
}

/// The balls (centres `ijk` rows [z, y, x], radii `radius`) bucketed by the z slices they touch (CSR).
struct SliceBuckets {
    std::vector<std::int64_t> hy, start;
    std::vector<std::uint32_t> members;
};

inline SliceBuckets bucket_balls(const Grid& g, Metric metric, const std::int32_t* ijk, const float* radius,
                                 std::size_t n) {
    const std::int64_t nz = g.dims[2];
    SliceBuckets b;
    std::vector<std::int64_t> z0(n), z1(n);
    b.hy.resize(n);
    b.start.assign(static_cast<std::size_t>(nz) + 1, 0);
    for (std::size_t k = 0; k < n; ++k) {
        const std::int64_t hz = ball_half_extent(radius[k], g.spacing[2], metric);
        b.hy[k] = ball_half_extent(radius[k], g.spacing[1], metric);
        z0[k] = hz < 0 ? 1 : std::max<std::int64_t>(0, ijk[3 * k] - hz);
        z1[k] = hz < 0 ? 0 : std::min<std::int64_t>(nz - 1, ijk[3 * k] + hz);
        for (std::int64_t z = z0[k]; z <= z1[k]; ++z) ++b.start[static_cast<std::size_t>(z) + 1];
    }
    for (std::size_t z = 0; z < static_cast<std::size_t>(nz); ++z) b.start[z + 1] += b.start[z];
    b.members.resize(static_cast<std::size_t>(b.start.back()));
    std::vector<std::int64_t> fill(b.start.begin(), b.start.end() - 1);
    for (std::size_t k = 0; k < n; ++k)
        for (std::int64_t z = z0[k]; z <= z1[k]; ++z)
            b.members[static_cast<std::size_t>(fill[static_cast<std::size_t>(z)]++)] = static_cast<std::uint32_t>(k);
    return b;
}

/// Calls run(z, y, x0, x1, k) for every x-run of every ball k clipped to the grid, slices in parallel (all calls
/// for one z come from one task, in ball order). `width(k, dy, dz)` gives the half-width of ball k's row at offset
/// (dy, dz) from its centre, -1 outside (row_half_width, or a table of it).
template <class Width, class Run>
void scan_balls(const Grid& g, Metric metric, const std::int32_t* ijk, const float* radius, std::size_t n,
                const Width& width, const Run& run) {
    const SliceBuckets b = bucket_balls(g, metric, ijk, radius, n);
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t z = r.begin(); z != r.end(); ++z) {
            for (std::int64_t m = b.start[static_cast<std::size_t>(z)]; m < b.start[static_cast<std::size_t>(z) + 1]; ++m) {
                const std::size_t k = b.members[static_cast<std::size_t>(m)];
                const std::int64_t cz = ijk[3 * k], cy = ijk[3 * k + 1], cx = ijk[3 * k + 2];
                const std::int64_t y0 = std::max<std::int64_t>(0, cy - b.hy[k]);
                const std::int64_t y1 = std::min<std::int64_t>(ny - 1, cy + b.hy[k]);
                for (std::int64_t y = y0; y <= y1; ++y) {
                    const std::int64_t w = width(k, y - cy, z - cz);
                    if (w < 0) continue;
                    const std::int64_t x0 = std::max<std::int64_t>(0, cx - w), x1 = std::min<std::int64_t>(nx - 1, cx + w);
                    if (x0 <= x1) run(z, y, x0, x1, k);
                }
            }
        }
    });
}

/// scan_balls with each row's width from row_half_width.
template <class Run>
void scan_balls(const Grid& g, Metric metric, const std::int32_t* ijk, const float* radius, std::size_t n,
                const Run& run) {
    scan_balls(g, metric, ijk, radius, n, [&](std::size_t k, std::int64_t dy, std::int64_t dz) {
        const double rad = radius[k];
        return row_half_width(metric, rad, metric == Metric::Euclidean ? open_ball_limit_sq(rad) : 0.0, dy, dz,
                              g.spacing);
    }, run);
}

}  // namespace volrig::common_detail

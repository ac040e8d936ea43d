#include "volrig/reconstruct.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace volrig {

std::int64_t ball_half_extent(double r, double spacing, Metric metric) {
    if (!(r > 0)) return -1;
    if (metric == Metric::Chamfer345) {
        // Largest t with 3t < r.
        return static_cast<std::int64_t>(std::ceil(r / 3.0)) - 1;
    }
    const double lim = open_ball_limit_sq(r);
    auto t = static_cast<std::int64_t>(std::floor(r / spacing));
    while (t >= 0 && static_cast<double>(t) * static_cast<double>(t) * spacing * spacing >= lim) --t;
    return t;
}

namespace {

/// Largest |dx| such that offset (dx, dy, dz) lies in the open ball, or -1.
std::int64_t row_half_width(Metric metric, double r, double lim_sq, std::int64_t dy, std::int64_t dz,
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

}  // namespace

std::vector<std::uint8_t> reconstruct(const Grid& g, Metric metric, const std::int32_t* ijk, const float* radius,
                                      std::size_t n, const Progress& progress) {
    check_grid(g, 1, std::numeric_limits<std::uint64_t>::max(), "reconstruct");
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    for (std::size_t k = 0; k < n; ++k)
        if (!std::isfinite(radius[k])) throw Error("reconstruct: radius of point " + std::to_string(k) + " is not finite");

    // Bucket the balls by the z slices they touch (CSR), so each slice is filled by one task without races.
    std::vector<std::int64_t> hz(n), hy(n), start(static_cast<std::size_t>(nz) + 1, 0);
    for (std::size_t k = 0; k < n; ++k) {
        hz[k] = ball_half_extent(radius[k], g.spacing[2], metric);
        hy[k] = ball_half_extent(radius[k], g.spacing[1], metric);
        if (hz[k] < 0) continue;
        const std::int64_t z0 = std::max<std::int64_t>(0, ijk[3 * k] - hz[k]);
        const std::int64_t z1 = std::min<std::int64_t>(nz - 1, ijk[3 * k] + hz[k]);
        for (std::int64_t z = z0; z <= z1; ++z) ++start[static_cast<std::size_t>(z) + 1];
    }
    for (std::size_t z = 0; z < static_cast<std::size_t>(nz); ++z) start[z + 1] += start[z];
    std::vector<std::uint32_t> members(static_cast<std::size_t>(start.back()));
    {
        std::vector<std::int64_t> fill(start.begin(), start.end() - 1);
        for (std::size_t k = 0; k < n; ++k) {
            if (hz[k] < 0) continue;
            const std::int64_t z0 = std::max<std::int64_t>(0, ijk[3 * k] - hz[k]);
            const std::int64_t z1 = std::min<std::int64_t>(nz - 1, ijk[3 * k] + hz[k]);
            for (std::int64_t z = z0; z <= z1; ++z)
                members[static_cast<std::size_t>(fill[static_cast<std::size_t>(z)]++)] = static_cast<std::uint32_t>(k);
        }
    }
    report(progress, 0.1);

    std::vector<std::uint8_t> out(static_cast<std::size_t>(g.voxel_count()), 0);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t z = r.begin(); z != r.end(); ++z) {
            std::uint8_t* slice = out.data() + z * nx * ny;
            for (std::int64_t m = start[static_cast<std::size_t>(z)]; m < start[static_cast<std::size_t>(z) + 1]; ++m) {
                const std::size_t k = members[static_cast<std::size_t>(m)];
                const double rad = radius[k];
                const double lim = open_ball_limit_sq(rad);
                const std::int64_t cz = ijk[3 * k], cy = ijk[3 * k + 1], cx = ijk[3 * k + 2];
                const std::int64_t y0 = std::max<std::int64_t>(0, cy - hy[k]), y1 = std::min<std::int64_t>(ny - 1, cy + hy[k]);
                for (std::int64_t y = y0; y <= y1; ++y) {
                    const std::int64_t w = row_half_width(metric, rad, lim, y - cy, z - cz, g.spacing);
                    if (w < 0) continue;
                    const std::int64_t x0 = std::max<std::int64_t>(0, cx - w), x1 = std::min<std::int64_t>(nx - 1, cx + w);
                    if (x0 <= x1) std::memset(slice + y * nx + x0, 1, static_cast<std::size_t>(x1 - x0 + 1));
                }
            }
        }
    });
    report(progress, 1.0);
    return out;
}

}  // namespace volrig

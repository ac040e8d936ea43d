#include "volrig/reconstruct.hpp"

#include "common/ball_scan.hpp"

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

std::vector<std::uint8_t> reconstruct(const Grid& g, Metric metric, const std::int32_t* ijk, const float* radius,
                                      std::size_t n, const Progress& progress) {
    check_grid(g, 1, std::numeric_limits<std::uint64_t>::max(), "reconstruct");
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    for (std::size_t k = 0; k < n; ++k)
        if (!std::isfinite(radius[k])) throw Error("reconstruct: radius of point " + std::to_string(k) + " is not finite");

    report(progress, 0.05);
    std::vector<std::uint8_t> out(static_cast<std::size_t>(g.voxel_count()), 0);
    common_detail::scan_balls(g, metric, ijk, radius, n, [&](std::int64_t z, std::int64_t y, std::int64_t x0, std::int64_t x1, std::size_t) {
        std::memset(out.data() + (z * ny + y) * nx + x0, 1, static_cast<std::size_t>(x1 - x0 + 1));
    });
    report(progress, 1.0);
    return out;
}

}  // namespace volrig

// rig/autorig/coarse.cpp: the object at autorig's own scale (see coarse.hpp).
#include "rig/autorig/coarse.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>
#include <cstdlib>

#include "volrig/skeleton.hpp"

namespace volrig::rig_detail {

std::array<std::int64_t, 6> object_box(const Grid& g, const std::uint8_t* mask) {
    using Box = std::array<std::int64_t, 6>;
    const Box empty{g.dims[0], g.dims[1], g.dims[2], 0, 0, 0};
    const Box box = tbb::parallel_reduce(
        tbb::blocked_range<std::int64_t>(0, g.dims[2]), empty,
        [&](const tbb::blocked_range<std::int64_t>& r, Box b) {
            for (std::int64_t z = r.begin(); z < r.end(); ++z)
                for (std::int64_t y = 0; y < g.dims[1]; ++y) {
                    const std::uint8_t* row = mask + g.index(0, y, z);
                    std::int64_t x0 = 0, x1 = g.dims[0];
                    while (x0 < x1 && !row[x0]) ++x0;
                    if (x0 == x1) continue;
                    while (!row[x1 - 1]) --x1;
                    b = {std::min(b[0], x0), std::min(b[1], y), std::min(b[2], z),
                         std::max(b[3], x1), std::max(b[4], y + 1), std::max(b[5], z + 1)};
                }
            return b;
        },
        [](const Box& a, const Box& b) {
            return Box{std::min(a[0], b[0]), std::min(a[1], b[1]), std::min(a[2], b[2]),
                       std::max(a[3], b[3]), std::max(a[4], b[4]), std::max(a[5], b[5])};
        });
    return box[3] > box[0] ? box : Box{0, 0, 0, 0, 0, 0};
}

double longest_cells(const Grid& g, const std::array<std::int64_t, 6>& box) {
    double longest = 0, finest = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        longest = std::max(longest, static_cast<double>(box[3 + a] - box[a]) * g.spacing[a]);
        finest = std::min(finest, g.spacing[a]);
    }
    return longest / finest;
}

std::array<std::int64_t, 3> coarse_factor(const Grid& g, const std::array<std::int64_t, 6>& box, double cells) {
    const double finest = g.min_spacing();
    const double size = finest * std::max(1.0, longest_cells(g, box) / cells);
    std::array<std::int64_t, 3> f;
    for (int a = 0; a < 3; ++a) f[a] = std::max<std::int64_t>(1, std::llround(size / g.spacing[a]));
    return f;
}

CoarseShape downsample(const Grid& g, const std::uint8_t* mask, const std::array<std::int64_t, 6>& box,
                       const std::array<std::int64_t, 3>& f) {
    CoarseShape c;
    c.factor = f;
    for (int a = 0; a < 3; ++a) {
        c.grid.dims[a] = (box[3 + a] - box[a] + f[a] - 1) / f[a] + 2;
        c.grid.spacing[a] = g.spacing[a] * static_cast<double>(f[a]);
        // Coarse voxel k + 1 covers fine voxels box[a] + f k .. + f - 1: its centre is their mean.
        c.offset[a] = g.origin[a] + (static_cast<double>(box[a]) + 0.5 * static_cast<double>(f[a] - 1)) *
                                        g.spacing[a] - c.grid.spacing[a];
        c.grid.origin[a] = 0.0;
    }
    c.mask.assign(static_cast<std::size_t>(c.grid.voxel_count()), 0);
    const std::int64_t half = (f[0] * f[1] * f[2] + 1) / 2;
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(1, c.grid.dims[2] - 1), [&](const auto& r) {
        std::vector<std::int64_t> count(static_cast<std::size_t>(c.grid.dims[0]));
        for (std::int64_t cz = r.begin(); cz < r.end(); ++cz)
            for (std::int64_t cy = 1; cy < c.grid.dims[1] - 1; ++cy) {
                std::fill(count.begin(), count.end(), 0);
                const std::int64_t z0 = box[2] + (cz - 1) * f[2], y0 = box[1] + (cy - 1) * f[1];
                for (std::int64_t z = z0; z < std::min(z0 + f[2], box[5]); ++z)
                    for (std::int64_t y = y0; y < std::min(y0 + f[1], box[4]); ++y) {
                        const std::uint8_t* row = mask + g.index(0, y, z);
                        for (std::int64_t x = box[0]; x < box[3]; ++x)
                            if (row[x]) ++count[static_cast<std::size_t>((x - box[0]) / f[0] + 1)];
                    }
                for (std::int64_t cx = 1; cx < c.grid.dims[0] - 1; ++cx)
                    c.mask[static_cast<std::size_t>(c.grid.index(cx, cy, cz))] = count[static_cast<std::size_t>(cx)] >= half;
            }
    });
    return c;
}

std::size_t with_ties(const Skeleton& sk, std::size_t n) {
    if (n == 0 || n >= sk.object_count()) return std::min(n, sk.object_count());
    const double cut = sk.score(n - 1), tol = kTiedScore * std::abs(cut);
    while (n < sk.object_count() && sk.score(n) >= cut - tol) ++n;
    return n;
}

CoarseShape coarse_shape(const Grid& g, const std::uint8_t* mask) {
    const auto box = object_box(g, mask);
    if (box[3] == 0) return CoarseShape{};
    const auto factor = coarse_factor(g, box, kCoarseCells);
    // A volume no finer than that scale has factor 1: only cropped, its own skeleton all the same (so that the
    // rig does not depend on the caller's point count), with a larger share: about as many points per cell of
    // length as at kCoarseCells.
    CoarseShape c = downsample(g, mask, box, factor);
    const Skeleton sk = skeletonize(c.grid, c.mask.data(), Metric::Euclidean);
    const double coarse_cells = longest_cells(g, box) * g.min_spacing() / c.grid.min_spacing();
    const double share = kCoarsePoints * std::max(1.0, kCoarseCells / coarse_cells);
    const std::size_t n = with_ties(sk, static_cast<std::size_t>(std::ceil(share * static_cast<double>(sk.object_count()))));
    c.ijk.resize(3 * n);
    c.radius.resize(n);
    skeleton_points(sk, n, c.ijk.data(), nullptr, c.radius.data(), nullptr);
    if (n >= 2) c.edges = skeleton_tree(c.grid, c.mask.data(), c.points(), TreeOptions{}).edges;
    return c;
}

}  // namespace volrig::rig_detail

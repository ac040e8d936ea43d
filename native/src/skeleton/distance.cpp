#include "volrig/distance.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>

#include "common/neighbourhood.hpp"

namespace volrig {

Metric metric_from_name(const std::string& name) {
    if (name == "euclidean") return Metric::Euclidean;
    if (name == "chamfer345" || name == "chamfer" || name == "345") return Metric::Chamfer345;
    throw Error("unknown metric '" + name + "' (use \"euclidean\" or \"chamfer345\")");
}

const char* metric_name(Metric m) { return m == Metric::Euclidean ? "euclidean" : "chamfer345"; }

namespace {

void check_mask_grid(const Grid& g, const char* what) {
    check_grid(g, 1, std::numeric_limits<std::uint64_t>::max(), what);
}

/// One 1-D squared distance transform along a line of n samples f[0..n) (stride `stride` in `line`), with
/// virtual background samples (value 0) at -1 and n: d(q) = min_p s²(q-p)² + f(p). In place.
/// Scratch: v (n+2 ints), zb (n+3 doubles), fv (n+2 doubles).
struct Envelope {
    std::vector<std::int64_t> v;
    std::vector<double> zb, fv;

    /// Abscissa (index units) where the parabola rooted at q (value fq) meets the one at v[k].
    double intersect(std::int64_t q, double fq, std::int64_t k, double s2) const {
        const std::int64_t p = v[static_cast<std::size_t>(k)];
        return ((fq - fv[static_cast<std::size_t>(k)]) / s2 + static_cast<double>(q * q - p * p)) /
               (2.0 * static_cast<double>(q - p));
    }

    /// Transforms a whole line. A zero (background) sample at z0 is closer to every sample on its side than any
    /// site beyond it, so zeros cut the line into independent runs of non-zero samples, each bounded by zeros (or
    /// the out-of-array background): only the runs are transformed, which makes the work proportional to the
    /// object voxels on the line rather than to its length.
    void run(float* line, std::int64_t n, std::int64_t stride, double s2) {
        std::int64_t q = 0;
        while (q < n) {
            while (q < n && line[q * stride] == 0.0f) ++q;
            const std::int64_t a = q;
            while (q < n && line[q * stride] != 0.0f) ++q;
            if (q > a) run_segment(line + a * stride, q - a, stride, s2);
        }
    }

    /// One run of n samples with (virtual) zero samples at -1 and n.
    void run_segment(float* line, std::int64_t n, std::int64_t stride, double s2) {
        v.resize(static_cast<std::size_t>(n + 2));
        zb.resize(static_cast<std::size_t>(n + 3));
        fv.resize(static_cast<std::size_t>(n + 2));
        const double inf = std::numeric_limits<double>::infinity();
        std::int64_t k = 0;
        v[0] = -1;
        fv[0] = 0.0;
        zb[0] = -inf;
        zb[1] = inf;
        for (std::int64_t q = 0; q <= n; ++q) {
            const double fq = q < n ? static_cast<double>(line[q * stride]) : 0.0;
            // Pop parabolas hidden by the new one; zb[0] = -inf stops the loop at k = 0.
            double s = intersect(q, fq, k, s2);
            while (s <= zb[k]) s = intersect(q, fq, --k, s2);
            ++k;
            v[k] = q;
            fv[k] = fq;
            zb[k] = s;
            zb[k + 1] = inf;
        }
        k = 0;
        for (std::int64_t q = 0; q < n; ++q) {
            while (zb[k + 1] < static_cast<double>(q)) ++k;
            const double d = static_cast<double>(q - v[k]);
            line[q * stride] = static_cast<float>(s2 * d * d + fv[k]);
        }
    }
};

}  // namespace

void euclidean_distance_transform(const Grid& g, const std::uint8_t* mask, float* dt, const Progress& progress) {
    check_mask_grid(g, "euclidean_distance_transform");
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    const double sx2 = g.spacing[0] * g.spacing[0], sy2 = g.spacing[1] * g.spacing[1],
                 sz2 = g.spacing[2] * g.spacing[2];
    const std::int64_t plane = nx * ny;

    // Passes 1 and 2, slice by slice so that each z slice is transformed while it is in cache.
    // Pass 1 (x): squared distance to the nearest background voxel in the row, out-of-array ends included.
    // Pass 2 (y): lower envelopes along the slice's columns (strided by nx).
    tbb::enumerable_thread_specific<Envelope> envelopes;
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& r) {
        Envelope& env = envelopes.local();
        for (std::int64_t z = r.begin(); z != r.end(); ++z) {
            for (std::int64_t y = 0; y < ny; ++y) {
                const std::uint8_t* m = mask + z * plane + y * nx;
                float* d = dt + z * plane + y * nx;
                std::int64_t last = -1;  // position of the last background voxel seen from the left
                for (std::int64_t x = 0; x < nx; ++x) {
                    if (!m[x]) last = x;
                    d[x] = static_cast<float>(x - last);  // voxels to the background on the left
                }
                last = nx;
                for (std::int64_t x = nx - 1; x >= 0; --x) {
                    if (!m[x]) last = x;
                    const double t = std::min<double>(d[x], static_cast<double>(last - x));
                    d[x] = static_cast<float>(t * t * sx2);
                }
            }
            for (std::int64_t x = 0; x < nx; ++x) env.run(dt + z * plane + x, ny, nx, sy2);
        }
    });
    report(progress, 0.5);

    // Pass 3 (z): for each y, gather the [z][x] plane into contiguous scratch, transform its columns, then write
    // back the square roots.
    tbb::enumerable_thread_specific<std::vector<float>> scratch;
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, ny), [&](const tbb::blocked_range<std::int64_t>& r) {
        Envelope& env = envelopes.local();
        std::vector<float>& buf = scratch.local();
        buf.resize(static_cast<std::size_t>(nz * nx));
        for (std::int64_t y = r.begin(); y != r.end(); ++y) {
            for (std::int64_t z = 0; z < nz; ++z) {
                const float* src = dt + z * plane + y * nx;
                std::copy(src, src + nx, buf.data() + z * nx);
            }
            for (std::int64_t x = 0; x < nx; ++x) env.run(buf.data() + x, nz, nx, sz2);
            for (std::int64_t z = 0; z < nz; ++z) {
                float* dst = dt + z * plane + y * nx;
                const float* src = buf.data() + z * nx;
                for (std::int64_t x = 0; x < nx; ++x) dst[x] = std::sqrt(src[x]);
            }
        }
    });
    report(progress, 1.0);
}

void chamfer345_distance_transform(const Grid& g, const std::uint8_t* mask, float* dt, const Progress& progress) {
    check_mask_grid(g, "chamfer345_distance_transform");
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2], n = g.voxel_count();
    if (n > static_cast<std::int64_t>(std::numeric_limits<std::uint32_t>::max()))
        throw Error("chamfer345_distance_transform: grids above 2^32 voxels are not supported");
    static constexpr int kWeight[4] = {0, 3, 4, 5};
    constexpr float kUnset = std::numeric_limits<float>::max();
    const common_detail::Neighbourhood nb(g);

    // Seeds: object voxels with a background (or out-of-array) neighbour get the smallest step weight to it.
    // Dial's bucket queue: distances grow by at most 5, so 6 circular buckets suffice.
    std::vector<std::uint32_t> bucket[6];
    std::int64_t object = 0;
    for (std::int64_t z = 0; z < nz; ++z) {
        for (std::int64_t y = 0; y < ny; ++y)
            for (std::int64_t x = 0; x < nx; ++x) {
                const std::int64_t i = g.index(x, y, z);
                if (!mask[i]) {
                    dt[i] = 0.0f;
                    continue;
                }
                ++object;
                int best = 6;
                nb.visit(x, y, z, i, [&](int k, std::int64_t j) {
                    if (j < 0 || !mask[j]) best = std::min(best, kWeight[common_detail::kOffsets[k].order]);
                });
                dt[i] = best < 6 ? static_cast<float>(best) : kUnset;
                if (best < 6) bucket[best].push_back(static_cast<std::uint32_t>(i));
            }
        if ((z & 63) == 63) report(progress, 0.3 * static_cast<double>(z) / static_cast<double>(nz));
    }
    std::int64_t settled = 0, pending = 0;
    for (auto& b : bucket) pending += static_cast<std::int64_t>(b.size());
    std::vector<std::uint32_t> current;
    for (std::int64_t d = 3; pending > 0; ++d) {
        current.swap(bucket[d % 6]);
        bucket[d % 6].clear();
        pending -= static_cast<std::int64_t>(current.size());
        for (std::uint32_t ui : current) {
            const std::int64_t i = ui;
            if (dt[i] != static_cast<float>(d)) continue;  // stale entry, settled earlier at a smaller distance
            const std::int64_t z = i / (nx * ny), y = (i / nx) % ny, x = i % nx;
            nb.visit(x, y, z, i, [&](int k, std::int64_t j) {
                if (j < 0 || !mask[j]) return;
                const std::int64_t nd = d + kWeight[common_detail::kOffsets[k].order];
                if (static_cast<float>(nd) < dt[j]) {
                    dt[j] = static_cast<float>(nd);
                    bucket[nd % 6].push_back(static_cast<std::uint32_t>(j));
                    ++pending;
                }
            });
            if ((++settled & 0xFFFFF) == 0)
                report(progress, 0.3 + 0.7 * static_cast<double>(settled) / static_cast<double>(object));
        }
        current.clear();
    }
    report(progress, 1.0);
}

std::vector<float> distance_transform(const Grid& g, const std::uint8_t* mask, Metric metric, const Progress& progress) {
    check_mask_grid(g, "distance_transform");
    std::vector<float> dt(static_cast<std::size_t>(g.voxel_count()));
    if (metric == Metric::Euclidean)
        euclidean_distance_transform(g, mask, dt.data(), progress);
    else
        chamfer345_distance_transform(g, mask, dt.data(), progress);
    return dt;
}

}  // namespace volrig

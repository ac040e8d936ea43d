#include "volrig/skeleton.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>


namespace volrig {

std::uint32_t descending_key(float score) {
    std::uint32_t u;
    std::memcpy(&u, &score, 4);
    // Ascending-sortable: flip all bits of negatives, set the sign bit of positives; then invert for descending.
    u = (u & 0x80000000u) ? ~u : (u | 0x80000000u);
    return ~u;
}

float score_of_key(std::uint32_t key) {
    std::uint32_t u = ~key;
    u = (u & 0x80000000u) ? (u & 0x7FFFFFFFu) : ~u;
    float f;
    std::memcpy(&f, &u, 4);
    return f;
}

float Skeleton::score(std::size_t k) const { return score_of_key(static_cast<std::uint32_t>(order[k] >> 32)); }

std::size_t Skeleton::count_at(double tp) const {
    // First position whose score is <= tp; scores descend along the order.
    std::size_t lo = 0, hi = order.size();
    while (lo < hi) {
        const std::size_t mid = lo + (hi - lo) / 2;
        if (static_cast<double>(score(mid)) > tp)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

double Skeleton::tp_for_count(std::size_t n) const {
    if (order.empty()) return 0.0;
    if (n >= order.size()) return std::nextafter(static_cast<double>(score(order.size() - 1)),
                                                 -std::numeric_limits<double>::infinity());
    return static_cast<double>(score(n));
}

std::vector<float> Skeleton::dense_scores() const {
    std::vector<float> out(dt.size(), 0.0f);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, order.size()), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) out[voxel(k)] = score(k);
    });
    return out;
}

namespace {

/// Sum of DT over the 3x3 (dy, dx) window around every voxel of slice z (out-of-array voxels count 0), in double.
/// `rows` is scratch of nx*ny doubles.
void window9(const Grid& g, const float* dt, std::int64_t z, double* out, double* rows) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    if (z < 0 || z >= nz) {
        std::fill(out, out + nx * ny, 0.0);
        return;
    }
    for (std::int64_t y = 0; y < ny; ++y) {
        const float* r = dt + (z * ny + y) * nx;
        double* o = rows + y * nx;
        if (nx == 1) {
            o[0] = r[0];
            continue;
        }
        o[0] = double(r[0]) + double(r[1]);
        for (std::int64_t x = 1; x + 1 < nx; ++x) o[x] = double(r[x - 1]) + double(r[x]) + double(r[x + 1]);
        o[nx - 1] = double(r[nx - 2]) + double(r[nx - 1]);
    }
    for (std::int64_t y = 0; y < ny; ++y) {
        double* o = out + y * nx;
        const double* c = rows + y * nx;
        const double* up = y > 0 ? rows + (y - 1) * nx : nullptr;
        const double* dn = y + 1 < ny ? rows + (y + 1) * nx : nullptr;
        for (std::int64_t x = 0; x < nx; ++x) o[x] = c[x] + (up ? up[x] : 0.0) + (dn ? dn[x] : 0.0);
    }
}

}  // namespace

Buffer<std::uint64_t> thinness_keys(const Grid& g, const std::uint8_t* mask, const float* dt) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2], plane = nx * ny;
    // Count object voxels per slice, then each slice writes its keys at its offset (keys stay in index order).
    std::vector<std::int64_t> offset(static_cast<std::size_t>(nz) + 1, 0);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t z = r.begin(); z != r.end(); ++z) {
            const std::uint8_t* m = mask + z * plane;
            std::int64_t c = 0;
            for (std::int64_t i = 0; i < plane; ++i) c += m[i] != 0;
            offset[static_cast<std::size_t>(z) + 1] = c;
        }
    });
    for (std::size_t z = 0; z < static_cast<std::size_t>(nz); ++z) offset[z + 1] += offset[z];
    Buffer<std::uint64_t> keys(static_cast<std::size_t>(offset.back()));
    // The 27-sum around a voxel is the sum of the 3x3 window sums of the slices z-1, z, z+1 (separable, so each
    // voxel costs a few additions instead of 26 gathers). A task walks a run of slices keeping three windows.
    const std::int64_t grain = std::max<std::int64_t>(4, nz / 64);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz, static_cast<std::size_t>(grain)),
                      [&](const tbb::blocked_range<std::int64_t>& r) {
        std::vector<double> buf(static_cast<std::size_t>(4 * plane));
        double* win[3] = {buf.data(), buf.data() + plane, buf.data() + 2 * plane};
        double* rows = buf.data() + 3 * plane;
        window9(g, dt, r.begin() - 1, win[0], rows);
        window9(g, dt, r.begin(), win[1], rows);
        for (std::int64_t z = r.begin(); z != r.end(); ++z) {
            window9(g, dt, z + 1, win[2], rows);
            const std::uint8_t* m = mask + z * plane;
            const float* d = dt + z * plane;
            std::uint64_t* out = keys.data() + offset[static_cast<std::size_t>(z)];
            for (std::int64_t i = 0; i < plane; ++i) {
                if (!m[i]) continue;
                const double neighbours = win[0][i] + win[1][i] + win[2][i] - double(d[i]);
                const auto s = static_cast<float>(double(d[i]) - neighbours / 26.0);
                *out++ = (static_cast<std::uint64_t>(descending_key(s)) << 32) | static_cast<std::uint64_t>(z * plane + i);
            }
            std::rotate(win, win + 1, win + 3);
        }
    });
    return keys;
}

void sort_by_upper_key(Buffer<std::uint64_t>& keys) {
    // Stable LSD radix sort on the upper 32 bits: three passes of 11, 11 and 10 bits. Each pass splits the input
    // into blocks; every block counts its digits, prefix sums give each (digit, block) its output range, and the
    // blocks scatter in parallel, each in input order, which keeps the sort stable.
    const std::size_t n = keys.size();
    if (n < 2) return;
    Buffer<std::uint64_t> tmp(n);
    static constexpr int kShift[3] = {32, 43, 54};
    static constexpr int kBits[3] = {11, 11, 10};
    const std::size_t blocks = std::max<std::size_t>(1, std::min<std::size_t>(64, n / 16384));
    const std::size_t per = (n + blocks - 1) / blocks;
    std::uint64_t* src = keys.data();
    std::uint64_t* dst = tmp.data();
    for (int pass = 0; pass < 3; ++pass) {
        const int shift = kShift[pass];
        const std::size_t buckets = std::size_t{1} << kBits[pass];
        const std::uint64_t digit_mask = buckets - 1;
        std::vector<std::size_t> count(blocks * buckets, 0);
        tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t b) {
            std::size_t* c = count.data() + b * buckets;
            const std::size_t e = std::min(n, (b + 1) * per);
            for (std::size_t i = b * per; i < e; ++i) ++c[(src[i] >> shift) & digit_mask];
        });
        // Skip a pass where every key has the same digit (common for the top bits).
        std::size_t first_total = 0;
        const std::size_t d0 = (src[0] >> shift) & digit_mask;
        for (std::size_t b = 0; b < blocks; ++b) first_total += count[b * buckets + d0];
        if (first_total == n) continue;
        std::size_t sum = 0;
        for (std::size_t d = 0; d < buckets; ++d)
            for (std::size_t b = 0; b < blocks; ++b) {
                const std::size_t t = count[b * buckets + d];
                count[b * buckets + d] = sum;
                sum += t;
            }
        tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t b) {
            std::size_t* c = count.data() + b * buckets;
            const std::size_t e = std::min(n, (b + 1) * per);
            for (std::size_t i = b * per; i < e; ++i) dst[c[(src[i] >> shift) & digit_mask]++] = src[i];
        });
        std::swap(src, dst);
    }
    if (src != keys.data()) std::memcpy(keys.data(), src, n * sizeof(std::uint64_t));
}

Skeleton skeletonize(const Grid& g, const std::uint8_t* mask, Metric metric, const Progress& progress) {
    if (g.voxel_count() > static_cast<std::int64_t>(std::numeric_limits<std::uint32_t>::max()))
        throw Error("skeletonize: grids above 2^32 voxels are not supported");
    Skeleton s;
    s.grid = g;
    s.metric = metric;
    auto scaled = [&](double a, double b) { return progress_span(progress, a, b); };
    check_grid(g, 1, std::numeric_limits<std::uint64_t>::max(), "skeletonize");
    s.dt.resize(static_cast<std::size_t>(g.voxel_count()));
    if (metric == Metric::Euclidean)
        euclidean_distance_transform(g, mask, s.dt.data(), scaled(0.0, 0.6));
    else
        chamfer345_distance_transform(g, mask, s.dt.data(), scaled(0.0, 0.6));
    s.order = thinness_keys(g, mask, s.dt.data());
    report(progress, 0.8);
    sort_by_upper_key(s.order);
    report(progress, 1.0);
    return s;
}

void skeleton_points(const Skeleton& s, std::size_t n, std::int32_t* ijk, double* centers, float* dt, float* scores) {
    n = std::min(n, s.order.size());
    const std::int64_t nx = s.grid.dims[0], ny = s.grid.dims[1];
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            const std::int64_t i = s.voxel(k);
            const std::int64_t z = i / (nx * ny), y = (i / nx) % ny, x = i % nx;
            if (ijk) {
                ijk[3 * k + 0] = static_cast<std::int32_t>(z);
                ijk[3 * k + 1] = static_cast<std::int32_t>(y);
                ijk[3 * k + 2] = static_cast<std::int32_t>(x);
            }
            if (centers) {
                centers[3 * k + 0] = s.grid.origin[0] + s.grid.spacing[0] * static_cast<double>(x);
                centers[3 * k + 1] = s.grid.origin[1] + s.grid.spacing[1] * static_cast<double>(y);
                centers[3 * k + 2] = s.grid.origin[2] + s.grid.spacing[2] * static_cast<double>(z);
            }
            if (dt) dt[k] = s.dt[static_cast<std::size_t>(i)];
            if (scores) scores[k] = s.score(k);
        }
    });
}

}  // namespace volrig

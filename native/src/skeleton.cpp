#include "volrig/skeleton.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "neighbourhood.hpp"

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

std::vector<std::uint64_t> thinness_keys(const Grid& g, const std::uint8_t* mask, const float* dt) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    const detail::Neighbourhood nb(g);
    // Count object voxels per slice, then each slice writes its keys at its offset (keys stay in index order).
    std::vector<std::int64_t> offset(static_cast<std::size_t>(nz) + 1, 0);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t z = r.begin(); z != r.end(); ++z) {
            const std::uint8_t* m = mask + z * nx * ny;
            std::int64_t c = 0;
            for (std::int64_t i = 0; i < nx * ny; ++i) c += m[i] != 0;
            offset[static_cast<std::size_t>(z) + 1] = c;
        }
    });
    for (std::size_t z = 0; z < static_cast<std::size_t>(nz); ++z) offset[z + 1] += offset[z];
    std::vector<std::uint64_t> keys(static_cast<std::size_t>(offset.back()));
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t z = r.begin(); z != r.end(); ++z) {
            std::uint64_t* out = keys.data() + offset[static_cast<std::size_t>(z)];
            for (std::int64_t y = 0; y < ny; ++y)
                for (std::int64_t x = 0; x < nx; ++x) {
                    const std::int64_t i = g.index(x, y, z);
                    if (!mask[i]) continue;
                    double sum = 0.0;
                    nb.visit(x, y, z, i, [&](int, std::int64_t j) {
                        if (j >= 0) sum += static_cast<double>(dt[j]);
                    });
                    const auto s = static_cast<float>(static_cast<double>(dt[i]) - sum / 26.0);
                    *out++ = (static_cast<std::uint64_t>(descending_key(s)) << 32) | static_cast<std::uint64_t>(i);
                }
        }
    });
    return keys;
}

void sort_by_upper_key(std::vector<std::uint64_t>& keys) {
    // Three stable LSD passes over the 32-bit key (11 + 11 + 10 bits). Histograms are built in parallel; the
    // scatter is sequential to stay stable and simple (it is memory-bound anyway).
    const std::size_t n = keys.size();
    if (n < 2) return;
    std::vector<std::uint64_t> tmp(n);
    static constexpr int kShift[3] = {32, 43, 54};
    static constexpr int kBits[3] = {11, 11, 10};
    std::uint64_t* src = keys.data();
    std::uint64_t* dst = tmp.data();
    for (int pass = 0; pass < 3; ++pass) {
        const int shift = kShift[pass];
        const std::size_t buckets = std::size_t{1} << kBits[pass];
        const std::uint64_t mask = buckets - 1;
        // Skip passes where every key has the same digit (common for the top bits).
        std::vector<std::size_t> count(buckets, 0);
        for (std::size_t i = 0; i < n; ++i) ++count[(src[i] >> shift) & mask];
        if (count[(src[0] >> shift) & mask] == n) continue;
        std::size_t sum = 0;
        for (auto& c : count) {
            const std::size_t t = c;
            c = sum;
            sum += t;
        }
        for (std::size_t i = 0; i < n; ++i) dst[count[(src[i] >> shift) & mask]++] = src[i];
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
    auto scaled = [&](double a, double b) -> Progress {
        if (!progress) return {};
        return [&progress, a, b](double f) { return progress(a + (b - a) * f); };
    };
    s.dt = distance_transform(g, mask, metric, scaled(0.0, 0.6));
    s.order = thinness_keys(g, mask, s.dt.data());
    report(progress, 0.8);
    sort_by_upper_key(s.order);
    report(progress, 1.0);
    return s;
}

void skeleton_points(const Skeleton& s, std::size_t n, std::int32_t* ijk, float* dt, float* scores) {
    n = std::min(n, s.order.size());
    const std::int64_t nx = s.grid.dims[0], ny = s.grid.dims[1];
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            const std::int64_t i = s.voxel(k);
            ijk[3 * k + 0] = static_cast<std::int32_t>(i / (nx * ny));
            ijk[3 * k + 1] = static_cast<std::int32_t>((i / nx) % ny);
            ijk[3 * k + 2] = static_cast<std::int32_t>(i % nx);
            if (dt) dt[k] = s.dt[static_cast<std::size_t>(i)];
            if (scores) scores[k] = s.score(k);
        }
    });
}

}  // namespace volrig

// The pore space over its pore voxels: the rank index, and the open-faced Euclidean distance transform.
#include "pore_space.hpp"

#include <cmath>
#include <limits>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

namespace volrig::pores_detail {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// The lower envelope of parabolas: d[q] = min over p of w (q - p)² + f[p], for n samples `stride` apart; samples
/// of f that are infinite are no sites. In place. v and zb: scratch of n and n + 1.
void envelope(double* f, std::int64_t n, std::int64_t stride, double w, std::vector<std::int64_t>& v,
              std::vector<double>& zb, std::vector<double>& out) {
    v.resize(static_cast<std::size_t>(n));
    zb.resize(static_cast<std::size_t>(n) + 1);
    out.resize(static_cast<std::size_t>(n));
    std::int64_t k = -1;
    auto at = [&](std::int64_t q) { return f[q * stride]; };
    for (std::int64_t q = 0; q < n; ++q) {
        if (at(q) == kInf) continue;
        double s = -kInf;
        while (k >= 0) {
            const std::int64_t p = v[static_cast<std::size_t>(k)];
            const auto dq = static_cast<double>(q), dp = static_cast<double>(p);
            s = ((at(q) + w * dq * dq) - (at(p) + w * dp * dp)) / (2.0 * w * (dq - dp));
            if (s > zb[static_cast<std::size_t>(k)]) break;
            --k;
        }
        ++k;
        v[static_cast<std::size_t>(k)] = q;
        zb[static_cast<std::size_t>(k)] = k == 0 ? -kInf : s;
        zb[static_cast<std::size_t>(k) + 1] = kInf;
    }
    if (k < 0) return;  // no site: every sample stays infinite
    std::int64_t j = 0;
    for (std::int64_t q = 0; q < n; ++q) {
        while (zb[static_cast<std::size_t>(j) + 1] < static_cast<double>(q)) ++j;
        const std::int64_t p = v[static_cast<std::size_t>(j)];
        const auto d = static_cast<double>(q - p);
        out[static_cast<std::size_t>(q)] = w * d * d + at(p);
    }
    for (std::int64_t q = 0; q < n; ++q) f[q * stride] = out[static_cast<std::size_t>(q)];
}

struct Scratch {
    std::vector<double> plane, zb, out;
    std::vector<std::int64_t> v;
};

/// Passes x and y over z slice z: squared distances within the slice, stored for its pore voxels.
void slice_pass(PoreSpace& s, const std::uint8_t* mask, std::int64_t z, Scratch& sc) {
    const Grid& g = s.grid;
    const std::int64_t nx = g.dims[0], ny = g.dims[1], first = z * nx * ny;
    sc.plane.resize(static_cast<std::size_t>(nx * ny));
    double* p = sc.plane.data();
    for (std::int64_t i = 0; i < nx * ny; ++i) p[i] = mask[first + i] ? kInf : 0.0;
    const double wx = g.spacing[0] * g.spacing[0], wy = g.spacing[1] * g.spacing[1];
    for (std::int64_t y = 0; y < ny; ++y) envelope(p + y * nx, nx, 1, wx, sc.v, sc.zb, sc.out);
    for (std::int64_t x = 0; x < nx; ++x) envelope(p + x, ny, nx, wy, sc.v, sc.zb, sc.out);
    std::int64_t r = s.index.rank(first);
    for (std::int64_t i = 0; i < nx * ny; ++i)
        if (mask[first + i]) s.dt[static_cast<std::size_t>(r++)] = static_cast<float>(p[i]);
}

/// Pass z over y plane y, then the square roots.
void column_pass(PoreSpace& s, const std::uint8_t* mask, std::int64_t y, Scratch& sc) {
    const Grid& g = s.grid;
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    sc.plane.resize(static_cast<std::size_t>(nx * nz));
    double* p = sc.plane.data();
    for (std::int64_t z = 0; z < nz; ++z) {
        const std::int64_t row = (z * ny + y) * nx;
        std::int64_t r = s.index.rank(row);
        for (std::int64_t x = 0; x < nx; ++x)
            p[z * nx + x] = mask[row + x] ? static_cast<double>(s.dt[static_cast<std::size_t>(r++)]) : 0.0;
    }
    const double wz = g.spacing[2] * g.spacing[2];
    for (std::int64_t x = 0; x < nx; ++x) envelope(p + x, nz, nx, wz, sc.v, sc.zb, sc.out);
    for (std::int64_t z = 0; z < nz; ++z) {
        const std::int64_t row = (z * ny + y) * nx;
        std::int64_t r = s.index.rank(row);
        for (std::int64_t x = 0; x < nx; ++x)
            if (mask[row + x]) s.dt[static_cast<std::size_t>(r++)] = static_cast<float>(std::sqrt(p[z * nx + x]));
    }
}

}  // namespace

PoreIndex::PoreIndex(const Grid& g, const std::uint8_t* mask) {
    const std::int64_t n = g.voxel_count();
    const std::size_t words = static_cast<std::size_t>((n + 63) / 64);
    bits_.assign(words, 0);
    prefix_.assign(words, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, words), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t w = r.begin(); w != r.end(); ++w) {
            std::uint64_t b = 0;
            const auto start = static_cast<std::int64_t>(w) * 64;
            for (std::int64_t k = 0; k < 64 && start + k < n; ++k)
                if (mask[start + k]) b |= std::uint64_t{1} << k;
            bits_[w] = b;
        }
    });
    for (std::size_t w = 0; w < words; ++w) {
        prefix_[w] = count_;
        count_ += __builtin_popcountll(bits_[w]);
    }
}

void pore_distance(PoreSpace& s, const std::uint8_t* mask, const Progress& progress) {
    s.dt.assign(static_cast<std::size_t>(s.index.count()), 0.0f);
    tbb::enumerable_thread_specific<Scratch> scratch;
    const std::int64_t nz = s.grid.dims[2], ny = s.grid.dims[1];
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t z = r.begin(); z != r.end(); ++z) slice_pass(s, mask, z, scratch.local());
    });
    report(progress, 0.5);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, ny), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t y = r.begin(); y != r.end(); ++y) column_pass(s, mask, y, scratch.local());
    });
    report(progress, 1.0);
}

}  // namespace volrig::pores_detail

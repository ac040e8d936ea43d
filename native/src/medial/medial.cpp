#include "volrig/medial.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <queue>

namespace volrig {

namespace {

/// The padded grid (one voxel more on every side): the layer outside the array is background.
struct Padded {
    std::int64_t px, py, pz;
    explicit Padded(const Grid& g) : px(g.dims[0] + 2), py(g.dims[1] + 2), pz(g.dims[2] + 2) {}
    /// Index of voxel (x, y, z) of the array (each may be -1 .. dims).
    std::int64_t at(std::int64_t x, std::int64_t y, std::int64_t z) const { return ((z + 1) * py + (y + 1)) * px + (x + 1); }
    std::array<std::int64_t, 3> xyz(std::int64_t i) const { return {i % px - 1, (i / px) % py - 1, i / (px * py) - 1}; }
};

/// Lower envelope of the parabolas f(q) + s2 (p - q)^2 over sites q = -1 .. n (f(-1) = f(n) = 0: the background
/// outside the array); writes, for each p in 0 .. n-1, the site of the lowest parabola (Felzenszwalb and
/// Huttenlocher). `f` holds the n inner values.
void envelope_sites(const std::vector<double>& f, double s2, std::vector<std::int64_t>& site,
                    std::vector<std::int64_t>& v, std::vector<double>& zb) {
    const auto n = static_cast<std::int64_t>(f.size());
    auto F = [&](std::int64_t q) { return q < 0 || q >= n ? 0.0 : f[static_cast<std::size_t>(q)]; };
    v.assign(static_cast<std::size_t>(n + 2), 0);
    zb.assign(static_cast<std::size_t>(n + 3), 0.0);
    const double inf = std::numeric_limits<double>::infinity();
    std::int64_t k = 0;
    v[0] = -1;
    zb[0] = -inf;
    zb[1] = inf;
    auto meet = [&](std::int64_t q, std::int64_t p) {
        return ((F(q) + s2 * double(q * q)) - (F(p) + s2 * double(p * p))) / (2.0 * s2 * double(q - p));
    };
    for (std::int64_t q = 0; q <= n; ++q) {
        if (q < n && !std::isfinite(F(q))) continue;
        double s = meet(q, v[static_cast<std::size_t>(k)]);
        while (s <= zb[static_cast<std::size_t>(k)]) s = meet(q, v[static_cast<std::size_t>(--k)]);
        ++k;
        v[static_cast<std::size_t>(k)] = q;
        zb[static_cast<std::size_t>(k)] = s;
        zb[static_cast<std::size_t>(k) + 1] = inf;
    }
    site.resize(static_cast<std::size_t>(n));
    k = 0;
    for (std::int64_t p = 0; p < n; ++p) {
        while (zb[static_cast<std::size_t>(k) + 1] < double(p)) ++k;
        site[static_cast<std::size_t>(p)] = v[static_cast<std::size_t>(k)];
    }
}

}  // namespace

std::vector<std::int64_t> feature_transform(const Grid& g, const std::uint8_t* mask, const Progress& progress) {
    check_grid(g, 1, std::numeric_limits<std::uint64_t>::max(), "feature transform");
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    const auto& sp = g.spacing;
    const auto N = static_cast<std::size_t>(g.voxel_count());
    // Per voxel, the nearest background's coordinates found so far (x after pass 1; x, y after pass 2).
    std::vector<std::int32_t> fx(N), fy(N);
    std::vector<std::int64_t> out(N);
    // Pass 1, rows along x: the nearest background in the row (-1 and nx outside).
    tbb::parallel_for(std::int64_t(0), ny * nz, [&](std::int64_t row) {
        const std::int64_t base = row * nx;
        std::int64_t last = -1;
        for (std::int64_t x = 0; x < nx; ++x) {
            if (!mask[base + x]) last = x;
            fx[static_cast<std::size_t>(base + x)] = static_cast<std::int32_t>(last);
        }
        std::int64_t next = nx;
        for (std::int64_t x = nx - 1; x >= 0; --x) {
            if (!mask[base + x]) next = x;
            const std::int64_t l = fx[static_cast<std::size_t>(base + x)];
            if (next - x < x - l) fx[static_cast<std::size_t>(base + x)] = static_cast<std::int32_t>(next);
        }
    });
    report(progress, 0.3);
    // Pass 2, columns along y: sites y' carry their row's nearest x.
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nx * nz), [&](const tbb::blocked_range<std::int64_t>& r) {
        std::vector<double> f(static_cast<std::size_t>(ny));
        std::vector<std::int64_t> site, v;
        std::vector<double> zb;
        std::vector<std::int32_t> col(static_cast<std::size_t>(ny));
        for (std::int64_t c = r.begin(); c != r.end(); ++c) {
            const std::int64_t x = c % nx, z = c / nx;
            for (std::int64_t y = 0; y < ny; ++y) {
                const std::int32_t X = fx[static_cast<std::size_t>(g.index(x, y, z))];
                col[static_cast<std::size_t>(y)] = X;
                const double d = double(x - X) * sp[0];
                f[static_cast<std::size_t>(y)] = d * d;
            }
            envelope_sites(f, sp[1] * sp[1], site, v, zb);
            for (std::int64_t y = 0; y < ny; ++y) {
                const std::int64_t s = site[static_cast<std::size_t>(y)];
                const auto i = static_cast<std::size_t>(g.index(x, y, z));
                fy[i] = static_cast<std::int32_t>(s);
                fx[i] = s < 0 || s >= ny ? static_cast<std::int32_t>(x) : col[static_cast<std::size_t>(s)];
            }
        }
    });
    report(progress, 0.65);
    // Pass 3, lines along z: sites z' carry their (x, y).
    const Padded pad(g);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nx * ny), [&](const tbb::blocked_range<std::int64_t>& r) {
        std::vector<double> f(static_cast<std::size_t>(nz));
        std::vector<std::int64_t> site, v;
        std::vector<double> zb;
        std::vector<std::int32_t> cx(static_cast<std::size_t>(nz)), cy(static_cast<std::size_t>(nz));
        for (std::int64_t c = r.begin(); c != r.end(); ++c) {
            const std::int64_t x = c % nx, y = c / nx;
            for (std::int64_t z = 0; z < nz; ++z) {
                const auto i = static_cast<std::size_t>(g.index(x, y, z));
                cx[static_cast<std::size_t>(z)] = fx[i];
                cy[static_cast<std::size_t>(z)] = fy[i];
                const double dx = double(x - fx[i]) * sp[0], dy = double(y - fy[i]) * sp[1];
                f[static_cast<std::size_t>(z)] = dx * dx + dy * dy;
            }
            envelope_sites(f, sp[2] * sp[2], site, v, zb);
            for (std::int64_t z = 0; z < nz; ++z) {
                const std::int64_t s = site[static_cast<std::size_t>(z)];
                const bool outside = s < 0 || s >= nz;
                out[static_cast<std::size_t>(g.index(x, y, z))] =
                    outside ? pad.at(x, y, s) : pad.at(cx[static_cast<std::size_t>(s)], cy[static_cast<std::size_t>(s)], s);
            }
        }
    });
    report(progress, 1.0);
    return out;
}

namespace {

/// The boundary: background voxels of the padded grid 6-adjacent to an object voxel (one byte per padded voxel).
std::vector<std::uint8_t> boundary_of(const Grid& g, const std::uint8_t* mask, const Padded& pad) {
    std::vector<std::uint8_t> b(static_cast<std::size_t>(pad.px * pad.py * pad.pz), 0);
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    const std::int64_t step[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    tbb::parallel_for(std::int64_t(-1), nz + 1, [&](std::int64_t z) {
        for (std::int64_t y = -1; y <= ny; ++y)
            for (std::int64_t x = -1; x <= nx; ++x) {
                const bool inside = x >= 0 && y >= 0 && z >= 0 && x < nx && y < ny && z < nz;
                if (inside && mask[g.index(x, y, z)]) continue;
                for (const auto& d : step) {
                    const std::int64_t X = x + d[0], Y = y + d[1], Z = z + d[2];
                    if (X >= 0 && Y >= 0 && Z >= 0 && X < nx && Y < ny && Z < nz && mask[g.index(X, Y, Z)]) {
                        b[static_cast<std::size_t>(pad.at(x, y, z))] = 1;
                        break;
                    }
                }
            }
    });
    return b;
}

/// A pair whose geodesic distance along the boundary d(M) needs: seed S(M), target S(X), and the edge slot
/// 3 M + axis of the lattice edge from X to M.
struct Pair {
    std::int64_t seed, target, slot;
    bool operator<(const Pair& o) const { return seed != o.seed ? seed < o.seed : target < o.target; }
};

/// Geodesic distances along the boundary from `seed` to each of `targets` (26-connected steps, world lengths),
/// +infinity for those farther than `limit`: 26-neighbours are a step apart, targets further than the limit in a
/// straight line out of reach, the others found by A* (search). The front never leaves the box of half-size
/// limit / spacing around the seed, so distances live in a dense window reset after each search.
class BoundaryWalk {
public:
    BoundaryWalk(const Grid& g, const Padded& pad, const std::vector<std::uint8_t>& boundary, double limit)
        : g_(g), pad_(pad), boundary_(boundary), limit_(limit) {
        for (int a = 0; a < 3; ++a) half_[a] = static_cast<std::int64_t>(std::ceil(limit / g.spacing[a])) + 1;
        side_ = {2 * half_[0] + 1, 2 * half_[1] + 1, 2 * half_[2] + 1};
        window_.assign(static_cast<std::size_t>(side_[0] * side_[1] * side_[2]), kFar);
        for (std::int64_t dz = -1; dz <= 1; ++dz)
            for (std::int64_t dy = -1; dy <= 1; ++dy)
                for (std::int64_t dx = -1; dx <= 1; ++dx)
                    if (dx || dy || dz) steps_.push_back({dx, dy, dz, length(dx, dy, dz)});
    }

    double length(std::int64_t dx, std::int64_t dy, std::int64_t dz) const {
        const auto& sp = g_.spacing;
        return std::sqrt(double(dx * dx) * sp[0] * sp[0] + double(dy * dy) * sp[1] * sp[1] + double(dz * dz) * sp[2] * sp[2]);
    }

    void run(std::int64_t seed, const std::vector<std::int64_t>& targets, std::vector<double>& out) {
        const auto c = pad_.xyz(seed);
        out.assign(targets.size(), kFar);
        // Targets further than the limit in a straight line are out of reach; 26-neighbours are a step away.
        for (std::size_t k = 0; k < targets.size(); ++k) {
            const auto p = pad_.xyz(targets[k]);
            const std::int64_t dx = p[0] - c[0], dy = p[1] - c[1], dz = p[2] - c[2];
            const double straight = length(dx, dy, dz);
            if (straight > limit_) continue;
            const bool adjacent = std::abs(dx) <= 1 && std::abs(dy) <= 1 && std::abs(dz) <= 1;
            out[k] = adjacent ? straight : search(c, p);
        }
    }

    /// A* from the seed (window centre) to `to` over the boundary, the straight distance left as the heuristic:
    /// the front stays in the ellipsoid of points whose way there plus the straight rest is within the limit,
    /// far smaller than the ball the limit spans when the target lies across a plate.
    double search(const std::array<std::int64_t, 3>& c, const std::array<std::int64_t, 3>& to) {
        const std::int64_t tx = to[0] - c[0], ty = to[1] - c[1], tz = to[2] - c[2];
        if (std::abs(tx) > half_[0] || std::abs(ty) > half_[1] || std::abs(tz) > half_[2]) return kFar;
        using Item = std::pair<double, std::int64_t>;  // (distance + straight rest, window cell)
        std::priority_queue<Item, std::vector<Item>, std::greater<Item>> heap;
        auto cell = [&](std::int64_t dx, std::int64_t dy, std::int64_t dz) {
            return ((dz + half_[2]) * side_[1] + (dy + half_[1])) * side_[0] + (dx + half_[0]);
        };
        const std::int64_t goal = cell(tx, ty, tz);
        double found = kFar;
        set(cell(0, 0, 0), 0.0);
        heap.push({length(tx, ty, tz), cell(0, 0, 0)});
        while (!heap.empty()) {
            const auto [f, w] = heap.top();
            heap.pop();
            if (f > limit_) break;
            if (w == goal) {
                found = window_[static_cast<std::size_t>(w)];
                break;
            }
            const double d = window_[static_cast<std::size_t>(w)];
            const std::int64_t wx = w % side_[0] - half_[0], wy = (w / side_[0]) % side_[1] - half_[1],
                               wz = w / (side_[0] * side_[1]) - half_[2];
            if (f > d + length(tx - wx, ty - wy, tz - wz) + 1e-12) continue;  // a stale entry
            for (const Step& s : steps_) {
                const std::int64_t ox = wx + s.dx, oy = wy + s.dy, oz = wz + s.dz;
                if (std::abs(ox) > half_[0] || std::abs(oy) > half_[1] || std::abs(oz) > half_[2]) continue;
                const std::int64_t X = c[0] + ox, Y = c[1] + oy, Z = c[2] + oz;
                if (X < -1 || Y < -1 || Z < -1 || X > g_.dims[0] || Y > g_.dims[1] || Z > g_.dims[2]) continue;
                if (!boundary_[static_cast<std::size_t>(pad_.at(X, Y, Z))]) continue;
                const double nd = d + s.length;
                const std::int64_t u = cell(ox, oy, oz);
                const double nf = nd + length(tx - ox, ty - oy, tz - oz);
                if (nd < window_[static_cast<std::size_t>(u)] && nf <= limit_) {
                    set(u, nd);
                    heap.push({nf, u});
                }
            }
        }
        for (std::int64_t w : touched_) window_[static_cast<std::size_t>(w)] = kFar;
        touched_.clear();
        return found;
    }

    static constexpr double kFar = std::numeric_limits<double>::infinity();

private:
    void set(std::int64_t w, double d) {
        if (window_[static_cast<std::size_t>(w)] == kFar) touched_.push_back(w);
        window_[static_cast<std::size_t>(w)] = d;
    }
    struct Step {
        std::int64_t dx, dy, dz;
        double length;
    };
    const Grid& g_;
    const Padded& pad_;
    const std::vector<std::uint8_t>& boundary_;
    double limit_;
    std::array<std::int64_t, 3> half_{}, side_{};
    std::vector<Step> steps_;
    std::vector<double> window_;
    std::vector<std::int64_t> touched_;
};

}  // namespace

PlaneEdges plane_edges(const Grid& g, const std::uint8_t* mask, double t, const Progress& progress) {
    if (!(t > 0) || !std::isfinite(t)) throw Error("plane measure: t must be positive and finite");
    PlaneEdges out;
    out.feature = feature_transform(g, mask, progress_span(progress, 0.0, 0.3));
    const std::vector<std::int64_t>& ft = out.feature;
    const Padded pad(g);
    const std::vector<std::uint8_t> boundary = boundary_of(g, mask, pad);
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    // The pairs (S(M), S(X)) with S(X) != S(M), gathered per slice.
    std::vector<std::vector<Pair>> per_slice(static_cast<std::size_t>(nz));
    tbb::parallel_for(std::int64_t(0), nz, [&](std::int64_t z) {
        auto& sl = per_slice[static_cast<std::size_t>(z)];
        for (std::int64_t y = 0; y < ny; ++y)
            for (std::int64_t x = 0; x < nx; ++x) {
                const std::int64_t m = g.index(x, y, z);
                if (!mask[m]) continue;
                const std::int64_t lower[3] = {x > 0 ? m - 1 : -1, y > 0 ? m - nx : -1, z > 0 ? m - nx * ny : -1};
                for (std::int64_t a = 0; a < 3; ++a) {
                    const std::int64_t xi = lower[a];
                    if (xi < 0 || !mask[xi] || ft[static_cast<std::size_t>(xi)] == ft[static_cast<std::size_t>(m)]) continue;
                    sl.push_back({ft[static_cast<std::size_t>(m)], ft[static_cast<std::size_t>(xi)], 3 * m + a});
                }
            }
    });
    std::vector<Pair> pairs;
    for (auto& v : per_slice) pairs.insert(pairs.end(), v.begin(), v.end());
    per_slice = {};
    out.edge.assign(3 * static_cast<std::size_t>(g.voxel_count()), 0.0f);
    report(progress, 0.4);
    tbb::parallel_sort(pairs.begin(), pairs.end());
    // Group starts, one search per seed.
    std::vector<std::size_t> starts;
    for (std::size_t i = 0; i < pairs.size(); ++i)
        if (i == 0 || pairs[i].seed != pairs[i - 1].seed) starts.push_back(i);
    starts.push_back(pairs.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, starts.size() - 1, 64), [&](const tbb::blocked_range<std::size_t>& r) {
        BoundaryWalk walk(g, pad, boundary, t);
        std::vector<std::int64_t> targets;
        std::vector<double> geo;
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            targets.clear();
            for (std::size_t i = starts[k]; i < starts[k + 1]; ++i)
                if (targets.empty() || targets.back() != pairs[i].target) targets.push_back(pairs[i].target);
            walk.run(pairs[starts[k]].seed, targets, geo);
            std::size_t j = 0;
            for (std::size_t i = starts[k]; i < starts[k + 1]; ++i) {
                if (i > starts[k] && pairs[i].target != pairs[i - 1].target) ++j;
                out.edge[static_cast<std::size_t>(pairs[i].slot)] = static_cast<float>(geo[j]);  // slots are distinct
            }
        }
    });
    report(progress, 1.0);
    return out;
}

std::vector<float> plane_measure(const Grid& g, const std::uint8_t* mask, double t, const Progress& progress) {
    const PlaneEdges e = plane_edges(g, mask, t, progress_span(progress, 0.0, 0.95));
    std::vector<float> d(static_cast<std::size_t>(g.voxel_count()));
    tbb::parallel_for(std::size_t{0}, d.size(), [&](std::size_t i) {
        d[i] = std::max({e.edge[3 * i], e.edge[3 * i + 1], e.edge[3 * i + 2]});
    });
    report(progress, 1.0);
    return d;
}

}  // namespace volrig

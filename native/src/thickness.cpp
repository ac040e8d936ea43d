#include "volrig/thickness.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "ball_scan.hpp"
#include "volrig/distance.hpp"

namespace volrig {

namespace {

struct Neighbour {
    std::int64_t dx, dy, dz;
    std::int64_t offset;  // linear index step
    double length;        // world units
};

std::vector<Neighbour> neighbours26(const Grid& g) {
    std::vector<Neighbour> out;
    for (std::int64_t dz = -1; dz <= 1; ++dz)
        for (std::int64_t dy = -1; dy <= 1; ++dy)
            for (std::int64_t dx = -1; dx <= 1; ++dx) {
                if (dx == 0 && dy == 0 && dz == 0) continue;
                const double l2 = double(dx * dx) * g.spacing[0] * g.spacing[0] +
                                  double(dy * dy) * g.spacing[1] * g.spacing[1] +
                                  double(dz * dz) * g.spacing[2] * g.spacing[2];
                out.push_back({dx, dy, dz, (dz * g.dims[1] + dy) * g.dims[0] + dx, std::sqrt(l2)});
            }
    return out;
}

/// The lattice shape of the open ball of one radius: the half-width of each row (dy, dz >= 0; the ball is
/// symmetric), exactly as painting sees it (detail::row_half_width), and the farthest lattice point's distance.
struct BallProfile {
    std::vector<std::int64_t> start;  ///< per dz: offset of its rows in `width` (dz = 0 .. hz, one past the end)
    std::vector<std::int64_t> width;  ///< row half-widths, dy = 0 .. rows of that dz - 1
    double reach = 0.0;               ///< distance of the farthest lattice point inside

    std::int64_t hz() const { return static_cast<std::int64_t>(start.size()) - 2; }
    /// Half-width of row (dy, dz) (any signs), -1 outside the ball.
    std::int64_t at(std::int64_t dy, std::int64_t dz) const {
        dy = dy < 0 ? -dy : dy;
        dz = dz < 0 ? -dz : dz;
        if (dz > hz()) return -1;
        const std::int64_t i = start[static_cast<std::size_t>(dz)] + dy;
        return i < start[static_cast<std::size_t>(dz) + 1] ? width[static_cast<std::size_t>(i)] : -1;
    }
};

BallProfile profile_of(double r, const Grid& g) {
    const double lim = open_ball_limit_sq(r);
    const auto& sp = g.spacing;
    BallProfile b;
    double far = 0.0;
    const std::int64_t hz = ball_half_extent(r, sp[2], Metric::Euclidean);
    for (std::int64_t dz = 0; dz <= hz; ++dz) {
        b.start.push_back(static_cast<std::int64_t>(b.width.size()));
        for (std::int64_t dy = 0;; ++dy) {
            const std::int64_t w = detail::row_half_width(Metric::Euclidean, r, lim, dy, dz, sp);
            if (w < 0) break;
            b.width.push_back(w);
            far = std::max(far, double(w * w) * sp[0] * sp[0] + double(dy * dy) * sp[1] * sp[1] +
                                    double(dz * dz) * sp[2] * sp[2]);
        }
    }
    b.start.push_back(static_cast<std::int64_t>(b.width.size()));
    b.reach = std::sqrt(far);
    return b;
}

/// True when every lattice point of ball `in`, centred `o` voxels (x, y, z) from the centre of ball `out`, lies
/// in `out`: row by row, the run [o_x - w, o_x + w] within out's row at (dy + o_y, dz + o_z). Exact: the same
/// integer rows painting uses.
bool contains(const BallProfile& out, const BallProfile& in, const std::array<std::int64_t, 3>& o) {
    const std::int64_t ox = o[0] < 0 ? -o[0] : o[0];
    for (std::int64_t dz = -in.hz(); dz <= in.hz(); ++dz) {
        const std::size_t a = static_cast<std::size_t>(dz < 0 ? -dz : dz);
        const std::int64_t rows = in.start[a + 1] - in.start[a];
        for (std::int64_t dy = 1 - rows; dy < rows; ++dy)
            if (in.at(dy, dz) + ox > out.at(dy + o[1], dz + o[2])) return false;
    }
    return true;
}

/// BallProfiles of the DT values met, per thread (a volume holds few distinct DT values).
class ProfileCache {
public:
    explicit ProfileCache(const Grid& g) : g_(g) {}
    const BallProfile& operator()(float r) {
        if (last_ != nullptr && r == last_r_) return *last_;  // neighbouring voxels often share a DT
        auto [it, fresh] = cache_.try_emplace(r);
        if (fresh) it->second = profile_of(r, g_);
        last_r_ = r;
        last_ = &it->second;
        return it->second;
    }

private:
    const Grid& g_;
    std::unordered_map<float, BallProfile> cache_;
    float last_r_ = 0.0f;
    const BallProfile* last_ = nullptr;
};

/// The neighbour of voxel v whose DT above v's own exceeds the step to it most (the one most likely to hold v's
/// ball), or -1 (v is a local maximum).
std::int64_t steepest(const Grid& g, const float* dt, std::int64_t v, const std::vector<Neighbour>& nb) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    const std::int64_t x = v % nx, y = (v / nx) % ny, z = v / (nx * ny);
    const bool inner = x > 0 && y > 0 && z > 0 && x + 1 < nx && y + 1 < ny && z + 1 < g.dims[2];
    std::int64_t best = -1;
    double slack = -std::numeric_limits<double>::infinity();
    for (const Neighbour& n : nb) {
        if (!inner) {
            const std::int64_t X = x + n.dx, Y = y + n.dy, Z = z + n.dz;
            if (X < 0 || Y < 0 || Z < 0 || X >= nx || Y >= ny || Z >= g.dims[2]) continue;
        }
        const std::int64_t w = v + n.offset;
        if (dt[w] > dt[v] && double(dt[w]) - n.length > slack) slack = double(dt[w]) - n.length, best = w;
    }
    return best;
}

/// True when voxel v's ball lies in the ball of a voxel up its DT's steepest ascent (at most kClimb steps): first
/// by the triangle inequality (the farthest lattice point of v's ball plus the distance between the centres
/// inside the other's limit, with a relative 1e-12 to spare), then, for the top of the climb, row by row
/// (contains). Dropping such a centre changes no voxel's thickness. (DT grows by less than a step on a lattice,
/// so the first neighbour up rarely holds the ball while one further up does.)
bool dominated(const Grid& g, const float* dt, std::int64_t v, const std::vector<Neighbour>& nb, ProfileCache& balls) {
    constexpr int kClimb = 64;
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    auto voxel = [&](std::int64_t i) { return std::array<std::int64_t, 3>{i % nx, (i / nx) % ny, i / (nx * ny)}; };
    const auto c = voxel(v);
    const double reach = balls(dt[v]).reach;
    std::int64_t u = v, top = -1;
    double miss = 0.0;  // by how much the triangle test missed at the top
    for (int k = 0; k < kClimb && (u = steepest(g, dt, u, nb)) >= 0; ++k) {
        const auto p = voxel(u);
        const double dx = double(p[0] - c[0]) * g.spacing[0], dy = double(p[1] - c[1]) * g.spacing[1],
                     dz = double(p[2] - c[2]) * g.spacing[2];
        const double far = reach + std::sqrt(dx * dx + dy * dy + dz * dz), lim = open_ball_limit_sq(dt[u]);
        if (far * far < lim * (1.0 - 1e-12)) return true;
        top = u;
        miss = far - std::sqrt(lim);
    }
    // The row test can only succeed where the triangle bound is loose, by less than the lattice's step.
    if (top < 0 || miss > std::min({g.spacing[0], g.spacing[1], g.spacing[2]})) return false;
    const auto p = voxel(top);
    const BallProfile& outer = balls(dt[top]);  // (references into the cache stay valid as it grows)
    return contains(outer, balls(dt[v]), {c[0] - p[0], c[1] - p[1], c[2] - p[2]});
}

}  // namespace

std::vector<std::int64_t> thickness_centres(const Grid& g, const float* dt) {
    const std::vector<Neighbour> nb = neighbours26(g);
    std::vector<std::vector<std::int64_t>> per_slice(static_cast<std::size_t>(g.dims[2]));
    tbb::enumerable_thread_specific<ProfileCache> caches([&] { return ProfileCache(g); });
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, g.dims[2]), [&](const tbb::blocked_range<std::int64_t>& r) {
        ProfileCache& balls = caches.local();
        for (std::int64_t z = r.begin(); z != r.end(); ++z)
            for (std::int64_t y = 0; y < g.dims[1]; ++y)
                for (std::int64_t x = 0; x < g.dims[0]; ++x)
                    if (dt[g.index(x, y, z)] > 0 && !dominated(g, dt, g.index(x, y, z), nb, balls))
                        per_slice[static_cast<std::size_t>(z)].push_back(g.index(x, y, z));
    });
    std::vector<std::int64_t> out;
    for (const auto& s : per_slice) out.insert(out.end(), s.begin(), s.end());
    return out;
}

std::vector<float> local_thickness_from_dt(const Grid& g, const float* dt, const Progress& progress) {
    check_grid(g, sizeof(float), std::numeric_limits<std::uint64_t>::max(), "local thickness");
    const std::vector<std::int64_t> centres = thickness_centres(g, dt);
    report(progress, 0.2);
    if (centres.size() > std::numeric_limits<std::uint32_t>::max())
        throw Error("local thickness: more than 2^32 ball centres");
    std::vector<std::int32_t> ijk(3 * centres.size());
    std::vector<float> radius(centres.size());
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    for (std::size_t k = 0; k < centres.size(); ++k) {
        const std::int64_t i = centres[k];
        ijk[3 * k] = static_cast<std::int32_t>(i / (nx * ny));
        ijk[3 * k + 1] = static_cast<std::int32_t>((i / nx) % ny);
        ijk[3 * k + 2] = static_cast<std::int32_t>(i % nx);
        radius[k] = dt[i];
    }
    // One row table per distinct radius (few), so painting looks widths up instead of taking square roots.
    std::vector<float> radii(radius);
    std::sort(radii.begin(), radii.end());
    radii.erase(std::unique(radii.begin(), radii.end()), radii.end());
    std::vector<BallProfile> tables(radii.size());
    tbb::parallel_for(std::size_t(0), radii.size(), [&](std::size_t i) { tables[i] = profile_of(radii[i], g); });
    std::vector<std::uint32_t> table(centres.size());
    for (std::size_t k = 0; k < centres.size(); ++k)
        table[k] = static_cast<std::uint32_t>(std::lower_bound(radii.begin(), radii.end(), radius[k]) - radii.begin());
    report(progress, 0.3);
    std::vector<float> out(static_cast<std::size_t>(g.voxel_count()), 0.0f);
    detail::scan_balls(
        g, Metric::Euclidean, ijk.data(), radius.data(), centres.size(),
        [&](std::size_t k, std::int64_t dy, std::int64_t dz) { return tables[table[k]].at(dy, dz); },
        [&](std::int64_t z, std::int64_t y, std::int64_t x0, std::int64_t x1, std::size_t k) {
            const float d = 2.0f * radius[k];
            float* row = out.data() + (z * ny + y) * nx;
            for (std::int64_t x = x0; x <= x1; ++x) row[x] = std::max(row[x], d);
        });
    report(progress, 1.0);
    return out;
}

std::vector<float> local_thickness(const Grid& g, const std::uint8_t* mask, const Progress& progress) {
    const std::vector<float> dt = distance_transform(g, mask, Metric::Euclidean, progress_span(progress, 0.0, 0.4));
    return local_thickness_from_dt(g, dt.data(), progress_span(progress, 0.4, 1.0));
}

}  // namespace volrig

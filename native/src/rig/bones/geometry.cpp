// rig/bones/geometry.cpp: what the bones show near a joint: a segment's voxels there, the contact between two
// segments, a sphere fitted to a head, the narrowest section of a segment.
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "rig/bones/bones.hpp"
#include "common/point_grid.hpp"
#include "volrig/distance.hpp"

namespace volrig::rig_detail {

namespace {

P3 centroid(const std::vector<P3>& pts) {
    P3 c{0, 0, 0};
    for (const P3& p : pts)
        for (int a = 0; a < 3; ++a) c[a] += p[a];
    for (int a = 0; a < 3; ++a) c[a] /= static_cast<double>(std::max<std::size_t>(pts.size(), 1));
    return c;
}

/// Whether voxel (x, y, z) of segment s has a 6-neighbour outside it (or lies on the grid's border).
bool on_surface(const Grid& g, const std::vector<std::int32_t>& labels, std::int32_t s, std::int64_t x,
                std::int64_t y, std::int64_t z) {
    const auto [nx, ny, nz] = g.dims;
    if (x == 0 || y == 0 || z == 0 || x + 1 == nx || y + 1 == ny || z + 1 == nz) return true;
    const std::int64_t i = g.index(x, y, z);
    for (std::int64_t d : {std::int64_t{1}, nx, nx * ny})
        if (labels[static_cast<std::size_t>(i - d)] != s || labels[static_cast<std::size_t>(i + d)] != s) return true;
    return false;
}

/// Voxel (x, y, z) of a linear index.
std::array<std::int64_t, 3> voxel_of(const Grid& g, std::int64_t index) {
    return {index % g.dims[0], (index / g.dims[0]) % g.dims[1], index / (g.dims[0] * g.dims[1])};
}

/// For each surface point of `a`, the distance to the nearest surface point of `b` when at most `limit`, else
/// infinity: b's surface voxels bucketed in cells at least `limit` wide, each of a's searched in the cells around it.
std::vector<double> nearest_of(const Grid& g, const Patch& a, const Patch& b, double limit) {
    std::vector<std::int32_t> zyx;
    std::vector<std::size_t> which;
    for (std::size_t k = 0; k < b.pos.size(); ++k)
        if (b.surface[k]) {
            const std::array<std::int64_t, 3> v = voxel_of(g, b.index[k]);
            zyx.insert(zyx.end(), {static_cast<std::int32_t>(v[2]), static_cast<std::int32_t>(v[1]),
                                   static_cast<std::int32_t>(v[0])});
            which.push_back(k);
        }
    std::array<std::int64_t, 3> cell{};
    for (int x = 0; x < 3; ++x) {  // (compared before the cast: an unbounded reach is one cell)
        const double c = std::ceil(limit / g.spacing[x]);
        cell[x] = c < static_cast<double>(g.dims[x]) ? std::max<std::int64_t>(1, static_cast<std::int64_t>(c)) : g.dims[x];
    }
    const common_detail::PointGrid near(g, PointSet{zyx.data(), nullptr, which.size()}, cell);
    std::vector<double> d(a.pos.size(), std::numeric_limits<double>::infinity());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, a.pos.size()), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            if (!a.surface[k]) continue;
            const std::array<std::int64_t, 3> v = voxel_of(g, a.index[k]);
            const std::int32_t at[3] = {static_cast<std::int32_t>(v[2]), static_cast<std::int32_t>(v[1]),
                                        static_cast<std::int32_t>(v[0])};
            const std::array<std::int64_t, 3> c = near.cell_of(at);
            double best = limit * limit;
            bool seen = false;
            near.for_each_in_box({c[0] - 1, c[1] - 1, c[2] - 1}, {c[0] + 1, c[1] + 1, c[2] + 1}, [&](std::uint32_t i) {
                const double e = dist2(a.pos[k], b.pos[which[i]]);
                if (e <= best) best = e, seen = true;
            });
            if (seen) d[k] = std::sqrt(best);
        }
    });
    return d;
}

std::vector<P3> within(const Patch& p, const std::vector<double>& d, double limit) {
    std::vector<P3> out;
    for (std::size_t k = 0; k < p.pos.size(); ++k)
        if (d[k] <= limit) out.push_back(p.pos[k]);
    return out;
}

}  // namespace

P3 voxel_position(const Grid& g, std::int64_t index) {
    const auto [x, y, z] = voxel_of(g, index);
    return {g.origin[0] + g.spacing[0] * static_cast<double>(x), g.origin[1] + g.spacing[1] * static_cast<double>(y),
            g.origin[2] + g.spacing[2] * static_cast<double>(z)};
}

Patch patch_of(const Grid& g, const std::vector<std::int32_t>& labels, std::int32_t s, const P3& centre,
               double radius) {
    std::array<std::int64_t, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
        lo[a] = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor((centre[a] - radius - g.origin[a]) /
                                                                               g.spacing[a])));
        hi[a] = std::min<std::int64_t>(g.dims[a] - 1, static_cast<std::int64_t>(std::ceil(
                                                          (centre[a] + radius - g.origin[a]) / g.spacing[a])));
    }
    Patch p;
    for (std::int64_t z = lo[2]; z <= hi[2]; ++z)
        for (std::int64_t y = lo[1]; y <= hi[1]; ++y)
            for (std::int64_t x = lo[0]; x <= hi[0]; ++x) {
                const std::int64_t i = g.index(x, y, z);
                if (labels[static_cast<std::size_t>(i)] != s) continue;
                const P3 q = voxel_position(g, i);
                if (dist2(q, centre) > radius * radius) continue;
                p.pos.push_back(q);
                p.surface.push_back(on_surface(g, labels, s, x, y, z));
                p.index.push_back(i);
            }
    return p;
}

Contact contact_of(const Grid& g, const Patch& a, const Patch& b, double reach, double tolerance) {
    Contact c;
    const std::vector<double> da = nearest_of(g, a, b, reach + tolerance), db = nearest_of(g, b, a, reach + tolerance);
    const double gap = da.empty() ? std::numeric_limits<double>::infinity() : *std::min_element(da.begin(), da.end());
    if (!(gap <= reach)) return c;
    c.found = true;
    c.gap = gap;
    c.a = within(a, da, gap + tolerance);
    c.b = within(b, db, gap + tolerance);
    const P3 ca = centroid(c.a), cb = centroid(c.b);
    for (int k = 0; k < 3; ++k) c.centre[k] = 0.5 * (ca[k] + cb[k]);
    return c;
}

Sphere fit_sphere(const std::vector<P3>& pts) {
    Sphere s;
    if (pts.size() < 8) return s;
    // |p|^2 = 2 c.p + (r^2 - |c|^2): linear in (c, k), about the centroid for conditioning.
    const P3 m = centroid(pts);
    Eigen::MatrixXd A(static_cast<Eigen::Index>(pts.size()), 4);
    Eigen::VectorXd rhs(static_cast<Eigen::Index>(pts.size()));
    for (std::size_t k = 0; k < pts.size(); ++k) {
        const Eigen::Vector3d q(pts[k][0] - m[0], pts[k][1] - m[1], pts[k][2] - m[2]);
        A.row(static_cast<Eigen::Index>(k)) << 2 * q.x(), 2 * q.y(), 2 * q.z(), 1.0;
        rhs(static_cast<Eigen::Index>(k)) = q.squaredNorm();
    }
    const Eigen::Vector4d x = A.colPivHouseholderQr().solve(rhs);
    const double r2 = x(3) + x.head<3>().squaredNorm();
    if (!std::isfinite(r2) || r2 <= 0) return s;
    s.radius = std::sqrt(r2);
    s.centre = {m[0] + x(0), m[1] + x(1), m[2] + x(2)};
    return s;
}

namespace {

/// Voxel counts of a patch in slabs along `axis` through `centre` (bin n = the centre), within `radius` of the
/// axis; bin[k] = each voxel's slab or -1.
std::vector<long> slab_profile(const Patch& p, const P3& centre, const P3& axis, double radius, double slab, int n,
                               std::vector<int>& bin) {
    std::vector<long> count(static_cast<std::size_t>(2 * n + 1), 0);
    bin.assign(p.pos.size(), -1);
    for (std::size_t k = 0; k < p.pos.size(); ++k) {
        const P3 q{p.pos[k][0] - centre[0], p.pos[k][1] - centre[1], p.pos[k][2] - centre[2]};
        const double t = q[0] * axis[0] + q[1] * axis[1] + q[2] * axis[2];
        if (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] - t * t > radius * radius) continue;
        const int b = static_cast<int>(std::lround(t / slab)) + n;
        if (b < 0 || b > 2 * n) continue;
        bin[k] = b;
        ++count[static_cast<std::size_t>(b)];
    }
    return count;
}

/// The deepest valley of a profile (three-slab sums): the bin whose lower wall, the most bone on either side,
/// stands highest above it; -1 when there is none.
/// `share` (when given): the valley's depth over its lower wall.
int deepest_valley(const std::vector<long>& count, double* share = nullptr) {
    const int m = static_cast<int>(count.size());
    std::vector<long> sum(count.size(), 0);
    for (int b = 1; b + 1 < m; ++b) sum[b] = count[b - 1] + count[b] + count[b + 1];
    int best = -1, run = 0;  // the middle of the first run of equally deep bins
    long best_depth = 0, best_wall = 1;
    for (int b = 2; b + 2 < m; ++b) {
        const long left = *std::max_element(sum.begin() + 1, sum.begin() + b);
        const long right = *std::max_element(sum.begin() + b + 1, sum.end() - 1);
        const long depth = std::min(left, right) - sum[b];
        if (depth > best_depth) best_depth = depth, best = b, run = 1, best_wall = std::max(1L, std::min(left, right));
        else if (depth == best_depth && best >= 0 && b == best + run) ++run;
    }
    if (share) *share = static_cast<double>(best_depth) / static_cast<double>(best_wall);
    return best < 0 ? best : best + (run - 1) / 2;
}

/// The centroid of the voxels whose bin lies in [lo, hi]; where those bins hold no bone (a valley that is a clean
/// gap), the range widens a bin each way until it does (the gap's facing ends), not the origin.
P3 bins_centroid(const Patch& p, const std::vector<int>& bin, int lo, int hi) {
    std::vector<P3> in;
    const int last = bin.empty() ? 0 : *std::max_element(bin.begin(), bin.end());
    for (; in.empty() && (lo >= 0 || hi <= last); --lo, ++hi)
        for (std::size_t k = 0; k < p.pos.size(); ++k)
            if (bin[k] >= 0 && bin[k] >= lo && bin[k] <= hi) in.push_back(p.pos[k]);
    return centroid(in);
}

}  // namespace

Section narrowest_section(const Patch& p, const P3& centre, const P3& axis, double half_length, double slab) {
    Section s;
    const int n = static_cast<int>(std::floor(half_length / slab));
    if (n < 3 || p.pos.empty()) return s;
    std::vector<int> bin;
    const std::vector<long> count = slab_profile(p, centre, axis, half_length, slab, n, bin);
    const int best = deepest_valley(count, &s.share);
    if (best < 0) return s;
    s.found = true;
    s.centre = bins_centroid(p, bin, best - 1, best + 1);
    return s;
}

Section fused_end(const Patch& p, const P3& at, const P3& axis, double radius, double back, double ahead, double slab,
                  double least) {
    Section s;
    const int n = static_cast<int>(std::ceil(std::max(back, ahead) / slab));
    if (n < 3 || p.pos.empty()) return s;
    std::vector<int> bin;
    std::vector<long> count = slab_profile(p, at, axis, radius, slab, n, bin);
    const int first = n - static_cast<int>(std::floor(back / slab)), last = n + static_cast<int>(std::floor(ahead / slab));
    for (std::size_t k = 0; k < bin.size(); ++k)
        if (bin[k] >= 0 && (bin[k] < first || bin[k] > last)) bin[k] = -1;
    const std::vector<long> window(count.begin() + first, count.begin() + last + 1);
    double share = 0;
    const int v = deepest_valley(window, &share);
    if (v < 0 || v + first >= n || share < least) return s;
    s.found = true;
    s.centre = bins_centroid(p, bin, v + first - 1, v + first + 1);
    return s;
}

namespace {

/// Each voxel's bin along the limb a -> k -> b (arc length from a, nearest point of either stretch; -1 beyond
/// `radius` of it or outside [from, to]), `slab` per bin; returns the bone per bin.
std::vector<long> limb_profile(const Patch& p, const Limb& limb, double radius, double from, double to, double slab,
                               std::vector<int>& bin) {
    const int n = static_cast<int>(std::floor((to - from) / slab)) + 1;
    std::vector<long> count(static_cast<std::size_t>(n), 0);
    bin.assign(p.pos.size(), -1);
    const double first = norm(sub(limb.k, limb.a));
    for (std::size_t v = 0; v < p.pos.size(); ++v) {
        double best = radius * radius, along = -1;
        for (int part = 0; part < 2; ++part) {
            const P3& s = part ? limb.k : limb.a;
            const P3& e = part ? limb.b : limb.k;
            const double t = share_along(p.pos[v], s, e), d2 = dist2(p.pos[v], lerp(s, e, t));
            if (d2 <= best) best = d2, along = (part ? first : 0.0) + t * norm(sub(e, s));
        }
        if (along < from || along > to) continue;
        const int b = std::min(n - 1, static_cast<int>((along - from) / slab));
        bin[v] = b;
        ++count[static_cast<std::size_t>(b)];
    }
    return count;
}

}  // namespace

Section limb_section(const Patch& p, const Limb& limb, double radius, double slab) {
    Section s;
    const double length = norm(sub(limb.k, limb.a)) + norm(sub(limb.b, limb.k));
    if ((limb.to - limb.from) * length < 6 * slab || p.pos.empty()) return s;
    std::vector<int> bin;
    const std::vector<long> count = limb_profile(p, limb, radius, limb.from * length, limb.to * length, slab, bin);
    double share = 0;
    int at = deepest_valley(count, &share), lo = at - 1, hi = at + 1;
    s.bulge = at < 0 || share < kLimbValley;
    if (s.bulge) {  // no joint space: the bulge around the widest slab
        at = static_cast<int>(std::max_element(count.begin(), count.end()) - count.begin());
        if (count[static_cast<std::size_t>(at)] == 0) return s;
        const double floor = kLimbBulge * static_cast<double>(count[static_cast<std::size_t>(at)]);
        for (lo = at; lo > 0 && static_cast<double>(count[static_cast<std::size_t>(lo - 1)]) >= floor;) --lo;
        for (hi = at; hi + 1 < static_cast<int>(count.size()) &&
                      static_cast<double>(count[static_cast<std::size_t>(hi + 1)]) >= floor;)
            ++hi;
    }
    s.found = true;
    s.centre = bins_centroid(p, bin, lo, hi);
    return s;
}

std::optional<P3> thickest_point(const Grid& g, const std::vector<std::int32_t>& labels, std::int32_t s,
                                 const P3& centre, double radius) {
    Grid crop = g;
    std::array<std::int64_t, 3> lo{};
    for (int a = 0; a < 3; ++a) {
        lo[a] = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor((centre[a] - radius - g.origin[a]) /
                                                                               g.spacing[a])) - 1);
        const std::int64_t hi = std::min<std::int64_t>(
            g.dims[a] - 1, static_cast<std::int64_t>(std::ceil((centre[a] + radius - g.origin[a]) / g.spacing[a])) + 1);
        crop.dims[a] = std::max<std::int64_t>(1, hi - lo[a] + 1);
        crop.origin[a] = g.origin[a] + g.spacing[a] * static_cast<double>(lo[a]);
    }
    std::vector<std::uint8_t> mask(static_cast<std::size_t>(crop.voxel_count()));
    for (std::int64_t z = 0; z < crop.dims[2]; ++z)
        for (std::int64_t y = 0; y < crop.dims[1]; ++y)
            for (std::int64_t x = 0; x < crop.dims[0]; ++x)
                mask[static_cast<std::size_t>(crop.index(x, y, z))] =
                    labels[static_cast<std::size_t>(g.index(x + lo[0], y + lo[1], z + lo[2]))] == s;
    std::vector<float> dt(mask.size());
    euclidean_distance_transform(crop, mask.data(), dt.data());
    double top = 0;
    for (std::size_t i = 0; i < dt.size(); ++i)
        if (dist2(voxel_position(crop, static_cast<std::int64_t>(i)), centre) <= radius * radius)
            top = std::max(top, static_cast<double>(dt[i]));
    std::vector<P3> best;
    for (std::size_t i = 0; i < dt.size(); ++i) {
        const P3 q = voxel_position(crop, static_cast<std::int64_t>(i));
        if (top > 0 && dt[i] >= top - g.min_spacing() && dist2(q, centre) <= radius * radius) best.push_back(q);
    }
    if (best.empty()) return std::nullopt;
    return centroid(best);
}

P3 principal_axis(const std::vector<P3>& pts, P3& centre) {
    centre = centroid(pts);
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const P3& p : pts) {
        const Eigen::Vector3d q(p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]);
        cov += q * q.transpose();
    }
    const Eigen::Vector3d axis = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(2);
    return {axis.x(), axis.y(), axis.z()};
}

SegmentEnds segment_ends(const Grid& g, const std::vector<std::int64_t>& voxels) {
    SegmentEnds e;
    std::vector<P3> pts;
    pts.reserve(voxels.size());
    for (const std::int64_t i : voxels) pts.push_back(voxel_position(g, i));
    if (pts.size() < 2) return e;
    const P3 axis = principal_axis(pts, e.centroid);
    std::vector<double> t(pts.size());
    for (std::size_t k = 0; k < pts.size(); ++k) t[k] = dot(sub(pts[k], e.centroid), axis);
    const auto [lo, hi] = std::minmax_element(t.begin(), t.end());
    const double band = std::max(0.04 * (*hi - *lo), 2.0 * std::max({g.spacing[0], g.spacing[1], g.spacing[2]}));
    std::vector<P3> low, high;
    for (std::size_t k = 0; k < pts.size(); ++k) {
        if (t[k] <= *lo + band) low.push_back(pts[k]);
        if (t[k] >= *hi - band) high.push_back(pts[k]);
    }
    e.found = true;
    e.a = centroid(low);
    e.b = centroid(high);
    return e;
}

}  // namespace volrig::rig_detail

// From a voxel path to a smooth, centred curve sampled at equal arc length; trilinear sampling; rotation-minimising
// frames and straightening (volrig/centerline.hpp).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "centerline/detail.hpp"
#include "volrig/centerline.hpp"

namespace volrig {

namespace centerline_detail {

namespace {

Vec3d add(const Vec3d& a, const Vec3d& b, double s = 1.0) { return {a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]}; }
double dot(const Vec3d& a, const Vec3d& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm(const Vec3d& a) { return std::sqrt(dot(a, a)); }
Vec3d cross(const Vec3d& a, const Vec3d& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec3d unit(const Vec3d& a) {
    const double n = norm(a);
    return n > 0 ? Vec3d{a[0] / n, a[1] / n, a[2] / n} : Vec3d{0, 0, 1};
}

/// Trilinear interpolation of value(x, y, z) at a world point; corners outside the grid give `fill`.
template <class Value>
double sample(const Grid& grid, const Vec3d& p, double fill, Value value) {
    double f[3];
    std::int64_t i0[3];
    for (int a = 0; a < 3; ++a) {
        f[a] = (p[a] - grid.origin[a]) / grid.spacing[a];
        if (!(f[a] > -1.0 && f[a] < static_cast<double>(grid.dims[a]))) return fill;
        i0[a] = static_cast<std::int64_t>(std::floor(f[a]));
        f[a] -= static_cast<double>(i0[a]);
    }
    double acc = 0.0;
    for (int c = 0; c < 8; ++c) {
        const std::int64_t x = i0[0] + (c & 1), y = i0[1] + ((c >> 1) & 1), z = i0[2] + ((c >> 2) & 1);
        const double w = ((c & 1) ? f[0] : 1 - f[0]) * (((c >> 1) & 1) ? f[1] : 1 - f[1]) *
                         (((c >> 2) & 1) ? f[2] : 1 - f[2]);
        if (w == 0.0) continue;
        const bool inside = x >= 0 && y >= 0 && z >= 0 && x < grid.dims[0] && y < grid.dims[1] && z < grid.dims[2];
        acc += w * (inside ? value(grid.index(x, y, z)) : fill);
    }
    return acc;
}

}  // namespace

double polyline_length(const std::vector<Vec3d>& pts) {
    double l = 0.0;
    for (std::size_t i = 1; i < pts.size(); ++i) l += norm(add(pts[i], pts[i - 1], -1.0));
    return l;
}

std::vector<Vec3d> resample(const std::vector<Vec3d>& pts, double step) {
    const double total = polyline_length(pts);
    if (pts.size() < 2 || total <= 0.0) return {pts.front()};
    const auto n = static_cast<std::size_t>(std::max(1.0, std::ceil(total / step - 1e-9)));
    const double ds = total / static_cast<double>(n);
    std::vector<Vec3d> out{pts.front()};
    std::size_t seg = 1;
    double before = 0.0;  // arc length at pts[seg - 1]
    for (std::size_t k = 1; k < n; ++k) {
        const double s = ds * static_cast<double>(k);
        double len = norm(add(pts[seg], pts[seg - 1], -1.0));
        while (seg + 1 < pts.size() && before + len < s) {
            before += len;
            ++seg;
            len = norm(add(pts[seg], pts[seg - 1], -1.0));
        }
        const double u = len > 0 ? std::clamp((s - before) / len, 0.0, 1.0) : 0.0;
        out.push_back(add(pts[seg - 1], add(pts[seg], pts[seg - 1], -1.0), u));
    }
    out.push_back(pts.back());
    return out;
}

std::vector<Vec3d> smooth(const std::vector<Vec3d>& pts, double sigma) {
    const std::size_t n = pts.size();
    if (sigma <= 0.0 || n < 3) return pts;
    const auto reach = static_cast<std::size_t>(std::ceil(3.0 * sigma));
    std::vector<Vec3d> out(n);
    for (std::size_t i = 0; i < n; ++i) {
        const std::size_t half = std::min({reach, i, n - 1 - i});  // symmetric window: the ends stay fixed
        Vec3d acc{0, 0, 0};
        double wsum = 0.0;
        for (std::size_t j = i - half; j <= i + half; ++j) {
            const double d = static_cast<double>(j) - static_cast<double>(i);
            const double w = std::exp(-0.5 * d * d / (sigma * sigma));
            acc = add(acc, pts[j], w);
            wsum += w;
        }
        out[i] = {acc[0] / wsum, acc[1] / wsum, acc[2] / wsum};
    }
    return out;
}

std::vector<Vec3d> tangents(const std::vector<Vec3d>& pts) {
    const std::size_t n = pts.size();
    std::vector<Vec3d> t(n, Vec3d{0, 0, 1});
    if (n < 2) return t;
    for (std::size_t i = 0; i < n; ++i) {
        const std::size_t a = i == 0 ? 0 : i - 1, b = i + 1 == n ? n - 1 : i + 1;
        t[i] = unit(add(pts[b], pts[a], -1.0));
    }
    return t;
}

Vec3d perpendicular(const Vec3d& t) {
    const double ax = std::abs(t[0]), ay = std::abs(t[1]), az = std::abs(t[2]);
    const Vec3d e = ax <= ay && ax <= az ? Vec3d{1, 0, 0} : (ay <= az ? Vec3d{0, 1, 0} : Vec3d{0, 0, 1});
    return unit(cross(t, e));
}

namespace {

/// A (2m + 1)^2 grid of flags on a plane, indexed from -m to m.
struct Section {
    std::int64_t m = 0;
    std::vector<std::uint8_t> flag;
    std::uint8_t& at(std::int64_t a, std::int64_t b) {
        return flag[static_cast<std::size_t>((b + m) * (2 * m + 1) + a + m)];
    }
};

/// Flags (1) the samples of the disc of m steps of `gs` around c in the plane (u, v) where the trilinear mask is at
/// least 0.5.
Section sample_section(const Grid& grid, const std::uint8_t* mask, const Vec3d& c, const Vec3d& u, const Vec3d& v,
                       std::int64_t m, double gs) {
    Section sec;
    sec.m = m;
    sec.flag.assign(static_cast<std::size_t>((2 * m + 1) * (2 * m + 1)), 0);
    auto is_object = [mask](std::int64_t k) { return mask[k] ? 1.0 : 0.0; };
    for (std::int64_t b = -m; b <= m; ++b)
        for (std::int64_t a = -m; a <= m; ++a) {
            if (a * a + b * b > m * m) continue;
            const Vec3d p = add(add(c, u, gs * static_cast<double>(a)), v, gs * static_cast<double>(b));
            sec.at(a, b) = sample(grid, p, 0.0, is_object) >= 0.5 ? 1 : 0;
        }
    return sec;
}

/// Mean (a, b) of the 4-connected flagged piece holding the flagged sample nearest the centre, which must lie
/// within `reach` steps; false when there is none.
bool piece_centroid(Section& sec, std::int64_t reach, double& ma, double& mb) {
    const std::int64_t m = sec.m;
    std::int64_t sa = 0, sb = 0, best = -1;
    for (std::int64_t b = -m; b <= m; ++b)
        for (std::int64_t a = -m; a <= m; ++a)
            if (sec.at(a, b) && (best < 0 || a * a + b * b < best)) {
                best = a * a + b * b;
                sa = a;
                sb = b;
            }
    if (best < 0 || best > reach * reach) return false;
    std::vector<std::array<std::int64_t, 2>> queue{{sa, sb}};
    sec.at(sa, sb) = 2;
    ma = mb = 0.0;
    for (std::size_t q = 0; q < queue.size(); ++q) {
        const auto [a, b] = queue[q];
        ma += static_cast<double>(a);
        mb += static_cast<double>(b);
        const std::int64_t na[4] = {a + 1, a - 1, a, a}, nb[4] = {b, b, b + 1, b - 1};
        for (int k = 0; k < 4; ++k) {
            if (na[k] < -m || na[k] > m || nb[k] < -m || nb[k] > m || sec.at(na[k], nb[k]) != 1) continue;
            sec.at(na[k], nb[k]) = 2;
            queue.push_back({na[k], nb[k]});
        }
    }
    ma /= static_cast<double>(queue.size());
    mb /= static_cast<double>(queue.size());
    return true;
}

}  // namespace

Vec3d section_centroid(const Grid& grid, const std::uint8_t* mask, const Vec3d& c, const Vec3d& t, double radius) {
    const double h = grid.min_spacing();
    const double rho = 1.5 * std::max(radius, h) + 2.0 * h;
    const double gs = std::max(0.5 * h, rho / 24.0);
    const auto m = static_cast<std::int64_t>(std::ceil(rho / gs));
    const Vec3d u = perpendicular(t), v = cross(t, u);
    Section sec = sample_section(grid, mask, c, u, v, m, gs);
    double ma = 0.0, mb = 0.0;
    if (!piece_centroid(sec, static_cast<std::int64_t>(std::floor(2.0 * h / gs)), ma, mb)) return c;
    return add(add(c, u, gs * ma), v, gs * mb);
}

}  // namespace centerline_detail

using namespace centerline_detail;

double trilinear(const Grid& grid, const float* values, const Vec3d& p, double fill) {
    return sample(grid, p, fill, [values](std::int64_t k) { return static_cast<double>(values[k]); });
}

namespace {

/// Solves the 3x3 system m x = b (Cramer); leaves x unchanged when singular.
void solve3(const double m[3][3], const double b[3], double x[3]) {
    auto det = [](const double a[3][3]) {
        return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
               a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    };
    const double d = det(m);
    if (std::abs(d) < 1e-12) return;
    for (int c = 0; c < 3; ++c) {
        double t[3][3];
        for (int r = 0; r < 3; ++r)
            for (int q = 0; q < 3; ++q) t[r][q] = q == c ? b[r] : m[r][q];
        x[c] = det(t) / d;
    }
}

/// Where to cut the last end of pts back to: 1.5 times the largest DT met walking in from the end (near a cap the DT
/// is only the distance to the cap), at least 2 voxels, at most half the curve. `rmax` gets that largest DT.
std::size_t cut_back(const VoxelGraph& g, const std::vector<Vec3d>& pts, double& rmax) {
    const double h = g.grid.min_spacing();
    double from_end = 0.0;
    rmax = 0.0;
    std::size_t k = pts.size() - 1;
    while (k > pts.size() / 2) {
        rmax = std::max(rmax, trilinear(g.grid, g.dense_dt, pts[k], 0.0));
        if (from_end >= 1.5 * rmax && from_end >= 2.0 * h) break;
        from_end += norm(add(pts[k], pts[k - 1], -1.0));
        --k;
    }
    return k;
}

/// a + b e + c e^2 in arc length e from a sample, forwards.
struct Quadratic {
    Vec3d a, b, c;
    Vec3d at(double e) const { return add(add(a, b, e), c, e * e); }
    Vec3d direction(double e) const { return add(b, c, 2.0 * e); }
};

/// The quadratic least-squares fit to the samples within `span` (arc length) before pts[k], with e = 0 at pts[k];
/// the straight continuation of the last segment when fewer than 5 samples are there.
Quadratic fit_before(const std::vector<Vec3d>& pts, std::size_t k, double span) {
    std::size_t j0 = k;
    for (double s = 0.0; j0 > 0 && s < span; --j0) s += norm(add(pts[j0], pts[j0 - 1], -1.0));
    if (k - j0 < 4) return {pts[k], unit(add(pts[k], pts[k - 1], -1.0)), {0, 0, 0}};
    double m[3][3] = {}, rhs[3][3] = {}, s = 0.0;
    for (std::size_t j = k + 1; j-- > j0;) {
        const double pw[3] = {1.0, -s, s * s};
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) m[r][c] += pw[r] * pw[c];
            for (int a = 0; a < 3; ++a) rhs[a][r] += pw[r] * pts[j][static_cast<std::size_t>(a)];
        }
        if (j > 0) s += norm(add(pts[j], pts[j - 1], -1.0));
    }
    Quadratic q{pts[k], {0, 0, 0}, {0, 0, 0}};
    for (std::size_t a = 0; a < 3; ++a) {
        double sol[3] = {pts[k][a], 0.0, 0.0};
        solve3(m, rhs[a], sol);
        q.a[a] = sol[0];
        q.b[a] = sol[1];
        q.c[a] = sol[2];
    }
    return q;
}

/// The last end of pts (see EndMode): cut back where the path still heads for its end voxel rather than along the
/// tube, and continue the curve (a quadratic fitted to the 2 radii before the cut: it keeps bending) to the
/// object's surface, or with `given`, to the plane through that point across the curve.
void extend_to_surface(const VoxelGraph& g, const std::uint8_t* mask, std::vector<Vec3d>& pts, const Vec3d* given) {
    if (pts.size() < 3) return;
    const double h = g.grid.min_spacing();
    double rmax = 0.0;
    const std::size_t k = cut_back(g, pts, rmax);
    const Quadratic curve = fit_before(pts, k, 2.0 * std::max(rmax, 2.0 * h));
    pts.resize(k + 1);
    auto is_object = [mask](std::int64_t i) { return mask[i] ? 1.0 : 0.0; };
    const double fine = 0.25 * h, limit = 3.0 * rmax + 4.0 * h;
    Vec3d p = pts.back();
    for (double e = fine; e < limit; e += fine) {
        const Vec3d q = curve.at(e);
        if (sample(g.grid, q, 0.0, is_object) < 0.5) break;
        if (given && dot(add(q, *given, -1.0), curve.direction(e)) >= 0.0) break;  // a Free end: its point's plane
        p = q;
    }
    if (norm(add(p, pts.back(), -1.0)) > 1e-9) pts.push_back(p);
}

void extend_ends(const VoxelGraph& g, const std::uint8_t* mask, std::vector<Vec3d>& pts, EndMode start, EndMode end,
                 const Vec3d& first, const Vec3d& last) {
    if (end != EndMode::Fixed) extend_to_surface(g, mask, pts, end == EndMode::Free ? &last : nullptr);
    if (start != EndMode::Fixed) {
        std::reverse(pts.begin(), pts.end());
        extend_to_surface(g, mask, pts, start == EndMode::Free ? &first : nullptr);
        std::reverse(pts.begin(), pts.end());
    }
}

}  // namespace

Centerline curve_of_path(const VoxelGraph& g, const std::uint8_t* mask, const std::vector<std::int32_t>& path,
                         const CenterlineOptions& opt, EndMode start, EndMode end) {
    if (path.size() < 2) throw Error("centerline: start and end are the same voxel");
    const double h = g.grid.min_spacing();
    const double step = opt.step > 0.0 ? opt.step : h;
    std::vector<Vec3d> pts;
    for (std::int32_t id : path) pts.push_back(world(g.grid, g.voxel[static_cast<std::size_t>(id)]));
    const Vec3d first = pts.front(), last = pts.back();
    const double fine = 0.5 * h;
    pts = resample(smooth(resample(pts, fine), opt.smoothing * h / fine), step);
    for (int it = 0; it < opt.refine && pts.size() > 2; ++it) {
        const std::vector<Vec3d> t = tangents(pts);
        std::vector<Vec3d> moved(pts.size());
        tbb::parallel_for(std::size_t{0}, pts.size(), [&](std::size_t i) {
            const double r = trilinear(g.grid, g.dense_dt, pts[i], 0.0);
            moved[i] = section_centroid(g.grid, mask, pts[i], t[i], r);
        });
        if (start == EndMode::Fixed) moved.front() = first;
        if (end == EndMode::Fixed) moved.back() = last;
        pts = resample(smooth(moved, 1.0 * h / step), step);
    }
    extend_ends(g, mask, pts, start, end, first, last);
    pts = resample(pts, step);
    Centerline out;
    out.points = std::move(pts);
    for (const Vec3d& p : out.points) out.radii.push_back(trilinear(g.grid, g.dense_dt, p, 0.0));
    out.length = polyline_length(out.points);
    for (std::int32_t id : path) out.voxels.push_back(g.voxel[static_cast<std::size_t>(id)]);
    return out;
}

void rotation_minimising_frames(const std::vector<Vec3d>& points, std::vector<Vec3d>& t, std::vector<Vec3d>& u,
                                std::vector<Vec3d>& v) {
    const std::size_t n = points.size();
    t = tangents(points);
    u.assign(n, Vec3d{0, 0, 0});
    v.assign(n, Vec3d{0, 0, 0});
    if (n == 0) return;
    u[0] = perpendicular(t[0]);
    for (std::size_t i = 0; i + 1 < n; ++i) {  // double reflection (Wang, Juttler, Zheng, Liu 2008)
        const Vec3d v1 = add(points[i + 1], points[i], -1.0);
        const double c1 = dot(v1, v1);
        if (c1 <= 0.0) {
            u[i + 1] = u[i];
            continue;
        }
        const Vec3d rl = add(u[i], v1, -2.0 / c1 * dot(v1, u[i]));
        const Vec3d tl = add(t[i], v1, -2.0 / c1 * dot(v1, t[i]));
        const Vec3d v2 = add(t[i + 1], tl, -1.0);
        const double c2 = dot(v2, v2);
        const Vec3d r = c2 > 1e-20 ? add(rl, v2, -2.0 / c2 * dot(v2, rl)) : rl;
        u[i + 1] = unit(add(r, t[i + 1], -dot(r, t[i + 1])));  // re-orthogonalise against rounding
    }
    for (std::size_t i = 0; i < n; ++i) v[i] = cross(t[i], u[i]);
}

std::vector<float> straighten(const Grid& grid, const float* values, const std::vector<Vec3d>& points,
                              const std::vector<Vec3d>& u, const std::vector<Vec3d>& v, std::int64_t m, double step,
                              float fill) {
    if (m < 0 || m > 4096) throw Error("straighten: the half-width must be 0 to 4096 samples, got " + std::to_string(m));
    if (!(step > 0.0) || !std::isfinite(step)) throw Error("straighten: the step must be positive and finite");
    const std::int64_t side = 2 * m + 1;
    std::vector<float> out(points.size() * static_cast<std::size_t>(side * side));
    tbb::parallel_for(std::size_t{0}, points.size(), [&](std::size_t k) {
        float* slice = out.data() + k * static_cast<std::size_t>(side * side);
        for (std::int64_t b = 0; b < side; ++b)
            for (std::int64_t a = 0; a < side; ++a) {
                const Vec3d p = add(add(points[k], u[k], step * static_cast<double>(a - m)), v[k],
                                    step * static_cast<double>(b - m));
                slice[b * side + a] = static_cast<float>(trilinear(grid, values, p, fill));
            }
    });
    return out;
}

}  // namespace volrig

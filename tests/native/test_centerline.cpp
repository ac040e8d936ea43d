// Centerlines, centerline trees, rotation-minimising frames and straightening (volrig/centerline.hpp) on synthetic
// tubes with known axes.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <functional>

#include "centerline/detail.hpp"
#include "volrig/centerline.hpp"
#include "volrig/distance.hpp"

using namespace volrig;

namespace {

struct Tube {
    Grid grid;
    std::vector<std::uint8_t> mask;
    std::vector<float> dt;
    std::vector<Vec3d> axis;  // dense samples of the true centerline
};

double dist(const Vec3d& a, const Vec3d& b) {
    return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

double to_axis(const Tube& t, const Vec3d& p) {
    double best = 1e300;
    for (const Vec3d& q : t.axis) best = std::min(best, dist(p, q));
    return best;
}

/// Voxels within r of the polyline `axis` (dense), cut flat at both ends.
Tube make_tube(std::vector<Vec3d> axis, double r, std::array<std::int64_t, 3> dims, Vec3d origin) {
    Tube t;
    t.grid.dims = dims;
    t.grid.origin = origin;
    t.axis = std::move(axis);
    t.mask.assign(static_cast<std::size_t>(t.grid.voxel_count()), 0);
    const std::size_t n = t.axis.size();
    for (std::int64_t z = 0; z < dims[2]; ++z)
        for (std::int64_t y = 0; y < dims[1]; ++y)
            for (std::int64_t x = 0; x < dims[0]; ++x) {
                const Vec3d p{origin[0] + x, origin[1] + y, origin[2] + z};
                double best = 1e300;
                std::size_t at = 0;
                for (std::size_t i = 0; i < n; ++i) {
                    const double d = dist(p, t.axis[i]);
                    if (d < best) best = d, at = i;
                }
                if (best > r) continue;
                if (at == 0 || at + 1 == n) {  // beyond a flat cap?
                    const Vec3d& e = t.axis[at];
                    const Vec3d& f = t.axis[at == 0 ? 1 : n - 2];
                    const double s = (p[0] - e[0]) * (e[0] - f[0]) + (p[1] - e[1]) * (e[1] - f[1]) + (p[2] - e[2]) * (e[2] - f[2]);
                    if (s > 1e-9) continue;
                }
                t.mask[static_cast<std::size_t>(t.grid.index(x, y, z))] = 1;
            }
    t.dt.resize(t.mask.size());
    euclidean_distance_transform(t.grid, t.mask.data(), t.dt.data());
    return t;
}

Tube torus_segment() {
    std::vector<Vec3d> axis;
    for (int i = 0; i <= 4000; ++i) {
        const double a = 1.5 * M_PI * i / 4000.0;
        axis.push_back({20.0 * std::cos(a), 20.0 * std::sin(a), 0.0});
    }
    return make_tube(axis, 3.5, {52, 52, 13}, {-26.0, -26.0, -6.0});
}

double polyline(const std::vector<Vec3d>& p) { return centerline_detail::polyline_length(p); }

}  // namespace

TEST_CASE("centerline of a torus segment follows its axis, ends at its caps", "[centerline]") {
    const Tube t = torus_segment();
    const VoxelGraph g = voxel_graph(t.grid, t.mask.data(), t.dt.data());
    const Centerline c = centerline(g, t.mask.data(), nullptr, nullptr);
    double sum = 0.0, worst = 0.0;
    for (const Vec3d& p : c.points) {
        const double d = to_axis(t, p);
        sum += d;
        worst = std::max(worst, d);
    }
    CHECK(sum / static_cast<double>(c.points.size()) < 0.5);
    CHECK(worst < 1.5);
    const double truth = polyline(t.axis);
    CHECK(std::abs(c.length - truth) < 0.02 * truth);
    CHECK(std::min(dist(c.points.front(), t.axis.front()), dist(c.points.back(), t.axis.front())) < 1.0);
    CHECK(std::min(dist(c.points.front(), t.axis.back()), dist(c.points.back(), t.axis.back())) < 1.0);
    for (std::size_t i = 1; i < c.points.size(); ++i)
        CHECK(dist(c.points[i], c.points[i - 1]) == Approx(c.length / static_cast<double>(c.points.size() - 1)).epsilon(0.02));
    REQUIRE(c.radii.size() == c.points.size());
    CHECK(c.radii[c.radii.size() / 2] == Approx(3.5).margin(1.0));
}

TEST_CASE("centerline between given points; clear errors on bad input", "[centerline]") {
    const Tube t = torus_segment();
    const VoxelGraph g = voxel_graph(t.grid, t.mask.data(), t.dt.data());
    const Vec3d a{21.5 * std::cos(0.3), 21.5 * std::sin(0.3), 0.0}, b{0.0, 20.0, 0.0};  // a: 1.5 off the axis
    const Centerline c = centerline(g, t.mask.data(), &a, &b);
    CHECK(to_axis(t, c.points.front()) < 0.75);  // moved into the middle of a's cross-section
    CHECK(dist(c.points.back(), b) < 1.0);
    CHECK(c.length == Approx(20.0 * (M_PI / 2 - 0.3)).epsilon(0.05));

    const Vec3d off{0.0, 0.0, 0.0}, nan{std::nan(""), 0.0, 0.0};
    CHECK_THROWS_WITH(centerline(g, t.mask.data(), &off, &b), Catch::Contains("not on the object"));
    CHECK_THROWS_WITH(centerline(g, t.mask.data(), &nan, &b), Catch::Contains("not finite"));
    std::vector<std::uint8_t> empty(t.mask.size(), 0);
    CHECK_THROWS_WITH(voxel_graph(t.grid, empty.data(), t.dt.data()), Catch::Contains("empty"));

    Grid two;
    two.dims = {20, 5, 5};
    std::vector<std::uint8_t> m(100 * 5, 0);
    for (int x = 1; x < 19; ++x)
        if (x != 9 && x != 10)
            for (int y = 1; y < 4; ++y)
                for (int z = 1; z < 4; ++z) m[static_cast<std::size_t>(two.index(x, y, z))] = 1;
    std::vector<float> dt(m.size());
    euclidean_distance_transform(two, m.data(), dt.data());
    const VoxelGraph g2 = voxel_graph(two, m.data(), dt.data());
    const Vec3d p{2, 2, 2}, q{16, 2, 2};
    CHECK_THROWS_WITH(centerline(g2, m.data(), &p, &q), Catch::Contains("different parts"));
}

TEST_CASE("the minimal-cost path avoids a one-voxel bridge", "[centerline]") {
    std::vector<Vec3d> axis;  // a U: down, round a half circle, up; arms 8 apart
    for (int i = 0; i <= 300; ++i) axis.push_back({0.0, 30.0 - 0.1 * i, 0.0});
    for (int i = 1; i <= 600; ++i) {
        const double a = M_PI * i / 600.0;
        axis.push_back({4.0 - 4.0 * std::cos(a), -4.0 * std::sin(a), 0.0});
    }
    for (int i = 1; i <= 300; ++i) axis.push_back({8.0, 0.1 * i, 0.0});
    Tube t = make_tube(axis, 2.5, {20, 44, 9}, {-6.0, -8.0, -4.0});
    for (int x = 0; x <= 8; ++x) t.mask[static_cast<std::size_t>(t.grid.index(6 + x, 8 + 25, 4))] = 1;  // y = 25
    euclidean_distance_transform(t.grid, t.mask.data(), t.dt.data());
    const VoxelGraph g = voxel_graph(t.grid, t.mask.data(), t.dt.data());
    const Vec3d a{0.0, 30.0, 0.0}, b{8.0, 30.0, 0.0};
    const Centerline c = centerline(g, t.mask.data(), &a, &b);
    CHECK(c.length > 0.95 * polyline(t.axis));
    double sum = 0.0;
    for (const Vec3d& p : c.points) {
        CHECK(to_axis(t, p) < 2.0);
        sum += to_axis(t, p);
    }
    CHECK(sum / static_cast<double>(c.points.size()) < 0.5);
    CenterlineOptions plain;
    plain.power = 0.0;  // without the DT term the geodesic takes the bridge
    CHECK(centerline(g, t.mask.data(), &a, &b, plain).length < 0.5 * polyline(t.axis));
}

TEST_CASE("centerline tree of a Y: a stem and two arms from one branch point", "[centerline]") {
    std::vector<Vec3d> axis;
    for (int i = 0; i <= 300; ++i) axis.push_back({0.0, 0.0, 0.1 * i});
    for (int i = 300; i >= 1; --i) axis.push_back({-0.06 * i, 0.0, 30.0 + 0.08 * i});
    for (int i = 1; i <= 300; ++i) axis.push_back({0.06 * i, 0.0, 30.0 + 0.08 * i});
    const Tube t = make_tube(axis, 3.0, {50, 12, 64}, {-25.0, -6.0, -4.0});
    const VoxelGraph g = voxel_graph(t.grid, t.mask.data(), t.dt.data());
    const Vec3d root{0.0, 0.0, 0.0};
    const CenterlineTree tr = centerline_tree(g, t.mask.data(), &root);
    REQUIRE(tr.branches.size() == 3);
    CHECK(tr.parents == std::vector<std::int32_t>{-1, 0, 0});
    CHECK(tr.generations == std::vector<std::int32_t>{0, 1, 1});
    const Vec3d fork = tr.branches[1].points.front();
    CHECK(dist(fork, {0.0, 0.0, 30.0}) < 3.0);
    CHECK(dist(fork, tr.branches[0].points.back()) < 1e-9);
    CHECK(dist(fork, tr.branches[2].points.front()) < 1e-9);
    CHECK(tr.branches[0].length == Approx(30.0).margin(3.0));
    CHECK(tr.branches[1].length == Approx(30.0).margin(3.0));
}

TEST_CASE("centerline and centerline_tree report progress up to 1 and cancel", "[centerline]") {
    const Tube t = torus_segment();
    const VoxelGraph g = voxel_graph(t.grid, t.mask.data(), t.dt.data());
    for (int tree = 0; tree < 2; ++tree) {
        std::vector<double> seen;
        const Progress record = [&](double f) {
            seen.push_back(f);
            return true;
        };
        if (tree)
            centerline_tree(g, t.mask.data(), nullptr, {}, record);
        else
            centerline(g, t.mask.data(), nullptr, nullptr, {}, record);
        REQUIRE(seen.size() >= 4);
        CHECK(seen.front() == 0.0);
        CHECK(seen.back() == 1.0);
        CHECK(std::is_sorted(seen.begin(), seen.end()));
        const Progress stop = [](double f) { return f < 0.3; };
        if (tree)
            CHECK_THROWS_AS(centerline_tree(g, t.mask.data(), nullptr, {}, stop), Cancelled);
        else
            CHECK_THROWS_AS(centerline(g, t.mask.data(), nullptr, nullptr, {}, stop), Cancelled);
    }
}

TEST_CASE("polyline resampling and smoothing keep the ends; frames are orthonormal and do not twist", "[centerline]") {
    using namespace centerline_detail;
    std::vector<Vec3d> p{{0, 0, 0}, {1, 0, 0}, {1, 2, 0}, {4, 2, 1}};
    const auto r = resample(p, 0.3);
    CHECK(dist(r.front(), p.front()) == 0.0);
    CHECK(dist(r.back(), p.back()) == 0.0);
    for (std::size_t i = 1; i < r.size(); ++i) CHECK(dist(r[i], r[i - 1]) <= 0.3 + 1e-9);
    const auto s = smooth(r, 2.0);
    CHECK(dist(s.front(), p.front()) == 0.0);
    CHECK(dist(s.back(), p.back()) == 0.0);

    std::vector<Vec3d> helix;  // rotation-minimising frames along a helix stay orthonormal and change smoothly
    for (int i = 0; i <= 400; ++i) {
        const double a = 0.02 * i;
        helix.push_back({10 * std::cos(a), 10 * std::sin(a), 2.0 * a});
    }
    std::vector<Vec3d> t, u, v;
    rotation_minimising_frames(helix, t, u, v);
    auto dot = [](const Vec3d& a, const Vec3d& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
    for (std::size_t i = 0; i < helix.size(); ++i) {
        CHECK(dot(t[i], u[i]) == Approx(0.0).margin(1e-9));
        CHECK(dot(u[i], u[i]) == Approx(1.0));
        CHECK(dot(v[i], v[i]) == Approx(1.0));
        if (i) CHECK(dot(u[i], u[i - 1]) > 0.999);
    }
}

TEST_CASE("straightening samples the planes across the curve, trilinear", "[centerline]") {
    Grid g;
    g.dims = {30, 20, 10};
    g.spacing = {1.0, 0.5, 2.0};
    std::vector<float> f(static_cast<std::size_t>(g.voxel_count()));
    auto value = [](const Vec3d& p) { return 1.0 + 2.0 * p[0] - p[1] + 0.5 * p[2]; };  // linear: trilinear is exact
    for (std::int64_t z = 0; z < 10; ++z)
        for (std::int64_t y = 0; y < 20; ++y)
            for (std::int64_t x = 0; x < 30; ++x)
                f[static_cast<std::size_t>(g.index(x, y, z))] = static_cast<float>(value({1.0 * x, 0.5 * y, 2.0 * z}));
    std::vector<Vec3d> pts;
    for (int i = 0; i <= 20; ++i) pts.push_back({5.0 + i, 4.0 + 0.1 * i, 9.0});
    std::vector<Vec3d> t, u, v;
    rotation_minimising_frames(pts, t, u, v);
    const std::int64_t m = 3;
    const double step = 0.5;
    const auto out = straighten(g, f.data(), pts, u, v, m, step, -1.0f);
    REQUIRE(out.size() == pts.size() * 49);
    for (std::size_t k = 0; k < pts.size(); k += 5)
        for (std::int64_t b = 0; b < 7; ++b)
            for (std::int64_t a = 0; a < 7; ++a) {
                Vec3d p = pts[k];
                for (int c = 0; c < 3; ++c) p[static_cast<std::size_t>(c)] += step * ((a - m) * u[k][static_cast<std::size_t>(c)] + (b - m) * v[k][static_cast<std::size_t>(c)]);
                CHECK(out[k * 49 + static_cast<std::size_t>(b * 7 + a)] == Approx(value(p)).epsilon(1e-5));
            }
    CHECK(trilinear(g, f.data(), {-5.0, 0.0, 0.0}, -1.0) == -1.0);
}

// Tests for volrig/mesh.hpp's voxelize: against analytic volumes and voxel-by-voxel geometry, hole closing,
// orientation, progress and bad arguments; its triangles' distance tree (mesh/triangle_tree.hpp) against every
// triangle tried.
#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

#include "mesh/triangle_tree.hpp"
#include "volrig/mesh.hpp"

#include "mesh_fixture.hpp"

using namespace volrig;
namespace fs = std::filesystem;

// =================================================================================================================
// Voxelization
// =================================================================================================================

TEST_CASE("voxelize: an axis-aligned box gives exactly its cells, on the documented grid", "[mesh][voxelize]") {
    const Mesh box = QuadBox({0, 0, 0}, {1, 1, 1}).mesh();
    for (double r : {1.5, 0.0}) {
        INFO("closing radius " << r);
        VoxelizeOptions opt;
        opt.closing_radius = r;
        const Volume v = voxelize(box, 0.05, opt);
        CHECK(v.dtype == DType::UInt8);
        CHECK(v.grid.dims == std::array<std::int64_t, 3>{24, 24, 24});  // 20 cells + 2 padding each side
        CHECK(v.grid.spacing == Vec3{0.05, 0.05, 0.05});
        for (double o : v.grid.origin) CHECK(o == Approx(-0.075).margin(1e-12));
        CHECK(count(v) == 8000);
        // voxel-by-voxel: inside exactly when the centre is inside the box
        std::int64_t wrong = 0;
        for (std::int64_t z = 0; z < 24; ++z)
            for (std::int64_t y = 0; y < 24; ++y)
                for (std::int64_t x = 0; x < 24; ++x) {
                    const Vec3 c = centre_of(v, x, y, z);
                    const bool in = c[0] > 0 && c[0] < 1 && c[1] > 0 && c[1] < 1 && c[2] > 0 && c[2] < 1;
                    wrong += in != (v.data[static_cast<std::size_t>(v.grid.index(x, y, z))] == 1);
                }
        CHECK(wrong == 0);
    }
    // padding: 0 and rounded up
    CHECK(voxelize(box, 0.05, 0.0).grid.dims == std::array<std::int64_t, 3>{20, 20, 20});
    CHECK(voxelize(box, 0.05, 2.2).grid.dims == std::array<std::int64_t, 3>{26, 26, 26});
    CHECK(count(voxelize(box, 0.05, 0.0)) == 8000);
    // a box offset from the origin and flat in one axis relative to the voxel size
    const Volume thin = voxelize(QuadBox({10, -5, 3}, {10.5, -4.5, 3.2}).mesh(), 0.1);
    CHECK(thin.grid.dims == std::array<std::int64_t, 3>{9, 9, 6});
    CHECK(count(thin) == 5 * 5 * 2);
}

TEST_CASE("voxelize: rotated boxes and spheres match their analytic volumes", "[mesh][voxelize]") {
    const Mesh cube = rotated(QuadBox({-0.5, -0.5, -0.5}, {0.5, 0.5, 0.5}).mesh(), 0.3, 0.7, -1.1, {0.2, -3, 5});
    for (double h : {0.031, 0.047}) {
        const double want = 1.0 / (h * h * h);
        const double got = static_cast<double>(count(voxelize(cube, h)));
        INFO("voxel size " << h << ": " << got << " voxels, analytic " << want);
        CHECK(std::abs(got / want - 1) < 0.02);
    }
    const Mesh sphere = icosphere(3, 0.8, {1, 2, 3});
    for (double h : {0.02, 0.04}) {
        const double poly = volume_of(sphere) / (h * h * h), ball = 4.0 / 3.0 * M_PI * 0.512 / (h * h * h);
        for (double r : {1.5, 0.0}) {
            VoxelizeOptions opt;
            opt.closing_radius = r;
            const double got = static_cast<double>(count(voxelize(sphere, h, opt)));
            INFO("voxel size " << h << ", closing " << r << ": " << got << " voxels, polyhedron " << poly
                               << ", ball " << ball);
            CHECK(std::abs(got / poly - 1) < 0.01);
            CHECK(std::abs(got / ball - 1) < 0.03);
        }
    }
}

TEST_CASE("voxelize: voxel by voxel, a sphere is inside its inscribed ball and outside its circumscribed one",
          "[mesh][voxelize]") {
    const Vec3 c{0.3, -0.2, 0.1};
    const Mesh sphere = icosphere(3, 1.0, c);
    // inradius: the smallest distance from the centre to a face plane
    double inr = 1;
    for (const auto& t : sphere.triangles) {
        const Vec3 &a = sphere.vertices[t[0]], &b = sphere.vertices[t[1]], &d = sphere.vertices[t[2]];
        const Vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w{d[0] - a[0], d[1] - a[1], d[2] - a[2]};
        Vec3 n{u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        inr = std::min(inr, std::abs(n[0] * (a[0] - c[0]) + n[1] * (a[1] - c[1]) + n[2] * (a[2] - c[2])) / len);
    }
    REQUIRE(inr > 0.98);
    for (double r : {1.5, 0.0}) {
        VoxelizeOptions opt;
        opt.closing_radius = r;
        const Volume v = voxelize(sphere, 0.037, opt);
        std::int64_t wrong = 0, checked = 0;
        for (std::int64_t z = 0; z < v.grid.dims[2]; ++z)
            for (std::int64_t y = 0; y < v.grid.dims[1]; ++y)
                for (std::int64_t x = 0; x < v.grid.dims[0]; ++x) {
                    const Vec3 p = centre_of(v, x, y, z);
                    const double d = std::sqrt((p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
                                               (p[2] - c[2]) * (p[2] - c[2]));
                    const bool in = v.data[static_cast<std::size_t>(v.grid.index(x, y, z))] == 1;
                    if (d < inr) wrong += !in, ++checked;
                    if (d > 1.0) wrong += in, ++checked;
                }
        INFO("closing radius " << r);
        CHECK(checked > 0.95 * static_cast<double>(v.grid.voxel_count()));
        CHECK(wrong == 0);
    }
}

TEST_CASE("voxelize: a sphere with deleted triangles still comes out filled", "[mesh][voxelize][holes]") {
    const Mesh closed = icosphere(3);  // edges ~0.15: 5 voxels at voxel size 0.03
    Mesh holed = closed;
    std::set<std::uint32_t> used;
    std::vector<Tri> kept;
    int deleted = 0;
    for (std::size_t i = 0; i < closed.triangles.size(); ++i) {
        const Tri& t = closed.triangles[i];
        if (deleted < 6 && i % 97 == 13 && !used.count(t[0]) && !used.count(t[1]) && !used.count(t[2])) {
            used.insert(t.begin(), t.end());
            ++deleted;
            continue;
        }
        kept.push_back(t);
    }
    REQUIRE(deleted == 6);
    holed.triangles = kept;
    const double h = 0.03;
    const Volume a = voxelize(closed, h), b = voxelize(holed, h);
    const auto [same, kept_fraction] = agreement(a, b);
    INFO("closed " << count(a) << " voxels, with holes " << count(b));
    CHECK(kept_fraction >= 0.98);
    CHECK(same >= 0.995);
    CHECK(std::abs(static_cast<double>(count(a)) / (volume_of(closed) / (h * h * h)) - 1) < 0.01);
    // Why the closing exists: OpenVDB's own sign leaks through these holes and loses the interior.
    VoxelizeOptions vdb;
    vdb.closing_radius = 0;
    try {
        const Volume c = voxelize(holed, h, vdb);
        CHECK(agreement(a, c).second < 0.5);
    } catch (const Error& e) {
        CHECK(std::string(e.what()).find("encloses no voxel centre") != std::string::npos);
    }
    // A smaller closing radius lets the exterior in as well; a larger one keeps closing.
    VoxelizeOptions small, large;
    small.closing_radius = 1.0;
    large.closing_radius = 3.0;
    try {
        CHECK(agreement(a, voxelize(holed, h, small)).second < 0.5);
    } catch (const Error&) {
    }
    CHECK(agreement(a, voxelize(holed, h, large)).second >= 0.98);
}

TEST_CASE("voxelize: triangle orientation and self-overlap do not matter", "[mesh][voxelize]") {
    Mesh sphere = icosphere(2, 1.0);
    const Volume a = voxelize(sphere, 0.06);
    for (std::size_t i = 0; i < sphere.triangles.size(); i += 2)
        std::swap(sphere.triangles[i][1], sphere.triangles[i][2]);
    CHECK(voxelize(sphere, 0.06).data == a.data);
    // Two overlapping boxes: the union, except that both methods also fill the voxel row hugging each of the six
    // concave edges where a face of one box meets a face of the other (centres half a voxel from both faces).
    Mesh two = QuadBox({0, 0, 0}, {1, 1, 1}).mesh();
    const Mesh other = QuadBox({0.5, 0.5, 0.5}, {1.5, 1.5, 1.5}).mesh();
    for (auto t : other.triangles) two.triangles.push_back({t[0] + 8, t[1] + 8, t[2] + 8});
    two.vertices.insert(two.vertices.end(), other.vertices.begin(), other.vertices.end());
    auto in_box = [](const Vec3& p, double lo, double hi) {
        return p[0] > lo && p[0] < hi && p[1] > lo && p[1] < hi && p[2] > lo && p[2] < hi;
    };
    for (double r : {1.5, 0.0}) {
        VoxelizeOptions opt;
        opt.closing_radius = r;
        const Volume u = voxelize(two, 0.05, opt);
        std::int64_t lost = 0, extra = 0, extra_off_edge = 0;
        for (std::int64_t z = 0; z < u.grid.dims[2]; ++z)
            for (std::int64_t y = 0; y < u.grid.dims[1]; ++y)
                for (std::int64_t x = 0; x < u.grid.dims[0]; ++x) {
                    const Vec3 p = centre_of(u, x, y, z);
                    const bool want = in_box(p, 0, 1) || in_box(p, 0.5, 1.5);
                    const bool got = u.data[static_cast<std::size_t>(u.grid.index(x, y, z))] == 1;
                    lost += want && !got;
                    if (got && !want) {
                        ++extra;
                        // a concave edge: one coordinate 1 (a far face of the first box), another 0.5 (a near
                        // face of the second)
                        bool at_one = false, at_half = false;
                        for (double c : p) {
                            at_one = at_one || std::abs(c - 1) < 0.05;
                            at_half = at_half || std::abs(c - 0.5) < 0.05;
                        }
                        extra_off_edge += !(at_one && at_half);
                    }
                }
        INFO("closing radius " << r << ": " << extra << " voxels beyond the union");
        CHECK(lost == 0);
        CHECK(extra <= 6 * 11);
        CHECK(extra_off_edge == 0);
    }
}

TEST_CASE("voxelize: progress is reported in order and cancelling stops it", "[mesh][voxelize]") {
    const Mesh sphere = icosphere(3);
    for (double r : {1.5, 0.0}) {
        VoxelizeOptions opt;
        opt.closing_radius = r;
        check_voxelize_progress(sphere, 0.05, opt, 3, {0.0, 0.3, 0.7});
    }
}

TEST_CASE("voxelize: bad arguments and absurd grids are refused", "[mesh][voxelize][errors]") {
    const Mesh box = QuadBox().mesh();
    for (double h : {0.0, -0.1, std::nan(""), double(INFINITY)})
        expect_error<Error>([&] { voxelize(box, h); }, {"voxelize: voxel size must be finite and positive"});
    for (double p : {-1.0, 1001.0, std::nan("")})
        expect_error<Error>([&] { voxelize(box, 0.1, p); }, {"voxelize: padding must be between 0 and 1000"});
    for (double r : {0.2, 4.5, -1.0}) {
        VoxelizeOptions opt;
        opt.closing_radius = r;
        expect_error<Error>([&] { voxelize(box, 0.1, opt); }, {"closing radius must be 0 or between 0.5 and 4"});
    }
    expect_error<Error>([&] { voxelize(box, 1e-4); }, {"voxelize: the grid at voxel size 0.0001", "exceeds the limit"});
    expect_error<Error>([&] { voxelize(box, 1e-12); }, {"voxels along x", "limit is 2^28"});
    VoxelizeOptions tiny;
    tiny.max_bytes = 1000;
    expect_error<Error>([&] { voxelize(box, 0.1, tiny); }, {"exceeds the limit of 1000 bytes"});
    expect_error<Error>([&] { voxelize(Mesh{}, 0.1); }, {"voxelize: no vertices"});
    Mesh bad = box;
    bad.triangles[3][1] = 8;
    expect_error<Error>([&] { voxelize(bad, 0.1); }, {"voxelize: triangle 3 uses vertex 8 out of range"});
    bad = box;
    bad.vertices[2][0] = std::nan("");
    expect_error<Error>([&] { voxelize(bad, 0.1); }, {"vertex 2 has a non-finite coordinate"});
    // an open surface, and a box smaller than a voxel: nothing enclosed
    Mesh open;
    open.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    open.triangles = {{0, 1, 2}};
    expect_error<Error>([&] { voxelize(open, 0.1); }, {"encloses no voxel centre at voxel size 0.1"});
    expect_error<Error>([&] { voxelize(QuadBox({0, 0, 0}, {0.01, 0.01, 0.01}).mesh(), 0.1); }, {"encloses no voxel"});
}

TEST_CASE("voxelize's triangle tree: the nearest distance and any_within exactly as trying every triangle",
          "[mesh][voxelize]") {
    // The tree passes over a leaf's triangles whose planes lie beyond the bound; its answers must be those of the
    // brute force bit for bit (the same closest points, the least of them), at and near the surface, at vertices
    // and on edges, with and without a bound that cuts the search short.
    Mesh m = icosphere(2);  // with an overlapping box: curved and flat parts, coplanar neighbours
    const Mesh box = rotated(QuadBox({0, 0, 0}, {1, 1, 1}).mesh(), 0.3, 0.2, 0.1, {0.2, 0.1, 0.0});
    const auto first = static_cast<std::uint32_t>(m.vertices.size());
    m.vertices.insert(m.vertices.end(), box.vertices.begin(), box.vertices.end());
    for (auto t : box.triangles) m.triangles.push_back({t[0] + first, t[1] + first, t[2] + first});
    std::vector<openvdb::Vec3d> points;
    for (const auto& v : m.vertices) points.emplace_back(v[0] * 20, v[1] * 20, v[2] * 20);  // about voxel units
    const mesh_detail::TriangleTree tree(points, m.triangles);
    const auto brute = [&](const openvdb::Vec3d& p) {
        double best = std::numeric_limits<double>::infinity();
        for (const auto& t : m.triangles) {
            openvdb::Vec3d uvw;
            const openvdb::Vec3d q = openvdb::math::closestPointOnTriangleToPoint(points[t[0]], points[t[1]],
                                                                                 points[t[2]], p, uvw);
            best = std::min(best, (q - p).lengthSqr());
        }
        return best;
    };
    std::mt19937 rng(25);
    std::uniform_real_distribution<double> u(-1.0, 1.0), step(0.0, 3.0);
    std::vector<openvdb::Vec3d> queries;
    for (std::size_t k = 0; k < 400; ++k) {
        const openvdb::Vec3d& v = points[(k * 7919) % points.size()];
        queries.push_back(k % 4 == 0 ? v : v + openvdb::Vec3d(u(rng), u(rng), u(rng)) * step(rng));
        if (k % 8 == 1) queries.back() = (v + points[(k * 7919 + 1) % points.size()]) * 0.5;
    }
    for (const auto& p : queries) {
        const double want2 = brute(p);
        for (double bound : {0.5, 1.5, 4.0, 1e9}) {
            const double got = tree.nearest(p, bound);
            CHECK(got == (want2 < bound * bound ? std::sqrt(want2) : bound));
            CHECK(tree.any_within(p, bound) == (want2 < bound * bound));
        }
    }
}

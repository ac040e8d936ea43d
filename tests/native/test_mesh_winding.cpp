// Tests for volrig/mesh.hpp's generalized winding number (WindingNumber, is_closed) and voxelize's Winding and Auto
// methods: exact values on closed surfaces, the fast evaluation against the brute-force sum, open boxes, soups of
// overlapping parts, reversed orientation, and Auto giving Flood's mask bit for bit on closed meshes; the near
// field's angles summed as one product's argument (mesh_detail::AngleSum) against their atan2s summed.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "mesh/angle_sum.hpp"
#include "volrig/mesh.hpp"

#include "mesh_fixture.hpp"

using namespace volrig;

namespace {

/// The mesh with every triangle's orientation reversed.
Mesh flipped(Mesh m) {
    for (auto& t : m.triangles) std::swap(t[1], t[2]);
    return m;
}

/// Two meshes as one soup (no shared vertices).
Mesh soup(Mesh a, const Mesh& b) {
    const auto n = static_cast<std::uint32_t>(a.vertices.size());
    a.vertices.insert(a.vertices.end(), b.vertices.begin(), b.vertices.end());
    for (auto t : b.triangles) a.triangles.push_back({t[0] + n, t[1] + n, t[2] + n});
    return a;
}

/// The unit box without its top face (z = 1): QuadBox's second quad.
Mesh open_box() {
    QuadBox q;
    q.quads.erase(q.quads.begin() + 1);
    return q.mesh();
}

bool in_box(const Vec3& p, double lo, double hi) {
    return p[0] > lo && p[0] < hi && p[1] > lo && p[1] < hi && p[2] > lo && p[2] < hi;
}

std::int64_t mismatches(const Volume& v, const std::function<bool(const Vec3&)>& want) {
    std::int64_t wrong = 0;
    for (std::int64_t z = 0; z < v.grid.dims[2]; ++z)
        for (std::int64_t y = 0; y < v.grid.dims[1]; ++y)
            for (std::int64_t x = 0; x < v.grid.dims[0]; ++x)
                wrong += want(centre_of(v, x, y, z)) != (v.data[static_cast<std::size_t>(v.grid.index(x, y, z))] == 1);
    return wrong;
}

VoxelizeOptions with(VoxelizeMethod m) {
    VoxelizeOptions opt;
    opt.method = m;
    return opt;
}

}  // namespace

TEST_CASE("winding number: 1 inside and 0 outside a closed surface; fast within 1e-3 of the exact sum",
          "[mesh][winding]") {
    const Mesh cube = QuadBox({0, 0, 0}, {1, 1, 1}).mesh();
    const double sign = signed_volume6(cube) > 0 ? 1.0 : -1.0;
    const WindingNumber w(cube);
    CHECK(w({0.5, 0.5, 0.5}) == Approx(sign).margin(1e-9));
    CHECK(w({0.01, 0.98, 0.5}) == Approx(sign).margin(1e-9));
    CHECK(w({1.5, 0.5, 0.5}) == Approx(0).margin(1e-9));
    CHECK(w({-3, 7, 2}) == Approx(0).margin(1e-9));

    // Many triangles, so that the hierarchy's far-field expansions are used.
    const Mesh sphere = icosphere(4, 0.8, {0.1, -0.2, 0.3});
    REQUIRE(sphere.triangles.size() == 5120);
    // beta = 2 (voxelize's accuracy) is within a few thousandths; beta = 4 within 1e-3.
    const WindingNumber ws(sphere, 4.0), ws2(sphere);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-2, 2);
    double worst = 0, worst2 = 0, worst_vs_truth = 0;
    for (int i = 0; i < 2000; ++i) {
        const Vec3 p{u(rng), u(rng), u(rng)};
        const double fast = ws(p), exact = ws.exact(p);
        worst = std::max(worst, std::abs(fast - exact));
        worst2 = std::max(worst2, std::abs(ws2(p) - exact));
        const double r = std::hypot(p[0] - 0.1, p[1] + 0.2, p[2] - 0.3);
        if (std::abs(r - 0.8) > 0.02) worst_vs_truth = std::max(worst_vs_truth, std::abs(exact - (r < 0.8 ? 1 : 0)));
        // and on the cube
        const Vec3 q{u(rng) * 0.5 + 0.5, u(rng) * 0.5 + 0.5, u(rng) * 0.5 + 0.5};
        worst = std::max(worst, std::abs(w(q) - w.exact(q)));
    }
    INFO("largest |fast - exact| " << worst << " (beta 4), " << worst2 << " (beta 2); largest |exact - indicator| "
                                   << worst_vs_truth);
    CHECK(worst < 1e-3);
    CHECK(worst2 < 1e-2);
    CHECK(worst_vs_truth < 1e-6);
}

TEST_CASE("winding number: reversed orientation negates it; nested parts add up", "[mesh][winding]") {
    const Mesh sphere = icosphere(3, 1.0);
    const WindingNumber a(sphere), b(flipped(sphere));
    for (const Vec3& p : {Vec3{0, 0, 0}, Vec3{0.3, -0.5, 0.2}, Vec3{2, 0, 0}}) {
        CHECK(a(p) == Approx(-b(p)).margin(1e-3));
        CHECK(a.exact(p) == Approx(p[0] < 1.5 ? 1 : 0).margin(1e-9));
        CHECK(b.exact(p) == Approx(p[0] < 1.5 ? -1 : 0).margin(1e-9));
        CHECK(std::abs(a(p)) == Approx(p[0] < 1.5 ? 1 : 0).margin(1e-2));
    }
    const WindingNumber two(soup(sphere, icosphere(3, 0.5)), 4.0);
    CHECK(two.exact({0, 0, 0}) == Approx(2).margin(1e-9));
    CHECK(two.exact({0.75, 0, 0}) == Approx(1).margin(1e-9));
    CHECK(two({0, 0, 0}) == Approx(2).margin(1e-3));
    CHECK(two({0.75, 0, 0}) == Approx(1).margin(1e-3));
    expect_error<Error>([] { WindingNumber{Mesh{}}; }, {"winding number: the mesh has no triangles"});
    expect_error<Error>([&] { WindingNumber(sphere, 0.5); }, {"beta must be at least 1"});
}

TEST_CASE("is_closed: boundary and non-manifold edges", "[mesh][winding]") {
    CHECK(is_closed(QuadBox().mesh()));
    CHECK(is_closed(icosphere(2)));
    CHECK_FALSE(is_closed(open_box()));
    Mesh fin = QuadBox().mesh();  // a third triangle on an edge of the box
    fin.vertices.push_back({0.5, -1, -1});
    fin.triangles.push_back({0, 1, 8});
    fin.triangles.push_back({0, 8, 1});  // its back face: every edge but (0, 1) is then used twice
    CHECK_FALSE(is_closed(fin));
    CHECK(is_closed(soup(QuadBox().mesh(), icosphere(1))));
}

TEST_CASE("voxelize, winding: an open box keeps its inside (the flood method loses it)", "[mesh][voxelize][winding]") {
    const Mesh box = open_box();
    const Volume v = voxelize(box, 0.05, with(VoxelizeMethod::Winding));
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{24, 24, 24});
    CHECK(count(v) == 8000);
    CHECK(mismatches(v, [](const Vec3& p) { return in_box(p, 0, 1); }) == 0);
    // Auto sees the boundary edges and takes the winding number: the same mask.
    CHECK(voxelize(box, 0.05, with(VoxelizeMethod::Auto)).data == v.data);
    // The flood method lets the exterior in through the 20-voxel hole.
    try {
        CHECK(count(voxelize(box, 0.05, with(VoxelizeMethod::Flood))) < 4000);
    } catch (const Error& e) {
        CHECK(std::string(e.what()).find("encloses no voxel centre") != std::string::npos);
    }
    // reversed orientation: the same mask
    CHECK(voxelize(flipped(box), 0.05, with(VoxelizeMethod::Winding)).data == v.data);
}

TEST_CASE("voxelize, winding: a soup of two overlapping closed boxes gives their union exactly",
          "[mesh][voxelize][winding]") {
    const Mesh two = soup(QuadBox({0, 0, 0}, {1, 1, 1}).mesh(), QuadBox({0.5, 0.5, 0.5}, {1.5, 1.5, 1.5}).mesh());
    REQUIRE(is_closed(two));  // each part is closed, so Auto keeps the flood method
    const Volume v = voxelize(two, 0.05, with(VoxelizeMethod::Winding));
    CHECK(mismatches(v, [](const Vec3& p) { return in_box(p, 0, 1) || in_box(p, 0.5, 1.5); }) == 0);
    // one box reversed: the overlap has w = 0 (1 - 1); the rest is still inside
    const Mesh mixed = soup(QuadBox({0, 0, 0}, {1, 1, 1}).mesh(), flipped(QuadBox({0.5, 0.5, 0.5}, {1.5, 1.5, 1.5}).mesh()));
    const Volume m = voxelize(mixed, 0.05, with(VoxelizeMethod::Winding));
    CHECK(mismatches(m, [](const Vec3& p) { return in_box(p, 0, 1) != in_box(p, 0.5, 1.5); }) == 0);
    // two open boxes (tops missing), the second reversed and apart: both filled
    Mesh b = open_box();
    for (auto& p : b.vertices) p[0] += 1.5;
    const Volume o = voxelize(soup(open_box(), flipped(b)), 0.05, with(VoxelizeMethod::Winding));
    CHECK(mismatches(o, [](const Vec3& p) {
              return in_box(p, 0, 1) || (p[0] > 1.5 && p[0] < 2.5 && p[1] > 0 && p[1] < 1 && p[2] > 0 && p[2] < 1);
          }) == 0);
}

TEST_CASE("voxelize, auto: closed meshes give the flood method's mask bit for bit", "[mesh][voxelize][winding]") {
    const Mesh sphere = icosphere(3, 0.8, {1, 2, 3});
    const Mesh cube = rotated(QuadBox({-0.5, -0.5, -0.5}, {0.5, 0.5, 0.5}).mesh(), 0.3, 0.7, -1.1, {0.2, -3, 5});
    for (const Mesh* m : {&sphere, &cube})
        for (double r : {1.5, 0.0, 3.0}) {
            VoxelizeOptions flood, autom;
            flood.closing_radius = autom.closing_radius = r;
            autom.method = VoxelizeMethod::Auto;
            CHECK(voxelize(*m, 0.04, autom).data == voxelize(*m, 0.04, flood).data);
        }
    // and the winding number agrees with them on a closed sphere up to voxels whose centres hug the surface
    const Volume a = voxelize(sphere, 0.02), w = voxelize(sphere, 0.02, with(VoxelizeMethod::Winding));
    CHECK(agreement(a, w).first > 0.999);
    CHECK(std::abs(static_cast<double>(count(w)) / (volume_of(sphere) / (0.02 * 0.02 * 0.02)) - 1) < 0.005);
}

TEST_CASE("voxelize, winding: a sphere with a missing cap is filled voxel by voxel", "[mesh][voxelize][winding]") {
    // Every triangle with a vertex above z = 0.6 removed: a hole about 1.6 wide (27 voxels at 0.06).
    const Mesh sphere = icosphere(3, 1.0);
    Mesh cut = sphere;
    cut.triangles.clear();
    for (const auto& t : sphere.triangles)
        if (std::max({sphere.vertices[t[0]][2], sphere.vertices[t[1]][2], sphere.vertices[t[2]][2]}) < 0.6)
            cut.triangles.push_back(t);
    REQUIRE_FALSE(is_closed(cut));
    const Volume v = voxelize(cut, 0.06, with(VoxelizeMethod::Auto));
    const Volume full = voxelize(sphere, 0.06);
    // Below the cut the two agree; the cap region is bridged by the w = 0.5 surface spanning the hole.
    std::int64_t below_wrong = 0, below = 0;
    for (std::int64_t z = 0; z < v.grid.dims[2]; ++z)
        for (std::int64_t y = 0; y < v.grid.dims[1]; ++y)
            for (std::int64_t x = 0; x < v.grid.dims[0]; ++x) {
                const Vec3 p = centre_of(v, x, y, z);
                if (p[2] > 0.5) continue;
                const std::size_t i = static_cast<std::size_t>(v.grid.index(x, y, z));
                REQUIRE(i < full.data.size());
                below += full.data[i];
                below_wrong += full.data[i] != v.data[i];
            }
    INFO(below_wrong << " of " << below << " voxels below the cut differ");
    CHECK(below_wrong <= below / 500);
    // w = 0.5 on the flat disc spanning the hole's rim (z between 0.5 and 0.6): above it w < 0.5, so the cap is
    // cut off flat rather than restored, and nothing above z = 0.65 is inside.
    std::int64_t above = 0, cap = 0;
    for (std::int64_t z = 0; z < v.grid.dims[2]; ++z)
        for (std::int64_t y = 0; y < v.grid.dims[1]; ++y)
            for (std::int64_t x = 0; x < v.grid.dims[0]; ++x) {
                const double pz = centre_of(v, x, y, z)[2];
                const std::size_t i = static_cast<std::size_t>(v.grid.index(x, y, z));
                above += pz > 0.65 && v.data[i];
                cap += pz > 0.5 && pz < 0.55 && v.data[i] != full.data[i];
            }
    CHECK(above == 0);
    CHECK(cap < 500);
}

TEST_CASE("voxelize, winding: bad input is refused as with the flood method", "[mesh][voxelize][winding][errors]") {
    const VoxelizeOptions opt = with(VoxelizeMethod::Winding);
    Mesh bad = QuadBox().mesh();
    bad.vertices[2][0] = std::nan("");
    expect_error<Error>([&] { voxelize(bad, 0.1, opt); }, {"vertex 2 has a non-finite coordinate"});
    Mesh none = QuadBox().mesh();
    none.triangles.clear();
    expect_error<Error>([&] { voxelize(none, 0.1, opt); }, {"voxelize"});
    Mesh flat;
    flat.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    flat.triangles = {{0, 1, 2}};
    expect_error<Error>([&] { voxelize(flat, 0.1, opt); }, {"encloses no voxel centre at voxel size 0.1"});
    VoxelizeOptions unknown;
    unknown.method = static_cast<VoxelizeMethod>(7);
    expect_error<Error>([&] { voxelize(QuadBox().mesh(), 0.1, unknown); }, {"voxelize: unknown method"});
}

TEST_CASE("voxelize, winding and auto: progress in order, cancelling stops it", "[mesh][voxelize][winding]") {
    Mesh holed = icosphere(3);
    holed.triangles.resize(holed.triangles.size() - 40);  // open: Auto runs both methods
    for (VoxelizeMethod m : {VoxelizeMethod::Winding, VoxelizeMethod::Auto}) {
        check_voxelize_progress(holed, 0.04, with(m), 10, {0.0, 0.3, 0.6, 0.9});
    }
}

namespace {

/// The icosphere (levels, radius r) without the triangles that have a vertex above z = `cut`: an open cap.
Mesh cut_sphere(int levels, double r, double cut) {
    const Mesh sphere = icosphere(levels, r);
    Mesh m = sphere;
    m.triangles.clear();
    for (const auto& t : sphere.triangles)
        if (std::max({sphere.vertices[t[0]][2], sphere.vertices[t[1]][2], sphere.vertices[t[2]][2]}) < cut)
            m.triangles.push_back(t);
    return m;
}

}  // namespace

TEST_CASE("winding number: the far-field expansion is of second order (its error falls as the fifth power)",
          "[mesh][winding]") {
    // Seen from farther than beta times its radius the whole open cap is one cluster: fast gives the root's
    // expansion alone. The kernel falls as 1 / d^2 and each order of the expansion adds a power, so the error
    // against the exact sum falls as 1 / d^5 with the distance d when the zeroth, first and second order terms are
    // right (measured: by 32 to 43 times per doubling); any wrong term leaves 1 / d^4 (16 times) or slower.
    const Mesh cap = cut_sphere(3, 1.0, 0.3);
    const WindingNumber w(cap, 2.0);
    for (const Vec3& dir : {Vec3{0.3, -0.2, 1.0}, Vec3{1.0, 0.5, -0.4}, Vec3{-0.6, 0.8, 0.1}}) {
        const double len = std::hypot(dir[0], dir[1], dir[2]);
        auto error = [&](double d) {
            const Vec3 p{dir[0] / len * d, dir[1] / len * d, dir[2] / len * d};
            return std::abs(w(p) - w.exact(p));
        };
        const double e8 = error(8), e16 = error(16), e32 = error(32);
        INFO("errors at 8, 16, 32: " << e8 << " " << e16 << " " << e32);
        CHECK(e8 < 1e-4);
        CHECK(e8 / e16 > 24);
        CHECK(e16 / e32 > 24);
    }
}

TEST_CASE("voxelize, auto: on open meshes exactly the union of the flood's and the winding number's masks",
          "[mesh][voxelize][winding]") {
    // Auto evaluates the winding number only where the flood has not already found the inside; the union must
    // come out voxel for voxel as the two methods' masks computed apart.
    Mesh holes = icosphere(3, 1.0, {0.2, 0.1, -0.3});
    for (std::size_t k = 0; k < holes.triangles.size(); k += 37) holes.triangles.erase(holes.triangles.begin() + k);
    Mesh boxes = open_box();
    Mesh far_box = flipped(open_box());
    for (auto& p : far_box.vertices) p = {p[0] * 0.6 + 1.3, p[1] * 1.4 - 0.2, p[2] * 0.8 + 0.1};
    boxes = soup(boxes, far_box);
    const Mesh cap = cut_sphere(3, 1.0, 0.6);
    for (const Mesh* m : std::initializer_list<const Mesh*>{&holes, &boxes, &cap}) {
        REQUIRE_FALSE(is_closed(*m));
        for (double h : {0.05, 0.031}) {
            const Volume a = voxelize(*m, h, with(VoxelizeMethod::Auto));
            // (a method that finds no inside voxel throws: all outside)
            auto apart = [&](VoxelizeMethod method) {
                try {
                    return voxelize(*m, h, with(method)).data;
                } catch (const Error&) {
                    return std::vector<std::uint8_t>(a.data.size(), 0);
                }
            };
            const std::vector<std::uint8_t> f = apart(VoxelizeMethod::Flood), w = apart(VoxelizeMethod::Winding);
            REQUIRE(a.data.size() == f.size());
            REQUIRE(a.data.size() == w.size());
            std::int64_t wrong = 0, only_winding = 0, only_flood = 0;
            for (std::size_t i = 0; i < a.data.size(); ++i) {
                wrong += a.data[i] != (f[i] | w[i]);
                only_winding += w[i] && !f[i];
                only_flood += f[i] && !w[i];
            }
            INFO("voxel size " << h << ": " << only_winding << " voxels inside by the winding number alone, "
                                << only_flood << " by the flood alone");
            CHECK(wrong == 0);
            CHECK(only_winding > 0);  // the union is not one method's mask: both parts are exercised
        }
    }
}

TEST_CASE("winding number: the leaves' half solid angles summed as one product's argument equal their atan2s summed",
          "[mesh][winding]") {
    // mesh_detail::AngleSum (the exact near-field sums of WindingNumber's fast evaluation): one atan2 in all.
    std::mt19937 rng(53);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const auto check = [](const std::vector<std::pair<double, double>>& pairs) {
        mesh_detail::AngleSum sum;
        double want = 0;
        for (const auto& [y, x] : pairs) {
            sum.add(y, x);
            want += std::atan2(y, x);
        }
        CHECK(std::abs(sum.total() - want) <= 1e-13 * static_cast<double>(pairs.size() + 1));
    };
    for (int round = 0; round < 2000; ++round) {  // random pairs of every quadrant and size, up to 300 terms
        std::vector<std::pair<double, double>> pairs(static_cast<std::size_t>(1 + round % 300));
        const double scale = std::ldexp(1.0, round % 61 - 30);
        for (auto& p : pairs) p = {scale * u(rng), scale * u(rng)};
        check(pairs);
    }
    // Angles just under pi/2, all one way: the product turns round many times (each term near the branch cut of
    // the next); atan2's signed zeros, zero x, and sizes beyond 2^200 or under 2^-200 on their own.
    check(std::vector<std::pair<double, double>>(200, {1.0, 1e-9}));
    check(std::vector<std::pair<double, double>>(200, {-1.0, 1e-12}));
    check({{0.0, -1.0}, {-0.0, -1.0}, {0.0, 0.0}, {-0.0, -0.0}, {1.0, 0.0}, {-1.0, -0.0}, {2.0, 3.0}});
    check({{1e70, 1e70}, {1e-70, 3e-70}, {1.0, 1e300}, {1e-300, 1e-300}, {0.5, 0.5}});
    std::vector<std::pair<double, double>> big(100, {3e150, 4e150}), tiny(100, {-3e-150, 4e-150});
    check(big);
    check(tiny);
}

TEST_CASE("winding number: the fast sum against the exact one next to the surface of a fine sphere",
          "[mesh][winding]") {
    // Queries a thirtieth to a third of a triangle away from the surface, inside and outside: the near field's
    // triangles subtend large angles there (x <= 0 among them), their sum about 2 pi inside.
    const Mesh m = icosphere(4);  // 5,120 triangles about 0.066 across, sunk up to 0.0008 below the sphere
    const WindingNumber wn(m);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0), d(0.002, 0.02);
    for (int k = 0; k < 300; ++k) {
        Vec3 p{u(rng), u(rng), u(rng)};
        const double len = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        const double r = 1.0 + (k % 2 ? d(rng) : -d(rng));
        for (double& c : p) c *= r / len;
        const double fast = wn(p), exact = wn.exact(p);
        CHECK(std::abs(fast - exact) < 1e-2);  // the far field's own error, up to 0.004 here
        CHECK((fast >= 0.5) == (k % 2 == 0));
    }
}

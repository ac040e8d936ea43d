// Autorig and binding (docs/ALGORITHMS.md §6) on synthetic shapes with known structure and against brute-force
// references (the skeleton-tree of §5: test_tree.cpp). Also run under ASan/UBSan by scripts/test.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <set>

#include "volrig/rig.hpp"
#include "volrig/skeleton.hpp"
#include "volrig/tree.hpp"

#include "shape_fixture.hpp"

using namespace volrig;

namespace {

/// A union of capsules of one radius; segments in voxel coordinates (x, y, z).
Shape capsules(std::array<std::int64_t, 3> dims, const std::vector<std::array<double, 6>>& segs, double radius) {
    Shape s;
    s.grid.dims = dims;
    s.mask.assign(static_cast<std::size_t>(s.grid.voxel_count()), 0);
    for (std::int64_t z = 0; z < dims[2]; ++z)
        for (std::int64_t y = 0; y < dims[1]; ++y)
            for (std::int64_t x = 0; x < dims[0]; ++x)
                for (const auto& g : segs) {
                    const double d[3] = {g[3] - g[0], g[4] - g[1], g[5] - g[2]};
                    const double q[3] = {x - g[0], y - g[1], z - g[2]};
                    const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                    const double t = std::clamp((q[0] * d[0] + q[1] * d[1] + q[2] * d[2]) / dd, 0.0, 1.0);
                    double r2 = 0;
                    for (int a = 0; a < 3; ++a) r2 += (q[a] - t * d[a]) * (q[a] - t * d[a]);
                    if (r2 <= radius * radius) s.mask[static_cast<std::size_t>(s.grid.index(x, y, z))] = 1;
                }
    return s;
}

Points skeleton_of(const Shape& s, double tp) {
    const Skeleton sk = skeletonize(s.grid, s.mask.data(), Metric::Euclidean);
    Points p;
    const std::size_t n = sk.count_at(tp);
    p.ijk.resize(3 * n);
    p.radius.resize(n);
    skeleton_points(sk, n, p.ijk.data(), nullptr, p.radius.data(), nullptr);
    return p;
}

}  // namespace

TEST_CASE("rest_matrix is Blender's roll-0 bone matrix", "[rig]") {
    const auto m = rest_matrix({1, 2, 3}, {1, 5, 3});  // along +Y: identity rotation
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) CHECK(m[static_cast<std::size_t>(4 * c + r)] == Approx(c == r ? 1.0 : 0.0));
    CHECK(m[12] == 1);
    CHECK(m[13] == 2);
    CHECK(m[14] == 3);
    const auto down = rest_matrix({0, 0, 0}, {0, -1, 0});  // Blender's special case
    CHECK(down[0] == -1);
    CHECK(down[5] == -1);
    CHECK(down[10] == 1);
    CHECK_THROWS_AS(rest_matrix({0, 0, 0}, {0, 0, 0}), Error);
}

TEST_CASE("autorig turns a T into three chains that meet at the crossing", "[rig]") {
    // A T: a stem along z and a bar along x at the top.
    const Shape s = capsules({60, 16, 70}, {{30, 8, 4, 30, 8, 50}, {6, 8, 50, 54, 8, 50}}, 5.0);
    const Points p = skeleton_of(s, 0.3);
    const SkeletonTree t = skeleton_tree(s.grid, s.mask.data(), p.set(), TreeOptions{});
    AutorigDetail detail;
    const Rig rig = autorig(s.grid, s.mask.data(), p.set(), t.edges, AutorigOptions{}, {}, &detail);
    CHECK(rig.kind == "chains");
    std::vector<int> degree(rig.joints.size(), 0);
    for (const auto& b : rig.bones) {
        ++degree[static_cast<std::size_t>(b[0])];
        ++degree[static_cast<std::size_t>(b[1])];
    }
    CHECK(std::count(degree.begin(), degree.end(), 1) == 3);
    // the branching joint lies near the crossing (30, 8, 50)
    bool near_crossing = false;
    for (std::size_t j = 0; j < rig.joints.size(); ++j)
        if (degree[j] >= 3) {
            const double dx = rig.joints[j][0] - 30, dy = rig.joints[j][1] - 8, dz = rig.joints[j][2] - 50;
            near_crossing = near_crossing || std::sqrt(dx * dx + dy * dy + dz * dz) <= 1.5 * 5.0;
        }
    CHECK(near_crossing);
    // every end joint reaches an end of the T (within one radius)
    const double ends[3][3] = {{30, 8, 0}, {2, 8, 50}, {58, 8, 50}};
    for (std::size_t j = 0; j < rig.joints.size(); ++j) {
        if (degree[j] != 1) continue;
        double best = 1e9;
        for (const auto& e : ends) {
            const double dx = rig.joints[j][0] - e[0], dy = rig.joints[j][1] - e[1], dz = rig.joints[j][2] - e[2];
            best = std::min(best, std::sqrt(dx * dx + dy * dy + dz * dz));
        }
        CHECK(best <= 5.0);
    }
    CHECK(std::count(detail.kept.begin(), detail.kept.end(), 1) > 0);
    // binding: every point is bound, smooth weights sum to 1
    const Binding b = bind(s.grid, s.mask.data(), p.set(), rig, BindMode::Smooth);
    REQUIRE(b.bone.size() == p.radius.size());
    for (std::size_t i = 0; i < b.bone.size(); ++i) {
        CHECK(b.bone[i] >= 0);
        CHECK(b.weights[i][0] + b.weights[i][1] + b.weights[i][2] == Approx(1.0).epsilon(1e-6));
    }
}

TEST_CASE("check_rig names what is wrong", "[rig]") {
    Rig r;
    r.joints = {{0, 0, 0}, {0, 1, 0}};
    r.bones = {{0, 1}};
    r.names = {"a"};
    r.parents = {-1};
    CHECK_NOTHROW(check_rig(r));
    r.parents = {0};
    CHECK_THROWS_WITH(check_rig(r), Catch::Contains("parent"));
    r.parents = {-1};
    r.bones = {{0, 2}};
    CHECK_THROWS_WITH(check_rig(r), Catch::Contains("joint 2"));
    r.bones = {{0, 1}};
    r.joints[1] = {0, 0, 0};
    CHECK_THROWS_WITH(check_rig(r), Catch::Contains("zero length"));
}

TEST_CASE("autorig gives the same rig and runner-up with and without the detail", "[rig][autorig]") {
    // Without the detail autorig leaves out neutral chains when two body plans stand before them; the rig and its
    // runner-up must not change. A stick figure (head, trunk, arms, legs) and the T.
    const std::vector<std::array<double, 6>> figure = {{30, 10, 40, 30, 10, 75}, {30, 10, 75, 30, 10, 92},
                                                       {30, 10, 70, 8, 10, 50},  {30, 10, 70, 52, 10, 50},
                                                       {30, 10, 40, 22, 10, 4},  {30, 10, 40, 38, 10, 4}};
    const std::vector<std::array<double, 6>> tee = {{30, 8, 4, 30, 8, 50}, {6, 8, 50, 54, 8, 50}};
    for (const auto* segs : {&figure, &tee}) {
        const Shape s = capsules({60, 20, 98}, *segs, 4.0);
        const Points p = skeleton_of(s, 0.3);
        const SkeletonTree t = skeleton_tree(s.grid, s.mask.data(), p.set(), TreeOptions{});
        for (const bool up : {false, true}) {
            AutorigOptions opt;
            if (up) opt.up = std::array<double, 3>{0, 0, 1};
            AutorigDetail detail;
            const Rig with = autorig(s.grid, s.mask.data(), p.set(), t.edges, opt, {}, &detail);
            const Rig without = autorig(s.grid, s.mask.data(), p.set(), t.edges, opt, {}, nullptr);
            CHECK(with.kind == without.kind);
            CHECK(with.names == without.names);
            CHECK(with.joints == without.joints);
            CHECK(with.fit == without.fit);
            CHECK(with.runner_up == without.runner_up);
            CHECK(with.runner_up_fit == without.runner_up_fit);
            CHECK(detail.chains_fit != -1.0);  // the detail still reports the chains' fit
        }
    }
}

TEST_CASE("rigid tissue spanning joints keeps each point's bone even when one bone holds most of its volume",
          "[rig][bind]") {
    // An arm along x: upper 0-40, lower 40-70, hand 70-86. Its bone tissue runs unbroken through both joints (a fine
    // label map, where the humerus, forearm and hand bones touch), and the upper's points are thick (radius 6, the
    // others 2): the upper holds 96% of the component's ball volume, over the 90% that gives a component wholly
    // to one bone. The lower's and the hand's points lie far past their joints, so the component spans joints.
    const Shape s = capsules({90, 16, 16}, {{2, 8, 8, 88, 8, 8}}, 6.5);
    Rig rig;
    rig.joints = {{0, 8, 8}, {40, 8, 8}, {70, 8, 8}, {86, 8, 8}};
    rig.bones = {{0, 1}, {1, 2}, {2, 3}};
    rig.names = {"upper", "lower", "hand"};
    rig.parents = {-1, 0, 1};
    Points p;
    for (int x = 2; x <= 88; ++x) {
        p.ijk.insert(p.ijk.end(), {8, 8, x});
        p.radius.push_back(x < 40 ? 6.f : 2.f);
    }
    std::vector<std::uint8_t> rigid(s.mask.size(), 0);
    for (int x = 2; x <= 88; ++x) rigid[static_cast<std::size_t>(s.grid.index(x, 8, 8))] = 1;
    const Binding b = bind(s.grid, s.mask.data(), p.set(), rig, BindMode::Smooth, {}, rigid.data());
    for (std::size_t i = 0; i < p.radius.size(); ++i) {
        const int x = p.ijk[3 * i + 2];
        CHECK(b.weights[i][0] == 1.f);
        if (x < 38) CHECK(b.bone[i] == 0);
        if (x > 42 && x < 68) CHECK(b.bone[i] == 1);  // not carried off with the upper
        if (x > 72) CHECK(b.bone[i] == 2);
    }
    // The same bone ending just past the joint (within two of its points' radii): wholly the upper's, as before.
    std::fill(rigid.begin(), rigid.end(), 0);
    for (int x = 2; x <= 43; ++x) rigid[static_cast<std::size_t>(s.grid.index(x, 8, 8))] = 1;
    const Binding c = bind(s.grid, s.mask.data(), p.set(), rig, BindMode::Smooth, {}, rigid.data());
    for (std::size_t i = 0; i < p.radius.size(); ++i)
        if (p.ijk[3 * i + 2] <= 43) CHECK(c.bone[i] == 0);
}

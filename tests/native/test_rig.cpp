// Skeleton-tree, autorig and binding (docs/ALGORITHMS.md §5-6) on synthetic shapes with known structure and against
// brute-force references. Also run under ASan/UBSan by scripts/test.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <set>

#include "volrig/rig.hpp"
#include "volrig/skeleton.hpp"
#include "volrig/tree.hpp"

using namespace volrig;

namespace {

struct Shape {
    Grid grid;
    std::vector<std::uint8_t> mask;
    std::uint8_t at(int x, int y, int z) const { return mask[static_cast<std::size_t>(grid.index(x, y, z))]; }
};

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

struct Points {
    std::vector<std::int32_t> ijk;
    std::vector<float> radius;
    PointSet set() const { return PointSet{ijk.data(), radius.data(), radius.size()}; }
};

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

TEST_CASE("line_inside walks a 26-connected line and checks every voxel", "[tree]") {
    Shape s;
    s.grid.dims = {12, 10, 8};
    s.mask.assign(static_cast<std::size_t>(s.grid.voxel_count()), 1);
    const std::int32_t a[3] = {1, 2, 1}, b[3] = {6, 8, 10};  // [z, y, x]
    CHECK(line_inside(s.grid, s.mask.data(), a, b));
    CHECK(line_inside(s.grid, s.mask.data(), a, a));
    // A wall at x = 5 blocks every line crossing it.
    for (int z = 0; z < 8; ++z)
        for (int y = 0; y < 10; ++y) s.mask[static_cast<std::size_t>(s.grid.index(5, y, z))] = 0;
    CHECK_FALSE(line_inside(s.grid, s.mask.data(), a, b));
    const std::int32_t c[3] = {6, 8, 4};
    CHECK(line_inside(s.grid, s.mask.data(), a, c));
    const std::int32_t outside[3] = {1, 2, 12};
    CHECK_FALSE(line_inside(s.grid, s.mask.data(), a, outside));
}

TEST_CASE("skeleton_tree of points in a convex box is the Euclidean MST (alpha 1)", "[tree]") {
    std::mt19937 rng(11);
    Shape s;
    s.grid.dims = {16, 14, 12};
    s.mask.assign(static_cast<std::size_t>(s.grid.voxel_count()), 1);
    std::set<std::array<std::int32_t, 3>> unique;
    std::uniform_int_distribution<int> X(0, 15), Y(0, 13), Z(0, 11);
    while (unique.size() < 120) unique.insert({Z(rng), Y(rng), X(rng)});
    Points p;
    for (const auto& v : unique) {
        p.ijk.insert(p.ijk.end(), v.begin(), v.end());
        p.radius.push_back(1.f);
    }
    TreeOptions opt;
    opt.alpha = 1.0;
    opt.max_edge = 100.0;
    const SkeletonTree t = skeleton_tree(s.grid, s.mask.data(), p.set(), opt);
    REQUIRE(t.component_count == 1);
    REQUIRE(t.edges.size() == p.radius.size() - 1);
    // Prim's algorithm over all pairs.
    const std::size_t n = p.radius.size();
    auto dist = [&](std::size_t i, std::size_t j) {
        double d = 0;
        for (int a = 0; a < 3; ++a) d += double(p.ijk[3 * i + a] - p.ijk[3 * j + a]) * (p.ijk[3 * i + a] - p.ijk[3 * j + a]);
        return std::sqrt(d);
    };
    std::vector<double> best(n, 1e300);
    std::vector<char> in(n, 0);
    best[0] = 0;
    double total = 0;
    for (std::size_t k = 0; k < n; ++k) {
        std::size_t u = n;
        for (std::size_t i = 0; i < n; ++i)
            if (!in[i] && (u == n || best[i] < best[u])) u = i;
        in[u] = 1;
        total += best[u];
        for (std::size_t i = 0; i < n; ++i)
            if (!in[i]) best[i] = std::min(best[i], dist(u, i));
    }
    CHECK(std::accumulate(t.weights.begin(), t.weights.end(), 0.0) == Approx(total).epsilon(1e-12));
}

TEST_CASE("skeleton_tree keeps separate parts apart unless bridged", "[tree]") {
    Shape s;
    s.grid.dims = {30, 8, 8};
    s.mask.assign(static_cast<std::size_t>(s.grid.voxel_count()), 0);
    for (int z = 2; z < 6; ++z)
        for (int y = 2; y < 6; ++y)
            for (int x = 0; x < 30; ++x)
                if (x < 12 || x >= 15) s.mask[static_cast<std::size_t>(s.grid.index(x, y, z))] = 1;
    Points p;
    for (int x : {2, 5, 8, 11, 15, 18, 21}) {
        p.ijk.insert(p.ijk.end(), {4, 4, x});
        p.radius.push_back(1.5f);
    }
    TreeOptions opt;
    opt.max_edge = 10.0;
    const SkeletonTree t = skeleton_tree(s.grid, s.mask.data(), p.set(), opt);
    CHECK(t.component_count == 2);
    CHECK(t.edges.size() == 5);
    opt.bridge = true;
    const SkeletonTree b = skeleton_tree(s.grid, s.mask.data(), p.set(), opt);
    CHECK(b.component_count == 1);
    REQUIRE(b.edges.size() == 6);
    CHECK(std::count(b.bridged.begin(), b.bridged.end(), 1) == 1);
}

TEST_CASE("skeleton_tree rejects points off the mask", "[tree]") {
    Shape s;
    s.grid.dims = {4, 4, 4};
    s.mask.assign(64, 0);
    Points p{{1, 1, 1}, {1.f}};
    CHECK_THROWS_WITH(skeleton_tree(s.grid, s.mask.data(), p.set(), TreeOptions{}),
                      Catch::Contains("not an object voxel"));
}

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

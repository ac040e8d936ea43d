// Skeleton-tree (docs/ALGORITHMS.md §5) on synthetic shapes with known structure and against brute-force references.
// Also run under ASan/UBSan by scripts/test.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <set>

#include "volrig/tree.hpp"

#include "shape_fixture.hpp"

using namespace volrig;

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

// The feature transform and the plane-like measure (docs/ALGORITHMS.md §11) against brute force, and on plates.
#include <catch2/catch.hpp>

#include <cmath>
#include <queue>
#include <random>

#include "volrig/distance.hpp"
#include "volrig/medial.hpp"

using namespace volrig;

namespace {

struct P3 {
    std::int64_t x, y, z;
};

P3 padded_xyz(const Grid& g, std::int64_t i) {
    const std::int64_t px = g.dims[0] + 2, py = g.dims[1] + 2;
    return {i % px - 1, (i / px) % py - 1, i / (px * py) - 1};
}

bool object(const Grid& g, const std::vector<std::uint8_t>& m, std::int64_t x, std::int64_t y, std::int64_t z) {
    return x >= 0 && y >= 0 && z >= 0 && x < g.dims[0] && y < g.dims[1] && z < g.dims[2] && m[g.index(x, y, z)];
}

double dist(const Grid& g, P3 a, P3 b) {
    const double dx = double(a.x - b.x) * g.spacing[0], dy = double(a.y - b.y) * g.spacing[1],
                 dz = double(a.z - b.z) * g.spacing[2];
    return std::sqrt(dx * dx + dy * dy + dz * dz);
}

Grid random_grid(std::mt19937& rng, bool aniso) {
    std::uniform_int_distribution<int> dim(1, 9);
    std::uniform_real_distribution<double> u(0.5, 2.0);
    Grid g;
    g.dims = {dim(rng), dim(rng), dim(rng)};
    if (aniso) g.spacing = {u(rng), u(rng), u(rng)};
    return g;
}

std::vector<std::uint8_t> random_mask(const Grid& g, std::mt19937& rng, double density) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()));
    for (auto& v : m) v = u(rng) < density;
    return m;
}

/// All geodesic distances along the boundary (background voxels 6-adjacent to the object, the padded layer
/// included) from `seed`: plain Dijkstra over the whole boundary.
std::vector<double> boundary_distances(const Grid& g, const std::vector<std::uint8_t>& m, std::int64_t seed) {
    const std::int64_t px = g.dims[0] + 2, py = g.dims[1] + 2, pz = g.dims[2] + 2;
    auto on_boundary = [&](P3 p) {
        if (object(g, m, p.x, p.y, p.z)) return false;
        const int d6[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        for (const auto& d : d6)
            if (object(g, m, p.x + d[0], p.y + d[1], p.z + d[2])) return true;
        return false;
    };
    std::vector<double> out(static_cast<std::size_t>(px * py * pz), INFINITY);
    using Item = std::pair<double, std::int64_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> q;
    out[static_cast<std::size_t>(seed)] = 0;
    q.push({0, seed});
    while (!q.empty()) {
        auto [d, v] = q.top();
        q.pop();
        if (d > out[static_cast<std::size_t>(v)]) continue;
        const P3 p = padded_xyz(g, v);
        for (int dz = -1; dz <= 1; ++dz)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const P3 n{p.x + dx, p.y + dy, p.z + dz};
                    if (n.x < -1 || n.y < -1 || n.z < -1 || n.x > g.dims[0] || n.y > g.dims[1] || n.z > g.dims[2]) continue;
                    if (!on_boundary(n)) continue;
                    const std::int64_t u = ((n.z + 1) * py + (n.y + 1)) * px + (n.x + 1);
                    const double nd = d + dist(g, p, n);
                    if (nd < out[static_cast<std::size_t>(u)]) {
                        out[static_cast<std::size_t>(u)] = nd;
                        q.push({nd, u});
                    }
                }
    }
    return out;
}

}  // namespace

TEST_CASE("the feature transform gives a nearest background voxel", "[medial]") {
    std::mt19937 rng(7);
    for (int trial = 0; trial < 80; ++trial) {
        const Grid g = random_grid(rng, trial % 2 == 1);
        const auto m = random_mask(g, rng, 0.8);
        const auto dt = distance_transform(g, m.data(), Metric::Euclidean);
        const auto ft = feature_transform(g, m.data());
        for (std::int64_t z = 0; z < g.dims[2]; ++z)
            for (std::int64_t y = 0; y < g.dims[1]; ++y)
                for (std::int64_t x = 0; x < g.dims[0]; ++x) {
                    const P3 f = padded_xyz(g, ft[static_cast<std::size_t>(g.index(x, y, z))]);
                    INFO("trial " << trial << " voxel " << x << "," << y << "," << z);
                    REQUIRE(!object(g, m, f.x, f.y, f.z));
                    REQUIRE(dist(g, {x, y, z}, f) == Approx(dt[static_cast<std::size_t>(g.index(x, y, z))]).margin(1e-5));
                }
    }
}

TEST_CASE("the plane-like measure equals brute-force geodesics up to t", "[medial]") {
    std::mt19937 rng(11);
    for (int trial = 0; trial < 40; ++trial) {
        const Grid g = random_grid(rng, trial % 2 == 1);
        const auto m = random_mask(g, rng, 0.75);
        const double t = 2.5 + trial % 4;
        const auto ft = feature_transform(g, m.data());
        const auto d = plane_measure(g, m.data(), t);
        for (std::int64_t z = 0; z < g.dims[2]; ++z)
            for (std::int64_t y = 0; y < g.dims[1]; ++y)
                for (std::int64_t x = 0; x < g.dims[0]; ++x) {
                    const std::int64_t i = g.index(x, y, z);
                    if (!m[static_cast<std::size_t>(i)]) {
                        REQUIRE(d[static_cast<std::size_t>(i)] == 0.0f);
                        continue;
                    }
                    const auto geo = boundary_distances(g, m, ft[static_cast<std::size_t>(i)]);
                    double want = 0;
                    const P3 lower[3] = {{x - 1, y, z}, {x, y - 1, z}, {x, y, z - 1}};
                    for (const P3& l : lower)
                        if (object(g, m, l.x, l.y, l.z))
                            want = std::max(want, geo[static_cast<std::size_t>(ft[static_cast<std::size_t>(g.index(l.x, l.y, l.z))])]);
                    INFO("trial " << trial << " voxel " << x << "," << y << "," << z << " t " << t);
                    if (want > t)
                        REQUIRE(std::isinf(d[static_cast<std::size_t>(i)]));
                    else
                        REQUIRE(d[static_cast<std::size_t>(i)] == Approx(want).epsilon(1e-6));
                }
    }
}

TEST_CASE("a plate's plane-like voxels are one layer at its middle; a thin rod has none", "[medial]") {
    for (double sz : {1.0, 0.7}) {
        Grid g;
        g.dims = {100, 100, 20};
        g.spacing = {1.0, 1.0, sz};
        std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()), 0);
        for (std::int64_t z = 7; z < 13; ++z)
            for (std::int64_t y = 10; y < 90; ++y)
                for (std::int64_t x = 10; x < 90; ++x) m[static_cast<std::size_t>(g.index(x, y, z))] = 1;
        const auto d = plane_measure(g, m.data(), 5.0);
        // every column inside (away from the plate's rim by more than t) has exactly one, in the middle two slices
        for (std::int64_t y = 20; y < 80; ++y)
            for (std::int64_t x = 20; x < 80; ++x) {
                int n = 0;
                for (std::int64_t z = 0; z < 20; ++z)
                    if (d[static_cast<std::size_t>(g.index(x, y, z))] > 5.0f) {
                        ++n;
                        CHECK((z == 9 || z == 10));
                    }
                CHECK(n == 1);
            }
    }
    Grid g;
    g.dims = {30, 30, 60};
    std::vector<std::uint8_t> rod(static_cast<std::size_t>(g.voxel_count()), 0);
    for (std::int64_t z = 5; z < 55; ++z)
        for (std::int64_t y = 0; y < 30; ++y)
            for (std::int64_t x = 0; x < 30; ++x)
                rod[static_cast<std::size_t>(g.index(x, y, z))] = (x - 15) * (x - 15) + (y - 15) * (y - 15) < 10;
    const auto d = plane_measure(g, rod.data(), 12.0);  // round a rod of radius 3: ~10 < t
    CHECK(std::none_of(d.begin(), d.end(), [](float v) { return v > 12.0f; }));
}

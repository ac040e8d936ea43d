// Local thickness against a brute-force maximum over every object voxel's ball, and on shapes of known thickness.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>

#include "volrig/distance.hpp"
#include "volrig/reconstruct.hpp"
#include "volrig/thickness.hpp"

using namespace volrig;

namespace {

/// Max over every object voxel c with p in c's open ball of 2·DT(c): the definition, O(N²).
std::vector<float> brute_thickness(const Grid& g, const std::vector<float>& dt) {
    std::vector<float> out(dt.size(), 0.0f);
    const auto& d = g.dims;
    const auto& s = g.spacing;
    for (std::int64_t cz = 0; cz < d[2]; ++cz)
        for (std::int64_t cy = 0; cy < d[1]; ++cy)
            for (std::int64_t cx = 0; cx < d[0]; ++cx) {
                const float r = dt[g.index(cx, cy, cz)];
                if (!(r > 0)) continue;
                const double lim = open_ball_limit_sq(r);
                for (std::int64_t z = 0; z < d[2]; ++z)
                    for (std::int64_t y = 0; y < d[1]; ++y)
                        for (std::int64_t x = 0; x < d[0]; ++x) {
                            const std::int64_t dx = x - cx, dy = y - cy, dz = z - cz;
                            const double rest = lim - double(dy * dy) * s[1] * s[1] - double(dz * dz) * s[2] * s[2];
                            if (double(dx * dx) * s[0] * s[0] < rest)
                                out[g.index(x, y, z)] = std::max(out[g.index(x, y, z)], 2.0f * r);
                        }
            }
    return out;
}

Grid grid_of(std::array<std::int64_t, 3> dims, std::array<double, 3> spacing = {1, 1, 1}) {
    Grid g;
    g.dims = dims;
    g.spacing = spacing;
    return g;
}

/// Random blobs: a few random balls unioned, so shapes have thick and thin parts (pure noise is all thin).
std::vector<std::uint8_t> random_blobs(const Grid& g, std::mt19937& rng) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()), 0);
    const int balls = 1 + static_cast<int>(u(rng) * 4);
    for (int b = 0; b < balls; ++b) {
        const double c[3] = {u(rng) * double(g.dims[0]), u(rng) * double(g.dims[1]), u(rng) * double(g.dims[2])};
        const double r = 1.0 + u(rng) * 5.0;
        for (std::int64_t z = 0; z < g.dims[2]; ++z)
            for (std::int64_t y = 0; y < g.dims[1]; ++y)
                for (std::int64_t x = 0; x < g.dims[0]; ++x) {
                    const double dx = double(x) - c[0], dy = double(y) - c[1], dz = double(z) - c[2];
                    if (dx * dx + dy * dy + dz * dz < r * r) m[static_cast<std::size_t>(g.index(x, y, z))] = 1;
                }
    }
    for (auto& v : m)
        if (u(rng) < 0.03) v ^= 1;  // a little noise
    return m;
}

}  // namespace

TEST_CASE("local thickness equals the brute-force maximum over all balls", "[thickness]") {
    std::mt19937 rng(20261126);
    std::uniform_int_distribution<int> dim(1, 14);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int trial = 0; trial < 60; ++trial) {
        const bool aniso = trial % 2 == 1;
        Grid g = grid_of({dim(rng), dim(rng), dim(rng)});
        if (aniso) g.spacing = {0.4 + 1.6 * u(rng), 0.4 + 1.6 * u(rng), 0.4 + 1.6 * u(rng)};
        const auto mask = random_blobs(g, rng);
        const auto dt = distance_transform(g, mask.data(), Metric::Euclidean);
        const auto want = brute_thickness(g, dt);
        const auto got = local_thickness(g, mask.data());
        INFO("trial " << trial << " dims " << g.dims[0] << "x" << g.dims[1] << "x" << g.dims[2]);
        REQUIRE(got == want);
    }
}

TEST_CASE("on one or two slices of a deep object, local thickness is the brute-force maximum", "[thickness]") {
    // The DT of a deep object, and one or two of its slices as the grid (a drawing: one image, the DT of its
    // extrusion): the balls reach far deeper than the grid, whose tables stop at its depth.
    std::mt19937 rng(20261206);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int trial = 0; trial < 16; ++trial) {
        const Grid deep = grid_of({28 + trial % 3 * 6, 32 - trial % 4 * 3, 30});
        std::vector<std::uint8_t> m(static_cast<std::size_t>(deep.voxel_count()), 0);
        for (int b = 0; b < 4; ++b) {
            const double c[3] = {u(rng) * 30.0, u(rng) * 30.0, 8.0 + u(rng) * 14.0}, r = 3.0 + u(rng) * 11.0;
            for (std::int64_t z = 0; z < deep.dims[2]; ++z)
                for (std::int64_t y = 0; y < deep.dims[1]; ++y)
                    for (std::int64_t x = 0; x < deep.dims[0]; ++x) {
                        const double dx = double(x) - c[0], dy = double(y) - c[1], dz = double(z) - c[2];
                        if (dx * dx + dy * dy + dz * dz < r * r) m[static_cast<std::size_t>(deep.index(x, y, z))] = 1;
                    }
        }
        const auto all = distance_transform(deep, m.data(), Metric::Euclidean);
        const Grid g = grid_of({deep.dims[0], deep.dims[1], 1 + trial % 2});
        const auto from = all.begin() + deep.index(0, 0, 13);
        const std::vector<float> dt(from, from + g.voxel_count());
        INFO("trial " << trial << " dims " << g.dims[0] << "x" << g.dims[1] << "x" << g.dims[2]);
        REQUIRE(local_thickness_from_dt(g, dt.data()) == brute_thickness(g, dt));
    }
}

TEST_CASE("local thickness of plates is the plate's thickness within a voxel", "[thickness]") {
    for (int n : {1, 2, 3, 4, 5, 8, 11}) {
        for (double sz : {1.0, 0.5, 2.0}) {
            Grid g = grid_of({40, 30, n + 6}, {1.0, 1.0, sz});
            std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()), 0);
            for (std::int64_t z = 3; z < 3 + n; ++z)
                for (std::int64_t y = 0; y < 30; ++y)
                    for (std::int64_t x = 0; x < 40; ++x) m[static_cast<std::size_t>(g.index(x, y, z))] = 1;
            const auto t = local_thickness(g, m.data());
            INFO("plate of " << n << " voxels, z spacing " << sz);
            // Away from the array's x/y border (there out-of-array voxels are background), every plate voxel has
            // the plate's thickness: n voxels when n is even, n + 1 when odd (DT reaches the background's centre).
            const double want = sz * double(n % 2 == 0 ? n : n + 1);
            for (std::int64_t z = 3; z < 3 + n; ++z)
                CHECK(t[static_cast<std::size_t>(g.index(20, 15, z))] == Approx(want));
            CHECK(t[static_cast<std::size_t>(g.index(20, 15, 2))] == 0.0f);
        }
    }
}

TEST_CASE("a ball's local thickness is its diameter everywhere, from very few centres", "[thickness]") {
    const Grid g = grid_of({41, 41, 41});
    std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()), 0);
    std::int64_t count = 0;
    for (std::int64_t z = 0; z < 41; ++z)
        for (std::int64_t y = 0; y < 41; ++y)
            for (std::int64_t x = 0; x < 41; ++x)
                if ((x - 20) * (x - 20) + (y - 20) * (y - 20) + (z - 20) * (z - 20) <= 18 * 18) {
                    m[static_cast<std::size_t>(g.index(x, y, z))] = 1;
                    ++count;
                }
    const auto dt = distance_transform(g, m.data(), Metric::Euclidean);
    const auto centres = thickness_centres(g, dt.data());
    // The painting's work (the centres' ball volumes, ~r^3) is a small part of every voxel's: what is left is the
    // thin outer shell, where lattice balls of radius 1-2 voxels do not nest.
    double kept = 0, all = 0;
    for (std::size_t i = 0; i < dt.size(); ++i) all += double(dt[i]) * dt[i] * dt[i];
    for (std::int64_t i : centres) kept += double(dt[static_cast<std::size_t>(i)]) * dt[static_cast<std::size_t>(i)] * dt[static_cast<std::size_t>(i)];
    CHECK(kept < 0.05 * all);
    CHECK(std::find(centres.begin(), centres.end(), g.index(20, 20, 20)) != centres.end());
    const auto t = local_thickness_from_dt(g, dt.data());
    const float d = 2.0f * dt[static_cast<std::size_t>(g.index(20, 20, 20))];
    CHECK(d == Approx(2.0 * std::sqrt(325.0)));  // the nearest background voxels lie at (18, 1, 0) and the like
    // The central ball (|p - c|^2 < 325) is the whole object: every voxel gets its diameter.
    std::int64_t at_diameter = 0;
    for (std::size_t i = 0; i < t.size(); ++i)
        if (m[i]) at_diameter += t[i] == d;
    CHECK(at_diameter == count);
}

TEST_CASE("local thickness of an empty mask is zero; cancel stops it", "[thickness]") {
    const Grid g = grid_of({5, 6, 7});
    std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()), 0);
    const auto t = local_thickness(g, m.data());
    CHECK(std::all_of(t.begin(), t.end(), [](float v) { return v == 0.0f; }));
    m[3] = 1;
    CHECK_THROWS_AS(local_thickness(g, m.data(), [](double) { return false; }), Cancelled);
}

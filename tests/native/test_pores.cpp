// Pore networks (volrig/pores.hpp): the transport solve against hand-solved networks, and the extraction on
// geometries whose pores and throats are known, and the pore space's transform against brute force (docs/pores.md).
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>

#include "pores/pore_space.hpp"
#include "volrig/pores.hpp"

using namespace volrig;

namespace {

/// Two balls of radius r joined by a straight neck of radius rn along x, in a box.
std::vector<std::uint8_t> dumbbell(Grid& g, double r, double rn) {
    g.dims = {40, 20, 20};
    std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()), 0);
    const double c1 = 10.5, c2 = 29.5, cy = 10, cz = 10;
    for (std::int64_t z = 0; z < 20; ++z)
        for (std::int64_t y = 0; y < 20; ++y)
            for (std::int64_t x = 0; x < 40; ++x) {
                const double dy = static_cast<double>(y) - cy + 0.5, dz = static_cast<double>(z) - cz + 0.5;
                const double d1 = std::hypot(static_cast<double>(x) - c1, dy, dz);
                const double d2 = std::hypot(static_cast<double>(x) - c2, dy, dz);
                const bool neck = x > c1 && x < c2 && std::hypot(dy, dz) < rn;
                m[static_cast<std::size_t>(g.index(x, y, z))] = (d1 < r || d2 < r || neck) ? 1 : 0;
            }
    return m;
}

}  // namespace

TEST_CASE("network_rate: conductances in series and in parallel", "[pores]") {
    // 0 (inlet) -- g=2 -- 1 -- g=3 -- 2 (outlet): series 1/(1/2 + 1/3) = 1.2.
    const std::int32_t series[] = {0, 1, 1, 2};
    const double gs[] = {2.0, 3.0};
    const std::uint8_t in3[] = {1, 0, 0}, out3[] = {0, 0, 1};
    CHECK(network_rate(3, series, gs, 2, in3, out3) == Approx(1.2).epsilon(1e-12));
    // Plus a parallel branch 0 -- g=1 -- 3 -- g=1 -- 2 (0.5): 1.7. A node 4 joined to nothing is left out.
    const std::int32_t par[] = {0, 1, 1, 2, 0, 3, 3, 2};
    const double gp[] = {2.0, 3.0, 1.0, 1.0};
    const std::uint8_t in5[] = {1, 0, 0, 0, 0}, out5[] = {0, 0, 1, 0, 0};
    CHECK(network_rate(5, par, gp, 4, in5, out5) == Approx(1.7).epsilon(1e-12));
    // A Wheatstone bridge: 0 -> 1 (1), 0 -> 2 (2), 1 -> 2 (1), 1 -> 3 (2), 2 -> 3 (1); by hand 4 x1 = 1 + x2 and
    // 4 x2 = 2 + x1, so x1 = 0.4, x2 = 0.6 and the rate is 1 (1 - 0.4) + 2 (1 - 0.6) = 1.4.
    const std::int32_t br[] = {0, 1, 0, 2, 1, 2, 1, 3, 2, 3};
    const double gb[] = {1.0, 2.0, 1.0, 2.0, 1.0};
    const std::uint8_t in4[] = {1, 0, 0, 0}, out4[] = {0, 0, 0, 1};
    CHECK(network_rate(4, br, gb, 5, in4, out4) == Approx(1.4).epsilon(1e-12));
}

TEST_CASE("network_rate: no path from inlet to outlet gives 0", "[pores]") {
    const std::int32_t c[] = {0, 1, 2, 3};
    const double g[] = {1.0, 1.0};
    const std::uint8_t in[] = {1, 0, 0, 0}, out[] = {0, 0, 0, 1};
    CHECK(network_rate(4, c, g, 2, in, out) == 0.0);
    const double bad[] = {1.0, 0.0};
    CHECK_THROWS_AS(network_rate(4, c, bad, 2, in, out), Error);
}

TEST_CASE("extract_pore_network: two balls joined by a neck are two pores and one throat", "[pores]") {
    Grid g;
    const auto m = dumbbell(g, 7.0, 2.5);
    const PoreNetwork n = extract_pore_network(g, m.data());
    REQUIRE(n.pore_count() == 2);
    REQUIRE(n.throat_count() == 1);
    CHECK(n.throat_conns[0] == 0);
    CHECK(n.throat_conns[1] == 1);
    // The neck's inscribed diameter (2 x 2.5, on the voxel grid within a voxel); the balls' about 14.
    CHECK(n.throat_inscribed[0] == Approx(5.0).margin(1.0));
    CHECK(n.pore_inscribed[0] == Approx(14.0).margin(1.5));
    CHECK(n.pore_volume[0] + n.pore_volume[1] == Approx(static_cast<double>(n.pore_voxels)));
    // The pores' centres lie on the balls' centres (by symmetry of the regions, within a voxel).
    CHECK(std::abs(n.pore_coords[0] - 11.0) < 1.0);
    CHECK(std::abs(n.pore_coords[3] - 30.0) < 1.0);
    CHECK(n.throat_total_length[0] == Approx(19.0).margin(1.5));
    CHECK(n.pore_faces[0] == 0);
}

TEST_CASE("extract_pore_network: a tube across the box touches both x faces; errors", "[pores]") {
    Grid g;
    g.dims = {30, 11, 11};
    std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()), 0);
    for (std::int64_t z = 0; z < 11; ++z)
        for (std::int64_t y = 0; y < 11; ++y)
            for (std::int64_t x = 0; x < 30; ++x)
                m[static_cast<std::size_t>(g.index(x, y, z))] = std::hypot(y - 5.0, z - 5.0) <= 3.0 ? 1 : 0;
    const PoreNetwork n = extract_pore_network(g, m.data());
    REQUIRE(n.pore_count() >= 1);
    std::uint8_t faces = 0;
    for (auto f : n.pore_faces) faces |= f;
    CHECK(faces == (XMin | XMax));
    std::vector<std::uint8_t> none(m.size(), 0), all(m.size(), 1);
    CHECK_THROWS_AS(extract_pore_network(g, none.data()), Error);
    CHECK_THROWS_AS(extract_pore_network(g, all.data()), Error);
    CHECK_THROWS_AS(extract_pore_network(g, m.data(), [](double) { return false; }), Cancelled);
}

TEST_CASE("pore_distance: the open-faced transform against brute force; ranks", "[pores]") {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int trial = 0; trial < 20; ++trial) {
        Grid g;
        g.dims = {1 + static_cast<std::int64_t>(u(rng) * 9), 1 + static_cast<std::int64_t>(u(rng) * 9),
                  1 + static_cast<std::int64_t>(u(rng) * 9)};
        if (trial % 2) g.spacing = {0.5 + u(rng), 0.5 + u(rng), 0.5 + u(rng)};
        std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()));
        for (auto& v : m) v = u(rng) < 0.7 ? 1 : 0;
        m[0] = 0;  // at least one solid voxel
        pores_detail::PoreSpace s(g, m.data());
        pores_detail::pore_distance(s, m.data(), {});
        std::int64_t rank = 0;
        for (std::int64_t i = 0; i < g.voxel_count(); ++i) {
            REQUIRE(s.index.pore(i) == (m[static_cast<std::size_t>(i)] != 0));
            REQUIRE(s.index.rank(i) == rank);
            if (!m[static_cast<std::size_t>(i)]) {
                CHECK(s[i] == 0.0f);
                continue;
            }
            ++rank;
            // Brute force: the nearest solid voxel's centre inside the image (outside counts as pore).
            const std::int64_t x = i % g.dims[0], y = (i / g.dims[0]) % g.dims[1], z = i / (g.dims[0] * g.dims[1]);
            double best = 1e300;
            for (std::int64_t j = 0; j < g.voxel_count(); ++j) {
                if (m[static_cast<std::size_t>(j)]) continue;
                const double dx = static_cast<double>(j % g.dims[0] - x) * g.spacing[0];
                const double dy = static_cast<double>((j / g.dims[0]) % g.dims[1] - y) * g.spacing[1];
                const double dz = static_cast<double>(j / (g.dims[0] * g.dims[1]) - z) * g.spacing[2];
                best = std::min(best, dx * dx + dy * dy + dz * dz);
            }
            CHECK(s[i] == Approx(std::sqrt(best)).epsilon(1e-5));
        }
        CHECK(s.index.count() == rank);
    }
}

// Feature tracking: scan-order components (6- and 26-connected) equal a brute-force flood fill numbered by first
// voxel; a step's features drop the small ones and renumber the rest in order; point overlaps with every voxel as a
// point of weight 1 equal the brute-force |a ∩ b|.
#include <catch2/catch.hpp>

#include <array>
#include <map>
#include <random>
#include <vector>

#include "volrig/components.hpp"
#include "volrig/track.hpp"

using namespace volrig;

namespace {

Grid grid_of(std::int64_t nx, std::int64_t ny, std::int64_t nz) {
    Grid g;
    g.dims = {nx, ny, nz};
    return g;
}

std::vector<std::uint8_t> random_mask(const Grid& g, double p, unsigned seed) {
    std::mt19937 rng(seed);
    std::bernoulli_distribution on(p);
    std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()));
    for (auto& v : m) v = on(rng) ? 1 : 0;
    return m;
}

/// Flood fill from each unlabelled object voxel in index order: the components numbered by first voxel.
std::vector<std::int32_t> flood_labels(const Grid& g, const std::vector<std::uint8_t>& m, int connectivity) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    std::vector<std::int32_t> lab(m.size(), 0);
    std::int32_t next = 0;
    for (std::int64_t s = 0; s < g.voxel_count(); ++s) {
        if (!m[static_cast<std::size_t>(s)] || lab[static_cast<std::size_t>(s)]) continue;
        std::vector<std::int64_t> stack{s};
        lab[static_cast<std::size_t>(s)] = ++next;
        while (!stack.empty()) {
            const std::int64_t v = stack.back();
            stack.pop_back();
            const std::int64_t x = v % nx, y = (v / nx) % ny, z = v / (nx * ny);
            for (int dz = -1; dz <= 1; ++dz)
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        if (std::abs(dx) + std::abs(dy) + std::abs(dz) == 0) continue;
                        if (connectivity == 6 && std::abs(dx) + std::abs(dy) + std::abs(dz) != 1) continue;
                        const std::int64_t X = x + dx, Y = y + dy, Z = z + dz;
                        if (X < 0 || Y < 0 || Z < 0 || X >= nx || Y >= ny || Z >= nz) continue;
                        const auto j = static_cast<std::size_t>((Z * ny + Y) * nx + X);
                        if (m[j] && !lab[j]) lab[j] = next, stack.push_back(static_cast<std::int64_t>(j));
                    }
        }
    }
    return lab;
}

}  // namespace

TEST_CASE("scan-order components equal a flood fill numbered by first voxel", "[track][components]") {
    const Grid g = grid_of(11, 7, 9);
    for (unsigned seed = 0; seed < 12; ++seed)
        for (const int connectivity : {6, 26}) {
            const auto m = random_mask(g, seed % 2 ? 0.3 : 0.15, seed);
            const Components c = scan_components(g, m.data(), connectivity);
            const auto ref = flood_labels(g, m, connectivity);
            REQUIRE(c.labels == ref);
            std::vector<std::int64_t> sizes(c.sizes.size(), 0);
            for (const auto l : ref)
                if (l) ++sizes[static_cast<std::size_t>(l) - 1];
            REQUIRE(c.sizes == sizes);
        }
    const auto m = random_mask(g, 0.2, 1);
    REQUIRE_THROWS_WITH(scan_components(g, m.data(), 18), Catch::Contains("6 or 26"));
}

TEST_CASE("a step's features keep components of min_size voxels, renumbered in order", "[track]") {
    const Grid g = grid_of(13, 9, 8);
    const auto m = random_mask(g, 0.25, 7);
    const auto ref = flood_labels(g, m, 6);
    std::map<std::int32_t, std::int64_t> size;
    for (const auto l : ref)
        if (l) ++size[l];
    const Features f = track_features(g, m.data(), 3);
    std::map<std::int32_t, std::int32_t> renumber;
    for (const auto& [l, n] : size)
        if (n >= 3) renumber[l] = static_cast<std::int32_t>(renumber.size()) + 1;
    REQUIRE(f.sizes.size() == renumber.size());
    REQUIRE(renumber.size() > 2);
    for (std::size_t i = 0; i < ref.size(); ++i) {
        const auto it = renumber.find(ref[i]);
        REQUIRE(f.labels[i] == (it == renumber.end() ? 0 : it->second));
    }
    REQUIRE(f.centroids.size() == 3 * f.sizes.size());
}

TEST_CASE("point overlaps of every voxel at weight 1 are the exact intersections", "[track]") {
    const Grid g = grid_of(10, 10, 10);
    const Features a = track_features(g, random_mask(g, 0.3, 3).data(), 1);
    const Features b = track_features(g, random_mask(g, 0.3, 4).data(), 1);
    std::vector<std::int64_t> index;
    std::vector<std::int32_t> label;
    std::map<std::pair<std::int32_t, std::int32_t>, double> ref;
    for (std::size_t i = 0; i < a.labels.size(); ++i) {
        if (!a.labels[i]) continue;
        index.push_back(static_cast<std::int64_t>(i));
        label.push_back(a.labels[i]);
        if (b.labels[i]) ref[{a.labels[i], b.labels[i]}] += 1;
    }
    const std::vector<float> ones(index.size(), 1.0f);
    const auto nb = static_cast<std::int32_t>(b.sizes.size());
    const auto overlaps = [&](std::int32_t count) {
        return point_overlaps(g, b.labels.data(), count, index.data(), label.data(), ones.data(), index.size());
    };
    const Overlaps o = overlaps(nb);
    std::map<std::pair<std::int32_t, std::int32_t>, double> got;
    for (std::size_t k = 0; k < o.a.size(); ++k) got[{o.a[k], o.b[k]}] = o.weight[k];
    REQUIRE(got == ref);
    for (std::size_t f = 1; f < o.totals.size(); ++f)
        REQUIRE(o.totals[f] == static_cast<double>(a.sizes[f - 1]));
    REQUIRE_THROWS_WITH(overlaps(1), Catch::Contains("exceeds"));
    index[0] = g.voxel_count();
    REQUIRE_THROWS_WITH(overlaps(nb), Catch::Contains("off the grid"));
}

// Feature tracking: scan-order components (6- and 26-connected) equal a brute-force flood fill numbered by first
// voxel; a step's features drop the small ones and renumber the rest in order; step overlaps with every voxel as a
// point of weight 1 equal the brute-force |a ∩ b|, and of weighted points (both ways) a brute-force sum.
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

namespace {

using Pairs = std::map<std::pair<std::int32_t, std::int32_t>, double>;

Pairs pairs_of(const Overlaps& o) {
    Pairs got;
    for (std::size_t k = 0; k < o.a.size(); ++k) {
        if (k) REQUIRE(std::make_pair(o.a[k - 1], o.b[k - 1]) < std::make_pair(o.a[k], o.b[k]));  // sorted, once
        got[{o.a[k], o.b[k]}] = o.overlap[k];
    }
    return got;
}

/// A step as points: every feature voxel in index order (labels narrowed to L), with random weights when `weighted`.
template <class L>
struct Side {
    std::vector<L> labels, label;
    std::vector<std::uint32_t> index;
    std::vector<float> weight;
    std::vector<double> totals;
    std::vector<std::int64_t> sizes;
    StepPoints<std::uint32_t, L> points(bool weighted) const {
        StepPoints<std::uint32_t, L> p;
        p.labels = labels.data(), p.count = static_cast<std::int32_t>(sizes.size());
        p.index = index.data(), p.label = label.data(), p.n = index.size(), p.sizes = sizes.data();
        if (weighted) p.weight = weight.data(), p.totals = totals.data();
        return p;
    }
};

template <class L>
Side<L> side_of(const Features& f, std::uint32_t seed, double keep) {
    Side<L> s;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    s.sizes = f.sizes;
    s.totals.assign(f.sizes.size() + 1, 0.0);
    for (std::size_t i = 0; i < f.labels.size(); ++i) {
        s.labels.push_back(static_cast<L>(f.labels[i]));
        if (!f.labels[i] || u(rng) >= keep) continue;
        s.index.push_back(static_cast<std::uint32_t>(i));
        s.label.push_back(static_cast<L>(f.labels[i]));
        s.weight.push_back(static_cast<float>(0.5 + u(rng) * 4));
        s.totals[static_cast<std::size_t>(f.labels[i])] += s.weight.back();
    }
    return s;
}

/// The brute force: each direction's weights summed per pair point by point, scaled, the larger kept.
template <class L>
Pairs brute(const Side<L>& a, const Side<L>& b, bool weighted, bool both) {
    Pairs ab, ba, out;
    for (std::size_t i = 0; i < a.index.size(); ++i)
        if (const L y = b.labels[a.index[i]]) ab[{a.label[i], y}] += weighted ? a.weight[i] : 1.0;
    if (both)
        for (std::size_t i = 0; i < b.index.size(); ++i)
            if (const L x = a.labels[b.index[i]]) ba[{x, b.label[i]}] += b.weight[i];
    for (auto& [k, w] : ab) out[k] = weighted ? w * static_cast<double>(a.sizes[k.first - 1]) / a.totals[k.first] : w;
    for (auto& [k, w] : ba) {
        const double s = w * static_cast<double>(b.sizes[k.second - 1]) / b.totals[k.second];
        out[k] = std::max(out.count(k) ? out[k] : 0.0, s);
    }
    return out;
}

}  // namespace

TEST_CASE("step overlaps of every voxel at weight 1 are the exact intersections", "[track]") {
    const Grid g = grid_of(10, 10, 10);
    const Features fa = track_features(g, random_mask(g, 0.3, 3).data(), 1);
    const Features fb = track_features(g, random_mask(g, 0.3, 4).data(), 1);
    const Side<std::int32_t> a = side_of<std::int32_t>(fa, 1, 1.0), b = side_of<std::int32_t>(fb, 2, 1.0);
    Pairs ref;
    for (std::size_t i = 0; i < fa.labels.size(); ++i)
        if (fa.labels[i] && fb.labels[i]) ref[{fa.labels[i], fb.labels[i]}] += 1;
    REQUIRE(ref.size() > 5);
    REQUIRE(pairs_of(step_overlaps(g, a.points(false), b.points(false), false)) == ref);
    auto pa = a.points(false), pb = b.points(false);
    pb.count = 1;  // b's labels then exceed its count
    REQUIRE_THROWS_WITH(step_overlaps(g, pa, pb, false), Catch::Contains("above the other step's feature count"));
    auto index = a.index;
    index[0] = static_cast<std::uint32_t>(g.voxel_count());
    pa.index = index.data();
    REQUIRE_THROWS_WITH(step_overlaps(g, pa, b.points(false), false), Catch::Contains("off the grid"));
    auto label = a.label;
    label[1] = 0;
    pa = a.points(false), pa.label = label.data();
    REQUIRE_THROWS_WITH(step_overlaps(g, pa, b.points(false), false), Catch::Contains("no feature"));
}

TEST_CASE("step overlaps of weighted points equal a brute force both ways, in every label type", "[track]") {
    for (std::uint32_t seed = 0; seed < 12; ++seed) {
        const Grid g = grid_of(7 + seed % 5, 9, 6 + seed % 3);
        const Features fa = track_features(g, random_mask(g, 0.45, 10 + seed).data(), 1);
        const Features fb = track_features(g, random_mask(g, 0.45, 50 + seed).data(), 1);
        REQUIRE((fa.sizes.size() < 255 && fb.sizes.size() < 255));
        const double keep = seed % 3 == 0 ? 1.0 : 0.3;
        const auto check = [&](auto tag) {
            using L = decltype(tag);
            const Side<L> a = side_of<L>(fa, seed, keep), b = side_of<L>(fb, seed + 99, keep);
            for (const bool both : {false, true}) {
                const Pairs got = pairs_of(step_overlaps(g, a.points(true), b.points(true), both));
                const Pairs want = brute(a, b, true, both);
                REQUIRE(got == want);  // exactly: the weights are summed in point order as a plain loop sums them
            }
            REQUIRE(pairs_of(step_overlaps(g, a.points(false), b.points(false), false)) == brute(a, b, false, false));
        };
        check(std::uint8_t{});
        check(std::uint16_t{});
        check(std::int32_t{});
    }
}

TEST_CASE("run overlaps equal the exact intersections", "[track]") {
    for (unsigned seed = 0; seed < 6; ++seed) {
        const Grid g = grid_of(9 + seed, 7, 5 + seed % 3);
        const Features fa = track_features(g, random_mask(g, 0.5, 200 + seed).data(), 1);
        const Features fb = track_features(g, random_mask(g, 0.5, 300 + seed).data(), 1);
        struct Columns {
            std::vector<std::int32_t> row, x0, x1, label;
        };
        const auto runs_of = [&](const Features& f, Columns& c) {  // maximal runs of one label along x
            const std::int64_t nx = g.dims[0];
            for (std::int64_t i = 0; i < g.voxel_count(); ++i) {
                const std::int32_t l = f.labels[static_cast<std::size_t>(i)];
                if (!l) continue;
                if (i % nx && f.labels[static_cast<std::size_t>(i - 1)] == l) {
                    ++c.x1.back();
                    continue;
                }
                c.row.push_back(static_cast<std::int32_t>(i / nx));
                c.x0.push_back(static_cast<std::int32_t>(i % nx));
                c.x1.push_back(static_cast<std::int32_t>(i % nx + 1));
                c.label.push_back(l);
            }
            Runs r;
            r.row = c.row.data(), r.x0 = c.x0.data(), r.x1 = c.x1.data(), r.label = c.label.data();
            r.n = c.row.size(), r.count = static_cast<std::int32_t>(f.sizes.size());
            return r;
        };
        Columns ca, cb;
        const Runs ra = runs_of(fa, ca), rb = runs_of(fb, cb);
        Pairs ref;
        for (std::size_t i = 0; i < fa.labels.size(); ++i)
            if (fa.labels[i] && fb.labels[i]) ref[{fa.labels[i], fb.labels[i]}] += 1;
        REQUIRE(ref.size() > 3);
        REQUIRE(pairs_of(run_overlaps(ra, rb)) == ref);
        Runs bad = rb;
        bad.count = 1;
        REQUIRE_THROWS_WITH(run_overlaps(ra, bad), Catch::Contains("no feature of its step"));
    }
}

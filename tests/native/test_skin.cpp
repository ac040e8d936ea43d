// Skin weights by geodesic distance through the object (volrig/skin.hpp).
#include <catch2/catch.hpp>

#include <cmath>

#include "volrig/skin.hpp"

using namespace volrig;

namespace {

struct Solid {
    Grid g;
    std::vector<std::uint8_t> mask;
    Solid(std::int64_t nx, std::int64_t ny, std::int64_t nz) {
        g.dims = {nx, ny, nz};
        mask.assign(static_cast<std::size_t>(g.voxel_count()), 0);
    }
    void box(std::int64_t x0, std::int64_t x1, std::int64_t y0, std::int64_t y1, std::int64_t z0, std::int64_t z1) {
        for (std::int64_t z = z0; z <= z1; ++z)
            for (std::int64_t y = y0; y <= y1; ++y)
                for (std::int64_t x = x0; x <= x1; ++x) mask[static_cast<std::size_t>(g.index(x, y, z))] = 1;
    }
};

Rig chain(std::vector<std::array<double, 3>> joints) {
    Rig r;
    r.joints = joints;
    for (std::size_t b = 0; b + 1 < joints.size(); ++b) {
        r.bones.push_back({static_cast<std::int32_t>(b), static_cast<std::int32_t>(b + 1)});
        r.names.push_back("b" + std::to_string(b));
        r.parents.push_back(static_cast<std::int32_t>(b) - 1);
    }
    return r;
}

/// Point i's weight for bone b (0 when b is not in its row).
float weight(const SkinWeights& w, std::size_t i, std::int32_t b) {
    for (auto k = w.indptr[i]; k < w.indptr[i + 1]; ++k)
        if (w.bone[static_cast<std::size_t>(k)] == b) return w.weight[static_cast<std::size_t>(k)];
    return 0.f;
}

}  // namespace

TEST_CASE("skin weights: a bar of two bones blends at the joint only", "[skin]") {
    Solid s(61, 9, 9);  // x from 0 to 60, radius 4 around y = z = 4
    s.box(0, 60, 0, 8, 0, 8);
    const Rig rig = chain({{2, 4, 4}, {30, 4, 4}, {58, 4, 4}});
    const std::vector<std::array<double, 3>> pts = {{5, 4, 8.5}, {55, 0, 4}, {30, 4, 8.5}, {24, 8.5, 4}, {36, -0.5, 4}};
    const SkinWeights w = skin_weights(s.g, s.mask.data(), rig, pts);
    REQUIRE(w.indptr.size() == pts.size() + 1);
    for (std::size_t i = 0; i < pts.size(); ++i) {
        float sum = 0;
        for (auto k = w.indptr[i]; k < w.indptr[i + 1]; ++k) sum += w.weight[static_cast<std::size_t>(k)];
        CHECK(sum == Approx(1.0f));
        CHECK(w.outside[i] == 0);
    }
    CHECK(weight(w, 0, 0) == 1.0f);  // far ends: one bone
    CHECK(weight(w, 1, 1) == 1.0f);
    CHECK(weight(w, 2, 0) == Approx(0.5f).margin(0.05));  // on the joint plane: half and half
    CHECK(weight(w, 3, 0) > weight(w, 3, 1));             // either side of it: the own bone dominates, both blend
    CHECK(weight(w, 3, 1) > 0.05f);
    CHECK(weight(w, 4, 1) > weight(w, 4, 0));
}

TEST_CASE("skin weights: a bone is near only what it reaches inside the object", "[skin]") {
    // A U: two bars along x joined at x = 0..4, a gap of two voxels between them (y 0..4 and y 7..11). A point on
    // the lower bar's inner face near the free end is 3 voxels from the upper bar's bone in a straight line but
    // ~50 along the solid: the upper bone gets nothing there.
    Solid s(41, 12, 5);
    s.box(0, 40, 0, 4, 0, 4);
    s.box(0, 40, 7, 11, 0, 4);
    s.box(0, 4, 0, 11, 0, 4);
    Rig rig;
    rig.joints = {{2, 2, 2}, {38, 2, 2}, {2, 9, 2}, {38, 9, 2}};
    rig.bones = {{0, 1}, {2, 3}, {0, 2}};
    rig.names = {"lower", "upper", "base"};
    rig.parents = {2, 2, -1};
    const std::vector<std::array<double, 3>> pts = {{36, 4.5, 2}, {36, 6.5, 2}};
    const SkinWeights w = skin_weights(s.g, s.mask.data(), rig, pts);
    CHECK(weight(w, 0, 0) == 1.0f);
    CHECK(weight(w, 0, 1) == 0.0f);
    CHECK(weight(w, 1, 1) == 1.0f);
    CHECK(weight(w, 1, 0) == 0.0f);
}

TEST_CASE("skin weights: at most `influences` bones, far points by straight distance, bad input refused", "[skin]") {
    Solid s(21, 21, 21);  // a star: four bones meeting at the centre
    s.box(0, 20, 8, 12, 8, 12);
    s.box(8, 12, 0, 20, 8, 12);
    Rig rig;
    rig.joints = {{10, 10, 10}, {1, 10, 10}, {19, 10, 10}, {10, 1, 10}, {10, 19, 10}};
    rig.bones = {{0, 1}, {0, 2}, {0, 3}, {0, 4}};
    rig.names = {"a", "b", "c", "d"};
    rig.parents = {-1, -1, -1, -1};
    const std::vector<std::array<double, 3>> pts = {{10, 10, 12.5}, {18, 10, 40}};
    SkinOptions o;
    o.influences = 2;
    const SkinWeights w = skin_weights(s.g, s.mask.data(), rig, pts, o);
    CHECK(w.indptr[1] - w.indptr[0] == 2);  // the centre is as near to all four: two kept
    CHECK(w.outside[1] == 1);
    CHECK(weight(w, 1, 1) > 0.5f);  // nearest in a straight line
    o.influences = 5;
    CHECK_THROWS_WITH(skin_weights(s.g, s.mask.data(), rig, pts, o), Catch::Contains("influences"));
    o.influences = 4;
    o.blend = std::nan("");
    CHECK_THROWS_WITH(skin_weights(s.g, s.mask.data(), rig, pts, o), Catch::Contains("blend"));
    CHECK_THROWS_WITH(skin_weights(s.g, s.mask.data(), rig, {{0, std::nan(""), 0}}), Catch::Contains("finite"));
    std::vector<std::uint8_t> empty(s.mask.size(), 0);
    CHECK_THROWS_WITH(skin_weights(s.g, empty.data(), rig, pts), Catch::Contains("empty"));
}

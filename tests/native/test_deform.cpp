// Per-frame sampled reconstruction (ALGORITHMS.md §7): the Deformer against the thesis' brute-force scatter on
// small random rigs, the identity pose against reconstruct(), and bad input. Also run under ASan/UBSan.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "volrig/deform.hpp"
#include "volrig/distance.hpp"
#include "volrig/reconstruct.hpp"

using namespace volrig;

namespace {

/// An L-shaped limb (two capsules meeting at a joint) with a brighter core, and spheres on a sparse subset of
/// its voxels (radius = DT), bound to the capsule they lie in; near the joint, weights blend both bones.
struct Limb {
    Grid grid;
    std::vector<std::uint8_t> samples;
    std::vector<std::int32_t> ijk, bone;
    std::vector<float> radius;
    std::vector<std::int64_t> offsets{0};
    std::vector<std::int32_t> wbones;
    std::vector<float> weights;
    double joint[3] = {14, 12, 10};

    BoundSpheres spheres(bool with_weights) const {
        BoundSpheres s;
        s.ijk = ijk.data();
        s.radius = radius.data();
        s.n = radius.size();
        s.bone = bone.data();
        s.bone_count = 2;
        if (with_weights) {
            s.weight_offsets = offsets.data();
            s.weight_bones = wbones.data();
            s.weights = weights.data();
        }
        return s;
    }
    VolumeView view() const { return VolumeView{grid, DType::UInt8, samples.data()}; }
};

double segment_distance(const double* q, const double* a, const double* b) {
    double d[3], w[3], dd = 0, t = 0;
    for (int k = 0; k < 3; ++k) {
        d[k] = b[k] - a[k];
        w[k] = q[k] - a[k];
        dd += d[k] * d[k];
        t += w[k] * d[k];
    }
    t = std::max(0.0, std::min(1.0, t / dd));
    double r = 0;
    for (int k = 0; k < 3; ++k) r += (w[k] - t * d[k]) * (w[k] - t * d[k]);
    return std::sqrt(r);
}

Limb make_limb(std::array<double, 3> spacing) {
    Limb L;
    L.grid.dims = {30, 24, 34};
    L.grid.spacing = spacing;
    L.grid.origin = {-2.0, 1.5, 3.0};
    const auto n = static_cast<std::size_t>(L.grid.voxel_count());
    L.samples.assign(n, 0);
    std::vector<std::uint8_t> mask(n, 0);
    const double a[3] = {14, 12, 26}, b[3] = {14, 12, 10}, c[3] = {26, 12, 8};  // voxel coordinates
    for (std::int64_t z = 0; z < 34; ++z)
        for (std::int64_t y = 0; y < 24; ++y)
            for (std::int64_t x = 0; x < 30; ++x) {
                const double q[3] = {double(x), double(y), double(z)};
                const double d = std::min(segment_distance(q, a, b), segment_distance(q, b, c));
                const auto i = static_cast<std::size_t>(L.grid.index(x, y, z));
                if (d < 5.0) {
                    mask[i] = 1;
                    L.samples[i] = d < 2.0 ? 220 : 100;
                }
            }
    const std::vector<float> dt = distance_transform(L.grid, mask.data(), Metric::Euclidean);
    for (std::int64_t z = 0; z < 34; ++z)
        for (std::int64_t y = 0; y < 24; ++y)
            for (std::int64_t x = 0; x < 30; ++x) {
                const auto i = static_cast<std::size_t>(L.grid.index(x, y, z));
                if (!mask[i] || (x + y + z) % 3 != 0) continue;
                L.ijk.insert(L.ijk.end(), {std::int32_t(z), std::int32_t(y), std::int32_t(x)});
                L.radius.push_back(dt[i]);
                const std::int32_t owner = z >= 10 ? 0 : 1;
                L.bone.push_back(owner);
                const double along = std::abs(double(z) - 10.0);
                if (along < 3.0) {  // blend across the joint
                    const float w = static_cast<float>(0.5 + along / 6.0);
                    L.wbones.insert(L.wbones.end(), {owner, 1 - owner});
                    L.weights.insert(L.weights.end(), {w, 1.0f - w});
                } else {
                    L.wbones.push_back(owner);
                    L.weights.push_back(1.0f);
                }
                L.offsets.push_back(static_cast<std::int64_t>(L.wbones.size()));
            }
    return L;
}

/// Rotation by `deg` about `axis` through the world point `pivot`, plus a shift; row-major 4x4.
std::array<double, 16> motion(std::array<double, 3> axis, double deg, std::array<double, 3> pivot,
                              std::array<double, 3> shift) {
    const double n = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
    const double x = axis[0] / n, y = axis[1] / n, z = axis[2] / n, t = deg * M_PI / 180.0;
    const double c = std::cos(t), s = std::sin(t), C = 1 - c;
    const double R[9] = {c + x * x * C,     x * y * C - z * s, x * z * C + y * s, y * x * C + z * s, c + y * y * C,
                         y * z * C - x * s, z * x * C - y * s, z * y * C + x * s, c + z * z * C};
    std::array<double, 16> m{};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) m[4 * i + j] = R[3 * i + j];
        m[4 * i + 3] = pivot[i] - (R[3 * i] * pivot[0] + R[3 * i + 1] * pivot[1] + R[3 * i + 2] * pivot[2]) + shift[i];
    }
    m[15] = 1;
    return m;
}

std::array<double, 3> world(const Grid& g, const double* v) {
    return {g.origin[0] + g.spacing[0] * v[0], g.origin[1] + g.spacing[1] * v[1], g.origin[2] + g.spacing[2] * v[2]};
}

}  // namespace

TEST_CASE("the identity pose reproduces reconstruct() and the source", "[deform]") {
    const Limb L = make_limb({1.0, 1.0, 1.0});
    Deformer d(L.view(), L.spheres(false));
    std::vector<double> id(32, 0.0);
    for (int b = 0; b < 2; ++b)
        for (int k = 0; k < 4; ++k) id[16 * b + 5 * k] = 1.0;
    for (Proximity prox : {Proximity::Power, Proximity::Nearest}) {
        DeformOptions o;
        o.proximity = prox;
        const DeformedVolume f = d.frame(id.data(), o);
        const std::vector<std::uint8_t> rec = reconstruct(L.grid, Metric::Euclidean, L.ijk.data(), L.radius.data(), L.radius.size());
        std::int64_t covered = 0;
        for (std::int64_t z = 0; z < f.grid.dims[2]; ++z)
            for (std::int64_t y = 0; y < f.grid.dims[1]; ++y)
                for (std::int64_t x = 0; x < f.grid.dims[0]; ++x) {
                    const auto i = static_cast<std::size_t>(f.grid.index(x, y, z));
                    const std::int64_t sx = x + f.offset[0], sy = y + f.offset[1], sz = z + f.offset[2];
                    const bool in = sx >= 0 && sy >= 0 && sz >= 0 && sx < 30 && sy < 24 && sz < 34;
                    const auto si = in ? static_cast<std::size_t>(L.grid.index(sx, sy, sz)) : 0;
                    const bool want = in && rec[si];
                    REQUIRE((f.bone[i] > 0) == want);
                    if (want) {
                        REQUIRE(f.values[i] == float(L.samples[si]));
                        ++covered;
                    }
                }
        REQUIRE(covered == f.stats.covered);
        REQUIRE(covered > 2000);
    }
}

TEST_CASE("the Deformer equals the brute-force scatter on random poses", "[deform]") {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    for (auto spacing : {std::array<double, 3>{1.0, 1.0, 1.0}, std::array<double, 3>{0.9, 1.2, 1.5}}) {
        const Limb L = make_limb(spacing);
        Deformer d(L.view(), L.spheres(true));
        const auto joint = world(L.grid, L.joint);
        for (int trial = 0; trial < 4; ++trial) {
            std::vector<double> mats;
            for (int b = 0; b < 2; ++b) {
                const auto m = motion({U(rng), U(rng), U(rng)}, 50 * U(rng), joint, {3 * U(rng), 3 * U(rng), 3 * U(rng)});
                mats.insert(mats.end(), m.begin(), m.end());
            }
            for (DeformMode mode : {DeformMode::Rigid, DeformMode::Linear, DeformMode::DualQuaternion})
                for (Proximity prox : {Proximity::Power, Proximity::Nearest}) {
                    DeformOptions o;
                    o.mode = mode;
                    o.proximity = prox;
                    o.sampling = trial % 2 ? Sampling::Nearest : Sampling::Trilinear;
                    INFO("spacing " << spacing[2] << " trial " << trial << " mode " << int(mode) << " prox " << int(prox));
                    const DeformedVolume fast = d.frame(mats.data(), o);
                    const std::array<std::int64_t, 6> box{fast.offset[0], fast.offset[1], fast.offset[2],
                                                          fast.grid.dims[0], fast.grid.dims[1], fast.grid.dims[2]};
                    const DeformedVolume ref = deform_reference(L.view(), L.spheres(true), mats.data(), o, {}, &box);
                    REQUIRE(fast.stats.covered == ref.stats.covered);
                    REQUIRE(fast.bone == ref.bone);
                    REQUIRE(fast.values == ref.values);
                    if (mode != DeformMode::Rigid) REQUIRE(fast.stats.blended_spheres > 0);
                }
        }
    }
}

TEST_CASE("deform refuses non-rigid matrices and bad options, and can be cancelled", "[deform]") {
    const Limb L = make_limb({1.0, 1.0, 1.0});
    Deformer d(L.view(), L.spheres(true));
    std::vector<double> mats(32, 0.0);
    for (int b = 0; b < 2; ++b)
        for (int k = 0; k < 4; ++k) mats[16 * b + 5 * k] = 1.0;
    DeformOptions o;
    std::vector<double> scaled = mats;
    scaled[16] = 2.0;
    REQUIRE_THROWS_AS(d.frame(scaled.data(), o), Error);
    std::vector<double> nan = mats;
    nan[3] = std::nan("");
    REQUIRE_THROWS_AS(d.frame(nan.data(), o), Error);
    o.radius_scale = {1.0f, 2.0f};
    REQUIRE_THROWS_AS(d.frame(mats.data(), o), Error);
    o.radius_scale.clear();
    REQUIRE_THROWS_AS(d.frame(mats.data(), o, [](double f) { return f < 0.6; }), Cancelled);
    REQUIRE(d.frame(mats.data(), o).stats.covered > 0);  // still usable after a cancel
    std::vector<std::int32_t> bad_bone = L.bone;
    bad_bone[3] = 5;
    BoundSpheres s = L.spheres(false);
    s.bone = bad_bone.data();
    REQUIRE_THROWS_AS(Deformer(L.view(), s), Error);
}

TEST_CASE("inverse_warp of the identity is the source", "[deform]") {
    const Limb L = make_limb({1.0, 1.0, 1.0});
    const double id[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    for (Sampling s : {Sampling::Trilinear, Sampling::Nearest}) {
        const std::vector<float> w = inverse_warp(L.view(), id, s);
        REQUIRE(w.size() == L.samples.size());
        for (std::size_t i = 0; i < w.size(); ++i) REQUIRE(w[i] == float(L.samples[i]));
    }
}

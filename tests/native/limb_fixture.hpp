// limb_fixture.hpp: the test fixture the deformation and collision tests share: an L-shaped limb of two bones
// with spheres on its voxels, and rigid motions.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "volrig/deform.hpp"
#include "volrig/distance.hpp"

namespace volrig {

namespace {

/// A view of sphere arrays as BoundSpheres (weights optional: all three or none).
inline BoundSpheres bound_spheres(const std::vector<std::int32_t>& ijk, const std::vector<float>& radius,
                           const std::vector<std::int32_t>& bone, std::size_t bone_count,
                           const std::vector<std::int64_t>* offsets = nullptr,
                           const std::vector<std::int32_t>* wbones = nullptr,
                           const std::vector<float>* weights = nullptr) {
    BoundSpheres s;
    s.ijk = ijk.data();
    s.radius = radius.data();
    s.n = radius.size();
    s.bone = bone.data();
    s.bone_count = bone_count;
    if (offsets) {
        s.weight_offsets = offsets->data();
        s.weight_bones = wbones->data();
        s.weights = weights->data();
    }
    return s;
}

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
    std::array<std::int64_t, 3> dims{30, 24, 34};

    BoundSpheres spheres(bool with_weights) const {
        return with_weights ? bound_spheres(ijk, radius, bone, 2, &offsets, &wbones, &weights)
                            : bound_spheres(ijk, radius, bone, 2);
    }
    VolumeView view() const { return VolumeView{grid, DType::UInt8, samples.data()}; }
};

inline double segment_distance(const double* q, const double* a, const double* b) {
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

/// `thick` scales the limb (radius 5 * thick), its grid and its joint; spheres sit on every third voxel. `straight`:
/// the second capsule continues the first (along z, cut by the grid at z = 0) instead of turning along x.
inline Limb make_limb(std::array<double, 3> spacing, int thick = 1, bool straight = false) {
    Limb L;
    L.dims = {30 * thick, 24 * thick, 34 * thick};
    L.grid.dims = L.dims;
    for (double& j : L.joint) j *= thick;
    L.grid.spacing = spacing;
    L.grid.origin = {-2.0, 1.5, 3.0};
    const auto n = static_cast<std::size_t>(L.grid.voxel_count());
    L.samples.assign(n, 0);
    std::vector<std::uint8_t> mask(n, 0);
    const double t = thick;
    const double a[3] = {14 * t, 12 * t, 26 * t}, b[3] = {14 * t, 12 * t, 10 * t};
    const double c[3] = {straight ? 14 * t : 26 * t, 12 * t, straight ? -6 * t : 8 * t};
    for (std::int64_t z = 0; z < L.dims[2]; ++z)
        for (std::int64_t y = 0; y < L.dims[1]; ++y)
            for (std::int64_t x = 0; x < L.dims[0]; ++x) {
                const double q[3] = {double(x), double(y), double(z)};
                const double d = std::min(segment_distance(q, a, b), segment_distance(q, b, c));
                const auto i = static_cast<std::size_t>(L.grid.index(x, y, z));
                if (d < 5.0 * t) {
                    mask[i] = 1;
                    L.samples[i] = static_cast<std::uint8_t>(d < 2.0 * t ? 220 : 100 + (x * 7 + y * 3 + z) % 50);
                }
            }
    const std::vector<float> dt = distance_transform(L.grid, mask.data(), Metric::Euclidean);
    for (std::int64_t z = 0; z < L.dims[2]; ++z)
        for (std::int64_t y = 0; y < L.dims[1]; ++y)
            for (std::int64_t x = 0; x < L.dims[0]; ++x) {
                const auto i = static_cast<std::size_t>(L.grid.index(x, y, z));
                if (!mask[i] || (x + y + z) % 3 != 0) continue;
                L.ijk.insert(L.ijk.end(), {std::int32_t(z), std::int32_t(y), std::int32_t(x)});
                L.radius.push_back(dt[i]);
                const std::int32_t owner = z >= 10 * thick ? 0 : 1;
                L.bone.push_back(owner);
                const double along = std::abs(double(z) - 10.0 * t) / t;
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
inline std::array<double, 16> motion(std::array<double, 3> axis, double deg, std::array<double, 3> pivot,
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

inline std::array<double, 3> world(const Grid& g, const double* v) {
    return {g.origin[0] + g.spacing[0] * v[0], g.origin[1] + g.spacing[1] * v[1], g.origin[2] + g.spacing[2] * v[2]};
}

/// The limb's two bone matrices: each a random rotation of up to `degrees` about the joint plus a shift of up to
/// `shift` voxels per axis.
inline std::vector<double> random_pose(std::mt19937& rng, const Limb& L, double degrees, double shift) {
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    const auto joint = world(L.grid, L.joint);
    std::vector<double> mats;
    for (int b = 0; b < 2; ++b) {
        const auto m = motion({U(rng), U(rng), U(rng)}, degrees * U(rng), joint,
                              {shift * U(rng), shift * U(rng), shift * U(rng)});
        mats.insert(mats.end(), m.begin(), m.end());
    }
    return mats;
}

}  // namespace

}  // namespace volrig

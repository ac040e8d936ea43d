// stages_fixture.hpp: what the deformation stage tests (test_deform_stages*.cpp) share: random sphere sets, bone
// fields built on them and brute-force powers.
#pragma once

#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "deform/bend.hpp"
#include "deform/bone_field.hpp"
#include "deform/closed_cubes.hpp"
#include "deform/decide.hpp"
#include "deform/frame_box.hpp"
#include "deform/gather.hpp"
#include "deform/motion.hpp"
#include "deform/posed_balls.hpp"
#include "deform/queries.hpp"
#include "deform/sampler.hpp"
#include "deform/spheres.hpp"
#include "volrig/reconstruct.hpp"
#include "limb_fixture.hpp"

using namespace volrig;
using namespace volrig::deform_detail;

namespace {

/// Random spheres on a small anisotropic grid, all bound to bone 0.
struct RandomSpheres {
    Grid grid;
    std::vector<std::int32_t> ijk, bone;
    std::vector<float> radius;
    std::vector<double> radii;
    std::vector<std::uint32_t> members;

    RandomSpheres(std::uint32_t seed, std::size_t n, std::array<double, 3> spacing = {1.0, 1.25, 0.8}) {
        std::mt19937 rng(seed);
        grid.dims = {28, 24, 30};
        grid.spacing = spacing;
        grid.origin = {1.0, -2.0, 0.5};
        std::uniform_int_distribution<int> x(4, 23), y(4, 19), z(4, 25);
        std::uniform_real_distribution<float> r(0.6f, 4.5f);
        for (std::size_t i = 0; i < n; ++i) {
            const int zi = z(rng), yi = y(rng), xi = x(rng);
            ijk.push_back(zi);
            ijk.push_back(yi);
            ijk.push_back(xi);
            radius.push_back(r(rng));
            radii.push_back(radius.back());
            bone.push_back(0);
            members.push_back(static_cast<std::uint32_t>(i));
        }
    }
    BoundSpheres spheres() const { return bound_spheres(ijk, radius, bone, 1); }
    double T() const {
        const auto& sp = grid.spacing;
        return 0.25 * (sp[0] * sp[0] + sp[1] * sp[1] + sp[2] * sp[2]) * (1 + 1e-9);
    }
    std::array<double, 3> s2() const {
        return {grid.spacing[0] * grid.spacing[0], grid.spacing[1] * grid.spacing[1], grid.spacing[2] * grid.spacing[2]};
    }
    BoneField field(DiagramScratch* diagram = nullptr) const {
        double maxlim = 0;
        for (double r : radii) maxlim = std::max(maxlim, open_ball_limit_sq(r));
        return build_bone_field(grid, spheres(), members, radii, T(), (maxlim + 4 * T()) / 30000.0, diagram);
    }
    BoneField ball_field() const { return build_ball_field(grid, spheres(), members, radii, T(), 1.0); }
};

/// A skeleton's spheres: on random voxels inside a straight tube, each as large as its distance to the tube's
/// surface, so that small balls near the surface lie inside big ones and poke out of them between lattice points.
inline RandomSpheres tube_spheres(std::mt19937& rng, std::array<double, 3> spacing) {
    RandomSpheres rs(0, 0, spacing);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const double a[3] = {6, 6, 6}, b[3] = {14 + 6 * u(rng), 12 + 6 * u(rng), 16 + 8 * u(rng)}, R = 4.5 + 2 * u(rng);
    double ab2 = 0;
    for (int k = 0; k < 3; ++k) ab2 += (b[k] - a[k]) * (b[k] - a[k]);
    for (std::int32_t z = 0; z < rs.grid.dims[2]; ++z)
        for (std::int32_t y = 0; y < rs.grid.dims[1]; ++y)
            for (std::int32_t x = 0; x < rs.grid.dims[0]; ++x) {
                const double w[3] = {x * spacing[0], y * spacing[1], z * spacing[2]};
                double t = 0, d2 = 0;
                for (int k = 0; k < 3; ++k) t += (w[k] - a[k]) * (b[k] - a[k]);
                t = std::clamp(t / ab2, 0.0, 1.0);
                for (int k = 0; k < 3; ++k) d2 += std::pow(w[k] - a[k] - t * (b[k] - a[k]), 2);
                const double r = R - std::sqrt(d2);
                if (r < 0.5 || u(rng) > 0.35) continue;
                rs.ijk.insert(rs.ijk.end(), {z, y, x});
                rs.radius.push_back(static_cast<float>(r));
                rs.radii.push_back(rs.radius.back());
                rs.bone.push_back(0);
                rs.members.push_back(static_cast<std::uint32_t>(rs.members.size()));
            }
    return rs;
}

/// One bone's field over random spheres, with a random source for the points a test probes.
struct FieldCase {
    RandomSpheres rs;
    std::array<double, 3> s2;
    BoneField f;
    std::mt19937 rng;
    std::uniform_real_distribution<double> u{0.0, 1.0};
    FieldCase(std::uint32_t seed, std::size_t n, std::uint32_t probe_seed, std::array<double, 3> spacing = {1.0, 1.25, 0.8})
        : rs(seed, n, spacing), s2(rs.s2()), f(rs.field()), rng(probe_seed) {}
};

/// The brute-force least (power, local index) of a field's spheres at p (index space), ties to the lower global.
inline Best brute_power(const BoneField& f, const double* p, const double* s2) {
    Best b;
    for (std::uint32_t k = 0; k < f.sph.size(); ++k) {
        const double v = power_of(f, k, p, s2);
        if (b.better(v, f.global[k])) b = {v, k, f.global[k]};
    }
    return b;
}

/// Probes n random points (fixed point, as Pull gives them) of the closed cube with first corner c (absolute
/// lattice): wherever the brute-force least power is negative, the least over the corner labels a query reads must be
/// it, and its sphere. Returns how many points were checked.
inline std::int64_t probe_closed_cube(const BoneField& f, const std::int64_t* c, const double* s2, std::mt19937& rng,
                                      int n) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    auto in_cube = [&](std::int64_t v) { return v * (std::int64_t{1} << Pull::kBits) + static_cast<std::int64_t>(u(rng) * Pull::kUnit); };
    std::int64_t checked = 0;
    for (int t = 0; t < n; ++t) {
        const std::int64_t pf[3] = {in_cube(c[0]), in_cube(c[1]), in_cube(c[2])};  // (a braced list: left to right)
        double p[3];
        Pull::to_double(pf, p);
        const Best e = brute_power(f, p, s2);
        if (!(e.key < 0)) continue;
        std::uint32_t local;
        REQUIRE(least_over_corners(f, pf, s2, local) == e.key);
        REQUIRE(local == e.local);
        ++checked;
    }
    return checked;
}

inline std::array<double, 16> rotation_z(double deg, std::array<double, 3> shift) {
    const double t = deg * M_PI / 180.0, c = std::cos(t), s = std::sin(t);
    return {c, -s, 0, shift[0], s, c, 0, shift[1], 0, 0, 1, shift[2], 0, 0, 0, 1};
}

}  // namespace

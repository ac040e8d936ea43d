// Internal to the medial surface sources (medial/surface.cpp, medial/rods.cpp): grid-frame geometry of
// voxels and feature voxels, and the rods' tracing.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "volrig/medial_surface.hpp"
#include "volrig/volume.hpp"

namespace volrig::medial_detail {

using P3 = std::array<double, 3>;

/// Positions in the grid frame without the origin (spacing * index); the origin is added at the end.
inline P3 at(const Grid& g, double x, double y, double z) { return {x * g.spacing[0], y * g.spacing[1], z * g.spacing[2]}; }

/// Centre of the feature voxel `f` (an index in the grid padded by one voxel, medial.hpp).
inline P3 feature_centre(const Grid& g, std::int64_t f) {
    const std::int64_t px = g.dims[0] + 2, py = g.dims[1] + 2;
    return at(g, double(f % px - 1), double((f / px) % py - 1), double(f / (px * py) - 1));
}

inline double dot(const P3& a, const P3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/// Distance from `q` to the object's boundary before the background voxel centred at `c`: |c - q| less half the
/// voxel's extent along the direction (the spacing of the lattice seen along it, 1 / |u / spacing|).
inline double boundary_distance(const Grid& g, const P3& q, const P3& c) {
    P3 u = {c[0] - q[0], c[1] - q[1], c[2] - q[2]};
    const double n = std::sqrt(dot(u, u));
    if (n == 0) return 0;
    double s = 0;
    for (int a = 0; a < 3; ++a) s += (u[a] / n / g.spacing[a]) * (u[a] / n / g.spacing[a]);
    return std::max(0.0, n - 0.5 / std::sqrt(s));
}
inline P3 sub(const P3& a, const P3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }

/// Traces the curve and junction voxels of `cls` (SkeletonClass per voxel) into out.rods / out.rod_radii, after
/// pruning spurs shorter than `t` from `cls` (medial_surface.hpp); `ft` is the feature transform.
void add_rods(const Grid& g, std::vector<std::uint8_t>& cls, const std::vector<std::int64_t>& ft, double t,
              MedialSurface& out);

}  // namespace volrig::medial_detail

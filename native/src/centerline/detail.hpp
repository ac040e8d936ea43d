// Internal pieces of the centerline code (native/src/centerline/), shared by its files and tested by Catch2.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "volrig/centerline.hpp"

namespace volrig::centerline_detail {

/// The 26 neighbour steps of a grid: (dx, dy, dz), linear offsets and world lengths.
struct Neighbours {
    std::vector<std::array<int, 3>> d;
    std::vector<std::int64_t> offset;
    std::vector<double> length;
};
Neighbours neighbours(const Grid& grid);

std::array<std::int64_t, 3> coords(const Grid& grid, std::int64_t lin);  ///< (x, y, z) of a linear index
Vec3d world(const Grid& grid, std::int64_t lin);                         ///< world position of a linear index
std::int32_t thickest(const VoxelGraph& g);  ///< id of the largest DT (first on ties)

/// The cap centre of a tip: the voxel nearest the centroid of the voxels connected to `tip` whose `dist` is within
/// one (largest) spacing of dist[tip].
std::int32_t tip_centre(const VoxelGraph& g, const std::vector<double>& dist, std::int32_t tip);

/// Polyline helpers (world points).
std::vector<Vec3d> resample(const std::vector<Vec3d>& pts, double step);        ///< equal arc length, ends kept
std::vector<Vec3d> smooth(const std::vector<Vec3d>& pts, double sigma_samples);  ///< Gaussian, ends fixed
std::vector<Vec3d> tangents(const std::vector<Vec3d>& pts);                      ///< unit, central differences
double polyline_length(const std::vector<Vec3d>& pts);

/// The centroid of the connected cross-section of the mask around c in the plane normal to t (trilinear mask,
/// level 0.5), within 1.5 DT + 2 h of c; c itself when the plane holds no object there.
Vec3d section_centroid(const Grid& grid, const std::uint8_t* mask, const Vec3d& c, const Vec3d& t, double radius);

/// A unit vector perpendicular to unit t.
Vec3d perpendicular(const Vec3d& t);

}  // namespace volrig::centerline_detail

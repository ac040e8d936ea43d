// volrig/reconstruct.hpp: binary reconstruction from skeleton points (docs/ALGORITHMS.md §4).
//
// The ball of a point p with radius r is every voxel q with d(p, q) < r, strictly, in the point's metric:
// Euclidean world distance (spacing honoured) or the <3,4,5> chamfer length of the grid offset. The
// reconstruction is the union of the balls, scan-filled row by row, multithreaded over z slices.
#pragma once

#include <cstdint>
#include <vector>

#include "volrig/distance.hpp"
#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

/// Squared Euclidean radius below which a squared offset length counts as inside the open ball of radius r.
/// DT values are stored as float32, so r² may exceed the true squared distance by a relative 2^-23; the squared
/// radius is therefore lowered by a relative 5e-7, which keeps every voxel whose squared distance is a smaller
/// value of the grid's lattice (exact on unit grids for DT below 1,260 voxels) and never admits the background
/// voxel that lies at exactly distance r.
inline double open_ball_limit_sq(double r) { return r * r * (1.0 - 5e-7); }

/// Half-extent in voxels of a ball of radius r along an axis of the given spacing (Euclidean) or in grid steps
/// (chamfer: 3t < r).
std::int64_t ball_half_extent(double r, double spacing, Metric metric);

/// Union of the open balls of `n` points: `ijk` holds n rows [z, y, x] (voxel indices, may lie outside the grid),
/// `radius` the n radii in metric units (world units for Euclidean, chamfer units for <3,4,5>). Returns
/// grid.voxel_count() bytes, 1 = inside.
std::vector<std::uint8_t> reconstruct(const Grid& grid, Metric metric, const std::int32_t* ijk, const float* radius,
                                      std::size_t n, const Progress& progress = {});

}  // namespace volrig

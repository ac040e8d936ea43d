// volrig/medial.hpp: plane-like skeletons after the Amira paper (docs/ALGORITHMS.md §11, ../shared/papers/001).
//
// The boundary is the set of background voxels 6-adjacent to the object (voxels outside the array count as
// background, so the layer just outside the array belongs to it). Every object voxel M has a nearest boundary
// voxel S(M) (the feature transform: the background voxel DT measures to). For M and its three lower neighbours
// X in the object (x-1, y-1, z-1), the plane-like measure d(M) is the largest geodesic distance, along the boundary
// (26-connected steps, world lengths), between S(M) and S(X). Where the nearest boundary jumps from one side of a
// plate to the other, the way round along the boundary is long: d > t marks the medial surface of plates at least
// t across, while bumps on a noisy boundary (d below t) are ignored.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

/// Feature transform: for each voxel, the linear index, in the grid padded by one voxel on every side (dims + 2),
/// of the nearest background voxel (exact Euclidean, spacing honoured; background voxels give themselves). Ties
/// go to the lower coordinates.
std::vector<std::int64_t> feature_transform(const Grid& grid, const std::uint8_t* mask, const Progress& progress = {});

/// The plane-like measure per lattice edge: `edge[3 M + a]` is the geodesic distance along the boundary between
/// S(M) and S(M - e_a) (axis a = x, y, z; world units), 0 where M - e_a is background, outside the array or has
/// the same nearest boundary voxel, +infinity beyond `t`. `feature` is the feature transform it used.
struct PlaneEdges {
    std::vector<std::int64_t> feature;
    std::vector<float> edge;
};
PlaneEdges plane_edges(const Grid& grid, const std::uint8_t* mask, double t, const Progress& progress = {});

/// The plane-like measure d(M) of every object voxel (world units), 0 on the background; distances beyond `t`
/// (world units) are not followed: such voxels get +infinity.
std::vector<float> plane_measure(const Grid& grid, const std::uint8_t* mask, double t, const Progress& progress = {});

}  // namespace volrig

// volrig/thickness.hpp: local thickness of a binary object (docs/ALGORITHMS.md §11).
//
// The local thickness of an object voxel p is the diameter 2·DT(c) of the largest ball that contains p and lies in
// the object: the largest over object voxels c with |p - c| < DT(c) (the open ball of reconstruct.hpp, Euclidean,
// world units). Background voxels get 0. Computed after Hildebrand and Rüegsegger (1997): only the centres whose
// ball is not inside another's on the lattice (the distance ridge, thickness_centres) are painted, slices in
// parallel, each taking its balls largest first so that a voxel's first ball sets it and the rest skip what is done.
// Equal to the brute-force maximum over every object voxel's ball.
// On a plate n voxels thick the value is n (n even) or n + 1 (n odd) voxels: DT is measured to the centre of the
// nearest background voxel, half a voxel beyond the surface.
#pragma once

#include <cstdint>
#include <vector>

#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

/// Local thickness of `mask` (voxel_count() bytes, non-zero = object), world units, one float per voxel.
std::vector<float> local_thickness(const Grid& grid, const std::uint8_t* mask, const Progress& progress = {});

/// The same from the object's exact Euclidean DT (distance.hpp; 0 = background).
std::vector<float> local_thickness_from_dt(const Grid& grid, const float* dt, const Progress& progress = {});

/// Linear indices of the object voxels whose ball is not contained in another's (the only centres local thickness
/// needs), ascending. A ball is dropped when a 26-neighbour's ball holds it by the triangle inequality (the
/// farthest lattice point of the ball plus the step inside the other's), or a ball up its DT's steepest ascent holds
/// it, by the triangle inequality or on the lattice, row by row (a continuous test, DT(c) + |c - c'| <= DT(c'),
/// almost never holds on a lattice, where DT grows by less than a step). A digital ball keeps only its centre.
std::vector<std::int64_t> thickness_centres(const Grid& grid, const float* dt);

}  // namespace volrig

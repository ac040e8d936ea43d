// volrig/components.hpp: connected components of a mask (object voxels 26-connected, docs/ALGORITHMS.md §1).
#pragma once

#include <cstdint>
#include <vector>

#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

struct Components {
    std::vector<std::int32_t> labels;  ///< per voxel: 0 = background, 1..count = component, largest first
    std::vector<std::int64_t> sizes;   ///< sizes[c - 1] = voxels in component c (descending)
};

/// Labels the 26-connected components of `mask` (non-zero = object); labels are ordered by size, largest = 1
/// (ties by first voxel in index order).
Components label_components(const Grid& grid, const std::uint8_t* mask, const Progress& progress = {});

/// Labels the `connectivity`-connected (6: faces, 26: faces, edges and corners) components of `mask` in scan order:
/// 1..count numbered by each component's first voxel in index order (x fastest), as scipy.ndimage.label numbers
/// them; sizes[c - 1] = voxels in component c. Works on the mask's runs along x (union-find over the runs of
/// neighbouring rows): one read of the mask, memory per run besides the labels.
Components scan_components(const Grid& grid, const std::uint8_t* mask, int connectivity);

/// Mask (0/1 bytes) of the largest 26-connected component; all zeros for an empty mask.
std::vector<std::uint8_t> largest_component(const Grid& grid, const std::uint8_t* mask, const Progress& progress = {});

/// The 26-connected component of `mask` each of `n` points lies on (`ijk`: n rows [z, y, x] of voxel indices):
/// 1..count numbered by each component's first run in scan order, 0 for points off the mask or the grid. Works
/// on the mask's runs along x (union-find over runs of neighbouring rows), so it costs one read of the mask and
/// memory per run, not per voxel, unlike label_components.
std::vector<std::int32_t> point_components(const Grid& grid, const std::uint8_t* mask, const std::int32_t* ijk,
                                           std::size_t n);

/// Nearest-seed fill: `code` holds per voxel 0 (neither), 1 (a seed) or 2 (to fill). Every voxel to fill that a
/// 26-connected path of voxels to fill joins to a seed takes the seed reached in fewest steps (breadth first from
/// all seeds at once; ties to the first voxel in scan order, then the first neighbour in z, y, x order). Returns
/// the pairs (voxel filled, its seed) as linear indices, 2 per filled voxel, in the order filled; voxels no path
/// joins to a seed are left out. Memory: the pairs (16 bytes per filled voxel) and one bit per voxel.
std::vector<std::int64_t> nearest_seed_fill(const Grid& grid, const std::uint8_t* code);

}  // namespace volrig

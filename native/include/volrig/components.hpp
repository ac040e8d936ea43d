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

/// Mask (0/1 bytes) of the largest 26-connected component; all zeros for an empty mask.
std::vector<std::uint8_t> largest_component(const Grid& grid, const std::uint8_t* mask, const Progress& progress = {});

}  // namespace volrig

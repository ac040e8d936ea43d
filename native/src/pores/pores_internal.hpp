// Internal stages of the pore network extraction (extract.cpp, regions.cpp).
#pragma once

#include <cstdint>
#include <vector>

#include "volrig/pores.hpp"

namespace volrig::pores_detail {

/// Euclidean DT of the pore space with the image's faces open: the mask mirrored across each face by up to 8
/// voxels, transformed, cropped back.
std::vector<float> open_distance(const Grid& g, const std::uint8_t* mask, const Progress& progress);

/// Pore seeds: voxels whose DT is not below any of their 26 neighbours', largest DT first (ties in scan order),
/// a seed dropped when its centre lies in the ball (radius DT) of a seed kept before it.
std::vector<std::int64_t> pore_seeds(const Grid& g, const float* dt);

/// Region labels (1.. in the order of `seeds`; 0 = solid): a priority flood of the DT from the seeds, largest
/// first, over 6-connected pore voxels. Pore voxels no seed reaches start new regions (in scan order).
std::vector<std::int32_t> flood_regions(const Grid& g, const float* dt, std::vector<std::int64_t>& seeds,
                                        const Progress& progress);

/// The pores' and throats' measures from the regions.
PoreNetwork measure_network(const Grid& g, const float* dt, const std::vector<std::int32_t>& labels, std::size_t pores);

}  // namespace volrig::pores_detail

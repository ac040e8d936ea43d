// Internal stages of the pore network extraction (extract.cpp, regions.cpp), over the pore space of
// pore_space.hpp.
#pragma once

#include <cstdint>
#include <vector>

#include "pore_space.hpp"
#include "volrig/pores.hpp"

namespace volrig::pores_detail {

/// Pore seeds: voxels whose DT is not below any of their 26 neighbours', on plateaus that do not rise, largest DT
/// first (ties in scan order), a seed dropped when its centre lies in the ball (radius DT) of a seed kept before it.
std::vector<std::int64_t> pore_seeds(const PoreSpace& dt);

/// Region labels (1.. in the order of `seeds`): a priority flood of the DT from the seeds, largest first, over
/// 6-connected pore voxels. Pore voxels no seed reaches start new regions (in scan order; appended to `seeds`).
Regions flood_regions(const PoreSpace& dt, std::vector<std::int64_t>& seeds, const Progress& progress);

/// The pores' and throats' measures from the regions.
PoreNetwork measure_network(const PoreSpace& dt, const Regions& regions, std::size_t pores);

/// The labels as a volume: per voxel its region (0 = solid).
std::vector<std::int32_t> dense_labels(const PoreSpace& dt, const Regions& regions);

}  // namespace volrig::pores_detail

// volrig/distance.hpp: distance transforms of a binary mask (docs/ALGORITHMS.md §2).
//
// DT(p) = distance from object voxel p to the nearest background voxel; background voxels get 0. Voxels outside
// the array count as background, so DT is finite everywhere and a voxel on the array border has DT of one step.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

enum class Metric {
    Euclidean,   ///< exact Euclidean distance in world units (honours anisotropic spacing)
    Chamfer345,  ///< weighted <3,4,5> chamfer distance in chamfer units of grid steps (spacing is not used)
};

Metric metric_from_name(const std::string& name);  ///< "euclidean" | "chamfer345"
const char* metric_name(Metric m);

/// Exact Euclidean DT by separable lower envelopes of parabolas (Felzenszwalb-Huttenlocher), linear time,
/// multithreaded. `mask` holds voxel_count() bytes, non-zero = object. Writes DT (world units) to `dt`.
/// On unit grids DT² is an integer and is represented exactly before the final square root.
void euclidean_distance_transform(const Grid& grid, const std::uint8_t* mask, float* dt, const Progress& progress = {});

/// Weighted <3,4,5> chamfer DT: local steps 3 (face), 4 (edge), 5 (vertex), propagated from the background by a
/// bucket queue over object voxels only (cost proportional to the object). Values are integers, ~3x Euclidean.
void chamfer345_distance_transform(const Grid& grid, const std::uint8_t* mask, float* dt, const Progress& progress = {});

/// Dispatches on `metric`; returns a new DT array.
std::vector<float> distance_transform(const Grid& grid, const std::uint8_t* mask, Metric metric,
                                      const Progress& progress = {});

/// <3,4,5> chamfer length of a grid offset: with sorted magnitudes a >= b >= c, 5c + 4(b-c) + 3(a-b) = 3a + b + c.
inline std::int64_t chamfer345_length(std::int64_t dx, std::int64_t dy, std::int64_t dz) {
    dx = dx < 0 ? -dx : dx;
    dy = dy < 0 ? -dy : dy;
    dz = dz < 0 ? -dz : dz;
    std::int64_t a = dx > dy ? dx : dy;
    a = a > dz ? a : dz;
    return 2 * a + dx + dy + dz;
}

}  // namespace volrig

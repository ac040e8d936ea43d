// volrig/track.hpp: feature tracking over time steps (thesis 9.1; docs/track.md): the features of a step, and the
// overlaps of one step's features with the next step's, from points standing for each feature's volume.
#pragma once

#include <cstdint>
#include <vector>

#include "volrig/volume.hpp"

namespace volrig {

/// A step's features: the 6-connected components of a mask with at least `min_size` voxels, numbered 1.. in scan
/// order of their first voxel (scipy.ndimage.label's numbering with the small components removed and the rest
/// renumbered in order).
struct Features {
    std::vector<std::int32_t> labels;  ///< per voxel: 0 = no feature, else its number
    std::vector<std::int64_t> sizes;   ///< sizes[f - 1]: voxels of feature f
    std::vector<double> centroids;     ///< 3 per feature: mean voxel index (x, y, z)
};

Features track_features(const Grid& grid, const std::uint8_t* mask, std::int64_t min_size);

/// Overlaps between features a of one step and b of the next: each of `n` points (voxel `index[i]` of the grid
/// `next_labels` is on, standing for `weight[i]` voxels of feature `label[i]`) adds its weight to (label[i], b)
/// where b = next_labels[index[i]] > 0 (the next step has `next_count` features: no label above it). Points in
/// ascending index order read the next step's labels in memory order. With every voxel of every feature as a point of weight 1 this is the exact
/// overlap |a ∩ b| in voxels (Silver and Wang's volume test). The pairs come sorted by (a, b); `totals[a]` sums
/// the weights of a's points wherever they lie. Cost: one pass over the points (a dense pair table while it stays
/// under 2^20 entries, a hash table beyond).
struct Overlaps {
    std::vector<std::int32_t> a, b;
    std::vector<double> weight;
    std::vector<double> totals;
};

Overlaps point_overlaps(const Grid& grid, const std::int32_t* next_labels, std::int32_t next_count,
                        const std::int64_t* index,
                        const std::int32_t* label, const float* weight, std::size_t n);

}  // namespace volrig

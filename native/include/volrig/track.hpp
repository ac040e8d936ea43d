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

/// One step's side of `step_overlaps`: its feature label volume (0 = none, else 1..count; the grid's voxels) and
/// its points: point i, at voxel index[i], stands for weight[i] voxels of feature label[i] (1..count). Points in
/// ascending index order read the other step's labels in memory order. `weight` null: every point weighs 1 (every
/// voxel of every feature a point: the exact overlap |A ∩ B| in voxels, Silver and Wang's volume test). With
/// weights, `totals[f]` (f = 0..count) sums feature f's point weights and `sizes[f - 1]` is its voxels: a count
/// landing from f's points is scaled by sizes[f - 1] / totals[f], so a feature's points stand for its voxels.
/// Labels are one type throughout (uint8, uint16 or int32: the smallest that holds the count), indices uint32 or
/// int64.
template <class I, class L>
struct StepPoints {
    const L* labels = nullptr;
    std::int32_t count = 0;
    const I* index = nullptr;
    const L* label = nullptr;
    const float* weight = nullptr;
    std::size_t n = 0;
    const std::int64_t* sizes = nullptr;
    const double* totals = nullptr;
};

/// The overlaps of features a (step t) and b (step t+1), sorted by (a, b), in voxels: a's points looked up in b's
/// labels, and with `both` b's points in a's labels too, the larger estimate of the two kept per pair (a pair
/// either direction finds is listed). Cost: one pass over each side's points counting into a register while the
/// pair (a, b) stays the same (a dense pair table while it stays under 2^20 entries, a hash table beyond); the
/// weights are still added in point order, so the sums are a plain loop's bit for bit. Throws on a point off the
/// grid, a point label outside 1..count, or a label of the other step above its count.
struct Overlaps {
    std::vector<std::int32_t> a, b;
    std::vector<double> overlap;
};

template <class I, class L>
Overlaps step_overlaps(const Grid& grid, const StepPoints<I, L>& a, const StepPoints<I, L>& b, bool both);

/// A step's features as runs along x: run i covers voxels x0[i] <= x < x1[i] of row[i] (row = z * ny + y) and
/// belongs to feature label[i] (1..count); runs sorted by (row, x0), not overlapping.
struct Runs {
    const std::int32_t* row = nullptr;
    const std::int32_t* x0 = nullptr;
    const std::int32_t* x1 = nullptr;
    const std::int32_t* label = nullptr;
    std::size_t n = 0;
    std::int32_t count = 0;
};

/// The exact overlaps |A ∩ B| in voxels of a's features with b's, sorted by (a, b): the full-volume test (Silver
/// and Wang's) by runs, each row's runs of the two steps merged, at a cost per run rather than per voxel.
Overlaps run_overlaps(const Runs& a, const Runs& b);

}  // namespace volrig

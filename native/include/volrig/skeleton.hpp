// volrig/skeleton.hpp: the thinness score and the parameter-controlled skeleton (docs/ALGORITHMS.md §3).
//
// MNT(p) = mean of DT over the 26 neighbours of p (out-of-array and background neighbours contribute 0).
// Score s(p) = DT(p) - MNT(p). Condition 1: p is in the skeleton at thinness TP iff s(p) > TP. The object voxels
// are sorted once by descending score; the skeleton at any TP is then a prefix of that order.
#pragma once

#include <cstdint>
#include <vector>

#include "volrig/distance.hpp"
#include "volrig/memory.hpp"
#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

class Skeleton {
public:
    Grid grid;
    Metric metric = Metric::Euclidean;
    Buffer<float> dt;  ///< DT per voxel (metric units), [z, y, x]
    /// Object voxels by descending score (ties by ascending voxel index), packed as
    /// (descending-sortable score bits << 32) | voxel index.
    Buffer<std::uint64_t> order;

    std::size_t object_count() const { return order.size(); }
    float score(std::size_t k) const;            ///< score of the k-th voxel in the order
    std::uint32_t voxel(std::size_t k) const {   ///< linear voxel index of the k-th voxel in the order
        return static_cast<std::uint32_t>(order[k] & 0xFFFFFFFFu);
    }
    /// Number of voxels in the skeleton at thinness tp (those with s > tp): O(log n).
    std::size_t count_at(double tp) const;
    /// The smallest thinness whose skeleton has at most n points (exactly n unless scores tie at the cut).
    double tp_for_count(std::size_t n) const;
    /// Dense score per voxel (background voxels get 0).
    std::vector<float> dense_scores() const;
};

/// Computes DT, the scores and the sorted order of a mask (non-zero = object). Memory: the DT (4 bytes per
/// voxel) plus 8 bytes per object voxel for the order (and as much again, briefly, while sorting).
/// Grids up to 2^32 voxels.
Skeleton skeletonize(const Grid& grid, const std::uint8_t* mask, Metric metric, const Progress& progress = {});

/// Score of every object voxel from a DT (`dt` of grid.voxel_count()), written as packed order keys in index order
/// (unsorted); exposed for tests and tools that bring their own DT.
Buffer<std::uint64_t> thinness_keys(const Grid& grid, const std::uint8_t* mask, const float* dt);

/// Sorting keys: a float maps to a uint32 whose ascending order is the float's descending order.
std::uint32_t descending_key(float score);
float score_of_key(std::uint32_t key);

/// Sorts packed keys ascending by their upper 32 bits, stable (LSD radix sort, parallel histograms).
void sort_by_upper_key(Buffer<std::uint64_t>& keys);

/// Skeleton points: the first n voxels of the order. Writes ijk [z, y, x] (n x 3), world centres (x, y, z) (n x 3),
/// DT values and scores; any output pointer may be null.
void skeleton_points(const Skeleton& s, std::size_t n, std::int32_t* ijk, double* centers, float* dt, float* scores);

}  // namespace volrig

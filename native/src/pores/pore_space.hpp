// The pore space stored over its pore voxels only: a bit a voxel, the pore voxels' ranks, and per pore voxel its
// distance and region label (the extraction's working set, about 0.25 + 8 x porosity bytes a voxel).
#pragma once

#include <cstdint>
#include <vector>

#include "volrig/pores.hpp"

namespace volrig::pores_detail {

/// Which voxels are pore (a bit each) and each pore voxel's rank among them in scan order.
class PoreIndex {
public:
    PoreIndex(const Grid& g, const std::uint8_t* mask);
    std::int64_t count() const { return count_; }
    bool pore(std::int64_t i) const { return (bits_[static_cast<std::size_t>(i >> 6)] >> (i & 63)) & 1u; }
    /// Rank of voxel i among the pore voxels (of the pore voxels before it, when i is solid).
    std::int64_t rank(std::int64_t i) const {
        const auto w = static_cast<std::size_t>(i >> 6);
        const std::uint64_t below = (std::uint64_t{1} << (i & 63)) - 1;
        return prefix_[w] + __builtin_popcountll(bits_[w] & below);
    }

private:
    std::vector<std::uint64_t> bits_;
    std::vector<std::int64_t> prefix_;
    std::int64_t count_ = 0;
};

/// The distance transform over the pore voxels (world units; solid reads 0).
struct PoreSpace {
    Grid grid;
    PoreIndex index;
    std::vector<float> dt;  ///< per pore voxel, in rank order
    PoreSpace(const Grid& g, const std::uint8_t* mask) : grid(g), index(g, mask) {}
    PoreSpace(const PoreSpace&) = delete;  // as big as the pore space: passed by reference only
    PoreSpace& operator=(const PoreSpace&) = delete;
    float operator[](std::int64_t i) const {
        return index.pore(i) ? dt[static_cast<std::size_t>(index.rank(i))] : 0.0f;
    }
};

/// Region labels over the pore voxels (0 = none yet).
struct Regions {
    const PoreIndex* index = nullptr;
    std::vector<std::int32_t> labels;  ///< per pore voxel, in rank order
    std::int32_t& at(std::int64_t i) { return labels[static_cast<std::size_t>(index->rank(i))]; }
    std::int32_t get(std::int64_t i) const {
        return index->pore(i) ? labels[static_cast<std::size_t>(index->rank(i))] : 0;
    }
};

/// Fills `space.dt`: the exact Euclidean distance of every pore voxel to the nearest solid voxel's centre, with the
/// image's faces open (voxels outside the image count as pore, as PoreSpy's transform does), by separable lower
/// envelopes of parabolas (Felzenszwalb-Huttenlocher); x and y a z slice at a time, z a y plane at a time.
void pore_distance(PoreSpace& space, const std::uint8_t* mask, const Progress& progress);

}  // namespace volrig::pores_detail

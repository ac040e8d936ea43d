// rig/autorig/coarse.hpp: the object at autorig's own scale, so that the rig depends neither on the volume's
// resolution nor on how many skeleton points the user keeps (internal to the core; tested alone in
// tests/native/test_rig_autorig.cpp).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "volrig/skeleton.hpp"
#include "volrig/tree.hpp"

namespace volrig::rig_detail {

/// Cells along the object's longest extent at autorig's scale.
constexpr double kCoarseCells = 400;
/// The share of the coarse object's voxels kept as skeleton points (those of highest thinness score) at
/// kCoarseCells; a smaller object (a volume coarser than that scale) keeps a share larger by kCoarseCells / its
/// cells, about as many points per cell of length. A fixed thinness level gives skeletons too sparse to place joints
/// well.
constexpr double kCoarsePoints = 0.01;

struct CoarseShape {
    /// The coarse grid with its origin at 0 (the results then do not depend, bit for bit, on where the object lies:
    /// the same object moved gives the same rig); world = grid position + `offset`.
    Grid grid;
    std::array<double, 3> offset{0, 0, 0};
    std::vector<std::uint8_t> mask;
    std::array<std::int64_t, 3> factor{1, 1, 1};  ///< fine voxels per coarse voxel along x, y, z
    std::vector<std::int32_t> ijk;                ///< the curve skeleton's points [z, y, x] on `grid`
    std::vector<float> radius;                    ///< their radii (world units)
    std::vector<std::array<std::uint32_t, 2>> edges;  ///< their skeleton-tree

    PointSet points() const { return PointSet{ijk.data(), radius.data(), radius.size()}; }
};

/// Integer factors per axis making voxels about max(finest spacing, longest object extent / cells) wide.
std::array<std::int64_t, 3> coarse_factor(const Grid& g, const std::array<std::int64_t, 6>& box, double cells);

/// Bounding box of the object voxels: x0, y0, z0 (inclusive), x1, y1, z1 (exclusive); all zero when empty.
std::array<std::int64_t, 6> object_box(const Grid& g, const std::uint8_t* mask);

/// The object's bounding box resampled by `factor` (a coarse voxel is object when at least half of its fine voxels
/// are), with one empty voxel all around; coarse voxel centres are the means of their fine voxels' centres.
CoarseShape downsample(const Grid& g, const std::uint8_t* mask, const std::array<std::int64_t, 6>& box,
                       const std::array<std::int64_t, 3>& factor);

/// Cells of the finest spacing along the box's longest world extent.
double longest_cells(const Grid& g, const std::array<std::int64_t, 6>& box);

/// Scores this close to the n-th one (relative) count as tied with it: summed in another order (the object
/// turned or moved) a score changes in its last bits.
constexpr double kTiedScore = 1e-4;
/// n, or more when the points after the n-th tie with it: the same points whatever order the voxels come in.
std::size_t with_ties(const Skeleton& sk, std::size_t n);

/// The object at autorig's scale: downsampled to kCoarseCells along its longest extent (factor 1, only cropped,
/// when the volume is no finer than that), the kCoarsePoints share of its voxels of highest thinness score as
/// skeleton points (with_ties), and their skeleton-tree. Empty only for an empty mask. The caller's points are not used: the
/// rig does not depend on how many the user keeps.
CoarseShape coarse_shape(const Grid& g, const std::uint8_t* mask);

}  // namespace volrig::rig_detail

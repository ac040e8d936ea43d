// volrig/skin.hpp: skin weights of surface points (a mesh's vertices) from a rig, by geodesic distance through the
// object (after Dionne and de Lasa, "Geodesic Voxel Binding for Production Character Meshes", SCA 2013).
//
// 1. Every bone is rasterised into the object's voxels it crosses (its distance-0 sources; a bone that crosses
//    none starts from the object voxel nearest its midpoint).
// 2. One Dijkstra over the 26-neighbour graph of the object voxels (edge lengths in world units) gives every
//    object voxel its `influences` nearest bones by distance along paths inside the object: a bone is only near
//    skin it reaches without leaving the solid, so a hand resting on a thigh does not pull the thigh's skin.
//    (A k-nearest-sources Dijkstra is exact: if bone b is not among the k nearest of a voxel u on b's shortest
//    path to v, the k bones nearer u are nearer v too.)
// 3. A point takes, for each bone, the smallest (voxel distance + straight distance to the voxel centre) over the
//    object voxels at the corners of its lattice cell (the nearest object voxels within three voxels when none
//    is a corner; the straight distance to the bone's segment when none is even that close).
// 4. Falloff across joints: with d0 the smallest distance, bone i gets (1 - x_i / blend)² for
//    x_i = (d_i - d0) / d0 < blend, else 0. On a limb of radius r this blends neighbours within about
//    1.5 r of the joint for blend 1; the `influences` largest are kept and normalised to sum 1.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "volrig/progress.hpp"
#include "volrig/rig.hpp"
#include "volrig/volume.hpp"

namespace volrig {

struct SkinOptions {
    int influences = 4;   ///< bones per point at most (1 to 4)
    double blend = 1.0;   ///< falloff width across joints (> 0; larger blends over a longer stretch)
};

/// Weights per point as CSR rows: point i's bones are bone[indptr[i] .. indptr[i+1]) with weight[...]; every row
/// has 1 to `influences` entries, heaviest first, summing to 1.
struct SkinWeights {
    std::vector<std::int64_t> indptr;
    std::vector<std::int32_t> bone;
    std::vector<float> weight;
    /// Per point: 1 when no object voxel lay within three voxels (weights from straight distances to the bones).
    std::vector<std::uint8_t> outside;
};

/// Skin weights of `points` (world x, y, z; the grid's direction is taken as the identity, as bind does) on the
/// object `mask` (voxel_count() bytes, non-zero = object) for `rig`. Throws Error on an empty mask, a bad rig,
/// non-finite points or options out of range.
SkinWeights skin_weights(const Grid& grid, const std::uint8_t* mask, const Rig& rig,
                         const std::vector<std::array<double, 3>>& points, const SkinOptions& options = {},
                         const Progress& progress = {});

}  // namespace volrig

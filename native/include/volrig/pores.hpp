// volrig/pores.hpp: pore networks of a porous medium's pore space (thesis §9.4, "oil discovery"; docs/pores.md).
//
// The pore space's Euclidean distance transform gives the maximal inscribed balls. Pores are seeded at the local
// maxima of the distance transform (the centres of the skeleton's maximal balls), largest first, a seed dropped when
// an accepted pore's ball contains its centre. Every pore voxel is then assigned to one pore by a watershed of the
// distance transform (a priority flood from the seeds, largest balls first, 6-connected), so regions meet at the
// constrictions. Throats join regions that share a voxel face; a throat's inscribed diameter is twice the largest
// distance-transform value on the interface (the narrowest ball on the way from one pore to the other).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

/// Faces of the image a pore touches (bits of PoreNetwork::pore_faces).
enum PoreFace : std::uint8_t { XMin = 1, XMax = 2, YMin = 4, YMax = 8, ZMin = 16, ZMax = 32 };

/// A pore network. World coordinates are x, y, z from the image's corner: voxel (i, j, k) spans
/// [i, i + 1) * spacing, so a voxel centre is (i + 0.5) * spacing (grid origin added).
struct PoreNetwork {
    std::int64_t pore_voxels = 0;             ///< voxels of the pore space
    std::vector<double> pore_coords;          ///< 3 per pore: centre of mass (world x, y, z)
    std::vector<double> pore_inscribed;       ///< per pore: diameter of its largest inscribed ball (world)
    std::vector<double> pore_volume;          ///< per pore: its region's volume (world)
    std::vector<std::uint8_t> pore_faces;     ///< per pore: PoreFace bits of the image faces its region touches
    std::vector<std::int32_t> throat_conns;   ///< 2 per throat: pore indices, the smaller first
    std::vector<double> throat_inscribed;     ///< per throat: 2 x the largest DT on the interface (world)
    std::vector<double> throat_coords;        ///< 3 per throat: where that largest ball is (world x, y, z)
    std::vector<double> throat_area;          ///< per throat: the interface's area (voxel faces, world)
    std::vector<double> throat_total_length;  ///< per throat: |pore 1 - throat| + |throat - pore 2| (world)
    std::vector<std::int32_t> regions;        ///< with keep_regions: per voxel its pore + 1 (0 = solid), else empty
    std::size_t pore_count() const { return pore_volume.size(); }
    std::size_t throat_count() const { return throat_inscribed.size(); }
};

/// Extracts the network of `mask`'s pore space (non-zero = pore). The distance transform treats the image's faces
/// as open (voxels outside count as pore), so pores cut by a face keep their size. Memory: a bit and a quarter a
/// voxel, and per pore voxel a float distance, an int32 region label and, while queued, a 32-bit index (64 on grids
/// above 2^32 voxels). Throws Error for a mask without pore or without solid voxels; Cancelled when `progress`
/// says so.
/// With `keep_regions`, the network keeps the region labels (4 bytes a voxel).
PoreNetwork extract_pore_network(const Grid& grid, const std::uint8_t* mask, const Progress& progress = {},
                                 bool keep_regions = false);

/// Steady transport on a network (Laplace: sum of g (x_j - x_i) = 0 at every free node): `conns` holds 2 node
/// indices per edge, `g` its conductance (> 0). Nodes flagged in `inlet` are held at 1, in `outlet` at 0 (a node in
/// both counts as inlet). Nodes of components that do not join an inlet to an outlet are left out. Returns the
/// total rate flowing out of the inlet nodes (0 when no path joins them). Sparse Cholesky (Eigen SimplicialLDLT).
double network_rate(std::size_t nodes, const std::int32_t* conns, const double* g, std::size_t edges,
                    const std::uint8_t* inlet, const std::uint8_t* outlet);

}  // namespace volrig

// mesh/winding_mask.hpp: VoxelizeMethod::Winding's mask (volrig/mesh.hpp), filled block by block from the
// generalized winding number (mesh/winding.cpp); voxelize (mesh/voxelize.cpp) calls it for Winding and, on an open
// mesh, for Auto. Internal to the core; not installed.
#pragma once

#include <cstdint>

#include "volrig/mesh.hpp"

namespace volrig::mesh_detail {

/// VoxelizeMethod::Winding: inside when |w| >= 0.5 at the voxel centre (w the generalized winding number), over
/// the grid `out`. Fills v.data (out's voxels, 0 or 1); returns the number of inside voxels. `known` (optional, on
/// `out`; Auto passes the flood's mask): voxels taken as inside without evaluating their |w|. Every other voxel is
/// decided exactly as without `known`, so the union of `known` and the result does not depend on it.
std::int64_t winding_mask(const Mesh& mesh, const Grid& out, Volume& v, const Progress& progress,
                          const std::uint8_t* known = nullptr);

}  // namespace volrig::mesh_detail

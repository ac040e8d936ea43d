// deform/rigid_layer.hpp: the rigid layer drawn over a frame (issue 18): each bone's piece of rigid tissue moved
// by that bone alone. Shared by the Deformer (pooled output, marked as written) and the public painter.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "deform/common.hpp"
#include "deform/motion.hpp"
#include "volrig/deform.hpp"

namespace volrig::deform_detail {

/// Throws unless every piece lies on the source grid with a bone of the rig.
void check_pieces(const Grid& g, const std::vector<RigidPiece>& pieces, std::size_t bone_count);

/// The box {offset, dims} holding every piece moved by its bone's motion (`motions` indexed by bone); the
/// pieces must not be empty.
Box pieces_reach(const std::vector<RigidPiece>& pieces, const std::vector<Motion>& motions);

/// Voxels drawn, and their extent relative to the box (inclusive; lo > hi when none).
struct Drawn {
    static constexpr std::int64_t kNone = std::numeric_limits<std::int64_t>::max();
    std::int64_t count = 0;
    std::int64_t lo[3] = {kNone, kNone, kNone}, hi[3] = {-1, -1, -1};
};

/// Draws the pieces over a frame on box `bx` (the Deformer's pooled output, C order or in bricks: marks what it
/// writes).
Drawn paint_layer_pooled(const VolumeView& source, const std::vector<RigidPiece>& pieces,
                         const std::vector<Motion>& motions, Sampling sampling, const Box& bx, DeformedVolume& out,
                         bool bricks);

}  // namespace volrig::deform_detail

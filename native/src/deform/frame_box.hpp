// deform/frame_box.hpp: a frame's output box on the source lattice: from the posed balls, checked, allocated, and
// cropped to the covered voxels.
#pragma once

#include <vector>

#include "deform/bone_field.hpp"
#include "deform/motion.hpp"
#include "volrig/deform.hpp"

namespace volrig::deform_detail {

/// Output box {offset, dims} from a lattice-space AABB; throws when it holds more than 2^31 voxels.
Box box_of(const Vec3d& lo, const Vec3d& hi);

/// The bounding box of the lattice points the fields' posed balls hold (each field's spheres moved by its motion).
Box posed_box(const std::vector<BoneField>& fields, const std::vector<Motion>& motions, const Grid& g);

/// An empty frame on the box {offset, dims} of the source lattice.
DeformedVolume frame_on(const Grid& source, const Box& bx);

/// Crops a frame to the sub-box {offset, dims} of its grid (relative to its own offset), in place when it already
/// has that box. With the source grid, the origin is placed as frame_on() places it.
void crop(DeformedVolume& f, const Box& sub, const Grid* source = nullptr);

/// Crops a frame to the voxels [lo, hi] (relative to its offset, inclusive); one voxel at the offset along an axis
/// where hi < lo (nothing covered).
/// bx grown to multiples of 8 (offset and dims), for a frame in bricks.
Box brick_aligned(const Box& bx);

/// A frame in bricks: marks it so, with the covered voxels' box [lo, hi] (inclusive; hi < lo: none) as its extent.
void set_extent(DeformedVolume& f, const std::int64_t* lo, const std::int64_t* hi);

void crop_to_extent(DeformedVolume& f, const std::int64_t* lo, const std::int64_t* hi, const Grid* source = nullptr);

}  // namespace volrig::deform_detail

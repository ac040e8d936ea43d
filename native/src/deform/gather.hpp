// deform/gather.hpp: one frame's output, block by block. For each 8³ output block: the fields whose rest data its
// preimage meets (with their power ranges over it), the decisions (decide.hpp) over the block, its 4³ sub-blocks,
// then voxel by voxel (one 4-byte range lookup per voxel and field, decided in int16 lanes, the rest by the later
// tiers), and the samples, written straight into the output box.
#pragma once

#include <cstdint>
#include <vector>

#include "deform/decide.hpp"
#include "volrig/deform.hpp"

namespace volrig::deform_detail {

/// What the gather found: counts for DeformStats and the covered voxels' bounding box (output indices; hi < lo on
/// an axis when nothing is covered).
struct GatherResult {
    std::int64_t covered = 0, queries = 0;
    std::int64_t by_block = 0, by_cube = 0, by_sphere = 0, by_search = 0;
    std::int64_t exact_sub_blocks = 0;
    std::int64_t contact = 0;  // voxels a yielding field gave up to another (sliding contact)
    std::int64_t lo[3], hi[3];
};

/// Fills out.bone (and out.values unless options.values is false) over the box bx (the output's offset and dims):
/// field f's voxels are labelled field_owner[f] + 1. Progress runs from 0.55 to 0.95 (the Deformer's share).
GatherResult gather(const FieldSet& set, const std::vector<std::int32_t>& field_owner, const VolumeView& source,
                    const Box& bx, const DeformOptions& o, DeformedVolume& out, const Progress& progress);

/// The output blocks each field's rest blocks (dilated by one cell: cube corners) may reach under its motion: per
/// output block of the box, a bit set over the fields (words of 64), for gather's block candidates. The fields without
/// lattice tables (blend groups) are marked where their posed balls reach when `balls` is set (else the gather takes
/// them from pose_balls as one candidate).
std::vector<std::uint64_t> candidate_bits(const FieldSet& set, const Box& bx, bool balls = true);

}  // namespace volrig::deform_detail

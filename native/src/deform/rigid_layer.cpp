// The rigid layer (issue 18; docs/ARCHITECTURE.md, "The deformation, stage by stage"): each bone's piece of rigid
// tissue moved by that bone alone, drawn over a frame. An output voxel is the piece's when its rest position,
// through the same fixed-point posed-to-rest map the spheres' gather uses, rounds to one of the piece's voxels: no
// holes, whatever the rotation, and at rest exactly the piece.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <string>

#include "deform/rigid_layer.hpp"
#include "deform/sampler.hpp"
#include "deform/value_out.hpp"
#include "volrig/deform.hpp"

namespace volrig::deform_detail {

void check_pieces(const Grid& g, const std::vector<RigidPiece>& pieces, std::size_t bone_count) {
    for (const RigidPiece& p : pieces) {
        if (p.bone < 0 || static_cast<std::size_t>(p.bone) >= bone_count)
            throw Error("rigid layer: a piece of bone " + std::to_string(p.bone) + " but the rig has " +
                        std::to_string(bone_count) + " bones");
        for (int a = 0; a < 3; ++a)
            if (p.box[a] < 0 || p.box[3 + a] < 1 || p.box[a] + p.box[3 + a] > g.dims[a])
                throw Error("rigid layer: a piece's box lies outside the source grid");
        if (!p.bits) throw Error("rigid layer: a piece without voxels");
    }
}

namespace {

/// The posed box of one piece moved by `m` (its box's corners through the forward map, a voxel of margin for
/// rounding), as {lo x, y, z, hi x, y, z} (hi exclusive).
std::array<std::int64_t, 6> posed_bounds(const RigidPiece& p, const Motion& m) {
    std::array<double, 3> lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    for (int c = 0; c < 8; ++c) {
        double x[3], y[3];
        for (int a = 0; a < 3; ++a)
            x[a] = static_cast<double>(p.box[a]) - 0.5 + ((c >> a) & 1 ? static_cast<double>(p.box[3 + a]) : 0.0);
        m.forward.apply(x, y);
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], y[a]), hi[a] = std::max(hi[a], y[a]);
    }
    std::array<std::int64_t, 6> out{};
    const double reach = static_cast<double>(kMaxCoordinate);
    for (int a = 0; a < 3; ++a) {
        out[a] = static_cast<std::int64_t>(std::floor(std::max(lo[a], -reach))) - 1;
        out[3 + a] = static_cast<std::int64_t>(std::ceil(std::min(hi[a], reach))) + 2;
    }
    return out;
}

/// Rounds a fixed-point rest coordinate to its nearest lattice index (half up, as the nearest sampler does).
inline std::int64_t nearest_index(std::int64_t v) { return (v >> Pull::kBits) + ((v >> (Pull::kBits - 1)) & 1); }

void merge(Drawn& into, const Drawn& d) {
    into.count += d.count;
    for (int a = 0; a < 3; ++a) into.lo[a] = std::min(into.lo[a], d.lo[a]), into.hi[a] = std::max(into.hi[a], d.hi[a]);
}

/// One piece over the box: rows of its posed box, each voxel whose rest position rounds into the piece.
template <class S, class Mark>
Drawn paint_piece(const S& sampler, const RigidPiece& p, const Motion& m, Sampling sampling, const Box& bx,
                  ValueOut values, BoneOut bone, Mark& mark, bool bricks) {
    const std::array<std::int64_t, 3> dims{bx[3], bx[4], bx[5]};
    const auto b = posed_bounds(p, m);
    std::int64_t lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
        lo[a] = std::max(b[a], bx[a]);
        hi[a] = std::min(b[3 + a], bx[a] + bx[3 + a]);
        if (hi[a] <= lo[a]) return Drawn{};
    }
    const std::int64_t px = p.box[3], py = p.box[4], pz = p.box[5];
    const std::int32_t label = p.bone + 1;
    Drawn all = Drawn{};
    std::mutex merging;
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(lo[2], hi[2]), [&](const tbb::blocked_range<std::int64_t>& rg) {
        Drawn mine = Drawn{};
        for (std::int64_t z = rg.begin(); z < rg.end(); ++z)
            for (std::int64_t y = lo[1]; y < hi[1]; ++y) {
                const std::int64_t q[3] = {lo[0], y, z};
                std::int64_t r[3];
                m.pull.fixed(q, r);
                const std::int64_t row = ((z - bx[2]) * bx[4] + (y - bx[1])) * bx[3] - bx[0];
                std::int64_t first = -1, last = -1, n = 0;
                for (std::int64_t x = lo[0]; x < hi[0]; ++x, m.pull.step(r, 0)) {
                    const std::int64_t i = nearest_index(r[0]) - p.box[0], j = nearest_index(r[1]) - p.box[1],
                                       k = nearest_index(r[2]) - p.box[2];
                    if (i < 0 || j < 0 || k < 0 || i >= px || j >= py || k >= pz || !p.at(i, j, k))
                        continue;
                    const std::size_t at = bricks ? brick_index(x - bx[0], y - bx[1], z - bx[2], dims)
                                                  : static_cast<std::size_t>(row + x);
                    bone.put(at, label);
                    if (values) values.put(at, sampler.sample(r, sampling));
                    if (bricks) mark(at, at + 1);
                    if (first < 0) first = x;
                    last = x;
                    ++n;
                }
                if (!n) continue;
                if (!bricks) mark(static_cast<std::size_t>(row + first), static_cast<std::size_t>(row + last + 1));
                mine.count += n;
                const std::int64_t at[2][3] = {{first - bx[0], y - bx[1], z - bx[2]}, {last - bx[0], y - bx[1], z - bx[2]}};
                for (int a = 0; a < 3; ++a)
                    mine.lo[a] = std::min(mine.lo[a], at[0][a]), mine.hi[a] = std::max(mine.hi[a], at[1][a]);
            }
        const std::lock_guard<std::mutex> hold(merging);
        merge(all, mine);
    });
    return all;
}

}  // namespace

Box pieces_reach(const std::vector<RigidPiece>& pieces, const std::vector<Motion>& motions) {
    std::array<std::int64_t, 6> u{kMaxCoordinate, kMaxCoordinate, kMaxCoordinate, -kMaxCoordinate, -kMaxCoordinate,
                                  -kMaxCoordinate};
    for (const RigidPiece& p : pieces) {
        const auto b = posed_bounds(p, motions[static_cast<std::size_t>(p.bone)]);
        for (int a = 0; a < 3; ++a) u[a] = std::min(u[a], b[a]), u[3 + a] = std::max(u[3 + a], b[3 + a]);
    }
    const Box out{u[0], u[1], u[2], u[3] - u[0], u[4] - u[1], u[5] - u[2]};
    check_box_reach(out);
    return out;
}

template <class Mark>
Drawn paint_layer(const VolumeView& source, const std::vector<RigidPiece>& pieces, const std::vector<Motion>& motions,
                  Sampling sampling, const Box& bx, ValueOut values, BoneOut bone, Mark&& mark, bool bricks = false) {
    Drawn all = Drawn{};
    with_sampler(source, [&](const auto& sampler) {
        for (const RigidPiece& p : pieces)
            merge(all, paint_piece(sampler, p, motions[static_cast<std::size_t>(p.bone)], sampling, bx, values, bone,
                                   mark, bricks));
    });
    return all;
}

/// The Deformer's use: pooled output arrays (C order, or in bricks), marked as written.
Drawn paint_layer_pooled(const VolumeView& source, const std::vector<RigidPiece>& pieces,
                         const std::vector<Motion>& motions, Sampling sampling, const Box& bx, DeformedVolume& out,
                         bool bricks) {
    return paint_layer(
        source, pieces, motions, sampling, bx, ValueOut::of(out), BoneOut::of(out),
        [&](std::size_t i0, std::size_t i1) {
            mark_bones(out, i0, i1);
            mark_values(out, i0, i1);
        },
        bricks);
}

}  // namespace volrig::deform_detail

namespace volrig {

using namespace deform_detail;

std::array<std::int64_t, 6> rigid_pieces_box(const Grid& grid, const std::vector<RigidPiece>& pieces,
                                             BoneMatrices matrices, std::size_t bone_count) {
    check_pieces(grid, pieces, bone_count);
    if (pieces.empty()) return {0, 0, 0, 0, 0, 0};
    return pieces_reach(pieces, bone_motions(matrices, bone_count, grid));
}

std::int64_t paint_rigid_pieces(const VolumeView& source, const std::vector<RigidPiece>& pieces,
                                BoneMatrices matrices, std::size_t bone_count, Sampling sampling,
                                const std::array<std::int64_t, 6>& box, float* values, std::int16_t* bone) {
    check_pieces(source.grid, pieces, bone_count);
    check_box_reach(box);
    const std::vector<Motion> motions = bone_motions(matrices, bone_count, source.grid);
    return paint_layer(source, pieces, motions, sampling, box, ValueOut{values, nullptr}, BoneOut{bone, nullptr},
                       [](std::size_t, std::size_t) {}).count;
}

}  // namespace volrig

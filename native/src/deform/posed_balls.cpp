#include "deform/posed_balls.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

namespace volrig::deform_detail {

namespace {

struct PruneScratch {
    std::vector<double> powers;
    std::vector<std::uint32_t> region, in;
    std::vector<std::uint8_t> octants;
};

/// The voxels of block k of side s (clipped to the box bx) as {lo x, y, z, hi x, y, z} (absolute output lattice).
void box_of(const Box& bx, const std::int64_t* k, std::int64_t s, double* box) {
    for (int a = 0; a < 3; ++a) {
        box[a] = static_cast<double>(bx[a] + k[a] * s);
        box[3 + a] = static_cast<double>(bx[a] + std::min(bx[3 + a], (k[a] + 1) * s) - 1);
    }
}

/// The octant_masks of the spheres list[0, n) over `box`, split into halves of `half` voxels.
void halves_masks(const PosedBalls& out, const FieldSet& set, const double* box, std::int64_t half,
                  const std::vector<std::uint32_t>& list, std::vector<double>& scratch, std::vector<std::uint8_t>& mask) {
    const double split[3] = {box[0] + static_cast<double>(half), box[1] + static_cast<double>(half),
                             box[2] + static_cast<double>(half)};
    mask.resize(list.size());
    octant_masks(out.ball.data(), out.rel, set.s2, box, split, list.data(), list.size(), scratch, mask.data());
}

/// Region r's spheres pruned (prune_balls over those meeting it), then each of its 2³ tiles' from those the
/// region's octant masks keep for the tile, with the tile's own masks for its blocks.
void prune_region(PosedBalls& out, const FieldSet& set, const Box& bx, std::size_t r, PruneScratch& sc) {
    const std::uint32_t n = out.begin[r + 1] - out.begin[r];
    if (!n) return;
    const std::int64_t k[3] = {static_cast<std::int64_t>(r) % out.nr[0], (static_cast<std::int64_t>(r) / out.nr[0]) % out.nr[1],
                               static_cast<std::int64_t>(r) / (out.nr[0] * out.nr[1])};
    double box[6];
    box_of(bx, k, PosedBalls::kRegion, box);
    sc.region.clear();
    prune_balls(out.ball.data(), out.rel, set.s2, set.bound_step, box, out.meets.data() + out.begin[r], n, sc.region,
                sc.powers);
    if (sc.region.empty()) return;
    halves_masks(out, set, box, PosedBalls::kTile, sc.region, sc.powers, sc.octants);
    std::int64_t t[3];  // its 2³ tiles
    for (t[2] = 2 * k[2]; t[2] < std::min(2 * k[2] + 2, out.nt[2]); ++t[2])
        for (t[1] = 2 * k[1]; t[1] < std::min(2 * k[1] + 2, out.nt[1]); ++t[1])
            for (t[0] = 2 * k[0]; t[0] < std::min(2 * k[0] + 2, out.nt[0]); ++t[0]) {
                sc.in.clear();
                octant_list(sc.region.data(), sc.octants.data(), sc.region.size(), PosedBalls::octant_of(t), sc.in);
                box_of(bx, t, PosedBalls::kTile, box);
                const std::size_t ti = out.tile(t);
                prune_balls(out.ball.data(), out.rel, set.s2, set.bound_step, box, sc.in.data(), sc.in.size(),
                            out.kept[ti], sc.powers);
                halves_masks(out, set, box, kBlock, out.kept[ti], sc.powers, out.octants[ti]);
            }
}

}  // namespace

PosedBalls pose_balls(const FieldSet& set, const Box& bx) {
    PosedBalls out;
    std::vector<std::array<std::uint32_t, 3>> order;  // (global, field, local)
    double reach = 1;  // the largest coordinate the maps meet (output box, rest centres)
    for (int a = 0; a < 3; ++a) reach = std::max({reach, std::abs(static_cast<double>(bx[a])), std::abs(static_cast<double>(bx[a] + bx[3 + a]))});
    for (std::size_t f = 0; f < set.fields.size(); ++f) {
        const BoneField& field = set.fields[f];
        if (field.lattice) continue;
        for (std::size_t i = 0; i < field.sph.size(); ++i) {
            if (!(field.sph[i].lim > 0)) continue;
            order.push_back({field.global[i], static_cast<std::uint32_t>(f), static_cast<std::uint32_t>(i)});
            for (int a = 0; a < 3; ++a) reach = std::max(reach, std::abs(field.sph[i].c[a]));
        }
    }
    if (order.empty()) return out;
    std::sort(order.begin(), order.end());
    out.ball.resize(order.size());
    for (std::size_t j = 0; j < order.size(); ++j) {
        const std::uint32_t f = order[j][1], i = order[j][2];
        const BoneField::Sphere& sp = set.fields[f].sph[i];
        PosedBall& b = out.ball[j];
        set.motions[f].forward.apply(sp.c, b.c);
        b.lim = sp.lim;
        b.field = static_cast<std::int32_t>(f);
        b.local = i;
    }
    // The fixed-point maps' error, 1e-9 voxel per voxel of reach along each axis, as a world length eps: a power
    // computed through them is off by at most 2 eps d + eps² at world distance d from the centre, and
    // 2 d <= d² + 1, so eps (d² + lim + 1) + eps² bounds it; 1e-9 more covers the doubles' rounding.
    const double eps = 1e-9 * (reach + 1) * std::sqrt(set.s2[0] + set.s2[1] + set.s2[2]);
    out.rel = 1e-9 + eps + eps * eps;
    const std::int64_t side = PosedBalls::kRegion;
    for (int a = 0; a < 3; ++a) out.nr[a] = (bx[3 + a] + side - 1) / side;
    const auto nreg = static_cast<std::size_t>(out.nr[0] * out.nr[1] * out.nr[2]);
    out.begin.assign(nreg + 1, 0);
    auto index = [&](std::int64_t x, std::int64_t y, std::int64_t z) { return static_cast<std::size_t>((z * out.nr[1] + y) * out.nr[0] + x); };
    for (const PosedBall& b : out.ball)
        for_ball_blocks(b.c, b.lim, 1.0, set.s2, bx, out.nr, [&](std::int64_t x, std::int64_t y, std::int64_t z) { ++out.begin[index(x, y, z) + 1]; }, side);
    for (std::size_t k = 0; k < nreg; ++k) out.begin[k + 1] += out.begin[k];
    out.meets.resize(out.begin[nreg]);
    std::vector<std::uint32_t> next(out.begin.begin(), out.begin.end() - 1);
    for (std::size_t j = 0; j < out.ball.size(); ++j)
        for_ball_blocks(out.ball[j].c, out.ball[j].lim, 1.0, set.s2, bx, out.nr,
                        [&](std::int64_t x, std::int64_t y, std::int64_t z) { out.meets[next[index(x, y, z)]++] = static_cast<std::uint32_t>(j); }, side);
    for (int a = 0; a < 3; ++a) out.nt[a] = (bx[3 + a] + PosedBalls::kTile - 1) / PosedBalls::kTile;
    out.kept.resize(static_cast<std::size_t>(out.nt[0] * out.nt[1] * out.nt[2]));
    out.octants.resize(out.kept.size());
    tbb::enumerable_thread_specific<PruneScratch> scratch;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nreg), [&](const tbb::blocked_range<std::size_t>& rg) {
        PruneScratch& sc = scratch.local();
        for (std::size_t r = rg.begin(); r != rg.end(); ++r) prune_region(out, set, bx, r, sc);
    });
    return out;
}

}  // namespace volrig::deform_detail

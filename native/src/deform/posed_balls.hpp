// deform/posed_balls.hpp: one frame's blended spheres (the smooth blend groups', fields without lattice tables)
// posed into the output lattice, listed per 32³ region and pruned per 16³ tile of the output box, so that the gather
// takes all of them as one candidate (gather.cpp, the blend candidate) instead of one per group.
//
// Every blend is rigid (blended_motion), so a sphere's power at an output point q is |q − y|² − r² with y its posed
// centre (world metric), and two spheres' powers differ by an affine function of q whatever their groups: the
// pruning that ball_range does within a group in rest space holds across groups in output space. The computed
// powers go through each group's fixed-point map (Pull), whose error against the exact rigid map is below 1e-9
// voxel per voxel of distance from the lattice origin; `rel` turns that into a margin on every bound.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "deform/common.hpp"
#include "deform/bone_field.hpp"
#include "deform/decide.hpp"

namespace volrig::deform_detail {

/// A lower bound of sphere sp's power over the box {lo x, y, z, hi x, y, z} (its centre's squared distance to the
/// box, near2, less its limit, less the margin rel (near2 + 2 lim + 1)): negative when its ball may meet the box.
template <class S>
inline double least_power_over(const S& sp, const double* box, const double* s2, double rel, double& near2) {
    double near[3];
    for (int a = 0; a < 3; ++a) {
        const double d0 = box[a] - sp.c[a], d1 = box[3 + a] - sp.c[a];
        near[a] = d0 > 0 ? d0 : (d1 < 0 ? d1 : 0.0);
    }
    near2 = length2(near[0], near[1], near[2], s2);
    return near2 - sp.lim - rel * (near2 + 2 * sp.lim + 1);
}

/// Into centre[j] (j < n) sphere list[j]'s power at the centre of the box {lo x, y, z, hi x, y, z}, into h its
/// half extents and into half2 its squared half-diagonal; returns the index j of the least (prune_balls and
/// octant_masks start from it).
template <class S>
inline std::size_t powers_at_centre(const S* sph, const double* s2, const double* box, const std::uint32_t* list,
                                    std::size_t n, double* centre, double* h, double& half2) {
    const double mid[3] = {0.5 * (box[0] + box[3]), 0.5 * (box[1] + box[4]), 0.5 * (box[2] + box[5])};
    for (int a = 0; a < 3; ++a) h[a] = 0.5 * (box[3 + a] - box[a]);
    half2 = length2(h[0], h[1], h[2], s2);
    std::size_t k = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const auto& sp = sph[list[i]];
        centre[i] = length2(mid[0] - sp.c[0], mid[1] - sp.c[1], mid[2] - sp.c[2], s2) - sp.lim;
        if (centre[i] < centre[k]) k = i;
    }
    return k;
}

/// A ball candidate's power range over a box (a group's: a preimage box in rest index space, its spheres; the blend
/// candidate's: output voxels, the posed spheres) from the spheres `in` (indices into sph, a superset of those
/// whose balls meet the box), and into `out` (in the order of `in`) the spheres that may give its power there. Two
/// spheres' powers differ by an affine function, so sphere i is beaten everywhere by the one least at the box's
/// centre (k) when their difference there exceeds its largest change over the box, 2 Σ s²·h·|c_i − c_k| (h: the
/// box's half extents); of the others, those whose balls meet the box and whose least power there is at most the
/// least of their largest powers are kept. Lower bound: the least of the kept spheres' least powers over the box;
/// upper bound: the least of their largest. Margins, rel per unit of squared distance and limit, on the safe side
/// (rounding; for posed spheres the fixed-point maps' error too); at the centre, the squared distance to the
/// box's farthest point is at most 2 (the centre's + the half-diagonal's). `scratch` holds 2 n doubles.
template <class S>
CellBounds prune_balls(const S* sph, double rel, const double* s2, double bound_step, const double* box,
                       const std::uint32_t* in, std::size_t n, std::vector<std::uint32_t>& out,
                       std::vector<double>& scratch) {
    if (n == 0) return kNoCover;
    scratch.resize(2 * n);
    double* const centre = scratch.data();      // each one's power at the box's centre
    double* const least = scratch.data() + n;   // the kept ones' least powers over the box
    double h[3], half2 = 0;
    const std::size_t k = powers_at_centre(sph, s2, box, in, n, centre, h, half2);
    auto margin = [&](std::size_t i) {  // at least rel (far² + lim + 1)
        const double lim = sph[in[i]].lim;
        return rel * (2 * (centre[i] + lim + half2) + lim + 1);
    };
    const double* ck = sph[in[k]].c;
    const double beat = centre[k] + margin(k);  // k's power at the centre, plus its margin
    const auto first = out.size();
    double least_far = kInf;
    for (std::size_t i = 0; i < n; ++i) {
        const auto& sp = sph[in[i]];
        const double change = 2 * (s2[0] * h[0] * std::abs(sp.c[0] - ck[0]) + s2[1] * h[1] * std::abs(sp.c[1] - ck[1]) +
                                   s2[2] * h[2] * std::abs(sp.c[2] - ck[2]));
        if (centre[i] - margin(i) - beat > change * (1 + 1e-9)) continue;  // beaten by k all over the box
        double near2;
        if (!(least_power_over(sp, box, s2, rel, near2) < 0)) continue;  // its ball misses the box
        double far[3];
        for (int a = 0; a < 3; ++a) far[a] = std::max(std::abs(box[a] - sp.c[a]), std::abs(box[3 + a] - sp.c[a]));
        const double far2 = length2(far[0], far[1], far[2], s2), m = rel * (far2 + sp.lim + 1);
        least[out.size() - first] = near2 - sp.lim - m;
        least_far = std::min(least_far, far2 - sp.lim + m);
        out.push_back(in[i]);
    }
    double least_near = kInf;
    std::size_t kept = first;
    for (std::size_t j = first; j < out.size(); ++j) {
        const double v = least[j - first];
        // not covering anywhere in the box (the far margin), or beaten all over it by the one whose largest power
        // is least_far
        if (!(v < 0) || v > least_far) continue;
        out[kept++] = out[j];
        least_near = std::min(least_near, v);
    }
    out.resize(kept);
    if (!(least_near < 0)) return kNoCover;
    const double inv = 1.0 / bound_step;
    return CellBounds{exact_bounds(least_near, inv).lo, exact_bounds(least_far, inv).hi};
}

/// A blended sphere posed: its centre in the output lattice (index space), its open-ball limit, and where it lives.
struct PosedBall {
    double c[3];
    double lim;
    std::int32_t field;   // its blend group's field
    std::uint32_t local;  // its index in that field
};

/// Per sphere list[j] (j < n), into mask[j]: the octants of the box {lo x, y, z, hi x, y, z} (split along each axis
/// before the voxel split[a]; bit x + 2 y + 4 z, as sub_origin) where it may give the least power of the list's
/// spheres: its bit is clear where the sphere least at the box's centre (w) beats it all over the octant. Their
/// powers differ by an affine function (prune_balls): the difference at the centre, less both margins, against its
/// largest fall from the centre into the octant, per axis. An octant's pruning then reads only its spheres (w
/// among them), not all of the box's. `scratch` holds n doubles.
template <class S>
void octant_masks(const S* sph, double rel, const double* s2, const double* box, const double* split,
                  const std::uint32_t* list, std::size_t n, std::vector<double>& scratch, std::uint8_t* mask) {
    if (n == 0) return;
    scratch.resize(n);
    double* const centre = scratch.data();  // each one's power at the box's centre
    double h[3], half2 = 0;
    const std::size_t w = powers_at_centre(sph, s2, box, list, n, centre, h, half2);
    auto margin = [&](std::size_t j) { return rel * (2 * (centre[j] + sph[list[j]].lim + half2) + sph[list[j]].lim + 1); };
    const double* cw = sph[list[w]].c;
    const double beat = centre[w] + margin(w);
    double t[3][4];  // per axis, from the centre: the lower octant's first and last voxel, the upper one's
    for (int a = 0; a < 3; ++a) {
        const double mid = 0.5 * (box[a] + box[3 + a]);
        t[a][0] = box[a] - mid;
        t[a][1] = std::min(split[a] - 1, box[3 + a]) - mid;
        t[a][2] = split[a] - mid;
        t[a][3] = box[3 + a] - mid;
    }
    for (std::size_t j = 0; j < n; ++j) {
        const double lead = centre[j] - margin(j) - beat;  // j's least lead over w at the centre
        mask[j] = 0xff;
        if (!(lead > 0)) continue;
        const auto& sp = sph[list[j]];
        double fall[3][2], slack = 0;  // per axis and half: the most the lead falls (w's gain on j) from the centre
        for (int a = 0; a < 3; ++a) {
            const double g = 2 * s2[a] * (cw[a] - sp.c[a]);  // the lead's slope along axis a
            fall[a][0] = std::max(-g * t[a][0], -g * t[a][1]);
            fall[a][1] = std::max(-g * t[a][2], -g * t[a][3]);
            slack += std::abs(g) * h[a];
        }
        slack *= 1e-9;
        std::uint8_t m = 0;
        for (int o = 0; o < 8; ++o)
            if (!(lead > fall[0][o & 1] + fall[1][(o >> 1) & 1] + fall[2][o >> 2] + slack)) m |= static_cast<std::uint8_t>(1u << o);
        mask[j] = m;
    }
}

/// The entries of list[0, n) whose mask has bit `octant`, appended to out in their order.
inline void octant_list(const std::uint32_t* list, const std::uint8_t* mask, std::size_t n, int octant,
                        std::vector<std::uint32_t>& out) {
    const auto bit = static_cast<std::uint8_t>(1u << octant);
    for (std::size_t j = 0; j < n; ++j)
        if (mask[j] & bit) out.push_back(list[j]);
}

/// The posed spheres: per region of 4³ output blocks (32³ voxels) those meeting it, and per tile of 2³ blocks (16³
/// voxels) the ones that may give the blend's power over it (prune_balls over the region's, then over the tile's:
/// the blocks' lists start from these, each from those the tile's octant_masks keep for the block).
struct PosedBalls {
    static constexpr std::int64_t kRegion = 4 * kBlock, kTile = 2 * kBlock;
    std::vector<PosedBall> ball;        // in increasing global sphere index (ties go to the lower)
    std::int64_t nr[3] = {0, 0, 0};     // regions per axis
    std::int64_t nt[3] = {0, 0, 0};     // tiles per axis
    std::vector<std::uint32_t> begin;   // per region (x fastest), then one more: its span of `meets`
    std::vector<std::uint32_t> meets;   // the balls meeting each region (with a voxel's margin), increasing
    std::vector<std::vector<std::uint32_t>> kept;  // per tile: those that may give the blend's power there
    std::vector<std::vector<std::uint8_t>> octants;  // per tile, per kept sphere: its octant_masks (the tile's blocks)
    double rel = 0;                     // margin per unit of (squared distance + limit + 1) on any power bound

    bool empty() const { return ball.empty(); }
    /// The region of output block (kx, ky, kz).
    std::size_t region(const std::int64_t* k) const {
        return static_cast<std::size_t>(((k[2] / 4) * nr[1] + k[1] / 4) * nr[0] + k[0] / 4);
    }
    /// Tile (tx, ty, tz); tile_of: the tile of output block (kx, ky, kz).
    std::size_t tile(const std::int64_t* t) const { return static_cast<std::size_t>((t[2] * nt[1] + t[1]) * nt[0] + t[0]); }
    std::size_t tile_of(const std::int64_t* k) const {
        const std::int64_t t[3] = {k[0] / 2, k[1] / 2, k[2] / 2};
        return tile(t);
    }
    /// Output block k's octant in its tile (octant_masks' bit).
    static int octant_of(const std::int64_t* k) { return static_cast<int>((k[0] & 1) | ((k[1] & 1) << 1) | ((k[2] & 1) << 2)); }
};

/// The fields without lattice tables posed by their motions, over the output box bx (empty when there are none),
/// their regions' and tiles' lists made in parallel.
PosedBalls pose_balls(const FieldSet& set, const Box& bx);

/// The blocks [a, e] of `side` voxels (of the box bx, ob blocks per axis) along axis k that the lattice span
/// [lo, hi] meets; false when none does.
inline bool block_range(double lo, double hi, const Box& bx, const std::int64_t* ob, int k, std::int64_t& a,
                        std::int64_t& e, std::int64_t side = kBlock) {
    a = std::max<std::int64_t>(0, (static_cast<std::int64_t>(std::floor(lo)) - bx[k]) / side);
    const std::int64_t top = static_cast<std::int64_t>(std::ceil(hi)) - bx[k];
    if (top < 0) return false;
    e = std::min<std::int64_t>(ob[k] - 1, top / side);
    return e >= a;
}

/// Calls f(x, y, z) for each block of `side` voxels of the box bx (ob blocks per axis) within `grow` voxels of the
/// ball of squared world radius lim around y (output index space).
template <class F>
void for_ball_blocks(const double* y, double lim, double grow, const double* s2, const Box& bx, const std::int64_t* ob,
                     F&& f, std::int64_t side = kBlock) {
    const double reach = lim * (1 + 1e-9) + 1e-9;
    std::int64_t a[3], e[3];
    for (int k = 0; k < 3; ++k) {
        const double r = std::sqrt(reach / s2[k]) + grow;
        if (!block_range(y[k] - r, y[k] + r, bx, ob, k, a[k], e[k], side)) return;
    }
    auto gap2 = [&](int k, std::int64_t blk) {  // the squared world gap along axis k to the block grown by `grow`
        const double lo = static_cast<double>(bx[k] + blk * side) - grow, hi = lo + static_cast<double>(side - 1) + 2 * grow;
        const double g = std::max({lo - y[k], 0.0, y[k] - hi});
        return s2[k] * g * g;
    };
    for (std::int64_t z = a[2]; z <= e[2]; ++z) {
        const double gz = gap2(2, z);
        if (gz > reach) continue;
        for (std::int64_t yy = a[1]; yy <= e[1]; ++yy) {
            const double gy = gz + gap2(1, yy);
            if (gy > reach) continue;
            for (std::int64_t x = a[0]; x <= e[0]; ++x)
                if (gy + gap2(0, x) <= reach) f(x, yy, z);
        }
    }
}

}  // namespace volrig::deform_detail

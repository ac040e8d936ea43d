#include "deform/gather.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "deform/gatherer.hpp"
#include "deform/closed_cubes.hpp"
#include "deform/posed_balls.hpp"
#include "deform/sampler.hpp"
#include "deform/value_out.hpp"

namespace volrig::deform_detail {

namespace {

/// Sets bit b of output block (x, y, z) (`words` words a block).
void set_bit(std::vector<std::uint64_t>& bits, const std::int64_t* ob, std::size_t words, std::size_t b, std::int64_t x,
             std::int64_t y, std::int64_t z) {
    bits[static_cast<std::size_t>((z * ob[1] + y) * ob[0] + x) * words + b / 64] |= std::uint64_t{1} << (b % 64);
}

/// Sets bit b in the output blocks that meet the box {lo x, y, z, hi x, y, z} (absolute output lattice) widened by
/// a voxel.
void mark_blocks(std::vector<std::uint64_t>& bits, const double* box, const Box& bx, const std::int64_t* ob,
                 std::size_t words, std::size_t b) {
    std::int64_t a[3], e[3];
    for (int k = 0; k < 3; ++k)
        if (!block_range(box[k] - 1, box[3 + k] + 1, bx, ob, k, a[k], e[k])) return;
    for (std::int64_t z = a[2]; z <= e[2]; ++z)
        for (std::int64_t y = a[1]; y <= e[1]; ++y)
            for (std::int64_t x = a[0]; x <= e[0]; ++x) set_bit(bits, ob, words, b, x, y, z);
}

/// Sets bit b in the output blocks within two voxels of the ball of squared world radius lim around y (output
/// index space): a blend's map is rigid, so a posed ball is the ball of its radius around its posed centre, and the
/// margin covers the preimage boxes' widening by a voxel.
void mark_ball_blocks(std::vector<std::uint64_t>& bits, const double* y, double lim, const double* s2, const Box& bx,
                      const std::int64_t* ob, std::size_t words, std::size_t b) {
    for_ball_blocks(y, lim, 2.0, s2, bx, ob, [&](std::int64_t x, std::int64_t yy, std::int64_t z) { set_bit(bits, ob, words, b, x, yy, z); });
}

}  // namespace

std::vector<std::uint64_t> candidate_bits(const FieldSet& set, const Box& bx, bool balls) {
    const std::int64_t ob[3] = {(bx[3] + kBlock - 1) / kBlock, (bx[4] + kBlock - 1) / kBlock,
                                (bx[5] + kBlock - 1) / kBlock};
    const std::size_t words = (set.fields.size() + 63) / 64;
    std::vector<std::uint64_t> bits(static_cast<std::size_t>(ob[0] * ob[1] * ob[2]) * words, 0);
    for (std::size_t b = 0; b < set.fields.size(); ++b) {
        const Affine& fw = set.motions[b].forward;
        const BoneField& f = set.fields[b];
        for (const auto& sp : f.sph) {  // a field without lattice tables: the blocks each posed ball meets
            if (f.lattice || !balls || !(sp.lim > 0)) continue;
            double y[3];
            fw.apply(sp.c, y);
            mark_ball_blocks(bits, y, sp.lim, set.s2, bx, ob, words, b);
        }
        for (const auto& blk : f.blocks) {
            double box[6] = {kInf, kInf, kInf, -kInf, -kInf, -kInf};  // the image of the dilated rest block
            for (int c = 0; c < 8; ++c) {
                const double x[3] = {static_cast<double>(blk[0] + ((c & 1) ? kBlock : -1)),
                                     static_cast<double>(blk[1] + (((c >> 1) & 1) ? kBlock : -1)),
                                     static_cast<double>(blk[2] + (((c >> 2) & 1) ? kBlock : -1))};
                double y[3];
                fw.apply(x, y);
                for (int a = 0; a < 3; ++a) {
                    box[a] = std::min(box[a], y[a]);
                    box[3 + a] = std::max(box[3 + a], y[a]);
                }
            }
            mark_blocks(bits, box, bx, ob, words, b);
        }
    }
    return bits;
}

// ---- Gather (deform/gatherer.hpp): candidates, decisions, labels, writing (powers and lanes: gather_powers.cpp)

/// The bounding box of field f's preimages of the output voxels q0 + [0, side)³ (absolute lattice), in fixed point:
/// the cells [ra, rb] of the rest cubes holding them and the box itself as doubles (rest index space; exact: the
/// lookups' cells are the integer parts of the very same values, and the samples' points those values).
void Gather::preimage_box(std::int32_t f, const std::int64_t* q0, std::int64_t side, std::int64_t* ra,
                          std::int64_t* rb, double* box) const {
    const Pull& pl = s_.pull(f);
    std::int64_t p0[3];
    pl.fixed(q0, p0);
    for (int a = 0; a < 3; ++a) {
        std::int64_t lo_f = p0[a], hi_f = p0[a];
        for (int j = 0; j < 3; ++j) {
            const std::int64_t d = pl.a[3 * a + j] * (side - 1);
            (d < 0 ? lo_f : hi_f) += d;
        }
        ra[a] = lo_f >> Pull::kBits;
        rb[a] = hi_f >> Pull::kBits;
        box[a] = Pull::to_double(lo_f);
        box[3 + a] = Pull::to_double(hi_f);
    }
}

/// The quantised range of field f's power over the preimages of the output voxels q0 + [0, side)³ (absolute
/// lattice): over the rest cubes holding them (preimage_box). With `single`, also the sphere whose power is the
/// field's on all of those cubes, or kNone; the range is then that sphere's over the box, when sharper.
CellBounds Gather::preimage_range(std::int32_t f, const std::int64_t* q0, std::int64_t side,
                                  std::uint32_t* single) const {
    std::int64_t ra[3], rb[3];
    double box[6];
    preimage_box(f, q0, side, ra, rb, box);
    const BoneField& field = s_.field(f);
    const CellBounds r = field.range_bounds(ra, rb);
    if (!single) return r;
    *single = r.lo < 0 ? field.single_sphere(ra, rb) : kNone;
    if (*single == kNone) return r;
    const CellBounds e = sphere_box_range(field, *single, box, s_.s2, s_.bound_step);
    return CellBounds{std::max(r.lo, e.lo), std::min(r.hi, e.hi)};
}

/// A ball candidate's power range over a box and the spheres that may give its power there (prune_balls).
template <class S>
CellBounds Gather::ball_range(const S* sph, double rel, const double* box, const std::uint32_t* in, std::size_t n,
                              std::vector<std::uint32_t>& out, Local& loc) const {
    return prune_balls(sph, rel, s_.s2, s_.bound_step, box, in, n, out, loc.near_power);
}

/// Field f (without lattice tables) as a candidate of the block: its range over the block's preimage and the
/// spheres that may give its power there (a small group's scanned all, a large one's found by its k-d tree); false
/// when none of them covers any of it.
bool Gather::ball_candidate(const Block& b, std::int32_t f, Local& loc) const {
    std::int64_t ra[3], rb[3];
    double box[6];
    preimage_box(f, b.base, kBlock, ra, rb, box);
    const BoneField& field = s_.field(f);
    const std::uint32_t* in = loc.all_balls.data();
    std::size_t n = field.sph.size();
    if (n > loc.all_balls.size()) {  // a large group: the spheres whose balls meet the box, by its k-d tree
        spheres_meeting(field, box, box + 3, s_.spacing, s_.s2, loc.near);
        in = loc.near.id.data();
        n = loc.near.id.size();
    }
    const auto begin = static_cast<std::uint32_t>(loc.block_balls.size());
    const CellBounds rg = ball_range(field.sph.data(), 1e-9, box, in, n, loc.block_balls, loc);
    if (rg.lo >= 0) {
        loc.block_balls.resize(begin);
        return false;
    }
    // in increasing global index (the sub-blocks' lists keep this order): ball_powers' ties keep the lower
    std::sort(loc.block_balls.begin() + begin, loc.block_balls.end(),
              [&](std::uint32_t a, std::uint32_t c) { return field.global[a] < field.global[c]; });
    loc.fields.push_back(f);
    loc.range.push_back(rg);
    loc.ball.push_back(kGroup);
    loc.block_span.push_back({begin, static_cast<std::uint32_t>(loc.block_balls.size())});
    return true;
}

/// The blend candidate of the block (kBlend): its range over the block's voxels from the posed spheres of its tile
/// that the tile's octant masks keep for the block, and those that may give its power there (indices into
/// posed_.ball, increasing); none when none covers.
void Gather::blend_candidate(const Block& b, Local& loc) const {
    const std::size_t t = posed_.tile_of(b.k);
    const std::vector<std::uint32_t>& tile = posed_.kept[t];
    loc.octant_in.clear();
    octant_list(tile.data(), posed_.octants[t].data(), tile.size(), PosedBalls::octant_of(b.k), loc.octant_in);
    const std::vector<std::uint32_t>& in = loc.octant_in;
    if (in.empty()) return;
    double box[6];
    block_box(b, box);
    const auto begin = static_cast<std::uint32_t>(loc.block_balls.size());
    const CellBounds rg = ball_range(posed_.ball.data(), posed_.rel, box, in.data(), in.size(), loc.block_balls, loc);
    if (rg.lo >= 0) {
        loc.block_balls.resize(begin);
        return;
    }
    loc.fields.push_back(kBlend);
    loc.range.push_back(rg);
    loc.ball.push_back(kBlendBalls);
    loc.block_span.push_back({begin, static_cast<std::uint32_t>(loc.block_balls.size())});
}

/// Sliding contact's candidates of a block (loc.all_fields): the block's, with the blend candidate's groups one by
/// one (every group a posed sphere meeting the block belongs to: a field that yields hands its voxels to the
/// others, so none may be left out for being beaten), in increasing order. Here, before decide_block drops the
/// candidates that cannot win, the block's own; the groups are added by contact_groups at the block's first
/// voxel whose winner yields (few blocks of a contact zone have one).
void Gather::contact_fields(Local& loc) const {
    loc.all_fields.clear();
    loc.groups_pending = false;
    for (std::size_t k = 0; k < loc.fields.size(); ++k) {
        if (loc.ball[k] == kBlendBalls) loc.groups_pending = true;
        else loc.all_fields.push_back(loc.fields[k]);
    }
}

/// The blend candidate's groups of the block, appended to loc.all_fields in increasing order: those of the posed
/// balls of its region (posed_.meets) that meet the block.
void Gather::contact_groups(const Block& b, Local& loc) const {
    loc.groups_pending = false;
    double box[6];
    block_box(b, box);
    const std::size_t r = posed_.region(b.k);
    const auto first = loc.all_fields.size();
    for (std::uint32_t j = posed_.begin[r]; j < posed_.begin[r + 1]; ++j) {
        const PosedBall& pb = posed_.ball[posed_.meets[j]];
        double near2;
        if (least_power_over(pb, box, s_.s2, posed_.rel, near2) < 0) loc.all_fields.push_back(pb.field);
    }
    std::sort(loc.all_fields.begin() + static_cast<std::ptrdiff_t>(first), loc.all_fields.end());
    loc.all_fields.erase(std::unique(loc.all_fields.begin() + static_cast<std::ptrdiff_t>(first), loc.all_fields.end()),
                         loc.all_fields.end());
}

/// The fields whose rest data the block's preimage meets and that may cover it, with their power ranges over it.
void Gather::block_candidates(const Block& b, Local& loc) const {
    loc.fields.clear();
    loc.range.clear();
    loc.ball.clear();
    loc.block_span.clear();
    loc.block_balls.clear();
    const std::size_t blk = static_cast<std::size_t>((b.k[2] * nb_[1] + b.k[1]) * nb_[0] + b.k[0]);
    for (std::size_t w = 0; w < words_; ++w) {
        std::uint64_t m = bits_[blk * words_ + w];
        while (m) {
            const auto f = static_cast<std::int32_t>(w * 64 + static_cast<std::size_t>(__builtin_ctzll(m)));
            m &= m - 1;
            if (!s_.field(f).lattice) {
                ball_candidate(b, f, loc);
                continue;
            }
            double plo[3] = {kInf, kInf, kInf}, phi[3] = {-kInf, -kInf, -kInf};
            for (int c = 0; c < 8; ++c) {
                const std::int64_t q[3] = {b.base[0] + ((c & 1) ? kBlock : 0), b.base[1] + (((c >> 1) & 1) ? kBlock : 0),
                                           b.base[2] + (((c >> 2) & 1) ? kBlock : 0)};
                double r[3];
                s_.pull(f).apply(q, r);
                for (int a = 0; a < 3; ++a) {
                    plo[a] = std::min(plo[a], r[a]);
                    phi[a] = std::max(phi[a], r[a]);
                }
            }
            std::int64_t ca[3], cc[3];
            for (int a = 0; a < 3; ++a) {
                ca[a] = static_cast<std::int64_t>(std::floor(plo[a])) - 1;
                cc[a] = static_cast<std::int64_t>(std::floor(phi[a])) + 1;
            }
            if (!s_.field(f).any_block(ca, cc)) continue;
            std::uint32_t single;
            const CellBounds rg = preimage_range(f, b.base, kBlock, &single);
            if (rg.lo >= 0) continue;
            loc.fields.push_back(f);
            loc.range.push_back(rg);
            loc.ball.push_back(kLattice);
            loc.block_span.push_back({0, 0});
        }
    }
    if (!posed_.empty()) blend_candidate(b, loc);
}

/// Candidate k's range over the preimage of the 4³ sub-block sb (first voxel q0): from the lattice tables (and
/// loc.single), or from the spheres that may give a ball candidate's power over the block (and loc.sub_balls).
CellBounds Gather::sub_range(std::size_t k, const std::int64_t* q0, int sb, Local& loc) const {
    const std::int32_t f = loc.fields[k];
    const std::size_t ks = k * 8 + static_cast<std::size_t>(sb);
    if (loc.ball[k] == kLattice) return preimage_range(f, q0, 4, &loc.single[ks]);
    double box[6];
    const auto span = loc.block_span[k];
    const auto begin = static_cast<std::uint32_t>(loc.sub_balls.size());
    CellBounds r;
    if (loc.ball[k] == kBlendBalls) {  // the blend candidate: over the sub-block's voxels (a superset at the box's edge)
        for (int a = 0; a < 3; ++a) {
            box[a] = static_cast<double>(q0[a]);
            box[3 + a] = static_cast<double>(q0[a] + 3);
        }
        loc.octant_in.clear();  // those of the block's spheres that blend_sub_masks keeps for the sub-block
        octant_list(loc.block_balls.data() + span[0], loc.blend_octants.data(), span[1] - span[0], sb, loc.octant_in);
        r = ball_range(posed_.ball.data(), posed_.rel, box, loc.octant_in.data(), loc.octant_in.size(), loc.sub_balls,
                       loc);
    } else {
        std::int64_t ra[3], rb[3];
        preimage_box(f, q0, 4, ra, rb, box);
        r = ball_range(s_.field(f).sph.data(), 1e-9, box, loc.block_balls.data() + span[0], span[1] - span[0],
                       loc.sub_balls, loc);
    }
    loc.sub_span[ks] = {begin, static_cast<std::uint32_t>(loc.sub_balls.size())};
    return r;
}

/// The whole block first: a candidate that cannot win anywhere in it drops out, and one covering all of it and
/// winning everywhere fills it with no lookups; else the sub-blocks.
void Gather::decide_block(const Block& b, Local& loc) const {
    std::int32_t* const win = loc.win;
    loc.live.resize(loc.fields.size());
    const std::int32_t whole = decide_.settle(loc.range.data(), loc.fields.size(), loc.live.data(), 1);
    if (whole < 0) return decide_sub_blocks(b, loc);
    // the blend candidate's field is known per voxel only, unless all the balls that may give its power over the
    // block are one field's (then the least of them is that field's at every voxel): else its sub-blocks
    std::int32_t field = loc.fields[static_cast<std::size_t>(whole)];
    if (loc.ball[static_cast<std::size_t>(whole)] == kBlendBalls) {
        field = one_field(loc.block_balls.data(), loc.block_span[static_cast<std::size_t>(whole)]);
        if (field < 0) return decide_sub_blocks(b, loc);
    }
    std::fill(win, win + 512, kEmpty);
    for (std::int64_t dz = 0; dz < b.e[2]; ++dz)
        for (std::int64_t dy = 0; dy < b.e[1]; ++dy)
            std::fill(win + (dz * 8 + dy) * 8, win + (dz * 8 + dy) * 8 + b.e[0], field);
    loc.by[0] += b.e[0] * b.e[1] * b.e[2];
}

/// The octant_masks of the blend candidate's spheres of the block (loc.block_balls[span]) over its 4³ sub-blocks,
/// into loc.blend_octants: sub_range prunes each sub-block's from those its mask keeps.
void Gather::blend_sub_masks(const Block& b, Local& loc, std::array<std::uint32_t, 2> span) const {
    double box[6], split[3];  // the block's voxels (a superset at the box's edge, as sub_range's sub-blocks)
    for (int a = 0; a < 3; ++a) {
        box[a] = static_cast<double>(b.base[a]);
        box[3 + a] = box[a] + (kBlock - 1);
        split[a] = box[a] + 4;
    }
    loc.blend_octants.resize(span[1] - span[0]);
    octant_masks(posed_.ball.data(), posed_.rel, s_.s2, box, split, loc.block_balls.data() + span[0], span[1] - span[0],
                 loc.near_power, loc.blend_octants.data());
}

/// Each 4³ sub-block, from each live candidate's range over the sub-block's preimage: decided whole the same way,
/// or looked up voxel by voxel for the candidates live there.
void Gather::decide_sub_blocks(const Block& b, Local& loc) const {
    auto& cand = loc.fields;
    std::size_t K = 0;
    for (std::size_t k = 0; k < cand.size(); ++k)
        if (loc.live[k]) {
            loc.ball[K] = loc.ball[k];
            loc.block_span[K] = loc.block_span[k];
            cand[K++] = cand[k];
        }
    cand.resize(K);
    for (std::size_t k = 0; k < K; ++k)
        if (loc.ball[k] == kBlendBalls) blend_sub_masks(b, loc, loc.block_span[k]);
    loc.sub_balls.clear();
    loc.sub_span.resize(K * 8);
    std::int32_t sub_win[8];  // kOpen: decided voxel by voxel; else kEmpty or the winning field
    loc.live.assign(K * 8, 0);
    loc.single.assign(K * 8, kNone);
    bool any_open = false;
    auto& sr = loc.range_sub;
    sr.resize(K);
    for (int sb = 0; sb < 8; ++sb) {
        const auto s0 = sub_origin(sb);
        sub_win[sb] = kEmpty;
        if (s0[0] >= b.e[0] || s0[1] >= b.e[1] || s0[2] >= b.e[2]) continue;
        const std::int64_t q0[3] = {b.base[0] + s0[0], b.base[1] + s0[1], b.base[2] + s0[2]};
        for (std::size_t k = 0; k < K; ++k) sr[k] = sub_range(k, q0, sb, loc);
        std::uint8_t* lv = loc.live.data() + sb;
        const std::int32_t w = decide_.settle(sr.data(), K, lv, 8);
        const std::int32_t one = w >= 0 && loc.ball[static_cast<std::size_t>(w)] == kBlendBalls
                                     ? one_field(loc.sub_balls.data(), loc.sub_span[static_cast<std::size_t>(w) * 8 + static_cast<std::size_t>(sb)])
                                     : kNoField;
        if (one >= 0) {  // the blend candidate wins all of it, and its balls there are one field's
            sub_win[sb] = one;
            lv[static_cast<std::size_t>(w) * 8] = 0;
        } else if (w >= 0 && loc.ball[static_cast<std::size_t>(w)] == kBlendBalls) {  // its voxels' fields from its exact powers
            sub_win[sb] = kOpen;
            any_open = true;
        } else if (w >= 0) {
            sub_win[sb] = cand[static_cast<std::size_t>(w)];
            lv[static_cast<std::size_t>(w) * 8] = 0;
        } else {
            sub_win[sb] = w;
            any_open = any_open || w == kOpen;
        }
    }
    std::int32_t* const win = loc.win;
    if (any_open) {
        lookups(b, loc);
        lanes(loc);
        undecided(b, loc);
    } else {
        std::fill(win, win + 512, kEmpty);
    }
    for (int sb = 0; sb < 8; ++sb) {  // the sub-blocks decided whole
        if (sub_win[sb] == kOpen) continue;
        const auto s0 = sub_origin(sb);
        const std::int64_t x1 = std::min(s0[0] + 4, b.e[0]);
        if (x1 <= s0[0]) continue;
        for (std::int64_t dz = s0[2]; dz < std::min(s0[2] + 4, b.e[2]); ++dz)
            for (std::int64_t dy = s0[1]; dy < std::min(s0[1] + 4, b.e[1]); ++dy) {
                std::fill(win + (dz * 8 + dy) * 8 + s0[0], win + (dz * 8 + dy) * 8 + x1, sub_win[sb]);
                if (sub_win[sb] >= 0) loc.by[0] += x1 - s0[0];
            }
    }
}

/// Per candidate and voxel of its live sub-blocks: the range of the cube holding the voxel's preimage, or, where
/// one sphere's power is the field's over the whole sub-block, that power itself (exact_powers). The cells' ranges
/// are loaded apart from the address arithmetic, so that many loads are in flight at once.
void Gather::lookups(const Block& b, Local& loc) const {
    const std::size_t K = loc.fields.size();
    loc.cube_lo.resize(K * 512);
    loc.cube_hi.resize(K * 512);
    loc.cube_cell.resize(K * 512);
    loc.exact.resize(K * 512);
    loc.exact_local.resize(K * 512);
    loc.exact_field.resize(K * 512);
    if (loc.running.size() < K) {
        loc.running.resize(K);
        loc.cands.resize(K);
    }
    for (std::size_t k = 0; k < K; ++k) {
        if (loc.ball[k] != kLattice) {  // (no cells: load_first_label takes its exact powers)
            std::fill(loc.cube_lo.data() + k * 512, loc.cube_lo.data() + (k + 1) * 512, kBoundMax);
            std::fill(loc.cube_hi.data() + k * 512, loc.cube_hi.data() + (k + 1) * 512, kBoundMax);
            for (int sb = 0; sb < 8; ++sb) {
                if (!loc.live[k * 8 + static_cast<std::size_t>(sb)]) continue;
                if (loc.ball[k] == kBlendBalls) blend_powers(b, loc, k, sb);
                else ball_powers(b, loc, k, sb);
            }
            continue;
        }
        std::uint32_t* at = loc.cube_cell.data() + k * 512;
        std::fill(at, at + 512, kNoCell);
        for (int sb = 0; sb < 8; ++sb)
            if (loc.live[k * 8 + static_cast<std::size_t>(sb)] && loc.single[k * 8 + static_cast<std::size_t>(sb)] == kNone)
                cube_cells(b, loc, k, sb);
        std::int16_t* klo = loc.cube_lo.data() + k * 512;
        std::int16_t* khi = loc.cube_hi.data() + k * 512;
        const CellBounds* cells = s_.field(loc.fields[k]).bounds.data();
        for (std::size_t li = 0; li < 512; ++li) {
            const CellBounds c = cells[at[li]];
            klo[li] = c.lo;
            khi[li] = c.hi;
        }
        for (int sb = 0; sb < 8; ++sb)
            if (loc.live[k * 8 + static_cast<std::size_t>(sb)] && loc.single[k * 8 + static_cast<std::size_t>(sb)] != kNone)
                exact_powers(b, loc, k, sb);
    }
}

/// Candidate k's cube lower bound at voxel li, as a power.
double Gather::cube_lower(const Local& loc, std::size_t k, std::size_t li) const {
    const std::int16_t lo = loc.cube_lo[k * 512 + li];
    return lo == kBoundMin ? -kInf : lo * s_.bound_step;
}

/// Tier 3's candidate r from loc.running[r] at voxel li: its first-corner sphere's power (U, an upper bound of its
/// field's power) and its cube's lower bound; false when no sphere labels its cube.
bool Gather::load_first_label(Local& loc, std::size_t r, std::size_t li, const std::int64_t* m3) const {
    const auto k = static_cast<std::size_t>(loc.running[r]);
    Candidate& c = loc.cands[r];
    c.field = field_at(loc, k, li);
    if (loc.ball[k] != kLattice) {  // computed already (ball_powers, blend_powers)
        c.U = c.L = loc.exact[k * 512 + li];
        c.local = loc.exact_local[k * 512 + li];
        c.exact = c.sharp_L = true;
        c.closed = false;
        return true;
    }
    const std::uint32_t one = loc.single[k * 8 + sub_of(li)];
    if (one != kNone) {  // one sphere's power is the field's here: computed already
        c.U = c.L = loc.exact[k * 512 + li];
        c.local = one;
        c.exact = c.sharp_L = true;
        c.closed = false;
        return true;
    }
    const BoneField& f = s_.field(c.field);
    const std::uint32_t word = f.words[loc.cube_cell[k * 512 + li]];
    const std::uint32_t lab = label_of(word);
    if (lab == kNone) return false;
    s_.pull(c.field).fixed(m3, c.pf);
    Pull::to_double(c.pf, c.p);
    c.U = power_of(f, lab, c.p, s_.s2);
    c.local = lab;
    c.exact = same_of(word);
    c.closed = !c.exact && closed_of(word);
    c.L = c.exact ? c.U : cube_lower(loc, k, li);
    c.sharp_L = c.exact;
    return true;
}

/// Tier 3's candidates at voxel li, the lanes' best first: a rival whose cube lower bound lies above the first
/// candidate's U loses to it for certain (or, U >= 0, covers nowhere), so it leaves the running without being
/// loaded (smooth modes' blend groups crowd a voxel with such rivals). Compacts loc.running to the n_run left;
/// false when one of them has no label (then tier 3 cannot decide).
bool Gather::load_first_labels(Local& loc, std::size_t& n_run, std::size_t li, const std::int64_t* m3) const {
    const auto end = loc.running.begin() + static_cast<std::ptrdiff_t>(n_run);
    const auto first = std::find(loc.running.begin(), end, static_cast<std::int32_t>(loc.best[li]));
    if (first != end) std::iter_swap(loc.running.begin(), first);
    bool loaded = load_first_label(loc, 0, li, m3);
    const double u = loaded ? loc.cands[0].U : kInf;
    std::size_t n = 1;
    for (std::size_t r = 1; r < n_run; ++r) {
        const std::int32_t k = loc.running[r];
        if (cube_lower(loc, static_cast<std::size_t>(k), li) > u) continue;
        loc.running[n] = k;
        loaded = loaded && load_first_label(loc, n, li, m3);
        ++n;
    }
    n_run = n;
    return loaded;
}

/// Whether some voxel of the output block k (x, y, z) may lie past the contact plane within its zone: a corner of
/// the block past the plane (margin for rounding), and the block's box within reach of the joint.
bool Gather::block_meets(const Contact& c, const std::int64_t* k) const {
    double past = 0, d2 = 0;  // the most any corner lies past the plane; the box's squared distance from the joint
    for (int a = 0; a < 3; ++a) {
        const double lo = static_cast<double>(bx_[a] + k[a] * kBlock), hi = lo + kBlock - 1;
        past += std::max(c.normal[a] * (lo - c.joint[a]), c.normal[a] * (hi - c.joint[a]));
        const double gap = std::max({lo - c.joint[a], 0.0, c.joint[a] - hi});
        d2 += s_.s2[a] * gap * gap;
    }
    return past > -1e-9 && d2 < c.reach2 * (1 + 1e-9);
}

/// The output blocks where a contact plane may make a field yield: past the plane within its zone.
void Gather::mark_contact_zones() {
    if (!s_.contacts) return;
    for (const auto& planes : *s_.contacts)
        for (const Contact& c : planes) {
            if (zone_.empty()) zone_.assign(static_cast<std::size_t>(nb_[0] * nb_[1] * nb_[2]), 0);
            std::int64_t k0[3], k1[3];
            for (int a = 0; a < 3; ++a) {
                const double r = std::sqrt(c.reach2) / s_.spacing[a];
                k0[a] = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor((c.joint[a] - r - static_cast<double>(bx_[a])) / kBlock)));
                k1[a] = std::min<std::int64_t>(nb_[a] - 1, static_cast<std::int64_t>(std::floor((c.joint[a] + r - static_cast<double>(bx_[a])) / kBlock)));
            }
            std::int64_t k[3];
            for (k[2] = k0[2]; k[2] <= k1[2]; ++k[2])
                for (k[1] = k0[1]; k[1] <= k1[1]; ++k[1])
                    for (k[0] = k0[0]; k[0] <= k1[0]; ++k[0])
                        if (block_meets(c, k)) zone_[static_cast<std::size_t>((k[2] * nb_[1] + k[1]) * nb_[0] + k[0])] = 1;
        }
}

/// Sliding contact (bend.hpp) over a block in a contact zone: where the winner yields, the least power over the
/// block's other candidates that do not yield there, when one covers (exactly the scatter's (yields, power) key:
/// a winner that does not yield has the least power of all; one that does keeps the voxel only when every field
/// covering it yields).
void Gather::slide(const Block& b, Local& loc) const {
    const FieldContacts& fc = *s_.contacts;
    for (std::size_t li = 0; li < 512; ++li) {
        const std::int32_t w = loc.win[li];
        if (w < 0 || fc[static_cast<std::size_t>(w)].empty()) continue;
        const std::int64_t d[3] = {static_cast<std::int64_t>(li & 7), static_cast<std::int64_t>((li >> 3) & 7),
                                   static_cast<std::int64_t>(li >> 6)};
        if (d[0] >= b.e[0] || d[1] >= b.e[1] || d[2] >= b.e[2]) continue;  // past the box's edge
        const std::int64_t m3[3] = {b.base[0] + d[0], b.base[1] + d[1], b.base[2] + d[2]};
        if (!yields(fc[static_cast<std::size_t>(w)], m3, s_.s2)) continue;
        if (loc.groups_pending) contact_groups(b, loc);
        loc.others.clear();
        for (const std::int32_t f : loc.all_fields)
            if (f != w && !yields(fc[static_cast<std::size_t>(f)], m3, s_.s2)) loc.others.push_back(f);
        if (loc.cands.size() < loc.others.size()) loc.cands.resize(loc.others.size());
        const std::int32_t v = decide_.resolve(loc.others.data(), loc.others.size(), m3, loc.cands.data(), loc.queries);
        if (v < 0) continue;
        loc.win[li] = v;
        ++loc.contact;
    }
}

/// The voxels the lanes left open, one by one: tier 3, then tier 4.
void Gather::undecided(const Block& b, Local& loc) const {
    const std::size_t K = loc.fields.size();
    std::int32_t* const win = loc.win;
    for (std::size_t li = 0; li < 512; ++li) {
        if (win[li] != kOpen) continue;
        const std::int64_t m3[3] = {b.base[0] + static_cast<std::int64_t>(li & 7),
                                    b.base[1] + static_cast<std::int64_t>((li >> 3) & 7),
                                    b.base[2] + static_cast<std::int64_t>(li >> 6)};
        std::size_t n_run = 0;  // the candidates that may still cover and win
        for (std::size_t k = 0; k < K; ++k) {
            loc.running[n_run] = static_cast<std::int32_t>(k);
            n_run += in_running(loc.cube_lo[k * 512 + li], loc.least_hi[li], s_.nearest);
        }
        if (!s_.nearest && n_run && load_first_labels(loc, n_run, li, m3)) {
            const std::int32_t w = decide_.by_first_label(loc.cands.data(), n_run);
            if (w != kOpen) {
                win[li] = w;
                loc.by[2] += w >= 0;
                continue;
            }
        }
        for (std::size_t r = 0; r < n_run; ++r) loc.running[r] = field_at(loc, static_cast<std::size_t>(loc.running[r]), li);
        win[li] = decide_.resolve(loc.running.data(), n_run, m3, loc.cands.data(), loc.queries);
        loc.by[3] += win[li] >= 0;
    }
}

/// The samples of the block's covered voxels in row order (as write_block visits them), each through its winning
/// field's map as the decisions saw it (along a row, a run of one field steps its preimage by a column). Nearest
/// sampling takes the elements' indices first and loads them apart from that arithmetic, so that many loads of the
/// source (far larger than the caches) are in flight at once: waiting on one load a voxel was half of the writing.
template <class S>
void Gather::block_samples(const Block& b, const Local& loc, const S& sampler, float* v) const {
    const bool nearest = o_.sampling == Sampling::Nearest;
    std::int64_t at[512];
    std::size_t n = 0;
    for (std::int64_t dz = 0; dz < b.e[2]; ++dz)
        for (std::int64_t dy = 0; dy < b.e[1]; ++dy) {
            const std::int32_t* wrow = loc.win + (dz * 8 + dy) * 8;
            std::int32_t run = -1;  // the field of the previous voxel in the row, -1 after a gap
            std::int64_t pf[3] = {0, 0, 0};
            for (std::int64_t dx = 0; dx < b.e[0]; ++dx) {
                const std::int32_t w = wrow[dx];
                if (w < 0) {
                    run = -1;
                    continue;
                }
                const Pull& pl = s_.pull(w);
                if (w == run) {
                    pl.step(pf, 0);
                } else {
                    const std::int64_t m3[3] = {b.base[0] + dx, b.base[1] + dy, b.base[2] + dz};
                    pl.fixed(m3, pf);
                    run = w;
                }
                if (nearest) at[n++] = sampler.nearest_index(pf);
                else v[n++] = sampler.trilinear(pf);
            }
        }
    if (nearest)
        for (std::size_t i = 0; i < n; ++i) v[i] = sampler.element(at[i]);
}

/// The covered voxels, straight into the output row by row (C order, or the block's brick: the box is then aligned
/// to them): the bone label, and the sample (block_samples). Marks what it writes, records the covered voxels in
/// loc.layer, and returns their count.
template <class S>
std::int64_t Gather::write_block(const Block& b, Local& loc, const S& sampler) const {
    const std::int64_t nx = bx_[3], ny = bx_[4];
    std::int64_t ncov = 0;
    const BoneOut bone_out = BoneOut::of(out_);
    const ValueOut value_out = ValueOut::of(out_);
    float v[512];
    if (value_out) block_samples(b, loc, sampler, v);
    std::size_t n = 0;  // the next sample
    for (std::int64_t dz = 0; dz < b.e[2]; ++dz)
        for (std::int64_t dy = 0; dy < b.e[1]; ++dy) {
            const std::int32_t* wrow = loc.win + (dz * 8 + dy) * 8;
            const std::int64_t bx0 = b.k[0] * kBlock, y = b.k[1] * kBlock + dy, z = b.k[2] * kBlock + dz;
            const auto row = o_.bricks ? brick_index(bx0, y, z, out_.grid.dims) : static_cast<std::size_t>((z * ny + y) * nx + bx0);
            std::uint64_t xs = 0;
            for (std::int64_t dx = 0; dx < b.e[0]; ++dx) {
                const std::int32_t w = wrow[dx];
                if (w < 0) continue;
                xs |= std::uint64_t{1} << dx;
                bone_out.put(row + static_cast<std::size_t>(dx), owner_[static_cast<std::size_t>(w)] + 1);
                if (value_out) value_out.put(row + static_cast<std::size_t>(dx), v[n++]);
            }
            if (!xs) continue;
            ncov += __builtin_popcountll(xs);
            loc.layer[dz] |= xs << (8 * dy);
            const auto x0 = static_cast<std::size_t>(__builtin_ctzll(xs)), x1 = static_cast<std::size_t>(64 - __builtin_clzll(xs));
            mark_bones(out_, row + x0, row + x1);
            mark_values(out_, row + x0, row + x1);
        }
    return ncov;
}

/// Grows the thread's covered extent by the block's, from its bit layers.
void Gather::add_extent(const Block& b, Local& loc) const {
    std::uint64_t all = 0;
    std::int64_t z0 = -1, z1 = -1;
    for (std::int64_t dz = 0; dz < b.e[2]; ++dz)
        if (loc.layer[dz]) {
            all |= loc.layer[dz];
            if (z0 < 0) z0 = dz;
            z1 = dz;
        }
    std::uint64_t rows = 0, cols = 0;
    for (int dy = 0; dy < 8; ++dy) {
        const std::uint64_t r = (all >> (8 * dy)) & 0xff;
        rows |= std::uint64_t{r != 0} << dy;
        cols |= r;
    }
    const std::int64_t e0[3] = {__builtin_ctzll(cols), __builtin_ctzll(rows), z0},
                       e1[3] = {63 - __builtin_clzll(cols), 63 - __builtin_clzll(rows), z1};
    for (int a = 0; a < 3; ++a) {
        loc.lo[a] = std::min(loc.lo[a], b.k[a] * kBlock + e0[a]);
        loc.hi[a] = std::max(loc.hi[a], b.k[a] * kBlock + e1[a]);
    }
}

/// One block: its candidates, decisions, sliding contact and writing (block index k, x fastest).
template <class S>
void Gather::one_block(const Block& b, std::int64_t k, Local& loc, const S& sampler) const {
    block_candidates(b, loc);
    if (loc.fields.empty()) return;
    if (loc.fields.size() > 32767) throw Error("deform: more than 32767 bones or weight groups meet one output block");
    std::fill(loc.layer, loc.layer + 8, std::uint64_t{0});
    const bool contact = !zone_.empty() && zone_[static_cast<std::size_t>(k)];
    if (contact) contact_fields(loc);  // decide_block drops those that cannot win
    decide_block(b, loc);
    if (contact) slide(b, loc);
    const std::int64_t ncov = write_block(b, loc, sampler);
    if (!ncov) return;
    loc.covered += ncov;
    add_extent(b, loc);
}

/// One pass over all blocks (no barriers), a task per region of 4³ blocks (posed_'s regions, x fastest within), so
/// that the source its blocks sample and their tiles' posed balls stay in the caches from one block to the next
/// (along the box's rows of blocks, a block's neighbours in y and z came a whole row or slab of blocks later); the
/// calling thread reports progress as regions complete, and a cancel from it unwinds the whole loop.
template <class S>
void Gather::run(const S& sampler, const Progress& progress) {
    constexpr std::int64_t kSide = PosedBalls::kRegion / kBlock;  // blocks per region and axis
    const std::int64_t nr[3] = {(nb_[0] + kSide - 1) / kSide, (nb_[1] + kSide - 1) / kSide, (nb_[2] + kSide - 1) / kSide};
    const std::int64_t regions = nr[0] * nr[1] * nr[2];
    std::atomic<std::int64_t> done{0};
    const std::thread::id caller = std::this_thread::get_id();
    std::int64_t next_report = regions / 40;
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, regions, 1), [&](const tbb::blocked_range<std::int64_t>& rg) {
        Local& loc = locals_.local();
        for (std::int64_t r = rg.begin(); r != rg.end(); ++r) {
            const std::int64_t r0[3] = {(r % nr[0]) * kSide, ((r / nr[0]) % nr[1]) * kSide, (r / (nr[0] * nr[1])) * kSide};
            for (std::int64_t kz = r0[2]; kz < std::min(r0[2] + kSide, nb_[2]); ++kz)
                for (std::int64_t ky = r0[1]; ky < std::min(r0[1] + kSide, nb_[1]); ++ky)
                    for (std::int64_t kx = r0[0]; kx < std::min(r0[0] + kSide, nb_[0]); ++kx)
                        one_block(block(kx, ky, kz), (kz * nb_[1] + ky) * nb_[0] + kx, loc, sampler);
        }
        const std::int64_t now = done.fetch_add(static_cast<std::int64_t>(rg.size())) + static_cast<std::int64_t>(rg.size());
        if (progress && std::this_thread::get_id() == caller && now >= next_report) {
            next_report = now + regions / 40;
            report(progress, 0.55 + 0.4 * static_cast<double>(now) / static_cast<double>(regions));
        }
    });
    report(progress, 0.95);
}

GatherResult Gather::result() const {
    GatherResult r;
    for (int a = 0; a < 3; ++a) {
        r.lo[a] = bx_[3 + a];
        r.hi[a] = -1;
    }
    for (const Local& loc : locals_) {
        r.covered += loc.covered;
        r.queries += loc.queries;
        r.by_block += loc.by[0];
        r.by_cube += loc.by[1];
        r.by_sphere += loc.by[2];
        r.by_search += loc.by[3];
        r.exact_sub_blocks += loc.exact_pairs;
        r.contact += loc.contact;
        for (int a = 0; a < 3; ++a) {
            r.lo[a] = std::min(r.lo[a], loc.lo[a]);
            r.hi[a] = std::max(r.hi[a], loc.hi[a]);
        }
    }
    return r;
}

GatherResult gather(const FieldSet& set, const std::vector<std::int32_t>& field_owner, const VolumeView& source,
                    const Box& bx, const DeformOptions& o, DeformedVolume& out, const Progress& progress) {
    Gather g(set, field_owner, bx, o, out);
    with_sampler(source, [&](auto sampler) { g.run(sampler, progress); });
    return g.result();
}

}  // namespace volrig::deform_detail

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

namespace {

std::vector<std::uint32_t> iota(std::size_t n) {
    std::vector<std::uint32_t> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<std::uint32_t>(i);
    return v;
}

/// One thread's scratch and tallies.
struct Local {
    std::vector<Candidate> cands;
    std::int64_t lo[3] = {std::numeric_limits<std::int64_t>::max(), std::numeric_limits<std::int64_t>::max(),
                          std::numeric_limits<std::int64_t>::max()};
    std::int64_t hi[3] = {-1, -1, -1};
    std::int64_t covered = 0, queries = 0, by[4] = {0, 0, 0, 0};  // block, cube, sphere, search
    std::int64_t exact_pairs = 0;  // (candidate, sub-block) pairs whose powers came from one sphere
    std::int64_t contact = 0;      // voxels given up by a yielding field
    std::vector<std::int32_t> fields, running;  // the block's candidate fields; those still in the running at a voxel
    std::vector<std::int32_t> all_fields, others;  // sliding contact: every candidate; those not yielding at a voxel
    std::vector<CellBounds> range, range_sub;
    std::vector<std::uint8_t> live;
    // per candidate, per voxel of the block: the cube holding its preimage, split into lanes
    std::vector<std::int16_t> cube_lo, cube_hi;
    std::vector<std::uint32_t> cube_cell;   // the cells themselves, for their words
    // per candidate, per 4³ sub-block: the sphere whose power is the candidate's over all of the sub-block's
    // preimage (kNone when there is none), and then per voxel of such sub-blocks that power, exact
    std::vector<std::uint32_t> single;
    std::vector<double> exact;
    // Ball candidates (a blend group's field, or the blend candidate): per candidate its Kind, the spheres that may
    // give its power over the block (a span of block_balls), per (candidate, sub-block) those over the sub-block (a
    // span of sub_balls), and per voxel of its live sub-blocks the sphere giving `exact`
    std::vector<std::uint8_t> ball;
    std::vector<std::uint32_t> block_balls, sub_balls, exact_local;
    std::vector<std::int32_t> exact_field;  // the blend candidate's: per voxel the field (group) giving `exact`
    std::vector<std::array<std::uint32_t, 2>> block_span, sub_span;
    NearSpheres near;
    std::vector<double> near_power;
    std::vector<std::uint32_t> all_balls = iota(64);  // 0, 1, ...: all spheres of a small group, scanned at once
    std::int16_t least_hi[512];             // the least upper bound over the candidates
    std::int16_t best[512];                 // the candidate giving it
    std::int16_t rival_lo[512];             // the least lower bound over the others
    std::int16_t least_lo[512];             // the least lower bound over all
    std::int16_t least_lo_arg[512];         // the candidate giving it
    std::int16_t second_lo[512];            // the least lower bound over the others than that one
    std::int32_t win[512];                  // per voxel: the winning field, kEmpty or kOpen
    std::uint64_t layer[8];                 // covered voxels, one bit per (dy, dx) per dz
};

/// What a candidate is (Local::ball): a field with lattice tables (a bone), a blend group's field taken from its
/// spheres (nearest-centre proximity), or the blend candidate: all blended spheres at once (posed_balls.hpp), whose
/// field is known per voxel only (loc.exact_field) and whose loc.fields entry is kBlend.
enum Kind : std::uint8_t { kLattice = 0, kGroup = 1, kBlendBalls = 2 };
constexpr std::int32_t kBlend = -3;

/// The origin of 4³ sub-block sb (bits x, y, z) in its 8³ block.
std::array<std::int64_t, 3> sub_origin(int sb) { return {(sb & 1) * 4, ((sb >> 1) & 1) * 4, (sb >> 2) * 4}; }

class Gather {
public:
    Gather(const FieldSet& set, const std::vector<std::int32_t>& owner, const Box& bx, const DeformOptions& o,
           DeformedVolume& out)
        : s_(set), decide_(set), owner_(owner), bx_(bx), o_(o), out_(out), merge_(!set.nearest),
          posed_(merge_ ? pose_balls(set, bx) : PosedBalls{}), bits_(candidate_bits(set, bx, !merge_)) {
        for (int a = 0; a < 3; ++a) nb_[a] = (bx[3 + a] + kBlock - 1) / kBlock;
        words_ = (set.fields.size() + 63) / 64;
        mark_contact_zones();
    }

    template <class S>
    void run(const S& sampler, const Progress& progress);
    GatherResult result() const;

private:
    /// One block's extent inside the box and its first voxel (absolute lattice).
    struct Block {
        std::int64_t k[3], e[3], base[3];
    };
    Block block(std::int64_t kx, std::int64_t ky, std::int64_t kz) const {
        Block b{{kx, ky, kz}, {}, {}};
        for (int a = 0; a < 3; ++a) {
            b.e[a] = std::min(kBlock, bx_[3 + a] - b.k[a] * kBlock);
            b.base[a] = b.k[a] * kBlock + bx_[a];
        }
        return b;
    }
    /// The block's voxels as a box {lo x, y, z, hi x, y, z} (output lattice).
    static void block_box(const Block& b, double* box) {
        for (int a = 0; a < 3; ++a) {
            box[a] = static_cast<double>(b.base[a]);
            box[3 + a] = static_cast<double>(b.base[a] + b.e[a] - 1);
        }
    }
    void preimage_box(std::int32_t f, const std::int64_t* q0, std::int64_t side, std::int64_t* ra, std::int64_t* rb,
                      double* box) const;
    CellBounds preimage_range(std::int32_t f, const std::int64_t* q0, std::int64_t side,
                              std::uint32_t* single = nullptr) const;
    CellBounds sub_range(std::size_t k, const std::int64_t* q0, int sb, Local& loc) const;
    template <class S>
    CellBounds ball_range(const S* sph, double rel, const double* box, const std::uint32_t* in, std::size_t n,
                          std::vector<std::uint32_t>& out, Local& loc) const;
    bool ball_candidate(const Block& b, std::int32_t f, Local& loc) const;
    void blend_candidate(const Block& b, Local& loc) const;
    void contact_fields(const Block& b, Local& loc) const;
    std::int32_t field_at(const Local& loc, std::size_t k, std::size_t li) const {
        return loc.ball[k] == kBlendBalls ? loc.exact_field[k * 512 + li] : loc.fields[k];
    }
    void block_candidates(const Block& b, Local& loc) const;
    void decide_block(const Block& b, Local& loc) const;
    void mark_contact_zones();
    bool block_meets(const Contact& c, const std::int64_t* k) const;
    void slide(const Block& b, Local& loc) const;
    void decide_sub_blocks(const Block& b, Local& loc) const;
    void lookups(const Block& b, Local& loc) const;
    void cube_cells(const Block& b, Local& loc, std::size_t k, int sb) const;
    void exact_powers(const Block& b, Local& loc, std::size_t k, int sb) const;
    void ball_powers(const Block& b, Local& loc, std::size_t k, int sb) const;
    void blend_powers(const Block& b, Local& loc, std::size_t k, int sb) const;
    void keep_exact(Local& loc, std::size_t k, const std::uint16_t* at, int nv, const double* best) const;
    void lanes(Local& loc) const;
    void undecided(const Block& b, Local& loc) const;
    double cube_lower(const Local& loc, std::size_t k, std::size_t li) const;
    bool load_first_label(Local& loc, std::size_t r, std::size_t li, const std::int64_t* m3) const;
    bool load_first_labels(Local& loc, std::size_t& n_run, std::size_t li, const std::int64_t* m3) const;
    template <class S>
    std::int64_t write_block(const Block& b, Local& loc, const S& sampler) const;
    void add_extent(const Block& b, Local& loc) const;

    const FieldSet& s_;
    const Decider decide_;
    const std::vector<std::int32_t>& owner_;
    const Box bx_;
    const DeformOptions& o_;
    DeformedVolume& out_;
    const bool merge_;          // the blend groups as one candidate (power proximity)
    const PosedBalls posed_;    // then their spheres posed
    const std::vector<std::uint64_t> bits_;
    std::vector<std::uint8_t> zone_;  // per output block: whether a contact zone meets it (empty: no contacts)
    std::int64_t nb_[3];
    std::size_t words_;
    tbb::enumerable_thread_specific<Local> locals_;
};

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

/// The blend candidate of the block (kBlend): its range over the block's voxels from the posed spheres meeting the
/// block, and those that may give its power there (indices into posed_.ball, increasing); none when none covers.
void Gather::blend_candidate(const Block& b, Local& loc) const {
    const std::vector<std::uint32_t>& in = posed_.kept[posed_.tile_of(b.k)];
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
/// others, so none may be left out for being beaten).
void Gather::contact_fields(const Block& b, Local& loc) const {
    loc.all_fields.clear();
    bool blend = false;
    for (std::size_t k = 0; k < loc.fields.size(); ++k) {
        if (loc.ball[k] == kBlendBalls) blend = true;
        else loc.all_fields.push_back(loc.fields[k]);
    }
    if (!blend) return;
    const auto first = static_cast<std::ptrdiff_t>(loc.all_fields.size());
    double box[6];
    block_box(b, box);
    const std::size_t r = posed_.region(b.k);
    for (std::uint32_t j = posed_.begin[r]; j < posed_.begin[r + 1]; ++j) {  // those whose balls meet the block
        const PosedBall& pb = posed_.ball[posed_.meets[j]];
        double near2;
        if (least_power_over(pb, box, s_.s2, posed_.rel, near2) < 0) loc.all_fields.push_back(pb.field);
    }
    std::sort(loc.all_fields.begin() + first, loc.all_fields.end());
    loc.all_fields.erase(std::unique(loc.all_fields.begin() + first, loc.all_fields.end()), loc.all_fields.end());
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
        r = ball_range(posed_.ball.data(), posed_.rel, box, loc.block_balls.data() + span[0], span[1] - span[0],
                       loc.sub_balls, loc);
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
    // (the blend candidate's field is known per voxel only: its sub-blocks)
    if (whole < 0 || loc.ball[static_cast<std::size_t>(whole)] == kBlendBalls) return decide_sub_blocks(b, loc);
    std::fill(win, win + 512, kEmpty);
    for (std::int64_t dz = 0; dz < b.e[2]; ++dz)
        for (std::int64_t dy = 0; dy < b.e[1]; ++dy)
            std::fill(win + (dz * 8 + dy) * 8, win + (dz * 8 + dy) * 8 + b.e[0], loc.fields[static_cast<std::size_t>(whole)]);
    loc.by[0] += b.e[0] * b.e[1] * b.e[2];
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
        if (w >= 0 && loc.ball[static_cast<std::size_t>(w)] == kBlendBalls) {  // its voxels' fields from its exact powers
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

/// Calls f(li, pf) for each voxel of sub-block sb of the block with its preimage under pull pl (fixed point,
/// stepping by the map's columns: exactly the direct evaluation).
template <class F>
void for_sub_block(const Pull& pl, const std::int64_t* base, const std::int64_t* e_block, int sb, F&& f) {
    const auto s0 = sub_origin(sb);
    const std::int64_t q0[3] = {base[0] + s0[0], base[1] + s0[1], base[2] + s0[2]};
    const std::int64_t e[3] = {std::min<std::int64_t>(4, e_block[0] - s0[0]), std::min<std::int64_t>(4, e_block[1] - s0[1]),
                               std::min<std::int64_t>(4, e_block[2] - s0[2])};
    const std::size_t first = static_cast<std::size_t>((s0[2] * 8 + s0[1]) * 8 + s0[0]);
    std::int64_t pz[3];
    pl.fixed(q0, pz);
    for (std::int64_t dz = 0; dz < e[2]; ++dz, pl.step(pz, 2)) {
        std::int64_t py[3] = {pz[0], pz[1], pz[2]};
        for (std::int64_t dy = 0; dy < e[1]; ++dy, pl.step(py, 1)) {
            std::int64_t px[3] = {py[0], py[1], py[2]};
            for (std::int64_t dx = 0; dx < e[0]; ++dx, pl.step(px, 0))
                f(first + static_cast<std::size_t>((dz * 8 + dy) * 8 + dx), px);
        }
    }
}

/// The preimages under pull pl of the voxels of sub-block sb (as doubles, exact) and their places in the block; returns
/// their count nv and repeats the first at nv (least_powers takes two voxels at a time; that result is not read).
int sub_block_preimages(const Pull& pl, const std::int64_t* base, const std::int64_t* e_block, int sb, double* px,
                        double* py, double* pz, std::uint16_t* at) {
    int nv = 0;
    for_sub_block(pl, base, e_block, sb, [&](std::size_t li, const std::int64_t* pf) {
        px[nv] = Pull::to_double(pf[0]);
        py[nv] = Pull::to_double(pf[1]);
        pz[nv] = Pull::to_double(pf[2]);
        at[nv++] = static_cast<std::uint16_t>(li);
    });
    px[nv] = px[0];
    py[nv] = py[0];
    pz[nv] = pz[0];
    return nv;
}

/// Candidate k's cells of the cubes holding its sub-block sb's preimages.
void Gather::cube_cells(const Block& b, Local& loc, std::size_t k, int sb) const {
    const BoneField& f = s_.field(loc.fields[k]);
    std::uint32_t* at = loc.cube_cell.data() + k * 512;
    for_sub_block(s_.pull(loc.fields[k]), b.base, b.e, sb, [&](std::size_t li, const std::int64_t* p) { at[li] = f.cube_cell(p); });
}

/// Candidate k's exact power over sub-block sb, where one sphere's power is its field's: the power of that sphere
/// at each preimage (the very expression tier 3 evaluates), and its quantised range for the lanes.
void Gather::exact_powers(const Block& b, Local& loc, std::size_t k, int sb) const {
    const BoneField& f = s_.field(loc.fields[k]);
    const std::uint32_t one = loc.single[k * 8 + static_cast<std::size_t>(sb)];
    double* pw = loc.exact.data() + k * 512;
    std::int16_t* klo = loc.cube_lo.data() + k * 512;
    std::int16_t* khi = loc.cube_hi.data() + k * 512;
    const double inv_step = 1.0 / s_.bound_step;
    for_sub_block(s_.pull(loc.fields[k]), b.base, b.e, sb, [&](std::size_t li, const std::int64_t* pf) {
        double p[3];
        Pull::to_double(pf, p);
        pw[li] = power_of(f, one, p, s_.s2);
        const CellBounds r = exact_bounds(pw[li], inv_step);
        klo[li] = r.lo;
        khi[li] = r.hi;
    });
    ++loc.exact_pairs;
}

/// Lowers best[v] (with arg[v]) to the power at (px, py, pz)[v] of the sphere (centre c, limit lim) numbered id
/// where that is less (with kTies, or equal and id less than arg[v]), for v < nv (rounded up to even: the arrays
/// hold one more). The very operations of power_of, two voxels at a time where SSE2 is at hand (the compiler does
/// not vectorise the selects).
template <bool kTies>
inline void least_powers(const double* c, double lim, double id, const double* px, const double* py, const double* pz,
                         int nv, const double* s2, double* best, double* arg) {
#if defined(__SSE2__)
    const __m128d c0 = _mm_set1_pd(c[0]), c1 = _mm_set1_pd(c[1]), c2 = _mm_set1_pd(c[2]);
    const __m128d w0 = _mm_set1_pd(s2[0]), w1 = _mm_set1_pd(s2[1]), w2 = _mm_set1_pd(s2[2]);
    const __m128d limv = _mm_set1_pd(lim), idv = _mm_set1_pd(id);
    for (int v = 0; v < nv; v += 2) {
        const __m128d dx = _mm_sub_pd(_mm_load_pd(px + v), c0), dy = _mm_sub_pd(_mm_load_pd(py + v), c1),
                      dz = _mm_sub_pd(_mm_load_pd(pz + v), c2);
        const __m128d d2 = _mm_add_pd(_mm_add_pd(_mm_mul_pd(_mm_mul_pd(w0, dx), dx), _mm_mul_pd(_mm_mul_pd(w1, dy), dy)),
                                      _mm_mul_pd(_mm_mul_pd(w2, dz), dz));
        const __m128d pw = _mm_sub_pd(d2, limv), old = _mm_load_pd(best + v), old_arg = _mm_load_pd(arg + v);
        __m128d lt = _mm_cmplt_pd(pw, old);
        if (kTies) lt = _mm_or_pd(lt, _mm_and_pd(_mm_cmpeq_pd(pw, old), _mm_cmplt_pd(idv, old_arg)));
        _mm_store_pd(best + v, _mm_or_pd(_mm_and_pd(lt, pw), _mm_andnot_pd(lt, old)));
        _mm_store_pd(arg + v, _mm_or_pd(_mm_and_pd(lt, idv), _mm_andnot_pd(lt, old_arg)));
    }
#else
    for (int v = 0; v < nv; ++v) {
        const double pw = length2(px[v] - c[0], py[v] - c[1], pz[v] - c[2], s2) - lim;
        if (pw < best[v] || (kTies && pw == best[v] && id < arg[v])) {
            best[v] = pw;
            arg[v] = id;
        }
    }
#endif
}

/// Ball candidate k's exact power over sub-block sb: the least power at each preimage over the spheres that may give
/// it there (in increasing global index, so that a tie keeps the lower), as tier 3 takes it, and its quantised
/// range for the lanes (none where it does not cover: the field's power is not negative there). Sphere by sphere
/// over all the voxels at once, so that the loop vectorises.
void Gather::ball_powers(const Block& b, Local& loc, std::size_t k, int sb) const {
    const BoneField& f = s_.field(loc.fields[k]);
    const auto span = loc.sub_span[k * 8 + static_cast<std::size_t>(sb)];
    alignas(16) double px[65], py[65], pz[65];  // the preimages (and one more: least_powers takes two at a time)
    alignas(16) double best[65], arg[65];       // the least power and its sphere (a double, exact: best's lanes)
    std::uint16_t at[64];                       // the voxels' places in the block
    std::fill(best, best + 65, kInf);
    std::fill(arg, arg + 65, 0.0);
    const int nv = sub_block_preimages(s_.pull(loc.fields[k]), b.base, b.e, sb, px, py, pz, at);
    for (std::uint32_t i = span[0]; i < span[1]; ++i) {
        const auto& sp = f.sph[loc.sub_balls[i]];
        least_powers<false>(sp.c, sp.lim, loc.sub_balls[i], px, py, pz, nv, s_.s2, best, arg);
    }
    std::uint32_t* who = loc.exact_local.data() + k * 512;
    for (int v = 0; v < nv; ++v) who[at[v]] = static_cast<std::uint32_t>(arg[v]);
    keep_exact(loc, k, at, nv, best);
}

/// The blend candidate k's exact power over sub-block sb: the least power at each voxel over the posed spheres
/// that may give it there, each through its own group's map (the preimages once per group present), ties to the
/// lower global index (the spheres come group by group, so the comparison carries the index); per voxel the field
/// and the sphere giving it.
void Gather::blend_powers(const Block& b, Local& loc, std::size_t k, int sb) const {
    const auto span = loc.sub_span[k * 8 + static_cast<std::size_t>(sb)];
    const std::uint32_t* list = loc.sub_balls.data();
    alignas(16) double px[65], py[65], pz[65];  // the preimages under the group at hand (and one more: pairs)
    alignas(16) double best[65], arg[65];       // the least power and its posed sphere (index into posed_.ball)
    std::uint16_t at[64];
    std::fill(best, best + 65, kInf);
    std::fill(arg, arg + 65, 0.0);
    int nv = 0;
    for (std::uint32_t i = span[0]; i < span[1]; ++i) {
        const std::int32_t f = posed_.ball[list[i]].field;
        bool seen = false;
        for (std::uint32_t j = span[0]; j < i && !seen; ++j) seen = posed_.ball[list[j]].field == f;
        if (seen) continue;
        nv = sub_block_preimages(s_.pull(f), b.base, b.e, sb, px, py, pz, at);  // the same voxels for every group
        const BoneField& field = s_.field(f);
        for (std::uint32_t j = i; j < span[1]; ++j) {
            const PosedBall& pb = posed_.ball[list[j]];
            if (pb.field != f) continue;
            const auto& sp = field.sph[pb.local];
            least_powers<true>(sp.c, sp.lim, list[j], px, py, pz, nv, s_.s2, best, arg);
        }
    }
    std::uint32_t* who = loc.exact_local.data() + k * 512;
    std::int32_t* whose = loc.exact_field.data() + k * 512;
    for (int v = 0; v < nv; ++v) {
        const PosedBall& pb = posed_.ball[static_cast<std::size_t>(arg[v])];
        who[at[v]] = pb.local;
        whose[at[v]] = pb.field;
    }
    keep_exact(loc, k, at, nv, best);
}

/// Candidate k's exact powers best[v] at voxels at[v] of a sub-block, and their quantised ranges for the lanes
/// (none where it does not cover: its power is not negative there).
void Gather::keep_exact(Local& loc, std::size_t k, const std::uint16_t* at, int nv, const double* best) const {
    double* pw = loc.exact.data() + k * 512;
    std::int16_t* klo = loc.cube_lo.data() + k * 512;
    std::int16_t* khi = loc.cube_hi.data() + k * 512;
    const double inv_step = 1.0 / s_.bound_step;
    for (int v = 0; v < nv; ++v) {
        const std::size_t li = at[v];
        pw[li] = best[v];
        // where it covers, a range of a few quanta around it, without exact_bounds' floors (it runs per voxel);
        // branch-free: covered or not is as good as random here
        const bool covers = best[v] < 0;
        const auto x = static_cast<std::int32_t>(std::min(std::max(best[v] * inv_step, -32766.0), 0.0));  // ceil
        klo[li] = covers ? static_cast<std::int16_t>(x - 2) : kBoundMax;
        khi[li] = covers ? static_cast<std::int16_t>(x + 1) : kBoundMax;
    }
    ++loc.exact_pairs;
}

/// Tier 2, over the block's voxels in int16 lanes: u = the least upper bound (candidate arg's), mo = the least
/// lower bound of the others, ml = the least lower bound; a voxel is empty when ml >= 0, won for certain by arg
/// when certain(u, mo), else open. One pass over the candidates: mo is the second least lower bound where the
/// least is arg's own, else the least.
void Gather::lanes(Local& loc) const {
    const std::size_t K = loc.fields.size();
    std::int16_t* const u = loc.least_hi;
    std::int16_t* const mo = loc.rival_lo;
    std::int16_t* const ml = loc.least_lo;
    std::int16_t* const arg = loc.best;
    std::int16_t* const arg_lo = loc.least_lo_arg;
    std::int16_t* const m2 = loc.second_lo;
    const std::int16_t* khi = loc.cube_hi.data();
    const std::int16_t* klo = loc.cube_lo.data();
    for (std::size_t li = 0; li < 512; ++li) {
        u[li] = khi[li];
        arg[li] = 0;
        ml[li] = klo[li];
        arg_lo[li] = 0;
        m2[li] = kBoundMax;
    }
    for (std::size_t k = 1; k < K; ++k) {
        const std::int16_t* hk = khi + k * 512;
        const std::int16_t* lk = klo + k * 512;
        const auto kk = static_cast<std::int16_t>(k);
#if defined(__SSE2__)  // eight lanes at a time (the compiler does not vectorise the selects)
        const __m128i kv = _mm_set1_epi16(kk);
        auto select = [](__m128i m, __m128i a, __m128i b) { return _mm_or_si128(_mm_and_si128(m, a), _mm_andnot_si128(m, b)); };
        for (std::size_t li = 0; li < 512; li += 8) {
            auto at = [li](std::int16_t* x) { return reinterpret_cast<__m128i*>(x + li); };
            const __m128i h = _mm_loadu_si128(reinterpret_cast<const __m128i*>(hk + li));
            const __m128i l = _mm_loadu_si128(reinterpret_cast<const __m128i*>(lk + li));
            const __m128i uo = _mm_loadu_si128(at(u)), mlo = _mm_loadu_si128(at(ml));
            const __m128i lt = _mm_cmplt_epi16(h, uo), below = _mm_cmplt_epi16(l, mlo);
            _mm_storeu_si128(at(u), _mm_min_epi16(h, uo));
            _mm_storeu_si128(at(arg), select(lt, kv, _mm_loadu_si128(at(arg))));
            _mm_storeu_si128(at(m2), select(below, mlo, _mm_min_epi16(_mm_loadu_si128(at(m2)), l)));
            _mm_storeu_si128(at(ml), _mm_min_epi16(l, mlo));
            _mm_storeu_si128(at(arg_lo), select(below, kv, _mm_loadu_si128(at(arg_lo))));
        }
#else
        for (std::size_t li = 0; li < 512; ++li) {
            const bool lt = hk[li] < u[li];
            u[li] = lt ? hk[li] : u[li];
            arg[li] = lt ? kk : arg[li];
            const bool below = lk[li] < ml[li];
            m2[li] = below ? ml[li] : std::min(m2[li], lk[li]);
            ml[li] = below ? lk[li] : ml[li];
            arg_lo[li] = below ? kk : arg_lo[li];
        }
#endif
    }
    for (std::size_t li = 0; li < 512; ++li) mo[li] = arg_lo[li] == arg[li] ? m2[li] : ml[li];
    const bool nearest = s_.nearest;
    std::int64_t sure_count = 0;
    for (std::size_t li = 0; li < 512; ++li) {
        const bool sure = certain(u[li], mo[li], nearest);
        loc.win[li] = ml[li] >= 0 ? kEmpty : (sure ? field_at(loc, static_cast<std::size_t>(arg[li]), li) : kOpen);
        sure_count += sure && ml[li] < 0;
    }
    loc.by[1] += sure_count;
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
    if (loc.cands.size() < loc.all_fields.size()) loc.cands.resize(loc.all_fields.size());
    for (std::size_t li = 0; li < 512; ++li) {
        const std::int32_t w = loc.win[li];
        if (w < 0 || fc[static_cast<std::size_t>(w)].empty()) continue;
        const std::int64_t d[3] = {static_cast<std::int64_t>(li & 7), static_cast<std::int64_t>((li >> 3) & 7),
                                   static_cast<std::int64_t>(li >> 6)};
        if (d[0] >= b.e[0] || d[1] >= b.e[1] || d[2] >= b.e[2]) continue;  // past the box's edge
        const std::int64_t m3[3] = {b.base[0] + d[0], b.base[1] + d[1], b.base[2] + d[2]};
        if (!yields(fc[static_cast<std::size_t>(w)], m3, s_.s2)) continue;
        loc.others.clear();
        for (const std::int32_t f : loc.all_fields)
            if (f != w && !yields(fc[static_cast<std::size_t>(f)], m3, s_.s2)) loc.others.push_back(f);
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

/// The covered voxels, straight into the output row by row (C order, or the block's brick: the box is then aligned
/// to them): the bone label, and the sample through the winning field's map, as the decisions saw it (along a row,
/// a run of one field steps its preimage by a column). Marks what it writes, records the covered voxels in
/// loc.layer, and returns their count.
template <class S>
std::int64_t Gather::write_block(const Block& b, Local& loc, const S& sampler) const {
    const std::int64_t nx = bx_[3], ny = bx_[4];
    std::int64_t ncov = 0;
    const BoneOut bone_out = BoneOut::of(out_);
    const ValueOut value_out = ValueOut::of(out_);
    for (std::int64_t dz = 0; dz < b.e[2]; ++dz)
        for (std::int64_t dy = 0; dy < b.e[1]; ++dy) {
            const std::int32_t* wrow = loc.win + (dz * 8 + dy) * 8;
            const std::int64_t bx0 = b.k[0] * kBlock, y = b.k[1] * kBlock + dy, z = b.k[2] * kBlock + dz;
            const auto row = o_.bricks ? brick_index(bx0, y, z, out_.grid.dims) : static_cast<std::size_t>((z * ny + y) * nx + bx0);
            std::int32_t run = -1;  // the field of the previous voxel in the row, -1 after a gap
            std::int64_t pf[3] = {0, 0, 0};
            std::uint64_t xs = 0;
            for (std::int64_t dx = 0; dx < b.e[0]; ++dx) {
                const std::int32_t w = wrow[dx];
                if (w < 0) {
                    run = -1;
                    continue;
                }
                xs |= std::uint64_t{1} << dx;
                bone_out.put(row + static_cast<std::size_t>(dx), owner_[static_cast<std::size_t>(w)] + 1);
                if (!value_out) continue;
                const Pull& pl = s_.pull(w);
                if (w == run) {
                    pl.step(pf, 0);
                } else {
                    const std::int64_t m3[3] = {b.base[0] + dx, b.base[1] + dy, b.base[2] + dz};
                    pl.fixed(m3, pf);
                    run = w;
                }
                value_out.put(row + static_cast<std::size_t>(dx), sampler.sample(pf, o_.sampling));
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

/// One pass over all blocks (no barriers); the calling thread reports progress as blocks complete, and a cancel
/// from it unwinds the whole loop.
template <class S>
void Gather::run(const S& sampler, const Progress& progress) {
    const std::int64_t total_blocks = nb_[0] * nb_[1] * nb_[2];
    std::atomic<std::int64_t> done{0};
    const std::thread::id caller = std::this_thread::get_id();
    std::int64_t next_report = total_blocks / 40;
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, total_blocks, 64), [&](const tbb::blocked_range<std::int64_t>& rg) {
        Local& loc = locals_.local();
        for (std::int64_t k = rg.begin(); k != rg.end(); ++k) {
            const Block b = block(k % nb_[0], (k / nb_[0]) % nb_[1], k / (nb_[0] * nb_[1]));
            block_candidates(b, loc);
            if (loc.fields.empty()) continue;
            if (loc.fields.size() > 32767) throw Error("deform: more than 32767 bones or weight groups meet one output block");
            std::fill(loc.layer, loc.layer + 8, std::uint64_t{0});
            const bool contact = !zone_.empty() && zone_[static_cast<std::size_t>(k)];
            if (contact) contact_fields(b, loc);  // decide_block drops those that cannot win
            decide_block(b, loc);
            if (contact) slide(b, loc);
            const std::int64_t ncov = write_block(b, loc, sampler);
            if (!ncov) continue;
            loc.covered += ncov;
            add_extent(b, loc);
        }
        const std::int64_t now = done.fetch_add(static_cast<std::int64_t>(rg.size())) + static_cast<std::int64_t>(rg.size());
        if (progress && std::this_thread::get_id() == caller && now >= next_report) {
            next_report = now + total_blocks / 40;
            report(progress, 0.55 + 0.4 * static_cast<double>(now) / static_cast<double>(total_blocks));
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

}  // namespace

GatherResult gather(const FieldSet& set, const std::vector<std::int32_t>& field_owner, const VolumeView& source,
                    const Box& bx, const DeformOptions& o, DeformedVolume& out, const Progress& progress) {
    Gather g(set, field_owner, bx, o, out);
    with_sampler(source, [&](auto sampler) { g.run(sampler, progress); });
    return g.result();
}

}  // namespace volrig::deform_detail

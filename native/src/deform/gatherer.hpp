// deform/gatherer.hpp: the Gather class behind gather() (deform/gather.hpp): one pass over the output blocks that
// decides, per voxel, the field that owns it. Its members are defined in gather.cpp (candidates, decisions, labels,
// writing) and gather_powers.cpp (the powers of sphere candidates and the lanes). Not installed; not part of the API.
#pragma once

#include <tbb/enumerable_thread_specific.h>

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include "deform/closed_cubes.hpp"
#include "deform/gather.hpp"
#include "deform/posed_balls.hpp"

namespace volrig::deform_detail {

inline std::vector<std::uint32_t> iota(std::size_t n) {
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
    bool groups_pending = false;  // sliding contact: the blend candidate's groups are still to add to all_fields
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
    std::vector<std::uint32_t> octant_in;     // the blend candidate's spheres kept for a block or sub-block
    std::vector<std::uint8_t> blend_octants;  // per sphere of its block_balls span: its octant_masks (sub-blocks)
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
constexpr std::int32_t kNoField = -4;  // one_field: the balls are more than one field's

/// The origin of 4³ sub-block sb (bits x, y, z) in its 8³ block.
inline std::array<std::int64_t, 3> sub_origin(int sb) { return {(sb & 1) * 4, ((sb >> 1) & 1) * 4, (sb >> 2) * 4}; }

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
    void contact_fields(Local& loc) const;
    void contact_groups(const Block& b, Local& loc) const;
    std::int32_t field_at(const Local& loc, std::size_t k, std::size_t li) const {
        return loc.ball[k] == kBlendBalls ? loc.exact_field[k * 512 + li] : loc.fields[k];
    }
    /// The field of all the posed balls list[span] (the blend candidate's over a block or sub-block), or kNoField
    /// when they are more than one field's (or none).
    std::int32_t one_field(const std::uint32_t* list, std::array<std::uint32_t, 2> span) const {
        if (span[0] == span[1]) return kNoField;
        const std::int32_t f = posed_.ball[list[span[0]]].field;
        for (std::uint32_t i = span[0] + 1; i < span[1]; ++i)
            if (posed_.ball[list[i]].field != f) return kNoField;
        return f;
    }
    void block_candidates(const Block& b, Local& loc) const;
    void decide_block(const Block& b, Local& loc) const;
    void mark_contact_zones();
    bool block_meets(const Contact& c, const std::int64_t* k) const;
    void slide(const Block& b, Local& loc) const;
    void blend_sub_masks(const Block& b, Local& loc, std::array<std::uint32_t, 2> span) const;
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
    void one_block(const Block& b, std::int64_t k, Local& loc, const S& sampler) const;
    template <class S>
    void block_samples(const Block& b, const Local& loc, const S& sampler, float* v) const;
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

}  // namespace volrig::deform_detail

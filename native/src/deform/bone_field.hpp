// deform/bone_field.hpp: one bone's rest data, built once per rig: its spheres in k-d order with a k-d tree, and on
// the lattice near them the power diagram's labels and each cube's quantised power range, in allocated 8³ blocks
// (docs/ALGORITHMS.md §7).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "deform/common.hpp"
#include "deform/huge_pages.hpp"
#include "deform/motion.hpp"
#include "volrig/deform.hpp"
#include "volrig/memory.hpp"

namespace volrig::deform_detail {

struct KdNode {
    double lo[3], hi[3];  // the box of the centres (world offsets)
    double blo[3], bhi[3];  // the box of the balls
    double max_lim;
    std::uint32_t begin, end;
    std::int32_t left = -1, right = -1;
};

/// The power of a bone over one lattice cube (first corner at a cell), quantised outwards to int16 steps:
/// lo <= power <= hi everywhere in the cube. kBoundMin as lo means -inf, kBoundMax as hi means +inf (and as lo,
/// "not covered anywhere in the cube"). Trivial, so that tables of them are allocated unwritten.
struct CellBounds {
    std::int16_t lo, hi;
};
constexpr std::int16_t kBoundMin = -32768, kBoundMax = 32767;
constexpr CellBounds kNoCover{kBoundMax, kBoundMax};  // no point of the cube can be covered

/// q (a power in steps) rounded down / up to an int16 bound, clamped as above. No libm call: it runs per cell.
inline std::int16_t quantized_down(double q) {
    if (!(q >= -32767)) return kBoundMin;
    if (q >= 32767) return kBoundMax;
    return static_cast<std::int16_t>(fast_floor(q));
}
inline std::int16_t quantized_up(double q) {
    if (!(q <= 32766)) return kBoundMax;
    if (q <= -32767) return -32767;
    return static_cast<std::int16_t>(-fast_floor(-q));
}

/// A lattice cell of a bone's field holds the power's quantised range over the cube with that first corner
/// (BoneField::bounds) and a word (BoneField::words): the power-diagram label at the cell, top bit set when the cube
/// has this label at all eight corners (so the power there is exactly this sphere's), the next bit set when the cube
/// is closed: the least power over its corners' labels is the bone's power wherever that is negative (see
/// closed_cube). The two live in separate arrays, so that the lookups every voxel makes read only the ranges (4 bytes
/// a cell). Cell index 0 is "no cell".
constexpr std::uint32_t kSameBit = 0x80000000u, kClosedBit = 0x40000000u;
constexpr std::uint32_t kNoCell = 0;
inline std::uint32_t label_of(std::uint32_t w) { return w == kNone ? kNone : (w & ~(kSameBit | kClosedBit)); }
inline bool same_of(std::uint32_t w) { return w != kNone && (w & kSameBit); }
inline bool closed_of(std::uint32_t w) { return w != kNone && (w & kClosedBit); }

/// The cells' words, a byte a cell: an allocated block holds few distinct words (a power cell spans many lattice
/// cells), so each block keeps its distinct words in a palette and each cell the index of its own there; a block
/// with more than 256 distinct words keeps all 512 in its palette, in cell order. Cell 0 ("no cell") reads kNone.
struct CellWords {
    HugeVector<std::uint8_t> code;       // per cell: its word's index in its block's palette
    std::vector<std::uint32_t> palette;  // the blocks' palettes, one after the other
    std::vector<std::int64_t> at;        // per block: its palette's first entry, or ~that when it holds all 512

    std::uint32_t operator[](std::uint32_t cell) const {
        if (cell == kNoCell) return kNone;
        const std::int64_t a = at[(cell - 1) >> 9];
        return palette[static_cast<std::size_t>(a >= 0 ? a + code[cell] : ~a + ((cell - 1) & 511))];
    }
    std::size_t size() const { return code.size(); }  // cells, "no cell" included
    std::size_t bytes() const { return code.size() + palette.size() * 4 + at.size() * 8; }
    bool operator==(const CellWords& o) const { return code == o.code && palette == o.palette && at == o.at; }
};

/// A lower bound at p of a function that is |x|² (world metric) plus a concave one, from its values v at the corners
/// of p's lattice cube (corner k: bits x, y, z) and p's offsets u in the cube. The concave part at p is at least any
/// convex combination of its corner values that represents p (the trilinear weights, or the barycentric weights of
/// a tetrahedron of corners holding p), and |p|² less the same combination of the corners' is −Σ s²u(1−u) for all
/// of them; the largest of the trilinear and the four Kuhn triangulations' (one per main diagonal) is taken.
inline double concave_lower(const double* v, const double* u, const double* s2) {
    for (int k = 0; k < 8; ++k)
        if (!(v[k] > -kInf)) return -kInf;
    const double c00 = v[0] + u[0] * (v[1] - v[0]), c10 = v[2] + u[0] * (v[3] - v[2]);
    const double c01 = v[4] + u[0] * (v[5] - v[4]), c11 = v[6] + u[0] * (v[7] - v[6]);
    const double c0 = c00 + u[1] * (c10 - c00), c1 = c01 + u[1] * (c11 - c01);
    double best = c0 + u[2] * (c1 - c0);
    for (int m : {0, 1, 2, 4}) {  // the diagonal from corner m to corner 7 ^ m
        const double w[3] = {(m & 1) ? 1 - u[0] : u[0], (m & 2) ? 1 - u[1] : u[1], (m & 4) ? 1 - u[2] : u[2]};
        int a = 0, b = 1, c = 2;  // axes by decreasing w
        if (w[a] < w[b]) std::swap(a, b);
        if (w[b] < w[c]) std::swap(b, c);
        if (w[a] < w[b]) std::swap(a, b);
        const int v1 = 1 << a, v2 = v1 | (1 << b);
        best = std::max(best, (1 - w[a]) * v[m] + (w[a] - w[b]) * v[v1 ^ m] + (w[b] - w[c]) * v[v2 ^ m] + w[c] * v[7 ^ m]);
    }
    const double L = best - (s2[0] * u[0] * (1 - u[0]) + s2[1] * u[1] * (1 - u[1]) + s2[2] * u[2] * (1 - u[2]));
    return L - 1e-9 * (std::abs(L) + 1.0);  // rounding margin
}

/// A field: one bone's spheres, or one smooth blend group's. A bone's field keeps lattice tables (power-diagram
/// labels, cube ranges) near its spheres; a blend group's (`lattice` false) keeps only its spheres and
/// their k-d tree: groups are small and their balls overlap their neighbours' many times over, so the gather takes
/// their powers from the few spheres meeting each preimage instead (gather.cpp, ball candidates).
struct BoneField {
    bool lattice = true;  // false: no lattice tables (lo, dims and the tables below stay empty)
    // spheres in local (k-d) order
    std::vector<std::uint32_t> global;
    struct Sphere {
        double c[3];  // centre, index space
        double lim;   // open-ball squared radius (world units²)
    };
    std::vector<Sphere> sph;
    std::vector<KdNode> nodes;
    // power-diagram labels on the lattice over [lo, lo + dims), stored in allocated 8³ blocks
    std::array<std::int64_t, 3> lo{0, 0, 0}, dims{0, 0, 0}, bdims{0, 0, 0};
    std::vector<std::int32_t> block_index;        // per block: index into the pool, -1 = F >= T everywhere
    std::vector<std::array<std::int64_t, 3>> blocks;  // allocated blocks' first cells (absolute lattice)
    HugeVector<CellBounds> bounds;                // cell 0: none (no cover), then 512 per allocated block
    CellWords words;                              // likewise (encoded per block)
    double step = 1, floor_T = 0;                 // the quantum; the least power outside allocated blocks (T)
    std::vector<std::int32_t> block_sat;          // summed-area table of allocated blocks, (bdims + 1)³
    std::vector<CellBounds> sub;                  // 8 per allocated block: the bounds' range over each 4³ sub-block
                                                  // (quantised in steps common to all fields, so that they compare)
    std::vector<std::uint64_t> pair_alone;        // per allocated block, bit m for its 2³ cells m: one sphere's
                                                  // power is the bone's on all their cubes (they have that one label
                                                  // at all corners): their first cell's (pair_sphere)

    /// The sphere (local) whose power is the bone's on all the cubes of the 2³ cells m of allocated block blk (m:
    /// bits x, y, z of two each), else kNone.
    std::uint32_t pair_sphere(std::int32_t blk, int m) const {
        if (!((pair_alone[static_cast<std::size_t>(blk)] >> m) & 1)) return kNone;
        return label_of(words[cell_of(blk, (m & 3) * 2, ((m >> 2) & 3) * 2, (m >> 4) * 2)]);
    }

    /// The quantised range of the bone's power over the cubes whose first corners lie in cells [a, b] (absolute
    /// lattice, inclusive): lo >= 0 when none of them can be covered, hi = kBoundMax when one may not be.
    CellBounds range_bounds(const std::int64_t* a, const std::int64_t* b) const {
        std::int16_t l = kBoundMax, h = kBoundMin;
        std::int64_t s0[3], s1[3];
        for (int i = 0; i < 3; ++i) {
            const std::int64_t a0 = a[i] - lo[i], b0 = b[i] - lo[i];
            if (a0 < 0 || b0 >= dims[i]) h = kBoundMax;
            s0[i] = std::max<std::int64_t>(a0, 0);
            s1[i] = std::min<std::int64_t>(b0, dims[i] - 1);
            if (s1[i] < s0[i]) return kNoCover;
            s0[i] >>= 2;
            s1[i] >>= 2;
        }
        for (std::int64_t z = s0[2]; z <= s1[2]; ++z)
            for (std::int64_t y = s0[1]; y <= s1[1]; ++y)
                for (std::int64_t x = s0[0]; x <= s1[0]; ++x) {
                    const std::int32_t blk = block_index[static_cast<std::size_t>(((z >> 1) * bdims[1] + (y >> 1)) * bdims[0] + (x >> 1))];
                    if (blk < 0) {
                        h = kBoundMax;
                        continue;
                    }
                    const CellBounds c = sub[static_cast<std::size_t>(blk) * 8 + static_cast<std::size_t>(((z & 1) * 2 + (y & 1)) * 2 + (x & 1))];
                    l = std::min(l, c.lo);
                    h = std::max(h, c.hi);
                }
        return CellBounds{l, h};
    }

    /// The sphere (local) whose power is the bone's on all the cubes whose first corners lie in cells [a, b]
    /// (absolute lattice, inclusive), from the 2³ cells' pair_sphere; kNone when there is none (or the cells reach
    /// outside the allocated blocks).
    std::uint32_t single_sphere(const std::int64_t* a, const std::int64_t* b) const {
        std::int64_t s0[3], s1[3];
        for (int i = 0; i < 3; ++i) {
            s0[i] = a[i] - lo[i];
            s1[i] = b[i] - lo[i];
            if (s0[i] < 0 || s1[i] >= dims[i]) return kNone;
            s0[i] >>= 1;
            s1[i] >>= 1;
        }
        std::uint32_t one = kNone;
        for (std::int64_t z = s0[2]; z <= s1[2]; ++z)
            for (std::int64_t y = s0[1]; y <= s1[1]; ++y)
                for (std::int64_t x = s0[0]; x <= s1[0]; ++x) {
                    const std::int32_t blk = block_index[static_cast<std::size_t>(((z >> 2) * bdims[1] + (y >> 2)) * bdims[0] + (x >> 2))];
                    if (blk < 0) return kNone;
                    const std::uint32_t k = pair_sphere(blk, static_cast<int>(((z & 3) * 4 + (y & 3)) * 4 + (x & 3)));
                    if (k == kNone || (one != kNone && k != one)) return kNone;
                    one = k;
                }
        return one;
    }

    /// The cell at the first corner of the lattice cube holding p (rest index space in fixed point, as Pull gives
    /// it: the corner is the integer part), or kNoCell (its range says no point of that cube can be covered).
    std::uint32_t cube_cell(const std::int64_t* p) const {
        return cell_at((p[0] >> Pull::kBits) - lo[0], (p[1] >> Pull::kBits) - lo[1], (p[2] >> Pull::kBits) - lo[2]);
    }

    /// The allocated block (slot) holding cell (x, y, z) (relative to lo, inside the field), -1 when none is.
    std::int32_t block_at(std::int64_t x, std::int64_t y, std::int64_t z) const {
        return block_index[static_cast<std::size_t>(((z >> 3) * bdims[1] + (y >> 3)) * bdims[0] + (x >> 3))];
    }

    /// The index of cell (x, y, z) (relative to lo), kNoCell outside the field or its allocated blocks.
    std::uint32_t cell_at(std::int64_t x, std::int64_t y, std::int64_t z) const {
        if (static_cast<std::uint64_t>(x) >= static_cast<std::uint64_t>(dims[0]) ||
            static_cast<std::uint64_t>(y) >= static_cast<std::uint64_t>(dims[1]) ||
            static_cast<std::uint64_t>(z) >= static_cast<std::uint64_t>(dims[2]))
            return kNoCell;
        const std::int32_t blk = block_at(x, y, z);
        return blk < 0 ? kNoCell : cell_of(blk, x, y, z);
    }

    /// The cells at the eight corners of the lattice cube with first corner (x, y, z) (relative to lo; corner k:
    /// bits x, y, z), kNoCell where a corner lies outside the field or its allocated blocks.
    void corner_cells(std::int64_t x, std::int64_t y, std::int64_t z, std::uint32_t* c) const {
        if (x >= 0 && y >= 0 && z >= 0 && (x & 7) != 7 && (y & 7) != 7 && (z & 7) != 7 && x + 1 < dims[0] &&
            y + 1 < dims[1] && z + 1 < dims[2]) {  // the whole cube in one block (most of the time)
            const std::int32_t blk = block_at(x, y, z);
            const std::uint32_t c0 = blk < 0 ? kNoCell : cell_of(blk, x, y, z);
            const std::uint32_t offset[8] = {0, 1, 8, 9, 64, 65, 72, 73};
            for (int k = 0; k < 8; ++k) c[k] = blk < 0 ? kNoCell : c0 + offset[k];
            return;
        }
        for (int k = 0; k < 8; ++k) c[k] = cell_at(x + (k & 1), y + ((k >> 1) & 1), z + ((k >> 2) & 1));
    }

    /// A lower bound of the power at p (fixed point, as Pull gives it) from the powers at the eight corners of its
    /// lattice cube, each its label's (concave_lower: the power is |p|² plus a concave function). Corners outside
    /// the allocated blocks hold at least T. (Defined after power_of.)
    double corner_lower(const std::int64_t* p, const double* s2) const;

    /// The index of the cell at (x, y, z) (relative to lo) in allocated block blk.
    static std::uint32_t cell_of(std::int32_t blk, std::int64_t x, std::int64_t y, std::int64_t z) {
        return 1 + static_cast<std::uint32_t>(blk) * 512 + static_cast<std::uint32_t>(((z & 7) * 8 + (y & 7)) * 8 + (x & 7));
    }

    /// Whether any allocated block meets the cells [a, b] (absolute lattice, inclusive).
    bool any_block(const std::int64_t* a, const std::int64_t* b) const {
        std::int64_t k0[3], k1[3];
        for (int i = 0; i < 3; ++i) {
            k0[i] = std::max<std::int64_t>(0, a[i] - lo[i]);
            k1[i] = std::min<std::int64_t>(dims[i] - 1, b[i] - lo[i]);
            if (k0[i] > k1[i]) return false;
            k0[i] >>= 3;
            k1[i] = (k1[i] >> 3) + 1;
        }
        const std::int64_t sx = bdims[0] + 1, sy = bdims[1] + 1;
        auto at = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
            return static_cast<std::int64_t>(block_sat[static_cast<std::size_t>((z * sy + y) * sx + x)]);
        };
        const std::int64_t n = at(k1[0], k1[1], k1[2]) - at(k0[0], k1[1], k1[2]) - at(k1[0], k0[1], k1[2]) -
                               at(k1[0], k1[1], k0[2]) + at(k0[0], k0[1], k1[2]) + at(k0[0], k1[1], k0[2]) +
                               at(k1[0], k0[1], k0[2]) - at(k0[0], k0[1], k0[2]);
        return n > 0;
    }

    std::size_t bytes() const {
        return global.size() * 4 + sph.size() * sizeof(Sphere) + nodes.size() * sizeof(KdNode) + block_index.size() * 4 +
               blocks.size() * 24 + bounds.size() * sizeof(CellBounds) + words.bytes() +
               block_sat.size() * 4 + sub.size() * sizeof(CellBounds) + pair_alone.size() * 8;
    }
};

inline double power_of(const BoneField& f, std::uint32_t k, const double* x, const double* s2) {
    const auto& sp = f.sph[k];
    return length2(x[0] - sp.c[0], x[1] - sp.c[1], x[2] - sp.c[2], s2) - sp.lim;
}

inline double BoneField::corner_lower(const std::int64_t* p, const double* s2) const {
    const std::int64_t x = p[0] >> Pull::kBits, y = p[1] >> Pull::kBits, z = p[2] >> Pull::kBits;
    std::uint32_t c[8];
    corner_cells(x - lo[0], y - lo[1], z - lo[2], c);
    double v[8];
    for (int k = 0; k < 8; ++k) {
        const std::uint32_t lab = label_of(words[c[k]]);  // (kNone for kNoCell)
        const double at[3] = {static_cast<double>(x + (k & 1)), static_cast<double>(y + ((k >> 1) & 1)),
                              static_cast<double>(z + (k >> 2))};
        v[k] = lab == kNone ? floor_T : power_of(*this, lab, at, s2);
    }
    const double u[3] = {Pull::fraction(p[0]), Pull::fraction(p[1]), Pull::fraction(p[2])};
    return concave_lower(v, u, s2);
}

/// An exact power v as a quantised range in steps of 1 / inv_step (lo <= v <= hi, with a rounding margin; lo
/// kBoundMin below the int16 range, hi kBoundMax above it). No libm floor: it runs per voxel.
inline CellBounds exact_bounds(double v, double inv_step) {
    const double x = v * inv_step, m = 1e-9 * (std::abs(x) + 1);
    const double lo = std::min(std::max(x - m, -32768.0), 32767.0), hi = std::min(std::max(x + m, -32767.0), 32767.0);
    return CellBounds{static_cast<std::int16_t>(fast_floor(lo)), static_cast<std::int16_t>(-fast_floor(-hi))};
}

/// Sphere k's power over the box {lo x, y, z, hi x, y, z} (index space) as a quantised range (outwards).
inline CellBounds sphere_box_range(const BoneField& f, std::uint32_t k, const double* box, const double* s2, double step) {
    const auto& sp = f.sph[k];
    double near[3], far[3];
    for (int a = 0; a < 3; ++a) {
        const double d0 = box[a] - sp.c[a], d1 = box[3 + a] - sp.c[a];
        near[a] = d0 > 0 ? d0 : (d1 < 0 ? d1 : 0.0);
        far[a] = std::max(std::abs(d0), std::abs(d1));
    }
    const double inv = 1.0 / step;
    return CellBounds{exact_bounds(length2(near[0], near[1], near[2], s2) - sp.lim, inv).lo,
                      exact_bounds(length2(far[0], far[1], far[2], s2) - sp.lim, inv).hi};
}

/// The power diagram over a field's lattice box (its labels, 4 bytes a cell: the values are the labels' powers,
/// recomputed where they are read), kept across the fields of one build so that each field does not fault in fresh
/// pages for its own: grows to the largest box asked for. On huge pages: the z pass and the blocks' tiles step
/// through it by whole slices.
struct DiagramScratch {
    HugeVector<std::uint32_t> lab;
    void reserve(std::size_t n) {  // uninitialised: power_diagram fills what it uses, in parallel
        if (n <= lab.size()) return;
        HugeVector<std::uint32_t>().swap(lab);  // the old lattice goes before the larger one comes
        lab.resize(n);
    }
};

/// Builds one bone's field from its spheres (global indices) with radii r: T is the power above which nothing is
/// covered (a quarter of the lattice cell's squared diagonal, with a margin), step the quantum of the power ranges
/// (shared by every field, so that fields compare as integers). `scratch` (optional) lends the power diagram's
/// lattice, for a build of many fields.
BoneField build_bone_field(const Grid& g, const BoundSpheres& s, const std::vector<std::uint32_t>& members,
                           const std::vector<double>& r, double T, double step, DiagramScratch* scratch = nullptr);

/// A field without lattice tables (a blend group's): its spheres in k-d order and their k-d tree only.
BoneField build_ball_field(const Grid& g, const BoundSpheres& s, const std::vector<std::uint32_t>& members,
                           const std::vector<double>& r, double T, double step);

/// Sets a field's open-ball limits to its spheres' radii r times `factor` (bent_radius) and refits its k-d tree's
/// ball boxes and largest limits: a blend group's field, per frame (its spheres and their order stay).
void scale_ball_field(BoneField& f, const std::vector<double>& r, double factor, const Grid& g);

}  // namespace volrig::deform_detail

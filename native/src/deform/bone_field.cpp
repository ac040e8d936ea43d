#include "deform/bone_field.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <limits>
#include <memory>
#include <numeric>

#include "deform/bend.hpp"
#include "deform/closed_cubes.hpp"
#include "volrig/reconstruct.hpp"

namespace volrig::deform_detail {

namespace {

/// A k-d tree over the spheres lifted to 4-D, (centre, sqrt(M − lim)): the power distance is the lifted Euclidean
/// distance less M, so splitting on the fourth coordinate too separates big spheres from small ones and keeps each
/// node's max_lim, which bounds its pruning, tight.
void build_kd(BoneField& f, std::vector<std::uint32_t>& order, std::uint32_t begin, std::uint32_t end,
              const std::vector<double>& w3, const std::vector<double>& lims, const std::vector<double>& lift) {
    KdNode node;
    node.begin = begin;
    node.end = end;
    node.max_lim = 0;
    for (int a = 0; a < 3; ++a) {
        node.lo[a] = node.blo[a] = kInf;
        node.hi[a] = node.bhi[a] = -kInf;
    }
    double wlo = kInf, whi = -kInf;
    for (std::uint32_t k = begin; k < end; ++k) {
        const std::uint32_t i = order[k];
        for (int a = 0; a < 3; ++a) {
            node.lo[a] = std::min(node.lo[a], w3[3 * i + a]);
            node.hi[a] = std::max(node.hi[a], w3[3 * i + a]);
            const double r = std::sqrt(std::max(0.0, lims[i]));
            node.blo[a] = std::min(node.blo[a], w3[3 * i + a] - r);
            node.bhi[a] = std::max(node.bhi[a], w3[3 * i + a] + r);
        }
        node.max_lim = std::max(node.max_lim, lims[i]);
        wlo = std::min(wlo, lift[i]);
        whi = std::max(whi, lift[i]);
    }
    const auto self = static_cast<std::int32_t>(f.nodes.size());
    f.nodes.push_back(node);
    if (end - begin <= 8) return;
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (node.hi[a] - node.lo[a] > node.hi[axis] - node.lo[axis]) axis = a;
    if (whi - wlo > node.hi[axis] - node.lo[axis]) axis = 3;
    auto key = [&](std::uint32_t i) { return axis == 3 ? lift[i] : w3[3 * i + static_cast<std::size_t>(axis)]; };
    const std::uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                     [&](std::uint32_t a, std::uint32_t b) { return key(a) < key(b) || (key(a) == key(b) && a < b); });
    const auto left = static_cast<std::int32_t>(f.nodes.size());
    build_kd(f, order, begin, mid, w3, lims, lift);
    const auto right = static_cast<std::int32_t>(f.nodes.size());
    build_kd(f, order, mid, end, w3, lims, lift);
    f.nodes[static_cast<std::size_t>(self)].left = left;
    f.nodes[static_cast<std::size_t>(self)].right = right;
}

/// One 1-D lower envelope of parabolas w·(q − p)² + f(p) over the finite samples of a line, carrying labels. In
/// units of w each parabola is x² − 2px + g(p) with g(p) = f(p) / w + p², so two of them cross where the lines
/// −2px + g(p) do: the test whether a new parabola hides the last one kept needs no division.
struct LabelEnvelope {
    std::vector<std::int64_t> v;
    std::vector<double> z, fv, gv;
    std::vector<std::uint32_t> lv;
    std::vector<double> line;           // the values along the line being run, from its labels
    std::vector<std::uint8_t> z_blocks;  // per block along z: whether a column's power dips below T at its 9 points

    /// The envelope of the n samples f[q] (contiguous; +inf: none) labelled lab[q * stride]: each sample's label
    /// becomes the envelope's, and its value too with `values`.
    void run(double* f, std::uint32_t* lab, std::int64_t n, std::int64_t stride, double w, bool values) {
        v.resize(static_cast<std::size_t>(n));
        z.resize(static_cast<std::size_t>(n) + 1);
        fv.resize(static_cast<std::size_t>(n));
        gv.resize(static_cast<std::size_t>(n));
        lv.resize(static_cast<std::size_t>(n));
        const double inv_w = 1.0 / w;
        std::int64_t k = -1;
        for (std::int64_t q = 0; q < n; ++q) {
            const double fq = f[q];
            if (!(fq < kInf)) continue;
            const double gq = fq * inv_w + static_cast<double>(q * q);
            // pop the parabolas the new one hides from where they start: the crossing (gq − gp) / 2(q − p) <= z
            while (k >= 0 && gq - gv[static_cast<std::size_t>(k)] <=
                                 2.0 * static_cast<double>(q - v[static_cast<std::size_t>(k)]) * z[static_cast<std::size_t>(k)])
                --k;
            const double s = k < 0 ? -kInf
                                   : (gq - gv[static_cast<std::size_t>(k)]) /
                                         (2.0 * static_cast<double>(q - v[static_cast<std::size_t>(k)]));
            ++k;
            v[static_cast<std::size_t>(k)] = q;
            fv[static_cast<std::size_t>(k)] = fq;
            gv[static_cast<std::size_t>(k)] = gq;
            lv[static_cast<std::size_t>(k)] = lab[q * stride];
            z[static_cast<std::size_t>(k)] = s;
        }
        if (k < 0) return;
        std::int64_t j = 0;
        for (std::int64_t q = 0; q < n; ++q) {
            while (j < k && z[static_cast<std::size_t>(j + 1)] <= static_cast<double>(q)) ++j;
            lab[q * stride] = lv[static_cast<std::size_t>(j)];
            if (values) {
                const double d = static_cast<double>(q - v[static_cast<std::size_t>(j)]);
                f[q] = fv[static_cast<std::size_t>(j)] + w * d * d;
            }
        }
    }
};

/// The power at the field's lattice point (x, y, z) (relative to lo) of its sphere `label`, +inf for kNone: the
/// power diagram's value there, recomputed from its label (the diagram keeps labels only).
inline double label_power(const BoneField& f, std::uint32_t label, std::int64_t x, std::int64_t y, std::int64_t z,
                          const double* s2) {
    if (label == kNone) return kInf;
    const auto& sp = f.sph[label];
    return length2(static_cast<double>(f.lo[0] + x) - sp.c[0], static_cast<double>(f.lo[1] + y) - sp.c[1],
                   static_cast<double>(f.lo[2] + z) - sp.c[2], s2) - sp.lim;
}

/// The field's spheres in k-d order (with the tree) and its lattice extent: beyond a margin of sqrt(r² + T) around
/// each sphere its power exceeds T, so cells outside need no labels.
void place_spheres(BoneField& f, const Grid& g, const BoundSpheres& s, const std::vector<std::uint32_t>& members,
                   const std::vector<double>& r, double T) {
    const std::size_t m = members.size();
    std::vector<double> w3(3 * m), lims(m);
    for (std::size_t k = 0; k < m; ++k) {
        const std::uint32_t i = members[k];
        for (int a = 0; a < 3; ++a) w3[3 * k + a] = static_cast<double>(s.ijk[3 * i + 2 - a]) * g.spacing[a];
        lims[k] = r[i] > 0 ? open_ball_limit_sq(r[i]) : 0.0;
    }
    std::vector<std::uint32_t> order(m);
    std::iota(order.begin(), order.end(), 0u);
    const double top = m ? *std::max_element(lims.begin(), lims.end()) : 0.0;
    std::vector<double> lift(m);
    for (std::size_t k = 0; k < m; ++k) lift[k] = std::sqrt(top - lims[k]);
    if (m) build_kd(f, order, 0, static_cast<std::uint32_t>(m), w3, lims, lift);
    f.global.resize(m);
    f.sph.resize(m);
    constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max(), kMin = std::numeric_limits<std::int64_t>::min();
    std::array<std::int64_t, 3> lo{kMax, kMax, kMax}, hi{kMin, kMin, kMin};
    for (std::size_t k = 0; k < m; ++k) {
        const std::uint32_t src = order[k];
        const std::uint32_t i = members[src];
        f.global[k] = i;
        f.sph[k] = {{static_cast<double>(s.ijk[3 * i + 2]), static_cast<double>(s.ijk[3 * i + 1]),
                     static_cast<double>(s.ijk[3 * i])},
                    lims[src]};
        const double* c = f.sph[k].c;
        for (int a = 0; a < 3; ++a) {
            const auto e = static_cast<std::int64_t>(std::ceil(std::sqrt(r[i] * r[i] + T) / g.spacing[a])) + 1;
            lo[a] = std::min(lo[a], static_cast<std::int64_t>(c[a]) - e);
            hi[a] = std::max(hi[a], static_cast<std::int64_t>(c[a]) + e + 1);
        }
    }
    if (m == 0) return;
    f.lo = lo;
    for (int a = 0; a < 3; ++a) {
        f.dims[a] = hi[a] - lo[a];
        f.bdims[a] = (f.dims[a] + kBlock - 1) / kBlock;
    }
}

/// Marks the blocks that hold a point of column (x, y) among their 9³ points (their cells and the next one along
/// each axis), in the blocks along z flagged in `z_blocks`: the column's blocks, and the ones before along x and y
/// where the column starts its block.
void mark_blocks(const BoneField& f, std::int64_t x, std::int64_t y, const std::vector<std::uint8_t>& z_blocks,
                 std::atomic<std::uint8_t>* keep) {
    const std::int64_t bx = f.bdims[0], by = f.bdims[1];
    for (std::int64_t kx = x >> 3; kx >= 0 && kx >= (x - 1) >> 3; --kx)
        for (std::int64_t ky = y >> 3; ky >= 0 && ky >= (y - 1) >> 3; --ky)
            for (std::size_t kz = 0; kz < z_blocks.size(); ++kz)
                if (z_blocks[kz]) keep[(static_cast<std::int64_t>(kz) * by + ky) * bx + kx].store(1, std::memory_order_relaxed);
}

/// The power diagram on the field's lattice: the argmin over the spheres of |v − c|² − lim (local index, kNone
/// where none reaches), by separable lower envelopes of parabolas seeded at the centres, each pass taking its
/// samples' values from their labels. The lattice runs z fastest (point (x, y, z) at (x·ny + y)·nz + z): the x
/// pass, over the few rows that hold a centre, strides through it; the y pass strides within one x slab (a few
/// hundred KB); the z pass, over every column, reads it in order. Sets `keep` (per block of the field, zeroed)
/// where the power dips below T at one of the block's 9³ points.
void power_diagram(const BoneField& f, const double* s2, double T, std::uint32_t* lab, std::atomic<std::uint8_t>* keep) {
    const std::int64_t nx = f.dims[0], ny = f.dims[1], nz = f.dims[2];
    const auto slab = static_cast<std::size_t>(ny * nz);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nx), [&](const tbb::blocked_range<std::int64_t>& rg) {
        std::fill(lab + static_cast<std::size_t>(rg.begin()) * slab, lab + static_cast<std::size_t>(rg.end()) * slab, kNone);
    });
    std::vector<std::uint8_t> seeded(slab, 0), seeded_z(static_cast<std::size_t>(nz), 0);  // per x row (y, z); per z
    for (std::size_t k = 0; k < f.sph.size(); ++k) {
        const auto& sp = f.sph[k];
        if (!(sp.lim > 0)) continue;
        const std::int64_t x = static_cast<std::int64_t>(sp.c[0]) - f.lo[0], y = static_cast<std::int64_t>(sp.c[1]) - f.lo[1],
                           z = static_cast<std::int64_t>(sp.c[2]) - f.lo[2];
        std::uint32_t& l = lab[static_cast<std::size_t>((x * ny + y) * nz + z)];
        if (l == kNone || sp.lim > f.sph[l].lim) l = static_cast<std::uint32_t>(k);
        seeded[static_cast<std::size_t>(y * nz + z)] = 1;
        seeded_z[static_cast<std::size_t>(z)] = 1;
    }
    std::vector<std::int64_t> rows;  // the x rows holding a centre, as y·nz + z
    for (std::size_t r = 0; r < slab; ++r)
        if (seeded[r]) rows.push_back(static_cast<std::int64_t>(r));
    tbb::enumerable_thread_specific<LabelEnvelope> envs;
    // The values of the line of n samples from (x, y, z) along `axis` (labels l[q * stride]) into e.line, from their
    // labels, and the least of them.
    auto values = [&](LabelEnvelope& e, const std::uint32_t* l, std::int64_t n, std::int64_t stride, std::int64_t x,
                      std::int64_t y, std::int64_t z, int axis) {
        e.line.resize(static_cast<std::size_t>(n));
        std::int64_t p[3] = {x, y, z};
        double least = kInf;
        for (std::int64_t q = 0; q < n; ++q, ++p[axis]) {
            const double v = label_power(f, l[q * stride], p[0], p[1], p[2], s2);
            e.line[static_cast<std::size_t>(q)] = v;
            least = std::min(least, v);
        }
        return least;
    };
    // The envelope along that line (the z pass keeps its values in e.line).
    auto run = [&](LabelEnvelope& e, std::uint32_t* l, std::int64_t n, std::int64_t stride, std::int64_t x,
                   std::int64_t y, std::int64_t z, int axis) {
        values(e, l, n, stride, x, y, z, axis);
        e.run(e.line.data(), l, n, stride, s2[axis], axis == 2);
    };
    // x rows holding a centre, then y columns in the z planes holding one, then every z column; each pass parallel.
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows.size()), [&](const tbb::blocked_range<std::size_t>& rg) {
        LabelEnvelope& e = envs.local();
        for (std::size_t r = rg.begin(); r != rg.end(); ++r) {
            const std::int64_t y = rows[r] / nz, z = rows[r] % nz;
            run(e, lab + rows[r], nx, ny * nz, 0, y, z, 0);
        }
    });
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nx), [&](const tbb::blocked_range<std::int64_t>& rg) {
        LabelEnvelope& e = envs.local();
        for (std::int64_t x = rg.begin(); x != rg.end(); ++x)
            for (std::int64_t z = 0; z < nz; ++z)
                if (seeded_z[static_cast<std::size_t>(z)]) run(e, lab + x * ny * nz + z, ny, nz, x, 0, z, 1);
    });
    // The z pass. A column whose values are all at least T stays so (the pass only adds to them): it marks no block,
    // and its labels are wanted only where a kept block's tile reads them (the second loop below).
    std::vector<std::uint8_t> deferred(static_cast<std::size_t>(nx * ny), 0);  // per z column (x, y)
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nx), [&](const tbb::blocked_range<std::int64_t>& rg) {
        LabelEnvelope& e = envs.local();
        e.z_blocks.resize(static_cast<std::size_t>(f.bdims[2]));
        for (std::int64_t x = rg.begin(); x != rg.end(); ++x)
            for (std::int64_t y = 0; y < ny; ++y) {
                std::uint32_t* column = lab + (x * ny + y) * nz;
                if (!(values(e, column, nz, 1, x, y, 0, 2) < T)) {
                    deferred[static_cast<std::size_t>(x * ny + y)] = 1;
                    continue;
                }
                e.run(e.line.data(), column, nz, 1, s2[2], true);
                std::fill(e.z_blocks.begin(), e.z_blocks.end(), std::uint8_t{0});  // as for x and y in mark_blocks
                bool any = false;
                for (std::int64_t z = 0; z < nz; ++z)
                    if (e.line[static_cast<std::size_t>(z)] < T) {
                        any = true;
                        e.z_blocks[static_cast<std::size_t>(z >> 3)] = 1;
                        if (z > 0) e.z_blocks[static_cast<std::size_t>((z - 1) >> 3)] = 1;
                    }
                if (any) mark_blocks(f, x, y, e.z_blocks, keep);
            }
    });
    // The deferred columns that a kept block's 9³ tile reads (those of its 8 × 8 columns, and the next along x and y)
    const std::int64_t bx = f.bdims[0], by = f.bdims[1], bz = f.bdims[2];
    std::vector<std::uint8_t> kept_column(static_cast<std::size_t>(bx * by), 0);  // per (bx, by): a kept block
    for (std::int64_t k = 0; k < bx * by * bz; ++k)
        if (keep[k].load(std::memory_order_relaxed)) kept_column[static_cast<std::size_t>(k % (bx * by))] = 1;
    auto read = [&](std::int64_t x, std::int64_t y) {
        for (std::int64_t kx = x >> 3; kx >= 0 && kx >= (x - 1) >> 3; --kx)
            for (std::int64_t ky = y >> 3; ky >= 0 && ky >= (y - 1) >> 3; --ky)
                if (kx < bx && ky < by && kept_column[static_cast<std::size_t>(ky * bx + kx)]) return true;
        return false;
    };
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nx), [&](const tbb::blocked_range<std::int64_t>& rg) {
        LabelEnvelope& e = envs.local();
        for (std::int64_t x = rg.begin(); x != rg.end(); ++x)
            for (std::int64_t y = 0; y < ny; ++y)
                if (deferred[static_cast<std::size_t>(x * ny + y)] && read(x, y)) run(e, lab + (x * ny + y) * nz, nz, 1, x, y, 0, 2);
    });
}

/// Keeps the blocks marked by power_diagram, where the power dips below T at a cell or at the cells one step above
/// (the far corners of the block's cubes): elsewhere no point can be covered, and a cube whose first corner lies in
/// a block that is not kept has no corner below T. Allocates the kept blocks' cells.
void keep_blocks(BoneField& f, const std::atomic<std::uint8_t>* keep) {
    const std::int64_t bx = f.bdims[0], by = f.bdims[1], bz = f.bdims[2];
    f.block_index.assign(static_cast<std::size_t>(bx * by * bz), -1);
    for (std::int64_t k = 0; k < bx * by * bz; ++k) {
        if (!keep[k].load(std::memory_order_relaxed)) continue;
        const std::int64_t kx = k % bx, ky = (k / bx) % by, kz = k / (bx * by);
        f.block_index[static_cast<std::size_t>(k)] = static_cast<std::int32_t>(f.blocks.size());
        f.blocks.push_back({f.lo[0] + kx * kBlock, f.lo[1] + ky * kBlock, f.lo[2] + kz * kBlock});
    }
    if (f.blocks.size() * 512 + 1 > std::numeric_limits<std::uint32_t>::max())
        throw Error("deform: a bone's field is too large (more than 2^32 lattice cells near its spheres)");
    f.bounds.resize(f.blocks.size() * 512 + 1);  // unwritten: fill_block_cells writes every block's cells, in parallel
    f.words.code.resize(f.blocks.size() * 512 + 1);  // encode_block writes them (the words go by in build_bone_field)
    f.words.at.resize(f.blocks.size());
    f.bounds[0] = kNoCover;
    f.words.code[0] = 0;
    f.sub.resize(f.blocks.size() * 8);  // sub_block_ranges writes them
    f.pair_alone.resize(f.blocks.size());  // pair_spheres writes them
}

/// A cube to close: its cell in the block and its corners' labels.
struct Pending {
    int li, nk;
    std::uint32_t ks[8];
};

/// The inputs of the per-cell pass: the power diagram's labels on the field's lattice and the constants of its
/// bounds.
struct CellPass {
    const std::uint32_t* lab;
    const double* s2;
    double T, step;
    double quarter;  // the concave term's largest value over a cube, Σ s²/4
    double slack;    // rounding margin of the quantised bounds (far above the rounding of a product by inv_step)
    double inv_step;
    std::uint32_t* words;  // the cells' words as they are made, 512 a block (encoded into BoneField::words after)
};

/// The power diagram at the 9³ lattice points of one block's cubes (its 8³ cells and the next one along each
/// axis): the labels copied column by column, so that each cell's eight corners are read from a small local tile,
/// and their powers. Points outside the field hold the label kOutside (no sphere) and the power T (at least that
/// there).
struct Tile {
    static constexpr std::uint32_t kOutside = kNone - 1;
    double F[729];
    std::uint32_t lab[729];
    std::uint8_t seen;  // bit d (x, y, z): the points at 8 along those axes lie in an allocated block (d = 0: its own)

    /// Whether a query reads the label at tile point (x, y, z): its cell is allocated (the points at 8 along an axis
    /// belong to the next block, which may not be kept).
    bool visible(int x, int y, int z) const { return (seen >> ((x >> 3) | ((y >> 3) << 1) | ((z >> 3) << 2))) & 1; }

    void load(const BoneField& f, std::size_t slot, const std::uint32_t* lab_all, double T, const double* s2) {
        const std::int64_t nx = f.dims[0], ny = f.dims[1], nz = f.dims[2];
        const std::int64_t x0 = f.blocks[slot][0] - f.lo[0], y0 = f.blocks[slot][1] - f.lo[1], z0 = f.blocks[slot][2] - f.lo[2];
        seen = 0;
        for (int d = 0; d < 8; ++d)  // (a block past the field's edge: its points are kOutside, no label either way)
            seen |= static_cast<std::uint8_t>(f.cell_at(x0 + (d & 1) * kBlock, y0 + ((d >> 1) & 1) * kBlock,
                                                        z0 + (d >> 2) * kBlock) != kNoCell) << d;
        const std::int64_t ex = std::min<std::int64_t>(9, nx - x0), ey = std::min<std::int64_t>(9, ny - y0),
                           ez = std::min<std::int64_t>(9, nz - z0);
        if (ex < 9 || ey < 9 || ez < 9) {
            std::fill(F, F + 729, T);
            std::fill(lab, lab + 729, kOutside);
        }
        for (std::int64_t x = 0; x < ex; ++x)
            for (std::int64_t y = 0; y < ey; ++y) {
                const std::uint32_t* run = lab_all + ((x0 + x) * ny + y0 + y) * nz + z0;  // (the lattice runs z fastest)
                for (std::int64_t z = 0; z < ez; ++z) {
                    const auto i = static_cast<std::size_t>((z * 9 + y) * 9 + x);
                    lab[i] = run[z];
                    F[i] = label_power(f, run[z], x0 + x, y0 + y, z0 + z, s2);
                }
            }
    }
};

/// Per cube of a block (first corner at cell li): the least of its eight corners' powers and whether the eight
/// carry one label, made axis by axis over the tile (each pair of neighbours compared once, not once per cube).
struct CubeSummaries {
    double fmin[512];
    bool one[512];

    void make(const Tile& t) {
        double mx[648], my[576];  // the least over the corners so far: along x (9·9·8), then y (9·8·8)
        bool ex[648], ey[576];    // likewise whether their labels agree
        for (int r = 0; r < 81; ++r)
            for (int x = 0; x < 8; ++x) {
                const int i = r * 9 + x;
                mx[r * 8 + x] = std::min(t.F[i], t.F[i + 1]);
                ex[r * 8 + x] = t.lab[i] == t.lab[i + 1];
            }
        for (int z = 0; z < 9; ++z)
            for (int y = 0; y < 8; ++y)
                for (int x = 0; x < 8; ++x) {
                    const int a = (z * 9 + y) * 8 + x, o = (z * 8 + y) * 8 + x, i = (z * 9 + y) * 9 + x;
                    my[o] = std::min(mx[a], mx[a + 8]);
                    ey[o] = ex[a] && ex[a + 8] && t.lab[i] == t.lab[i + 9];
                }
        for (int li = 0; li < 512; ++li) {
            const int i = ((li >> 6) * 9 + ((li >> 3) & 7)) * 9 + (li & 7);
            fmin[li] = std::min(my[li], my[li + 64]);
            one[li] = ey[li] && ey[li + 64] && t.lab[i] == t.lab[i + 81];
        }
    }
};

/// The distinct labels (in corner order) of the eight corners of the cube whose first corner is tile point (x, y,
/// z), outside the field and unlabelled ones left out; `one`: the eight carry one label. With `seen`, only the
/// labels a query reads (Tile::visible): what the closure test may rely on.
struct Corners {
    std::uint32_t ks[8];
    int nk = 0;

    Corners(const Tile& t, int x, int y, int z, bool one, bool seen = false) {
        for (int k = 0; k < (one ? 1 : 8); ++k) {
            const int cx = x + (k & 1), cy = y + ((k >> 1) & 1), cz = z + (k >> 2);
            const std::uint32_t l = t.lab[(cz * 9 + cy) * 9 + cx];
            if (l < Tile::kOutside && (!seen || t.visible(cx, cy, cz)) && std::find(ks, ks + nk, l) == ks + nk) ks[nk++] = l;
        }
    }
};

/// The least over the spheres ks of each one's largest power over the cube with first corner `rest`: its value at
/// the corner farthest from its centre along every axis (convexity; and the same rounded number as the largest of
/// the eight corners' values, the distance expression rounding monotonically in each offset).
double cube_upper(const BoneField& f, const double* rest, const std::uint32_t* ks, int nk, const double* s2) {
    double upper = kInf;
    for (int k = 0; k < nk; ++k) {
        const auto& sp = f.sph[ks[k]];
        double far[3];
        for (int a = 0; a < 3; ++a) far[a] = std::max(std::abs(rest[a] - sp.c[a]), std::abs(rest[a] + 1 - sp.c[a]));
        upper = std::min(upper, length2(far[0], far[1], far[2], s2) - sp.lim);
    }
    return upper;
}

/// One allocated block's cells: the label word (with the same bit) and the power's range over each cube with its
/// first corner at the cell: at least the least corner value minus Σ s²/4 (corners outside the field hold at least
/// T); at most cube_upper over the spheres labelling a corner. The cubes whose ranges leave coverage open go to
/// `pending`; returns their count.
int fill_block_cells(BoneField& f, std::size_t slot, const CellPass& c, Tile& t, CubeSummaries& cubes,
                     Pending* pending) {
    t.load(f, slot, c.lab, c.T, c.s2);
    cubes.make(t);
    int n_pending = 0;
    CellBounds* out = f.bounds.data() + 1 + slot * 512;
    std::uint32_t* out_word = c.words + slot * 512;
    std::int64_t first[3], e[3];  // the block's first cell (relative to lo) and its extent inside the field
    for (int a = 0; a < 3; ++a) {
        first[a] = f.blocks[slot][static_cast<std::size_t>(a)] - f.lo[static_cast<std::size_t>(a)];
        e[a] = std::min<std::int64_t>(kBlock, f.dims[static_cast<std::size_t>(a)] - first[a]);
    }
    if (e[0] < kBlock || e[1] < kBlock || e[2] < kBlock) {  // cells past the field's edge: no label, no cover
        std::fill(out, out + 512, kNoCover);
        std::fill(out_word, out_word + 512, kNone);
    }
    for (std::int64_t z = 0; z < e[2]; ++z)
        for (std::int64_t y = 0; y < e[1]; ++y)
            for (std::int64_t x = 0; x < e[0]; ++x) {
                const int li = static_cast<int>((z * 8 + y) * 8 + x);
                const int ti = static_cast<int>((z * 9 + y) * 9 + x);
                // One label at all eight corners, a sphere's (the cell lies inside the field: not kOutside there)
                const bool same = cubes.one[li] && t.lab[ti] != kNone;
                const std::uint32_t word = t.lab[ti] | (same ? kSameBit : 0u);
                out_word[li] = word;
                const double lower = cubes.fmin[li] - c.quarter;
                if (!(lower < 0)) {
                    out[li] = CellBounds{kBoundMax, kBoundMax};
                    continue;
                }
                const Corners k(t, static_cast<int>(x), static_cast<int>(y), static_cast<int>(z), cubes.one[li]);
                const double rest[3] = {static_cast<double>(first[0] + x + f.lo[0]),
                                        static_cast<double>(first[1] + y + f.lo[1]),
                                        static_cast<double>(first[2] + z + f.lo[2])};
                const double upper = cube_upper(f, rest, k.ks, k.nk, c.s2);
                out[li] = CellBounds{quantized_down((lower - c.slack) * c.inv_step), quantized_up((upper + c.slack) * c.inv_step)};
                // A cube the ranges leave undecided (it may or may not be covered) is worth closing.
                // Closed, the least power over the labels a query reads at the corners is exact: the test takes those.
                if (word != kNone && !(word & kSameBit) && out[li].hi >= 0) {
                    const Corners read = t.seen == 0xff ? k : Corners(t, static_cast<int>(x), static_cast<int>(y), static_cast<int>(z), false, true);
                    Pending& pc = pending[n_pending++];
                    pc.li = li;
                    pc.nk = read.nk;
                    std::copy(read.ks, read.ks + read.nk, pc.ks);
                }
            }
    return n_pending;
}

/// Marks the pending cubes of a block that are closed, from the spheres whose balls meet the block's cubes, those
/// narrowed per 4³ sub-block and again per 2³ cells to the ones meeting their cubes' box (a ball meeting a cube
/// meets that box, and the test's margin only grows with the distance), so that each cube scans a few.
void close_cubes(const BoneField& f, std::size_t slot, std::uint32_t* out_word, const Pending* pending, int n_pending,
                 const Grid& g, const double* s2, NearSpheres& near, NearSpheres& sub, NearSpheres& pair) {
    const double blo[3] = {static_cast<double>(f.blocks[slot][0]), static_cast<double>(f.blocks[slot][1]),
                           static_cast<double>(f.blocks[slot][2])};
    const double bhi[3] = {blo[0] + kBlock, blo[1] + kBlock, blo[2] + kBlock};
    spheres_meeting(f, blo, bhi, g.spacing.data(), s2, near);
    // The pending cubes by their 2³ cells m (x, y, z of two bits each), in order.
    auto pair_of = [](int li) { return (((li >> 7) & 3) * 4 + ((li >> 4) & 3)) * 4 + ((li >> 1) & 3); };
    int start[65] = {}, order[512];
    for (int k = 0; k < n_pending; ++k) ++start[pair_of(pending[k].li) + 1];
    for (int m = 0; m < 64; ++m) start[m + 1] += start[m];
    {
        int at[64];
        std::copy(start, start + 64, at);
        for (int k = 0; k < n_pending; ++k) order[at[pair_of(pending[k].li)]++] = k;
    }
    for (int sb = 0; sb < 8; ++sb) {
        bool filtered = false;
        for (int p = 0; p < 8; ++p) {
            const int px = (sb & 1) * 2 + (p & 1), py = ((sb >> 1) & 1) * 2 + ((p >> 1) & 1), pz = (sb >> 2) * 2 + (p >> 2);
            const int m = (pz * 4 + py) * 4 + px;
            if (start[m] == start[m + 1]) continue;
            if (!filtered) {
                filtered = true;
                const double lo[3] = {blo[0] + (sb & 1) * 4, blo[1] + ((sb >> 1) & 1) * 4, blo[2] + (sb >> 2) * 4};
                sub.keep_meeting(near, lo, 4, s2);
            }
            const double lo[3] = {blo[0] + px * 2, blo[1] + py * 2, blo[2] + pz * 2};
            pair.keep_meeting(sub, lo, 2, s2);
            for (int k = start[m]; k < start[m + 1]; ++k) {
                const Pending& pc = pending[order[k]];
                const double base[3] = {blo[0] + (pc.li & 7), blo[1] + ((pc.li >> 3) & 7), blo[2] + (pc.li >> 6)};
                if (closed_cube(f, base, pc.ks, pc.nk, pair, s2)) out_word[pc.li] |= kClosedBit;
            }
        }
    }
}

/// The range of a block's cube ranges over each of its eight 4³ sub-blocks.
void sub_block_ranges(BoneField& f, std::size_t slot) {
    const CellBounds* cells = f.bounds.data() + 1 + slot * 512;
    CellBounds* sb = f.sub.data() + slot * 8;
    for (int k = 0; k < 8; ++k) sb[k] = CellBounds{kBoundMax, kBoundMin};
    for (int li = 0; li < 512; ++li) {
        CellBounds& t = sb[sub_of(static_cast<std::size_t>(li))];
        t.lo = std::min(t.lo, cells[li].lo);
        t.hi = std::max(t.hi, cells[li].hi);
    }
}

/// Which 2³ cells of a block have one sphere's power as the bone's on all their cubes: every cell's cube one label's
/// at all corners, the same label.
void pair_spheres(BoneField& f, std::size_t slot, const std::uint32_t* words) {
    std::uint64_t alone_bits = 0;
    for (int m = 0; m < 64; ++m) {
        const int first = (((m >> 4) * 2 * 8) + ((m >> 2) & 3) * 2) * 8 + (m & 3) * 2;  // cell (2x, 2y, 2z)
        const std::uint32_t lab = label_of(words[first]);
        bool alone = true;
        for (int c = 0; c < 8 && alone; ++c) {
            const std::uint32_t w = words[first + ((c >> 2) * 8 + ((c >> 1) & 1)) * 8 + (c & 1)];
            alone = same_of(w) && label_of(w) == lab;
        }
        alone_bits |= std::uint64_t{alone} << m;
    }
    f.pair_alone[slot] = alone_bits;
}

/// A block's 512 words encoded (CellWords): its cells' codes written, its distinct words moved to the front of
/// `words`; returns their count, or 512 when there are more than 256 (the words stay as they are, the codes 0).
int encode_block(std::uint32_t* words, std::uint8_t* code) {
    std::uint32_t palette[256];
    int n = 0, k = 0;
    for (int li = 0; li < 512; ++li) {
        const std::uint32_t w = words[li];
        if (n == 0 || palette[k] != w) {  // (mostly the previous cell's word)
            for (k = 0; k < n && palette[k] != w; ++k) {
            }
            if (k == n) {
                if (n == 256) {
                    std::fill(code, code + 512, std::uint8_t{0});
                    return 512;
                }
                palette[n++] = w;
            }
        }
        code[li] = static_cast<std::uint8_t>(k);
    }
    std::copy(palette, palette + n, words);
    return n;
}

/// The blocks' palettes gathered into f.words from the encoded words (encode_block's counts per block).
void gather_palettes(BoneField& f, const std::uint32_t* words, const std::vector<std::int32_t>& count) {
    std::int64_t total = 0;
    for (std::size_t slot = 0; slot < count.size(); ++slot) {
        f.words.at[slot] = count[slot] == 512 ? ~total : total;
        total += count[slot];
    }
    f.words.palette.resize(static_cast<std::size_t>(total));
    for (std::size_t slot = 0; slot < count.size(); ++slot) {
        const std::int64_t a = f.words.at[slot];
        std::copy(words + slot * 512, words + slot * 512 + count[slot], f.words.palette.begin() + (a >= 0 ? a : ~a));
    }
}

/// The summed-area table of the allocated blocks, (bdims + 1)³, for any_block.
void block_sums(BoneField& f) {
    const std::int64_t bx = f.bdims[0], by = f.bdims[1], bz = f.bdims[2], sx = bx + 1, sy = by + 1;
    f.block_sat.assign(static_cast<std::size_t>(sx * sy * (bz + 1)), 0);
    auto at = [&](std::int64_t i, std::int64_t j, std::int64_t k) -> std::int32_t& {
        return f.block_sat[static_cast<std::size_t>((k * sy + j) * sx + i)];
    };
    for (std::int64_t z = 1; z <= bz; ++z)
        for (std::int64_t y = 1; y <= by; ++y)
            for (std::int64_t x = 1; x <= bx; ++x)
                at(x, y, z) = (f.block_index[static_cast<std::size_t>(((z - 1) * by + (y - 1)) * bx + (x - 1))] >= 0) +
                              at(x - 1, y, z) + at(x, y - 1, z) + at(x, y, z - 1) - at(x - 1, y - 1, z) -
                              at(x - 1, y, z - 1) - at(x, y - 1, z - 1) + at(x - 1, y - 1, z - 1);
}

}  // namespace

BoneField build_ball_field(const Grid& g, const BoundSpheres& s, const std::vector<std::uint32_t>& members,
                           const std::vector<double>& r, double T, double step) {
    BoneField f;
    if (members.size() >= kClosedBit) throw Error("deform: too many spheres in one blend group");
    place_spheres(f, g, s, members, r, T);
    f.lattice = false;
    f.lo = {0, 0, 0};
    f.dims = f.bdims = {0, 0, 0};
    f.step = step;
    f.floor_T = T;
    return f;
}

namespace {

/// A k-d node's ball box and largest limit from its spheres (a leaf) or its children (made first).
void refit_node(BoneField& f, std::size_t j, const Grid& g) {
    KdNode& n = f.nodes[j];
    n.max_lim = 0;
    for (int a = 0; a < 3; ++a) {
        n.blo[a] = kInf;
        n.bhi[a] = -kInf;
    }
    if (n.left < 0) {
        for (std::uint32_t k = n.begin; k < n.end; ++k) {
            const auto& sp = f.sph[k];
            const double r = std::sqrt(std::max(0.0, sp.lim));
            for (int a = 0; a < 3; ++a) {
                n.blo[a] = std::min(n.blo[a], sp.c[a] * g.spacing[a] - r);
                n.bhi[a] = std::max(n.bhi[a], sp.c[a] * g.spacing[a] + r);
            }
            n.max_lim = std::max(n.max_lim, sp.lim);
        }
        return;
    }
    for (const std::int32_t c : {n.left, n.right}) {
        const KdNode& m = f.nodes[static_cast<std::size_t>(c)];
        for (int a = 0; a < 3; ++a) {
            n.blo[a] = std::min(n.blo[a], m.blo[a]);
            n.bhi[a] = std::max(n.bhi[a], m.bhi[a]);
        }
        n.max_lim = std::max(n.max_lim, m.max_lim);
    }
}

}  // namespace

void scale_ball_field(BoneField& f, const std::vector<double>& r, double factor, const Grid& g) {
    for (std::size_t k = 0; k < f.sph.size(); ++k) {
        const double rk = bent_radius(r[f.global[k]], factor);
        f.sph[k].lim = rk > 0 ? open_ball_limit_sq(rk) : 0.0;
    }
    for (std::size_t j = f.nodes.size(); j-- > 0;) refit_node(f, j, g);  // children come after their parents
}

BoneField build_bone_field(const Grid& g, const BoundSpheres& s, const std::vector<std::uint32_t>& members,
                           const std::vector<double>& r, double T, double step, DiagramScratch* diagram_scratch) {
    BoneField f;
    if (members.size() >= kClosedBit) throw Error("deform: too many spheres bound to one bone");
    place_spheres(f, g, s, members, r, T);
    if (members.empty()) return f;
    const double s2[3] = {g.spacing[0] * g.spacing[0], g.spacing[1] * g.spacing[1], g.spacing[2] * g.spacing[2]};
    DiagramScratch own;
    DiagramScratch& diagram = diagram_scratch ? *diagram_scratch : own;
    diagram.reserve(static_cast<std::size_t>(f.dims[0] * f.dims[1] * f.dims[2]));
    const std::unique_ptr<std::atomic<std::uint8_t>[]> keep(new std::atomic<std::uint8_t>[static_cast<std::size_t>(
        f.bdims[0] * f.bdims[1] * f.bdims[2])]());
    power_diagram(f, s2, T, diagram.lab.data(), keep.get());
    keep_blocks(f, keep.get());
    f.step = step;
    f.floor_T = T;
    double maxlim = 0;
    for (const auto& sp : f.sph) maxlim = std::max(maxlim, sp.lim);
    const double quarter = 0.25 * (s2[0] + s2[1] + s2[2]);
    Buffer<std::uint32_t> words(f.blocks.size() * 512);
    std::vector<std::int32_t> count(f.blocks.size());
    const CellPass pass{diagram.lab.data(), s2, T, step, quarter, 1e-9 * (maxlim + 4 * quarter),
                        1.0 / step, words.data()};
    struct Scratch {
        std::vector<Pending> pending = std::vector<Pending>(512);
        NearSpheres near, sub, pair;
        Tile tile;
        CubeSummaries cubes;
    };
    tbb::enumerable_thread_specific<Scratch> scratch;
    // The blocks in the lattice's order (x slowest, z fastest), so that the tiles of consecutive blocks share its pages
    std::vector<std::size_t> order;
    order.reserve(f.blocks.size());
    for (std::int64_t kx = 0; kx < f.bdims[0]; ++kx)
        for (std::int64_t ky = 0; ky < f.bdims[1]; ++ky)
            for (std::int64_t kz = 0; kz < f.bdims[2]; ++kz)
                if (const std::int32_t b = f.block_index[static_cast<std::size_t>((kz * f.bdims[1] + ky) * f.bdims[0] + kx)]; b >= 0)
                    order.push_back(static_cast<std::size_t>(b));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, order.size()), [&](const tbb::blocked_range<std::size_t>& rg) {
        Scratch& sc = scratch.local();
        for (std::size_t i = rg.begin(); i != rg.end(); ++i) {
            const std::size_t slot = order[i];
            std::uint32_t* block_words = words.data() + slot * 512;
            const int n_pending = fill_block_cells(f, slot, pass, sc.tile, sc.cubes, sc.pending.data());
            if (n_pending) close_cubes(f, slot, block_words, sc.pending.data(), n_pending, g, s2, sc.near, sc.sub, sc.pair);
            sub_block_ranges(f, slot);
            pair_spheres(f, slot, block_words);
            count[slot] = encode_block(block_words, f.words.code.data() + 1 + slot * 512);
        }
    });
    gather_palettes(f, words.data(), count);
    block_sums(f);
    return f;
}

}  // namespace volrig::deform_detail

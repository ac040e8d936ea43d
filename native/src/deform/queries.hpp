// deform/queries.hpp: exact answers from one bone's field: the lattice cube around a rest point (its corner labels),
// the least power over those labels (an upper bound, exact in same and closed cubes), a lower bound from the
// corners' exact powers, and the k-d searches that settle the rest.
#pragma once

#include <cstdint>

#include "deform/bone_field.hpp"

namespace volrig::deform_detail {

struct Best {
    double key = kInf;
    std::uint32_t local = kNone;
    std::uint32_t global = kNone;
    bool better(double k, std::uint32_t g) const { return beats(k, key, [&] { return g < global; }); }
};

/// Whether any of the bone's spheres covers the point (|p − c|² < lim): a search that stops at the first one.
/// `p` is the point in world offsets (for pruning), `pi` the same point in index space.
bool any_cover(const BoneField& f, const double* p, const double* pi, const double* s2);

/// The least (power, global index) over the bone's spheres at p_index (index space; s the spacing), or with
/// `nearest` the least (|p − c|², global index) over the spheres that cover p.
/// `seed`: a sphere's (power, local, global) at the point when one is known (power proximity only): it prunes the
/// search from the start and cannot change the result, the least (key, global) over all spheres.
Best exact(const BoneField& f, const double* p_index, const double* s, const double* s2, bool nearest,
           const Best& seed = Best{});

/// The power-diagram labels of the lattice cube around a rest point p (index space) of one bone.
struct Cube {
    std::uint32_t lab[8];
    double base[3];  // the cube's first corner
    bool same;       // all eight corners carry one sphere
    bool closed;     // the least power over the labels is exact where negative (closed_cube)
};

/// Reads the cube around p; false when no corner carries a label (then no sphere of the bone covers p).
inline bool fetch_cube(const BoneField& f, const double* p, Cube& cube) {
    if (!(p[0] >= -1e15 && p[0] <= 1e15 && p[1] >= -1e15 && p[1] <= 1e15 && p[2] >= -1e15 && p[2] <= 1e15)) return false;
    const double fx = fast_floor(p[0]), fy = fast_floor(p[1]), fz = fast_floor(p[2]);
    const auto x0 = static_cast<std::int64_t>(fx), y0 = static_cast<std::int64_t>(fy), z0 = static_cast<std::int64_t>(fz);
    const std::int64_t lx = x0 - f.lo[0], ly = y0 - f.lo[1], lz = z0 - f.lo[2];
    if (lx + 1 < 0 || ly + 1 < 0 || lz + 1 < 0 || lx >= f.dims[0] || ly >= f.dims[1] || lz >= f.dims[2]) return false;
    std::uint32_t cell[8];
    f.corner_cells(lx, ly, lz, cell);
    std::uint32_t* lab = cube.lab;
    for (int k = 0; k < 8; ++k) lab[k] = label_of(f.words[cell[k]]);
    cube.closed = closed_of(f.words[cell[0]]);
    bool same = true, any = false;
    for (int c = 0; c < 8; ++c) {
        same = same && lab[c] == lab[0];
        any = any || lab[c] != kNone;
    }
    cube.base[0] = fx;
    cube.base[1] = fy;
    cube.base[2] = fz;
    cube.same = same;
    return any;
}

/// The least power at p among the eight corner labels `lab` of its cube, ties to the lower global index (the sphere
/// in `local`): a real sphere's, so an upper bound of the bone's power (a negative value proves coverage), and its
/// exact value wherever negative when the cube is same or closed. With `any_negative` it stops at the first
/// negative value.
inline double least_over_labels(const BoneField& f, const std::uint32_t* lab, const double* p, const double* s2,
                         bool any_negative, std::uint32_t& local) {
    double U = kInf;
    local = kNone;
    for (int c = 0; c < 8; ++c) {
        const std::uint32_t k = lab[c];
        if (k == kNone || k == local) continue;
        const double v = power_of(f, k, p, s2);
        if (beats(v, U, [&] { return f.global[k] < f.global[local]; })) {
            U = v;
            local = k;
            if (any_negative && U < 0) break;
        }
    }
    return U;
}

/// least_over_labels at a fixed-point preimage pf (as Pull gives it), from its cube's corner labels.
inline double least_over_corners(const BoneField& f, const std::int64_t* pf, const double* s2, std::uint32_t& local) {
    std::uint32_t cell[8], lab[8];
    f.corner_cells((pf[0] >> Pull::kBits) - f.lo[0], (pf[1] >> Pull::kBits) - f.lo[1], (pf[2] >> Pull::kBits) - f.lo[2],
                   cell);
    for (int k = 0; k < 8; ++k) lab[k] = label_of(f.words[cell[k]]);
    const double p[3] = {Pull::to_double(pf[0]), Pull::to_double(pf[1]), Pull::to_double(pf[2])};
    return least_over_labels(f, lab, p, s2, false, local);
}

/// A lower bound of the bone's power at p from its exact values at the cube's corners (concave_lower: the power
/// is |p|² plus a concave function, a minimum of linear ones); corners without a label hold at least T.
inline double lower_bound(const BoneField& f, const Cube& cube, const double* p, const double* s2, double T) {
    const double u[3] = {p[0] - cube.base[0], p[1] - cube.base[1], p[2] - cube.base[2]};
    double v[8];
    for (int c = 0; c < 8; ++c) {
        const double corner[3] = {cube.base[0] + (c & 1), cube.base[1] + ((c >> 1) & 1), cube.base[2] + ((c >> 2) & 1)};
        v[c] = cube.lab[c] == kNone ? T : power_of(f, cube.lab[c], corner, s2);
    }
    return concave_lower(v, u, s2);
}

}  // namespace volrig::deform_detail

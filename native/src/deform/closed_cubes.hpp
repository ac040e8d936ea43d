// deform/closed_cubes.hpp: the closure test of a lattice cube (built once per rig): where it holds, the least power
// over the cube's corner labels is the bone's exact power wherever that is negative, so voxels just outside a
// surface need no k-d search.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "deform/bone_field.hpp"

namespace volrig::deform_detail {

/// How far squared distance d2 (world units²) lies beyond an open ball of squared radius lim, with a margin for
/// rounding on the safe side: the ball reaches it when negative.
inline double ball_gap(double d2, double lim) { return d2 - (lim + 1e-9 * (1.0 + d2 + lim)); }
inline bool ball_reaches(double d2, double lim) { return ball_gap(d2, lim) < 0; }

/// Whether sphere sp's open ball (with that margin) meets the box [lo, hi] (index space).
inline bool ball_meets_box(const BoneField::Sphere& sp, const double* lo, const double* hi, const double* s2) {
    double d2 = 0;
    for (int a = 0; a < 3; ++a) {
        const double e = sp.c[a] < lo[a] ? lo[a] - sp.c[a] : (sp.c[a] > hi[a] ? sp.c[a] - hi[a] : 0.0);
        d2 += s2[a] * e * e;
    }
    return ball_reaches(d2, sp.lim);
}

/// The squared distance (world units²) from centre (cx, cy, cz) to the cube of half-side h whose middle is m (index
/// space): per axis |c − m| − h where positive. Branch-free, so that loops over many centres vectorise; exact where
/// the centres and the cube's corners are integers (the lattice's).
inline double cube_distance2(double cx, double cy, double cz, const double* m, double h, const double* s2) {
    const double dx = std::abs(cx - m[0]) - h, dy = std::abs(cy - m[1]) - h, dz = std::abs(cz - m[2]) - h;
    const double ex = dx > 0 ? dx : 0.0, ey = dy > 0 ? dy : 0.0, ez = dz > 0 ? dz : 0.0;
    return s2[0] * ex * ex + s2[1] * ey * ey + s2[2] * ez * ez;
}

/// Spheres whose balls meeting a box (for closed_cube), their coordinates apart so that the ball tests vectorise.
struct NearSpheres {
    std::vector<std::uint32_t> id;
    std::vector<double> c[3], lim;
    std::vector<double> gap;  // closed_cube's: each ball's ball_gap to its cube
    void clear() {
        id.clear();
        for (auto& v : c) v.clear();
        lim.clear();
    }
    void add(const BoneField& f, std::uint32_t j) {
        id.push_back(j);
        for (int a = 0; a < 3; ++a) c[a].push_back(f.sph[j].c[a]);
        lim.push_back(f.sph[j].lim);
    }
    /// The spheres of `from` whose balls meet the cube [lo, lo + size]³ (index space, integer corners), in their
    /// order: ball_meets_box's test, by cube_distance2.
    void keep_meeting(const NearSpheres& from, const double* lo, double size, const double* s2);
};

/// The spheres whose balls meet the box [lo, hi] (index space), into `out`.
void spheres_meeting(const BoneField& f, const double* lo, const double* hi, const double* spacing, const double* s2,
                     NearSpheres& out);

/// Whether the lattice cube with first corner `base` (index space) is closed for the bone: every sphere whose ball
/// meets the cube, apart from its corners' labels S, has a larger power than one sphere of S all over the cube. The
/// difference of two powers is affine, so its largest value on the cube is at a corner, found per axis; the margin is
/// far above rounding. Then wherever the bone's power is negative in the cube its sphere is in S (that sphere's ball
/// holds the point), so the least power over S, ties to the lower global index, is the bone's exact answer there.
/// `near`: a superset of the spheres whose balls meet the cube.
bool closed_cube(const BoneField& f, const double* base, const std::uint32_t* S, int ns, NearSpheres& near,
                 const double* s2);

}  // namespace volrig::deform_detail

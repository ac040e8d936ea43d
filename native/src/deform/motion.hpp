// deform/motion.hpp: bone motions in the source lattice's index space, and the fixed-point posed-to-rest map every
// consumer (the fast path, the brute-force reference, the samples) goes through.
#pragma once

#include <Eigen/Dense>

#include <cstdint>
#include <utility>
#include <vector>

#include "deform/common.hpp"
#include "volrig/deform.hpp"

namespace volrig::deform_detail {

/// x -> A x + t, in the index space of the source lattice.
struct Affine {
    double a[9];
    double t[3];
    void apply(const double* x, double* y) const {
        y[0] = a[0] * x[0] + a[1] * x[1] + a[2] * x[2] + t[0];
        y[1] = a[3] * x[0] + a[4] * x[1] + a[5] * x[2] + t[1];
        y[2] = a[6] * x[0] + a[7] * x[1] + a[8] * x[2] + t[2];
    }
};

/// A world matrix (linear part L, translation d) as an index-space affine: m' = S⁻¹(L(o + S m) + d − o).
Affine index_affine(const Eigen::Matrix3d& L, const Eigen::Vector3d& d, const Grid& g);

/// The posed-to-rest map of a motion on lattice points, in fixed point with 32 fractional bits: integer arithmetic
/// is exact, so a block's points may be stepped by adding a column and land on the very values a direct evaluation
/// gives. Its error against the exact map is below 1e-9 voxel per voxel of distance from the source's centre.
struct Pull {
    static constexpr int kBits = 32;
    static constexpr double kUnit = 4294967296.0;  // 2^kBits
    std::int64_t a[9], t[3];
    /// p (rest index space, fixed point) of the posed lattice point q.
    void fixed(const std::int64_t* q, std::int64_t* p) const {
        p[0] = a[0] * q[0] + a[1] * q[1] + a[2] * q[2] + t[0];
        p[1] = a[3] * q[0] + a[4] * q[1] + a[5] * q[2] + t[1];
        p[2] = a[6] * q[0] + a[7] * q[1] + a[8] * q[2] + t[2];
    }
    /// Steps a fixed-point preimage by one lattice step along posed axis `axis` (a column of the map).
    void step(std::int64_t* p, int axis) const {
        p[0] += a[axis];
        p[1] += a[3 + axis];
        p[2] += a[6 + axis];
    }
    static double to_double(std::int64_t v) { return static_cast<double>(v) * (1.0 / kUnit); }
    static void to_double(const std::int64_t* v, double* p) {
        for (int i = 0; i < 3; ++i) p[i] = to_double(v[i]);
    }
    /// The fractional part of a fixed-point coordinate (its integer part, v >> kBits, is the lattice cell).
    static double fraction(std::int64_t v) {
        return static_cast<double>(v & ((std::int64_t{1} << kBits) - 1)) * (1.0 / kUnit);
    }
    void apply(const std::int64_t* q, double* p) const {
        std::int64_t f[3];
        fixed(q, f);
        to_double(f, p);
    }
};

/// The largest lattice coordinate (posed or rest) the fixed-point map accepts, and the largest entry of its
/// linear part (rotations scaled by spacing ratios): products and sums stay far inside 64 bits.
constexpr std::int64_t kMaxCoordinate = std::int64_t{1} << 21;
constexpr double kMaxRatio = 64;

/// The fixed-point map of an index-space affine; throws on spacings too anisotropic or translations too far.
Pull pull_of(const Affine& f);

struct Motion {
    Eigen::Matrix3d R;  // rotation
    Eigen::Vector3d d;
    Affine forward;  // rest lattice -> posed lattice
    Pull pull;       // posed lattice -> rest lattice
};

Motion motion_of(const Eigen::Matrix3d& R, const Eigen::Vector3d& d, const Grid& g);

/// Throws unless every coordinate of the output box is one the fixed-point map accepts.
void check_box_reach(const Box& bx);

/// Squared world distance between a posed lattice point q and a sphere of rest centre c moved rigidly by m,
/// measured in rest space, |T⁻¹q − c| (= |q − Tc|), as the per-bone fields measure it.
inline double moved_length2(const Motion& m, const double* c, const std::int64_t* q, const double* s2) {
    double p[3];
    m.pull.apply(q, p);
    return length2(p[0] - c[0], p[1] - c[1], p[2] - c[2], s2);
}

/// Checks and orthonormalises the bone matrices (row-major 4x4); matrices within float noise of the identity are
/// the identity.
std::vector<Motion> bone_motions(BoneMatrices mat, std::size_t bones, const Grid& g);

/// A sphere's weights: (bone, weight in kWeightSteps-ths) pairs sorted by bone, zero weights dropped.
using Weights = std::vector<std::pair<std::int32_t, std::int32_t>>;
/// Smooth weights are rounded to 16ths: at a 120° bend neighbouring groups differ by at most ~8°, and the groups
/// stay few enough for the per-bone machinery (the cost grows with the groups a voxel lies in).
constexpr std::int32_t kWeightSteps = 16;

/// The blended world transform of a sphere from its bones' weights (rigid in both modes).
///   Linear: the weighted mean of the matrices, made rigid: its linear part projected onto the nearest rotation
///           (polar decomposition) about `pivot` (world), which keeps the blend's position, so that spheres keep
///           their size and distances stay measurable in rest space.
///   DualQuaternion (Kavan et al.): the weighted mean of unit dual quaternions aligned with the owner's
///           hemisphere, normalised.
Motion blended_motion(const std::vector<Motion>& bones, const Weights& w, std::int32_t owner, DeformMode mode,
                      const Grid& g, const Eigen::Vector3d& pivot);

/// A rigid world transform x -> R x + d.
struct Rigid {
    Eigen::Matrix3d R;
    Eigen::Vector3d d;
};
/// The blend blended_motion makes, from real weights summing to 1 (bone, weight): the world transform alone.
Rigid blend_rigid(const std::vector<Motion>& bones, const std::vector<std::pair<std::int32_t, double>>& w,
                  std::int32_t owner, DeformMode mode, const Eigen::Vector3d& pivot);

}  // namespace volrig::deform_detail

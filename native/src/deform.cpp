#include "volrig/deform.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <string>
#include <thread>
#include <type_traits>

#include <stdlib.h>
#include <sys/mman.h>

#include "volrig/reconstruct.hpp"

namespace volrig {

DeformMode deform_mode_from_name(const std::string& name) {
    if (name == "rigid") return DeformMode::Rigid;
    if (name == "linear") return DeformMode::Linear;
    if (name == "dual_quaternion" || name == "dq") return DeformMode::DualQuaternion;
    throw Error("unknown deform mode '" + name + "' (use \"rigid\", \"linear\" or \"dual_quaternion\")");
}

Proximity proximity_from_name(const std::string& name) {
    if (name == "power") return Proximity::Power;
    if (name == "nearest") return Proximity::Nearest;
    throw Error("unknown proximity '" + name + "' (use \"power\" or \"nearest\")");
}

Sampling sampling_from_name(const std::string& name) {
    if (name == "trilinear") return Sampling::Trilinear;
    if (name == "nearest") return Sampling::Nearest;
    throw Error("unknown sampling '" + name + "' (use \"trilinear\" or \"nearest\")");
}

namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
constexpr std::int64_t kBlock = 8;  // power-diagram and output blocks are 8³ voxels
constexpr double kInf = std::numeric_limits<double>::infinity();

using Vec3d = std::array<double, 3>;

/// floor() without a libm call (x86-64's baseline has no SSE4.1 round); |x| must be far below 2^62.
inline double fast_floor(double x) {
    const double t = static_cast<double>(static_cast<std::int64_t>(x));
    return t > x ? t - 1.0 : t;
}

/// Squared world length of an index-space offset. Every distance test in this file goes through this one
/// expression, so that the fast path and the reference round identically.
inline double length2(double dx, double dy, double dz, const double* s2) {
    return s2[0] * dx * dx + s2[1] * dy * dy + s2[2] * dz * dz;
}

// ---- transforms --------------------------------------------------------------------------------------------

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
Affine index_affine(const Eigen::Matrix3d& L, const Eigen::Vector3d& d, const Grid& g) {
    Affine f;
    const Eigen::Vector3d o(g.origin[0], g.origin[1], g.origin[2]);
    const Eigen::Vector3d lo = L * o + d - o;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) f.a[3 * i + j] = L(i, j) * g.spacing[j] / g.spacing[i];
        f.t[i] = lo[i] / g.spacing[i];
    }
    return f;
}

/// The posed-to-rest map of a motion on lattice points, in fixed point with 32 fractional bits: integer arithmetic
/// is exact, so a block's points may be stepped by adding a column and land on the very values a direct evaluation
/// gives. Every consumer (the fast path, the brute-force reference, the samples) goes through it. Its error against
/// the exact map is below 1e-9 voxel per voxel of distance from the source's centre.
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
    static double to_double(std::int64_t v) { return static_cast<double>(v) * (1.0 / kUnit); }
    /// The fractional part of a fixed-point coordinate (its integer part, v >> kBits, is the lattice cell).
    static double fraction(std::int64_t v) {
        return static_cast<double>(v & ((std::int64_t{1} << kBits) - 1)) * (1.0 / kUnit);
    }
    void apply(const std::int64_t* q, double* p) const {
        std::int64_t f[3];
        fixed(q, f);
        for (int i = 0; i < 3; ++i) p[i] = to_double(f[i]);
    }
};

/// The largest lattice coordinate (posed or rest) the fixed-point map accepts, and the largest entry of its
/// linear part (rotations scaled by spacing ratios): products and sums stay far inside 64 bits.
constexpr std::int64_t kMaxCoordinate = std::int64_t{1} << 21;
constexpr double kMaxRatio = 64;

Pull pull_of(const Affine& f) {
    Pull p;
    for (int k = 0; k < 9; ++k) {
        if (!(std::abs(f.a[k]) <= kMaxRatio))
            throw Error("deform: the voxel spacing is too anisotropic (an axis more than 64 times another)");
        p.a[k] = std::llround(f.a[k] * Pull::kUnit);
    }
    for (int k = 0; k < 3; ++k) {
        if (!(std::abs(f.t[k]) <= 16.0 * kMaxRatio * static_cast<double>(kMaxCoordinate)))
            throw Error("deform: a bone moves the volume millions of voxels away: check the bone matrices' "
                        "translations and units");
        p.t[k] = std::llround(f.t[k] * Pull::kUnit);
    }
    return p;
}

struct Motion {
    Eigen::Matrix3d R;  // rotation
    Eigen::Vector3d d;
    Affine forward;  // rest lattice -> posed lattice
    Pull pull;       // posed lattice -> rest lattice
};

Motion motion_of(const Eigen::Matrix3d& R, const Eigen::Vector3d& d, const Grid& g) {
    Motion m;
    m.R = R;
    m.d = d;
    m.forward = index_affine(R, d, g);
    const Eigen::Matrix3d Rt = R.transpose();
    m.pull = pull_of(index_affine(Rt, -(Rt * d), g));
    return m;
}

/// Throws unless every coordinate of the output box is one the fixed-point map accepts.
void check_box_reach(const std::array<std::int64_t, 6>& bx) {
    for (int a = 0; a < 3; ++a)
        if (std::abs(bx[a]) > kMaxCoordinate || std::abs(bx[a] + bx[3 + a]) > kMaxCoordinate)
            throw Error("deform: the posed volume lies millions of voxels away: check the bone matrices' "
                        "translations and units");
}

/// Squared world distance between a posed lattice point q and a sphere of rest centre c moved rigidly by m,
/// measured in rest space, |T⁻¹q − c| (= |q − Tc|), as the per-bone fields measure it.
inline double moved_length2(const Motion& m, const double* c, const std::int64_t* q, const double* s2) {
    double p[3];
    m.pull.apply(q, p);
    return length2(p[0] - c[0], p[1] - c[1], p[2] - c[2], s2);
}

/// Checks and orthonormalises the bone matrices (row-major 4x4).
std::vector<Motion> bone_motions(BoneMatrices mat, std::size_t bones, const Grid& g) {
    std::vector<Motion> out;
    out.reserve(bones);
    for (std::size_t b = 0; b < bones; ++b) {
        const double* m = mat + 16 * b;
        const std::string who = "bone matrix " + std::to_string(b);
        for (int k = 0; k < 16; ++k)
            if (!std::isfinite(m[k])) throw Error(who + " has a non-finite entry");
        if (std::abs(m[12]) > 1e-6 || std::abs(m[13]) > 1e-6 || std::abs(m[14]) > 1e-6 || std::abs(m[15] - 1) > 1e-6)
            throw Error(who + ": the last row must be (0, 0, 0, 1)");
        Eigen::Matrix3d R;
        R << m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10];
        const Eigen::Vector3d d(m[3], m[7], m[11]);
        const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
        if (err > 1e-3 || R.determinant() <= 0)
            throw Error(who + " is not a rotation plus a translation (scale, shear or mirror): deform needs rigid "
                              "bone motions (use radius_scale for bulge and pinch)");
        // A bone at rest, as single-precision pose matrices give it (off by ~1e-5): the identity, so that sphere
        // boundaries lying exactly on lattice points (every ball touches the background at exactly its radius)
        // do not flip inwards.
        // A rotation that far from the identity moves points by up to 1e-5 of their distance from the origin.
        double reach = 1.0;
        for (int a = 0; a < 3; ++a)
            reach = std::max(reach, std::abs(g.origin[a]) + g.spacing[a] * static_cast<double>(g.dims[a]));
        if ((R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <= 1e-5 && d.cwiseAbs().maxCoeff() <= 1e-5 * reach) {
            out.push_back(motion_of(Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), g));
            continue;
        }
        if (err > 0) {  // polar decomposition: the nearest rotation
            Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
            const Eigen::Matrix3d Q = svd.matrixU() * svd.matrixV().transpose();
            if ((Q - R).cwiseAbs().maxCoeff() > 1e-15) R = Q;
        }
        out.push_back(motion_of(R, d, g));
    }
    return out;
}

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
                      const Grid& g, const Eigen::Vector3d& pivot) {
    double total = 0;
    for (const auto& [b, q] : w) total += q;
    if (mode == DeformMode::Linear) {
        Eigen::Matrix3d L = Eigen::Matrix3d::Zero();
        Eigen::Vector3d d = Eigen::Vector3d::Zero();
        for (const auto& [b, q] : w) {
            L += (q / total) * bones[static_cast<std::size_t>(b)].R;
            d += (q / total) * bones[static_cast<std::size_t>(b)].d;
        }
        Eigen::JacobiSVD<Eigen::Matrix3d> svd(L, Eigen::ComputeFullU | Eigen::ComputeFullV);
        Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
        if (R.determinant() < 0) {  // a blend of opposite rotations: keep a proper rotation
            Eigen::Matrix3d U = svd.matrixU();
            U.col(2) = -U.col(2);
            R = U * svd.matrixV().transpose();
        }
        return motion_of(R, L * pivot + d - R * pivot, g);
    }
    const Eigen::Quaterniond ref(bones[static_cast<std::size_t>(owner)].R);
    Eigen::Vector4d real = Eigen::Vector4d::Zero(), dual = Eigen::Vector4d::Zero();
    for (const auto& [b, q] : w) {
        const Motion& m = bones[static_cast<std::size_t>(b)];
        Eigen::Quaterniond r(m.R);
        if (r.coeffs().dot(ref.coeffs()) < 0) r.coeffs() = -r.coeffs();
        const Eigen::Quaterniond t(0, m.d[0], m.d[1], m.d[2]);
        Eigen::Quaterniond rd = t * r;
        rd.coeffs() *= 0.5;
        real += (q / total) * r.coeffs();
        dual += (q / total) * rd.coeffs();
    }
    const double n = real.norm();
    Eigen::Quaterniond qr, qd;
    qr.coeffs() = real / n;
    qd.coeffs() = dual / n;
    const Eigen::Quaterniond tq = qd * qr.conjugate();
    const Eigen::Vector3d d = 2.0 * tq.vec();
    return motion_of(qr.toRotationMatrix(), d, g);
}

// ---- sampling ----------------------------------------------------------------------------------------------

template <class T>
struct Sampler {
    const T* data;
    std::int64_t nx, ny, nz;

    float at(std::int64_t x, std::int64_t y, std::int64_t z) const {
        return static_cast<float>(data[(z * ny + y) * nx + x]);
    }
    /// A sample as a double: through float, as at() gives it (exactly, and in one conversion, for small integers).
    static double value(T v) {
        if constexpr (std::is_integral_v<T> && sizeof(T) <= 2) return static_cast<double>(v);
        else return static_cast<double>(static_cast<float>(v));
    }
    // Samples at a rest point in fixed point (Pull): the integer part is the lattice cell, the low bits the
    // fraction, so no rounding mode enters.
    static std::int64_t clamp_index(std::int64_t v, std::int64_t n) {
        const std::int64_t i = (v >> Pull::kBits) + ((v >> (Pull::kBits - 1)) & 1);  // round half up
        return i < 0 ? 0 : (i >= n ? n - 1 : i);
    }
    float nearest(const std::int64_t* p) const {
        return at(clamp_index(p[0], nx), clamp_index(p[1], ny), clamp_index(p[2], nz));
    }
    static void cell(std::int64_t v, std::int64_t n, std::int64_t& i0, std::int64_t& i1, double& f) {
        i0 = v >> Pull::kBits;
        f = Pull::fraction(v);
        if (i0 < 0 || i0 >= n - 1) {  // clamped to the lattice
            i0 = i0 < 0 ? 0 : n - 1;
            f = 0;
        }
        i1 = i0 + 1 < n ? i0 + 1 : i0;
    }
    float trilinear(const std::int64_t* p) const {
        const std::int64_t x0 = p[0] >> Pull::kBits, y0 = p[1] >> Pull::kBits, z0 = p[2] >> Pull::kBits;
        if (static_cast<std::uint64_t>(x0) < static_cast<std::uint64_t>(nx - 1) &&
            static_cast<std::uint64_t>(y0) < static_cast<std::uint64_t>(ny - 1) &&
            static_cast<std::uint64_t>(z0) < static_cast<std::uint64_t>(nz - 1)) {
            // Inside the lattice (nearly always): the same arithmetic as below without clamping.
            const double fx = Pull::fraction(p[0]), fy = Pull::fraction(p[1]), fz = Pull::fraction(p[2]);
            const T* d = data + (z0 * ny + y0) * nx + x0;
            const std::int64_t sy = nx, sz = nx * ny;
            const double v000 = value(d[0]), v100 = value(d[1]);
            const double v010 = value(d[sy]), v110 = value(d[sy + 1]);
            const double v001 = value(d[sz]), v101 = value(d[sz + 1]);
            const double v011 = value(d[sz + sy]), v111 = value(d[sz + sy + 1]);
            const double c00 = v000 + fx * (v100 - v000);
            const double c10 = v010 + fx * (v110 - v010);
            const double c01 = v001 + fx * (v101 - v001);
            const double c11 = v011 + fx * (v111 - v011);
            const double c0 = c00 + fy * (c10 - c00), c1 = c01 + fy * (c11 - c01);
            return static_cast<float>(c0 + fz * (c1 - c0));
        }
        std::int64_t x1, y1, z1, xa, ya, za;
        double fx, fy, fz;
        cell(p[0], nx, xa, x1, fx);
        cell(p[1], ny, ya, y1, fy);
        cell(p[2], nz, za, z1, fz);
        const double c00 = at(xa, ya, za) + fx * (at(x1, ya, za) - at(xa, ya, za));
        const double c10 = at(xa, y1, za) + fx * (at(x1, y1, za) - at(xa, y1, za));
        const double c01 = at(xa, ya, z1) + fx * (at(x1, ya, z1) - at(xa, ya, z1));
        const double c11 = at(xa, y1, z1) + fx * (at(x1, y1, z1) - at(xa, y1, z1));
        const double c0 = c00 + fy * (c10 - c00), c1 = c01 + fy * (c11 - c01);
        return static_cast<float>(c0 + fz * (c1 - c0));
    }
    float sample(const std::int64_t* p, Sampling s) const {
        return s == Sampling::Nearest ? nearest(p) : trilinear(p);
    }
};

/// Calls f(Sampler<T>) for the source's element type.
template <class F>
void with_sampler(const VolumeView& v, F&& f) {
    const std::int64_t nx = v.grid.dims[0], ny = v.grid.dims[1], nz = v.grid.dims[2];
    switch (v.dtype) {
        case DType::UInt8: return f(Sampler<std::uint8_t>{static_cast<const std::uint8_t*>(v.data), nx, ny, nz});
        case DType::Int8: return f(Sampler<std::int8_t>{static_cast<const std::int8_t*>(v.data), nx, ny, nz});
        case DType::UInt16: return f(Sampler<std::uint16_t>{static_cast<const std::uint16_t*>(v.data), nx, ny, nz});
        case DType::Int16: return f(Sampler<std::int16_t>{static_cast<const std::int16_t*>(v.data), nx, ny, nz});
        case DType::UInt32: return f(Sampler<std::uint32_t>{static_cast<const std::uint32_t*>(v.data), nx, ny, nz});
        case DType::Int32: return f(Sampler<std::int32_t>{static_cast<const std::int32_t*>(v.data), nx, ny, nz});
        case DType::UInt64: return f(Sampler<std::uint64_t>{static_cast<const std::uint64_t*>(v.data), nx, ny, nz});
        case DType::Int64: return f(Sampler<std::int64_t>{static_cast<const std::int64_t*>(v.data), nx, ny, nz});
        case DType::Float32: return f(Sampler<float>{static_cast<const float*>(v.data), nx, ny, nz});
        case DType::Float64: return f(Sampler<double>{static_cast<const double*>(v.data), nx, ny, nz});
    }
}

// ---- input checks ------------------------------------------------------------------------------------------

void check_spheres(const Grid& g, const BoundSpheres& s) {
    if (s.n > 0 && (!s.ijk || !s.radius || !s.bone)) throw Error("deform: missing sphere arrays");
    if (s.bone_count == 0) throw Error("deform: the rig has no bones");
    if (s.bone_count > 32767) throw Error("deform: at most 32,767 bones are supported");
    if (s.n >= kNone) throw Error("deform: too many spheres");
    for (std::size_t i = 0; i < s.n; ++i) {
        const std::int32_t z = s.ijk[3 * i], y = s.ijk[3 * i + 1], x = s.ijk[3 * i + 2];
        if (x < 0 || y < 0 || z < 0 || x >= g.dims[0] || y >= g.dims[1] || z >= g.dims[2])
            throw Error("deform: sphere " + std::to_string(i) + " has its centre outside the source grid");
        if (!std::isfinite(s.radius[i]) || s.radius[i] < 0)
            throw Error("deform: sphere " + std::to_string(i) + " has a negative or non-finite radius");
        if (s.bone[i] < 0 || static_cast<std::size_t>(s.bone[i]) >= s.bone_count)
            throw Error("deform: sphere " + std::to_string(i) + " is bound to bone " + std::to_string(s.bone[i]) +
                        " but the rig has " + std::to_string(s.bone_count) + " bones");
    }
    if (s.weight_offsets) {
        if (s.weight_offsets[0] != 0) throw Error("deform: weight rows must start at 0");
        for (std::size_t i = 0; i < s.n; ++i) {
            if (s.weight_offsets[i + 1] < s.weight_offsets[i])
                throw Error("deform: weight rows are not increasing");
            double total = 0;
            for (std::int64_t k = s.weight_offsets[i]; k < s.weight_offsets[i + 1]; ++k) {
                if (s.weight_bones[k] < 0 || static_cast<std::size_t>(s.weight_bones[k]) >= s.bone_count)
                    throw Error("deform: sphere " + std::to_string(i) + " has a weight on bone " +
                                std::to_string(s.weight_bones[k]) + " outside the rig");
                if (!std::isfinite(s.weights[k]) || s.weights[k] < 0)
                    throw Error("deform: sphere " + std::to_string(i) + " has a negative or non-finite weight");
                total += s.weights[k];
            }
            if (!(total > 0)) throw Error("deform: sphere " + std::to_string(i) + " has no positive weight");
        }
    }
}

void check_options(const DeformOptions& o, std::size_t n) {
    if (!o.radius_scale.empty()) {
        if (o.radius_scale.size() != n)
            throw Error("deform: radius_scale has " + std::to_string(o.radius_scale.size()) + " entries for " +
                        std::to_string(n) + " spheres");
        for (float f : o.radius_scale)
            if (!std::isfinite(f) || f < 0 || f > 100)
                throw Error("deform: radius_scale entries must lie in [0, 100]");
    }
}

std::vector<double> scaled_radii(const BoundSpheres& s, const DeformOptions& o) {
    std::vector<double> r(s.n);
    for (std::size_t i = 0; i < s.n; ++i)
        r[i] = static_cast<double>(s.radius[i]) * (o.radius_scale.empty() ? 1.0 : o.radius_scale[i]);
    return r;
}

/// A sphere's smooth weights rounded to kWeightSteps-ths of their sum (spheres whose rounded weights agree share one
/// blended transform, which is what lets smooth modes use the per-bone machinery).
Weights quantized_weights(const BoundSpheres& s, std::size_t i) {
    Weights w;
    if (!s.weight_offsets) return {{s.bone[i], kWeightSteps}};
    double total = 0;
    for (std::int64_t k = s.weight_offsets[i]; k < s.weight_offsets[i + 1]; ++k) total += s.weights[k];
    for (std::int64_t k = s.weight_offsets[i]; k < s.weight_offsets[i + 1]; ++k) {
        const auto q = static_cast<std::int32_t>(std::lround(kWeightSteps * s.weights[k] / total));
        if (q <= 0) continue;
        auto it = std::find_if(w.begin(), w.end(), [&](const auto& e) { return e.first == s.weight_bones[k]; });
        if (it != w.end()) it->second += q;
        else w.emplace_back(s.weight_bones[k], q);
    }
    std::sort(w.begin(), w.end());
    if (w.empty()) w.emplace_back(s.bone[i], kWeightSteps);
    return w;
}

/// Smooth-mode groups: spheres whose rounded weights and owner agree share one blended transform (for linear
/// blending, made rigid about the group's centroid).
struct SmoothGroups {
    std::vector<std::int32_t> group_of;  ///< per sphere: its group, or -1 when one bone moves it
    std::vector<std::int32_t> bone_of;   ///< per sphere: that bone (when group_of is -1)
    std::vector<Weights> weights;
    std::vector<std::int32_t> owner;
    std::vector<Eigen::Vector3d> pivot;  ///< world centroid of each group's centres
};

SmoothGroups smooth_groups(const BoundSpheres& s, const Grid& g) {
    SmoothGroups out;
    out.group_of.assign(s.n, -1);
    out.bone_of.assign(s.bone, s.bone + s.n);
    std::map<std::pair<std::int32_t, Weights>, std::int32_t> ids;
    std::vector<std::int64_t> count;
    for (std::size_t i = 0; i < s.n; ++i) {
        Weights w = quantized_weights(s, i);
        if (w.size() == 1) {
            out.bone_of[i] = w[0].first;
            continue;
        }
        auto [it, fresh] = ids.try_emplace({s.bone[i], w}, static_cast<std::int32_t>(out.weights.size()));
        if (fresh) {
            out.weights.push_back(std::move(w));
            out.owner.push_back(s.bone[i]);
            out.pivot.emplace_back(0, 0, 0);
            count.push_back(0);
        }
        const auto k = static_cast<std::size_t>(it->second);
        out.group_of[i] = it->second;
        for (int a = 0; a < 3; ++a)
            out.pivot[k][a] += g.origin[a] + g.spacing[a] * static_cast<double>(s.ijk[3 * i + 2 - a]);
        ++count[k];
    }
    for (std::size_t k = 0; k < count.size(); ++k) out.pivot[k] /= static_cast<double>(count[k]);
    return out;
}

/// Output box {offset, dims} from a lattice-space AABB; checks its size.
std::array<std::int64_t, 6> box_of(const Vec3d& lo, const Vec3d& hi) {
    std::array<std::int64_t, 6> b{};
    std::uint64_t count = 1;
    for (int a = 0; a < 3; ++a) {
        if (!(lo[a] <= hi[a])) {  // nothing to place
            b[a] = 0;
            b[3 + a] = 1;
            continue;
        }
        b[a] = static_cast<std::int64_t>(std::floor(lo[a]));
        b[3 + a] = static_cast<std::int64_t>(std::ceil(hi[a])) - b[a] + 1;
        count *= static_cast<std::uint64_t>(b[3 + a]);
    }
    if (count > (std::uint64_t{1} << 31))
        throw Error("deform: the posed spheres span " + std::to_string(count) +
                    " voxels (more than 2^31): check the bone matrices' translations and units");
    return b;
}

/// An empty frame on the box {offset, dims} of the source lattice.
DeformedVolume frame_on(const Grid& source, const std::array<std::int64_t, 6>& bx) {
    for (int a = 0; a < 3; ++a)
        if (bx[3 + a] <= 0) throw Error("deform: the output box must have positive dimensions");
    DeformedVolume out;
    out.offset = {bx[0], bx[1], bx[2]};
    out.grid.dims = {bx[3], bx[4], bx[5]};
    out.grid.spacing = source.spacing;
    for (int a = 0; a < 3; ++a) out.grid.origin[a] = source.origin[a] + source.spacing[a] * static_cast<double>(bx[a]);
    return out;
}

/// Crops a frame to the sub-box {offset, dims} of its grid (relative to its own offset), in place when it already
/// has that box. With the source grid, the origin is placed as frame_on() places it.
void crop(DeformedVolume& f, const std::array<std::int64_t, 6>& sub, const Grid* source = nullptr) {
    const std::int64_t nx = f.grid.dims[0], ny = f.grid.dims[1];
    if (sub[0] == 0 && sub[1] == 0 && sub[2] == 0 && sub[3] == nx && sub[4] == ny && sub[5] == f.grid.dims[2]) return;
    const std::int64_t ox = sub[3], oy = sub[4], oz = sub[5];
    const auto total = static_cast<std::size_t>(ox * oy * oz);
    ZeroedArray<float> values(f.values.empty() ? 0 : total);
    ZeroedArray<std::int16_t> bone(total);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, oz), [&](const tbb::blocked_range<std::int64_t>& rg) {
        for (std::int64_t z = rg.begin(); z != rg.end(); ++z)
            for (std::int64_t y = 0; y < oy; ++y) {
                const auto from = static_cast<std::size_t>(((z + sub[2]) * ny + y + sub[1]) * nx + sub[0]);
                const auto to = static_cast<std::size_t>((z * oy + y) * ox);
                const std::int16_t* b = f.bone.data() + from;
                // Copy only rows with a covered voxel: the others stay untouched zero pages.
                if (std::all_of(b, b + ox, [](std::int16_t v) { return v == 0; })) continue;
                std::copy(b, b + ox, bone.data() + to);
                if (!values.empty()) std::copy(f.values.data() + from, f.values.data() + from + ox, values.data() + to);
            }
    });
    f.values = std::move(values);
    f.bone = std::move(bone);
    for (int a = 0; a < 3; ++a) {
        f.offset[a] += sub[a];
        f.grid.dims[a] = sub[3 + a];
        f.grid.origin[a] = source ? source->origin[a] + source->spacing[a] * static_cast<double>(f.offset[a])
                                  : f.grid.origin[a] + f.grid.spacing[a] * static_cast<double>(sub[a]);
    }
}

// ---- per-bone rest data: spheres in k-d order, k-d tree, power-diagram labels -------------------------------

struct KdNode {
    double lo[3], hi[3];  // the box of the centres (world offsets)
    double blo[3], bhi[3];  // the box of the balls
    double max_lim;
    std::uint32_t begin, end;
    std::int32_t left = -1, right = -1;
};

/// An allocator for the large per-rig tables read at random every frame: 2 MiB aligned and marked for transparent
/// huge pages (where the kernel offers them), so that lookups spread over hundreds of MB do not miss the TLB.
template <class T>
struct HugePageAllocator {
    using value_type = T;
    HugePageAllocator() = default;
    template <class U>
    HugePageAllocator(const HugePageAllocator<U>&) {}
    T* allocate(std::size_t n) {
        const std::size_t bytes = n * sizeof(T);
        constexpr std::size_t kHuge = std::size_t{2} << 20;
        if (bytes < 2 * kHuge) return static_cast<T*>(::operator new(bytes));
        void* p = nullptr;
        if (posix_memalign(&p, kHuge, bytes) != 0) throw std::bad_alloc();
        madvise(p, bytes / kHuge * kHuge, MADV_HUGEPAGE);  // advice only: failure leaves ordinary pages
        return static_cast<T*>(p);
    }
    void deallocate(T* p, std::size_t n) {
        if (n * sizeof(T) < 2 * (std::size_t{2} << 20)) ::operator delete(p);
        else std::free(p);
    }
    template <class U>
    bool operator==(const HugePageAllocator<U>&) const { return true; }
    template <class U>
    bool operator!=(const HugePageAllocator<U>&) const { return false; }
};
template <class T>
using HugeVector = std::vector<T, HugePageAllocator<T>>;

/// Asks the kernel to back the 2 MiB-aligned interior of a large existing buffer (the source volume, sampled at
/// random every frame) with huge pages, collapsing it now where the kernel can (Linux 6.1+). Contents are
/// unchanged; any failure leaves ordinary pages.
void advise_huge_pages(const void* data, std::size_t bytes) {
    constexpr std::uintptr_t kHuge = std::uintptr_t{2} << 20;
    const auto a = (reinterpret_cast<std::uintptr_t>(data) + kHuge - 1) & ~(kHuge - 1);
    const auto b = (reinterpret_cast<std::uintptr_t>(data) + bytes) & ~(kHuge - 1);
    if (b <= a) return;
    void* p = reinterpret_cast<void*>(a);
    madvise(p, b - a, MADV_HUGEPAGE);
    madvise(p, b - a, 25 /* MADV_COLLAPSE, absent from older headers; EINVAL on older kernels */);
}

/// The power of a bone over one lattice cube (first corner at a cell), quantised outwards to int16 steps:
/// lo <= power <= hi everywhere in the cube. kBoundMin as lo means -inf, kBoundMax as hi means +inf (and as lo,
/// "not covered anywhere in the cube").
struct CellBounds {
    std::int16_t lo = 32767, hi = 32767;
};
constexpr std::int16_t kBoundMin = -32768, kBoundMax = 32767;

inline std::int16_t quantize_down(double v, double step) {
    const double q = std::floor(v / step);
    if (!(q >= -32767)) return kBoundMin;
    return static_cast<std::int16_t>(std::min(q, 32767.0));
}
inline std::int16_t quantize_up(double v, double step) {
    const double q = std::ceil(v / step);
    if (!(q <= 32766)) return kBoundMax;
    return static_cast<std::int16_t>(std::max(q, -32767.0));
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

/// A lower bound at p of a function that is |x|² (world metric) plus a concave one, from its values v at the corners
/// of p's lattice cube (corner k: bits x, y, z) and p's offsets u in the cube. The concave part at p is at least any
/// convex combination of its corner values that represents p (the trilinear weights, or the barycentric weights of
/// a tetrahedron of corners holding p), and |p|² less the same combination of the corners' is −Σ s²u(1−u) for all
/// of them; the largest of the trilinear and the four Kuhn triangulations' (one per main diagonal) is taken.
double concave_lower(const double* v, const double* u, const double* s2) {
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

struct BoneField {
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
    HugeVector<std::uint32_t> words;              // likewise
    HugeVector<std::int16_t> corner;              // likewise: the power at the cell itself, quantised down
    double step = 1, floor_T = 0;                 // the quantum; the least power outside allocated blocks (T)
    std::vector<std::int32_t> block_sat;          // summed-area table of allocated blocks, (bdims + 1)³
    std::vector<CellBounds> sub;                  // 8 per allocated block: the bounds' range over each 4³ sub-block
                                                  // (quantised in steps common to all fields, so that they compare)

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
            if (s1[i] < s0[i]) return CellBounds{};
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

    /// A lower bound of the power at p (fixed point, as Pull gives it) from the quantised powers at the eight
    /// corners of its lattice cube (concave_lower: the power is |p|² plus a concave function). Corners outside the
    /// allocated blocks hold at least T.
    double corner_lower(const std::int64_t* p, const double* s2) const {
        std::uint32_t c[8];
        corner_cells((p[0] >> Pull::kBits) - lo[0], (p[1] >> Pull::kBits) - lo[1], (p[2] >> Pull::kBits) - lo[2], c);
        double v[8];
        for (int k = 0; k < 8; ++k) {
            const std::int16_t q = corner[c[k]];
            v[k] = c[k] == kNoCell ? floor_T : (q == kBoundMin ? -kInf : q * step);
        }
        const double u[3] = {Pull::fraction(p[0]), Pull::fraction(p[1]), Pull::fraction(p[2])};
        return concave_lower(v, u, s2);
    }

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
               blocks.size() * 24 + bounds.size() * sizeof(CellBounds) + words.size() * 4 + corner.size() * 2 +
               block_sat.size() * 4 + sub.size() * sizeof(CellBounds);
    }
};

inline double power_of(const BoneField& f, std::uint32_t k, const double* x, const double* s2) {
    const auto& sp = f.sph[k];
    return length2(x[0] - sp.c[0], x[1] - sp.c[1], x[2] - sp.c[2], s2) - sp.lim;
}

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

/// One 1-D lower envelope of parabolas w·(q − p)² + f(p) over the finite samples of a line, carrying labels.
struct LabelEnvelope {
    std::vector<std::int64_t> v;
    std::vector<double> z, fv;
    std::vector<std::uint32_t> lv;

    void run(double* f, std::uint32_t* lab, std::int64_t n, std::int64_t stride, double w) {
        v.resize(static_cast<std::size_t>(n));
        z.resize(static_cast<std::size_t>(n) + 1);
        fv.resize(static_cast<std::size_t>(n));
        lv.resize(static_cast<std::size_t>(n));
        std::int64_t k = -1;
        for (std::int64_t q = 0; q < n; ++q) {
            const double fq = f[q * stride];
            if (!(fq < kInf)) continue;
            double s = -kInf;
            while (k >= 0) {
                const std::int64_t p = v[static_cast<std::size_t>(k)];
                s = ((fq - fv[static_cast<std::size_t>(k)]) / w + static_cast<double>(q * q - p * p)) /
                    (2.0 * static_cast<double>(q - p));
                if (s <= z[static_cast<std::size_t>(k)]) --k;
                else break;
            }
            ++k;
            v[static_cast<std::size_t>(k)] = q;
            fv[static_cast<std::size_t>(k)] = fq;
            lv[static_cast<std::size_t>(k)] = lab[q * stride];
            z[static_cast<std::size_t>(k)] = k == 0 ? -kInf : s;
        }
        if (k < 0) return;
        std::int64_t j = 0;
        for (std::int64_t q = 0; q < n; ++q) {
            while (j < k && z[static_cast<std::size_t>(j + 1)] <= static_cast<double>(q)) ++j;
            const double d = static_cast<double>(q - v[static_cast<std::size_t>(j)]);
            f[q * stride] = fv[static_cast<std::size_t>(j)] + w * d * d;
            lab[q * stride] = lv[static_cast<std::size_t>(j)];
        }
    }
};

/// Whether sphere sp's open ball (with a margin for rounding, on the safe side) meets the box [lo, hi] (index space).
inline bool ball_meets_box(const BoneField::Sphere& sp, const double* lo, const double* hi, const double* s2) {
    double d2 = 0;
    for (int a = 0; a < 3; ++a) {
        const double e = sp.c[a] < lo[a] ? lo[a] - sp.c[a] : (sp.c[a] > hi[a] ? sp.c[a] - hi[a] : 0.0);
        d2 += s2[a] * e * e;
    }
    return d2 < sp.lim + 1e-9 * (1.0 + d2 + sp.lim);
}

/// Spheres whose balls meeting a box (for closed_cube), their coordinates apart so that the ball tests vectorise.
struct NearSpheres {
    std::vector<std::uint32_t> id;
    std::vector<double> c[3], lim;
    std::vector<double> gap;
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
};

/// The spheres whose balls meet the box [lo, hi] (index space), into `out`.
void spheres_meeting(const BoneField& f, const double* lo, const double* hi, const double* spacing, const double* s2,
                     NearSpheres& out) {
    out.clear();
    if (f.nodes.empty()) return;
    double qlo[3], qhi[3];  // world offsets
    for (int a = 0; a < 3; ++a) {
        qlo[a] = lo[a] * spacing[a];
        qhi[a] = hi[a] * spacing[a];
    }
    std::int32_t stack[64];
    int top = 0;
    stack[top++] = 0;
    while (top) {
        const KdNode& n = f.nodes[static_cast<std::size_t>(stack[--top])];
        double md = 0;
        bool meets = true;
        for (int a = 0; a < 3 && meets; ++a) {
            const double tol = 1e-9 * (1.0 + std::abs(qlo[a]) + std::abs(qhi[a]) + (n.bhi[a] - n.blo[a]));
            meets = n.blo[a] <= qhi[a] + tol && n.bhi[a] >= qlo[a] - tol;
            const double e = n.hi[a] < qlo[a] ? qlo[a] - n.hi[a] : (n.lo[a] > qhi[a] ? n.lo[a] - qhi[a] : 0.0);
            md += e * e;
        }
        if (!meets || !(md < n.max_lim + 1e-9 * (1.0 + md + n.max_lim))) continue;
        if (n.left >= 0) {
            stack[top++] = n.left;
            stack[top++] = n.right;
            continue;
        }
        for (std::uint32_t j = n.begin; j < n.end; ++j)
            if (f.sph[j].lim > 0 && ball_meets_box(f.sph[j], lo, hi, s2)) out.add(f, j);
    }
}

/// Whether the lattice cube with first corner `base` (index space) is closed for the bone: every sphere whose ball
/// meets the cube, apart from its corners' labels S, has a larger power than one sphere of S all over the cube. The
/// difference of two powers is affine, so its largest value on the cube is at a corner, found per axis; the margin is
/// far above rounding. Then wherever the bone's power is negative in the cube its sphere is in S (that sphere's ball
/// holds the point), so the least power over S, ties to the lower global index, is the bone's exact answer there.
/// `near`: a superset of the spheres whose balls meet the cube.
bool closed_cube(const BoneField& f, const double* base, const std::uint32_t* S, int ns, NearSpheres& near,
                 const double* s2) {
    if (ns == 0) return false;
    // Per sphere: its power at the first corner and its change along each axis (the corners are sums of these).
    auto affine = [&](std::uint32_t k, double& p0, double* st, double& mag) {
        const auto& sp = f.sph[k];
        p0 = power_of(f, k, base, s2);
        mag = std::abs(p0) + sp.lim;
        for (int a = 0; a < 3; ++a) {
            st[a] = s2[a] * (2 * (base[a] - sp.c[a]) + 1);
            mag += std::abs(st[a]);
        }
    };
    double p0s[8], sts[8][3], mags[8];
    for (int i = 0; i < ns; ++i) affine(S[i], p0s[i], sts[i], mags[i]);
    // Which balls meet the cube (as ball_meets_box: a gap that is not >= 0), over all of them at once.
    const std::size_t n = near.id.size();
    near.gap.resize(n);
    {
        const double* cx = near.c[0].data();
        const double* cy = near.c[1].data();
        const double* cz = near.c[2].data();
        const double* lim = near.lim.data();
        double* gap = near.gap.data();
        const double b0 = base[0], b1 = base[1], b2 = base[2], w0 = s2[0], w1 = s2[1], w2 = s2[2];
        for (std::size_t k = 0; k < n; ++k) {
            const double ex = std::max(0.0, std::max(b0 - cx[k], cx[k] - b0 - 1));
            const double ey = std::max(0.0, std::max(b1 - cy[k], cy[k] - b1 - 1));
            const double ez = std::max(0.0, std::max(b2 - cz[k], cz[k] - b2 - 1));
            const double d2 = w0 * ex * ex + w1 * ey * ey + w2 * ez * ez;
            gap[k] = d2 - (lim[k] + 1e-9 * (1.0 + d2 + lim[k]));
        }
    }
    int last = 0;
    for (std::size_t k = 0; k < n; ++k) {
        const std::uint32_t j = near.id[k];
        if (near.gap[k] >= 0 || std::find(S, S + ns, j) != S + ns) continue;
        double p0, st[3], mag;
        affine(j, p0, st, mag);
        bool dominated = false;
        for (int t = 0; t < ns && !dominated; ++t) {
            const int i = t + last < ns ? t + last : t + last - ns;  // the one that dominated the last sphere first
            double mx = p0s[i] - p0;
            for (int a = 0; a < 3; ++a) mx += std::max(0.0, sts[i][a] - st[a]);
            if (mx < -1e-9 * (1.0 + mags[i] + mag)) {
                dominated = true;
                last = i;
            }
        }
        if (!dominated) return false;
    }
    return true;
}

/// Builds one bone's field from its spheres (global indices) with radii r.
BoneField build_bone_field(const Grid& g, const BoundSpheres& s, const std::vector<std::uint32_t>& members,
                           const std::vector<double>& r, double T, double step) {
    BoneField f;
    const std::size_t m = members.size();
    if (m >= kClosedBit) throw Error("deform: too many spheres bound to one bone");
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
    std::array<std::int64_t, 3> lo{std::numeric_limits<std::int64_t>::max(), std::numeric_limits<std::int64_t>::max(),
                                   std::numeric_limits<std::int64_t>::max()};
    std::array<std::int64_t, 3> hi{std::numeric_limits<std::int64_t>::min(), std::numeric_limits<std::int64_t>::min(),
                                   std::numeric_limits<std::int64_t>::min()};
    for (std::size_t k = 0; k < m; ++k) {
        const std::uint32_t src = order[k];
        const std::uint32_t i = members[src];
        f.global[k] = i;
        f.sph[k] = {{static_cast<double>(s.ijk[3 * i + 2]), static_cast<double>(s.ijk[3 * i + 1]),
                     static_cast<double>(s.ijk[3 * i])},
                    lims[src]};
        const double* c = f.sph[k].c;
        for (int a = 0; a < 3; ++a) {
            // Beyond this margin the power of the sphere exceeds T: cells outside the box need no labels.
            const auto e = static_cast<std::int64_t>(std::ceil(std::sqrt(r[i] * r[i] + T) / g.spacing[a])) + 1;
            lo[a] = std::min(lo[a], static_cast<std::int64_t>(c[a]) - e);
            hi[a] = std::max(hi[a], static_cast<std::int64_t>(c[a]) + e + 1);
        }
    }
    if (m == 0) return f;
    f.lo = lo;
    for (int a = 0; a < 3; ++a) {
        f.dims[a] = hi[a] - lo[a];
        f.bdims[a] = (f.dims[a] + kBlock - 1) / kBlock;
    }
    const std::int64_t nx = f.dims[0], ny = f.dims[1], nz = f.dims[2];
    const auto count = static_cast<std::size_t>(nx * ny * nz);
    std::vector<double> F(count, kInf);
    std::vector<std::uint32_t> lab(count, kNone);
    for (std::size_t k = 0; k < m; ++k) {
        const auto& sp = f.sph[k];
        if (!(sp.lim > 0)) continue;
        const auto idx = static_cast<std::size_t>(((static_cast<std::int64_t>(sp.c[2]) - lo[2]) * ny +
                                                   (static_cast<std::int64_t>(sp.c[1]) - lo[1])) * nx +
                                                  (static_cast<std::int64_t>(sp.c[0]) - lo[0]));
        if (-sp.lim < F[idx]) {
            F[idx] = -sp.lim;
            lab[idx] = static_cast<std::uint32_t>(k);
        }
    }
    const double s2[3] = {g.spacing[0] * g.spacing[0], g.spacing[1] * g.spacing[1], g.spacing[2] * g.spacing[2]};
    tbb::enumerable_thread_specific<LabelEnvelope> envs;
    // x rows, then y columns, then z columns; each pass parallel over the other two axes.
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& rg) {
        LabelEnvelope& e = envs.local();
        for (std::int64_t z = rg.begin(); z != rg.end(); ++z) {
            for (std::int64_t y = 0; y < ny; ++y) {
                const auto base = static_cast<std::size_t>((z * ny + y) * nx);
                e.run(F.data() + base, lab.data() + base, nx, 1, s2[0]);
            }
            for (std::int64_t x = 0; x < nx; ++x) {
                const auto base = static_cast<std::size_t>(z * ny * nx + x);
                e.run(F.data() + base, lab.data() + base, ny, nx, s2[1]);
            }
        }
    });
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, ny), [&](const tbb::blocked_range<std::int64_t>& rg) {
        LabelEnvelope& e = envs.local();
        for (std::int64_t y = rg.begin(); y != rg.end(); ++y)
            for (std::int64_t x = 0; x < nx; ++x) {
                const auto base = static_cast<std::size_t>(y * nx + x);
                e.run(F.data() + base, lab.data() + base, nz, nx * ny, s2[2]);
            }
    });
    // Keep the blocks where the power function dips below T at a cell or at the cells one step above (the far
    // corners of the block's cubes): elsewhere no point can be covered, and a cube whose first corner lies in a
    // block that is not kept has no corner below T.
    const std::int64_t bx = f.bdims[0], by = f.bdims[1], bz = f.bdims[2];
    f.block_index.assign(static_cast<std::size_t>(bx * by * bz), -1);
    std::vector<std::uint8_t> keep(static_cast<std::size_t>(bx * by * bz), 0);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, bz), [&](const tbb::blocked_range<std::int64_t>& rg) {
        for (std::int64_t kz = rg.begin(); kz != rg.end(); ++kz)
            for (std::int64_t ky = 0; ky < by; ++ky)
                for (std::int64_t kx = 0; kx < bx; ++kx) {
                    bool any = false;
                    for (std::int64_t z = kz * kBlock; z < std::min(nz, (kz + 1) * kBlock + 1) && !any; ++z)
                        for (std::int64_t y = ky * kBlock; y < std::min(ny, (ky + 1) * kBlock + 1) && !any; ++y) {
                            const double* row = F.data() + static_cast<std::size_t>((z * ny + y) * nx);
                            for (std::int64_t x = kx * kBlock; x < std::min(nx, (kx + 1) * kBlock + 1); ++x)
                                if (row[x] < T) {
                                    any = true;
                                    break;
                                }
                        }
                    keep[static_cast<std::size_t>((kz * by + ky) * bx + kx)] = any;
                }
    });
    for (std::int64_t k = 0; k < bx * by * bz; ++k) {
        if (!keep[static_cast<std::size_t>(k)]) continue;
        const std::int64_t kx = k % bx, ky = (k / bx) % by, kz = k / (bx * by);
        f.block_index[static_cast<std::size_t>(k)] = static_cast<std::int32_t>(f.blocks.size());
        f.blocks.push_back({lo[0] + kx * kBlock, lo[1] + ky * kBlock, lo[2] + kz * kBlock});
    }
    if (f.blocks.size() * 512 + 1 > std::numeric_limits<std::uint32_t>::max())
        throw Error("deform: a bone's field is too large (more than 2^32 lattice cells near its spheres)");
    f.bounds.assign(f.blocks.size() * 512 + 1, CellBounds{});
    f.words.assign(f.blocks.size() * 512 + 1, kNone);
    f.corner.assign(f.blocks.size() * 512 + 1, kBoundMax);
    f.step = step;
    f.floor_T = T;
    f.sub.assign(f.blocks.size() * 8, CellBounds{});
    double maxlim = 0;
    for (const auto& sp : f.sph) maxlim = std::max(maxlim, sp.lim);
    const double quarter = 0.25 * (s2[0] + s2[1] + s2[2]);
    const double slack = 1e-9 * (maxlim + 4 * quarter);
    struct Pending {  // a cube to close: its cell in the block and its corners' labels
        int li, nk;
        std::uint32_t ks[8];
    };
    struct Scratch {
        std::vector<Pending> pending = std::vector<Pending>(512);
        NearSpheres near;
    };
    tbb::enumerable_thread_specific<Scratch> scratch;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, f.blocks.size()), [&](const tbb::blocked_range<std::size_t>& rg) {
        Scratch& sc = scratch.local();
        Pending* const pending = sc.pending.data();
        for (std::size_t slot = rg.begin(); slot != rg.end(); ++slot) {
            int n_pending = 0;
            CellBounds* out = f.bounds.data() + 1 + slot * 512;
            std::uint32_t* out_word = f.words.data() + 1 + slot * 512;
            std::int16_t* out_corner = f.corner.data() + 1 + slot * 512;
            const std::int64_t x0 = f.blocks[slot][0] - lo[0], y0 = f.blocks[slot][1] - lo[1], z0 = f.blocks[slot][2] - lo[2];
            for (std::int64_t z = z0; z < std::min(nz, z0 + kBlock); ++z)
                for (std::int64_t y = y0; y < std::min(ny, y0 + kBlock); ++y)
                    for (std::int64_t x = x0; x < std::min(nx, x0 + kBlock); ++x) {
                        const int li = static_cast<int>(((z - z0) * 8 + (y - y0)) * 8 + (x - x0));
                        std::uint32_t word = lab[static_cast<std::size_t>((z * ny + y) * nx + x)];
                        out_corner[li] = quantize_down(F[static_cast<std::size_t>((z * ny + y) * nx + x)] - slack, step);
                        // The power over the cube with first corner (x, y, z): at least the least corner value
                        // minus the concave term's largest value Σ s²/4 (corners outside the field hold at least
                        // T); at most, for any sphere labelling a corner, its largest corner value (convexity).
                        double fmin = kInf;
                        std::uint32_t ks[8];
                        int nk = 0;
                        bool complete = true;  // all eight corners inside the field and labelled
                        for (int c = 0; c < 8; ++c) {
                            const std::int64_t cx = x + (c & 1), cy = y + ((c >> 1) & 1), cz = z + ((c >> 2) & 1);
                            if (cx >= nx || cy >= ny || cz >= nz) {
                                fmin = std::min(fmin, T);
                                complete = false;
                                continue;
                            }
                            const auto i = static_cast<std::size_t>((cz * ny + cy) * nx + cx);
                            fmin = std::min(fmin, F[i]);
                            complete = complete && lab[i] != kNone;
                            if (lab[i] != kNone && std::find(ks, ks + nk, lab[i]) == ks + nk) ks[nk++] = lab[i];
                        }
                        if (complete && nk == 1) word |= kSameBit;
                        const double lower = fmin - quarter;
                        if (!(lower < 0)) {
                            out[li] = CellBounds{kBoundMax, kBoundMax};
                            out_word[li] = word;
                            continue;
                        }
                        double upper = kInf;
                        const double rest[3] = {static_cast<double>(x + lo[0]), static_cast<double>(y + lo[1]),
                                                static_cast<double>(z + lo[2])};
                        for (int k = 0; k < nk; ++k) {
                            double mx = -kInf;
                            for (int c = 0; c < 8 && mx < upper; ++c) {
                                const double corner[3] = {rest[0] + (c & 1), rest[1] + ((c >> 1) & 1), rest[2] + ((c >> 2) & 1)};
                                mx = std::max(mx, power_of(f, ks[k], corner, s2));
                            }
                            upper = std::min(upper, mx);
                        }
                        out[li] = CellBounds{quantize_down(lower - slack, step), quantize_up(upper + slack, step)};
                        out_word[li] = word;
                        // A cube the ranges leave undecided (it may or may not be covered) is worth closing.
                        if (word != kNone && !(word & kSameBit) && out[li].hi >= 0) {
                            Pending& pc = pending[n_pending++];
                            pc.li = li;
                            pc.nk = nk;
                            std::copy(ks, ks + nk, pc.ks);
                        }
                    }
            if (n_pending) {  // close them, from the spheres whose balls meet the block's cubes
                const double blo[3] = {static_cast<double>(f.blocks[slot][0]), static_cast<double>(f.blocks[slot][1]),
                                       static_cast<double>(f.blocks[slot][2])};
                const double bhi[3] = {blo[0] + kBlock, blo[1] + kBlock, blo[2] + kBlock};
                spheres_meeting(f, blo, bhi, g.spacing.data(), s2, sc.near);
                for (int k = 0; k < n_pending; ++k) {
                    const Pending& pc = pending[k];
                    const double base[3] = {blo[0] + (pc.li & 7), blo[1] + ((pc.li >> 3) & 7), blo[2] + (pc.li >> 6)};
                    if (closed_cube(f, base, pc.ks, pc.nk, sc.near, s2)) out_word[pc.li] |= kClosedBit;
                }
            }
            CellBounds* sb = f.sub.data() + slot * 8;
            for (int k = 0; k < 8; ++k) sb[k] = CellBounds{kBoundMax, kBoundMin};
            for (int li = 0; li < 512; ++li) {
                CellBounds& t = sb[(((li >> 8) & 1) * 2 + ((li >> 5) & 1)) * 2 + ((li >> 2) & 1)];
                t.lo = std::min(t.lo, out[li].lo);
                t.hi = std::max(t.hi, out[li].hi);
            }
        }
    });
    const std::int64_t sx = bx + 1, sy = by + 1;
    f.block_sat.assign(static_cast<std::size_t>(sx * sy * (bz + 1)), 0);
    for (std::int64_t z = 1; z <= bz; ++z)
        for (std::int64_t y = 1; y <= by; ++y)
            for (std::int64_t x = 1; x <= bx; ++x) {
                auto at = [&](std::int64_t i, std::int64_t j, std::int64_t k) -> std::int32_t& {
                    return f.block_sat[static_cast<std::size_t>((k * sy + j) * sx + i)];
                };
                at(x, y, z) = (f.block_index[static_cast<std::size_t>(((z - 1) * by + (y - 1)) * bx + (x - 1))] >= 0) +
                              at(x - 1, y, z) + at(x, y - 1, z) + at(x, y, z - 1) - at(x - 1, y - 1, z) -
                              at(x - 1, y, z - 1) - at(x, y - 1, z - 1) + at(x - 1, y - 1, z - 1);
            }
    return f;
}

// ---- exact queries -----------------------------------------------------------------------------------------

struct Best {
    double key = kInf;
    std::uint32_t local = kNone;
    std::uint32_t global = kNone;
    bool better(double k, std::uint32_t g) const { return k < key || (k == key && g < global); }
};

double mindist2(const KdNode& n, const double* p) {
    double d = 0;
    for (int a = 0; a < 3; ++a) {
        const double e = p[a] < n.lo[a] ? n.lo[a] - p[a] : (p[a] > n.hi[a] ? p[a] - n.hi[a] : 0.0);
        d += e * e;
    }
    return d;
}

/// Walks the bone's k-d tree depth first, nearer child first, with an explicit stack (the tree is balanced: its
/// depth stays far below 64). `open(n, md)` says whether node n, at least squared distance md from p (world
/// offsets), may still matter; `leaf(n)` visits a leaf's spheres and returns true to stop the walk.
template <class Open, class Leaf>
void walk_kd(const BoneField& f, const double* p, Open&& open, Leaf&& leaf) {
    std::int32_t stack[64];
    double dist[64];
    int top = 0;
    std::int32_t node = 0;
    double md = mindist2(f.nodes[0], p);
    for (;;) {
        const KdNode& n = f.nodes[static_cast<std::size_t>(node)];
        if (open(n, md)) {
            if (n.left < 0) {
                if (leaf(n)) return;
            } else {
                const double dl = mindist2(f.nodes[static_cast<std::size_t>(n.left)], p);
                const double dr = mindist2(f.nodes[static_cast<std::size_t>(n.right)], p);
                const bool left_first = dl <= dr;
                stack[top] = left_first ? n.right : n.left;
                dist[top++] = left_first ? dr : dl;
                node = left_first ? n.left : n.right;
                md = left_first ? dl : dr;
                continue;
            }
        }
        if (top == 0) return;
        --top;
        node = stack[top];
        md = dist[top];
    }
}

/// Minimum over the bone's spheres of the power |p − c|² − lim (p in world offsets), or, with `nearest`, the
/// minimum of |p − c|² over the spheres that cover p.
/// `p` is in world offsets (for pruning, with a margin for rounding), `pi` the same point in index space.
void query(const BoneField& f, const double* p, const double* pi, const double* s2, bool nearest, Best& best) {
    walk_kd(
        f, p,
        [&](const KdNode& n, double md) {
            const double slack = 1e-9 * (1.0 + std::abs(md) + n.max_lim + (best.key < kInf ? std::abs(best.key) : 0.0));
            return nearest ? !(md > best.key + slack || md >= n.max_lim + slack) : !(md - n.max_lim > best.key + slack);
        },
        [&](const KdNode& n) {
            for (std::uint32_t k = n.begin; k < n.end; ++k) {
                const auto& sp = f.sph[k];
                const double d2 = length2(pi[0] - sp.c[0], pi[1] - sp.c[1], pi[2] - sp.c[2], s2);
                if (nearest && !(d2 < sp.lim)) continue;
                const double key = nearest ? d2 : d2 - sp.lim;
                if (best.better(key, f.global[k])) best = {key, k, f.global[k]};
            }
            return false;
        });
}

/// Whether any of the bone's spheres covers the point (|p − c|² < lim): a search that stops at the first one.
bool any_cover(const BoneField& f, const double* p, const double* pi, const double* s2) {
    bool found = false;
    walk_kd(
        f, p,
        [&](const KdNode& n, double md) {
            if (!(md < n.max_lim + 1e-9 * (1.0 + md + n.max_lim))) return false;
            for (int a = 0; a < 3; ++a) {  // outside the box of the balls (with a margin for rounding)
                const double tol = 1e-9 * (1.0 + std::abs(p[a]) + (n.bhi[a] - n.blo[a]));
                if (p[a] < n.blo[a] - tol || p[a] > n.bhi[a] + tol) return false;
            }
            return true;
        },
        [&](const KdNode& n) {
            for (std::uint32_t k = n.begin; k < n.end && !found; ++k) {
                const auto& sp = f.sph[k];
                found = length2(pi[0] - sp.c[0], pi[1] - sp.c[1], pi[2] - sp.c[2], s2) < sp.lim;
            }
            return found;
        });
    return found;
}

/// `seed`: a sphere's (power, local, global) at the point when one is known (power proximity only): it prunes the
/// search from the start and cannot change the result, the least (key, global) over all spheres.
Best exact(const BoneField& f, const double* p_index, const double* s, const double* s2, bool nearest,
           const Best& seed = Best{}) {
    Best b = seed;
    if (f.nodes.empty()) return b;
    const double pw[3] = {p_index[0] * s[0], p_index[1] * s[1], p_index[2] * s[2]};
    query(f, pw, p_index, s2, nearest, b);
    return b;
}

/// The power-diagram labels of the lattice cube around a rest point p (index space) of one bone.
struct Cube {
    std::uint32_t lab[8];
    double base[3];  // the cube's first corner
    bool same;       // all eight corners carry one sphere
    bool closed;     // the least power over the labels is exact where negative (closed_cube)
};

/// Reads the cube around p; false when no corner carries a label (then no sphere of the bone covers p).
bool fetch_cube(const BoneField& f, const double* p, Cube& cube) {
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
double least_over_labels(const BoneField& f, const std::uint32_t* lab, const double* p, const double* s2,
                         bool any_negative, std::uint32_t& local) {
    double U = kInf;
    local = kNone;
    for (int c = 0; c < 8; ++c) {
        const std::uint32_t k = lab[c];
        if (k == kNone || k == local) continue;
        const double v = power_of(f, k, p, s2);
        if (v < U || (v == U && f.global[k] < f.global[local])) {
            U = v;
            local = k;
            if (any_negative && U < 0) break;
        }
    }
    return U;
}

/// least_over_labels at a fixed-point preimage pf (as Pull gives it), from its cube's corner labels.
double least_over_corners(const BoneField& f, const std::int64_t* pf, const double* s2, std::uint32_t& local) {
    std::uint32_t cell[8], lab[8];
    f.corner_cells((pf[0] >> Pull::kBits) - f.lo[0], (pf[1] >> Pull::kBits) - f.lo[1], (pf[2] >> Pull::kBits) - f.lo[2],
                   cell);
    for (int k = 0; k < 8; ++k) lab[k] = label_of(f.words[cell[k]]);
    const double p[3] = {Pull::to_double(pf[0]), Pull::to_double(pf[1]), Pull::to_double(pf[2])};
    return least_over_labels(f, lab, p, s2, false, local);
}

/// A lower bound of the bone's power at p from its exact values at the cube's corners (concave_lower: the power
/// is |p|² plus a concave function, a minimum of linear ones); corners without a label hold at least T.
double lower_bound(const BoneField& f, const Cube& cube, const double* p, const double* s2, double T) {
    const double u[3] = {p[0] - cube.base[0], p[1] - cube.base[1], p[2] - cube.base[2]};
    double v[8];
    for (int c = 0; c < 8; ++c) {
        const double corner[3] = {cube.base[0] + (c & 1), cube.base[1] + ((c >> 1) & 1), cube.base[2] + ((c >> 2) & 1)};
        v[c] = cube.lab[c] == kNone ? T : power_of(f, cube.lab[c], corner, s2);
    }
    return concave_lower(v, u, s2);
}

/// A field (a bone, or a group of blended spheres) that may cover an output voxel.
struct Cand {
    Cand() {}  // members are set as they are computed: no zero-filling per voxel
    std::int32_t bone;    // the field
    double L, U;          // bounds of its power at the voxel (equal when exact; the nearest-centre key later)
    std::uint32_t local;  // the sphere achieving U (local index)
    std::uint32_t global;
    double p[3];          // the voxel's rest position under the field's motion
    bool covered;
    bool has_U, has_L;    // which bounds are computed yet
    Cube cube;
};

}  // namespace

// ---- the Deformer ------------------------------------------------------------------------------------------

struct Deformer::Impl {
    VolumeView source;
    Grid grid;
    std::size_t n = 0, bone_count = 0;
    std::vector<std::int32_t> ijk, bone, weight_bones;
    std::vector<float> radius, weights;
    std::vector<std::int64_t> weight_offsets;
    bool has_weights = false;
    std::shared_ptr<ZeroedPool> pool = ZeroedPool::create();  // frames' output memory, recycled

    // per-rig data for one (partition, radii) key
    bool built = false, built_smooth = false;
    std::vector<float> built_scale;
    // Fields: one per bone (its rigid spheres), then, in smooth modes, one per group of spheres whose rounded
    // weights agree (they share one blended transform).
    std::vector<BoneField> fields;
    std::vector<std::int32_t> field_owner;  // the bone each field's voxels are labelled with
    SmoothGroups groups;                    // fields from bone_count on are its groups, in order
    std::int64_t blended_spheres = 0;
    std::vector<double> radii;              // scaled radii
    double bound_step = 1;                  // the quantum of the fields' power bounds

    BoundSpheres view() const {
        BoundSpheres s;
        s.ijk = ijk.data();
        s.radius = radius.data();
        s.n = n;
        s.bone = bone.data();
        s.bone_count = bone_count;
        if (has_weights) {
            s.weight_offsets = weight_offsets.data();
            s.weight_bones = weight_bones.data();
            s.weights = weights.data();
        }
        return s;
    }

    double threshold() const {
        const auto& sp = grid.spacing;
        return 0.25 * (sp[0] * sp[0] + sp[1] * sp[1] + sp[2] * sp[2]) * (1 + 1e-9);
    }

    void build(bool smooth, const DeformOptions& o, const Progress& progress) {
        if (built && built_smooth == smooth && built_scale == o.radius_scale) return;
        built = false;
        fields.clear();
        field_owner.clear();
        blended_spheres = 0;
        const BoundSpheres s = view();
        radii = scaled_radii(s, o);
        std::vector<std::vector<std::uint32_t>> members(bone_count);
        for (std::size_t b = 0; b < bone_count; ++b) field_owner.push_back(static_cast<std::int32_t>(b));
        groups = smooth ? smooth_groups(s, grid) : SmoothGroups{};
        for (std::size_t k = 0; k < groups.weights.size(); ++k) {
            members.emplace_back();
            field_owner.push_back(groups.owner[k]);
        }
        for (std::size_t i = 0; i < n; ++i) {
            std::size_t f = static_cast<std::size_t>(bone[i]);
            if (smooth) {
                f = groups.group_of[i] >= 0 ? bone_count + static_cast<std::size_t>(groups.group_of[i])
                                            : static_cast<std::size_t>(groups.bone_of[i]);
                blended_spheres += groups.group_of[i] >= 0;
            }
            members[f].push_back(static_cast<std::uint32_t>(i));
        }
        const double T = threshold();
        // One quantum for every field's power bounds (they are compared across fields as integers).
        double maxlim = 0;
        for (double r : radii) maxlim = std::max(maxlim, open_ball_limit_sq(r));
        const double step = (maxlim + 4 * T) / 30000.0;
        bound_step = step;
        fields.reserve(members.size());
        for (std::size_t f = 0; f < members.size(); ++f) {
            fields.push_back(build_bone_field(grid, s, members[f], radii, T, step));
            report(progress, 0.5 * static_cast<double>(f + 1) / static_cast<double>(members.size()));
        }
        built = true;
        built_smooth = smooth;
        built_scale = o.radius_scale;
    }

    DeformedVolume frame(BoneMatrices matrices, const DeformOptions& o, const Progress& progress,
                         const std::array<std::int64_t, 6>* fixed_box);
};

Deformer::Deformer(const VolumeView& source, const BoundSpheres& spheres) : impl_(std::make_unique<Impl>()) {
    check_grid(source.grid, dtype_size(source.dtype), std::numeric_limits<std::uint64_t>::max(), "deform source");
    check_spheres(source.grid, spheres);
    Impl& m = *impl_;
    m.source = source;
    m.grid = source.grid;
    advise_huge_pages(source.data, static_cast<std::size_t>(source.grid.voxel_count()) * dtype_size(source.dtype));
    m.n = spheres.n;
    m.bone_count = spheres.bone_count;
    m.ijk.assign(spheres.ijk, spheres.ijk + 3 * spheres.n);
    m.radius.assign(spheres.radius, spheres.radius + spheres.n);
    m.bone.assign(spheres.bone, spheres.bone + spheres.n);
    if (spheres.weight_offsets) {
        m.has_weights = true;
        m.weight_offsets.assign(spheres.weight_offsets, spheres.weight_offsets + spheres.n + 1);
        const auto nnz = static_cast<std::size_t>(spheres.weight_offsets[spheres.n]);
        m.weight_bones.assign(spheres.weight_bones, spheres.weight_bones + nnz);
        m.weights.assign(spheres.weights, spheres.weights + nnz);
    }
}

Deformer::~Deformer() = default;

std::size_t Deformer::bone_count() const { return impl_->bone_count; }
std::size_t Deformer::sphere_count() const { return impl_->n; }

std::size_t Deformer::memory_bytes() const {
    std::size_t b = impl_->ijk.size() * 4 + impl_->radius.size() * 4 + impl_->bone.size() * 4 +
                    impl_->weights.size() * 8 + impl_->weight_offsets.size() * 8 + impl_->radii.size() * 8 +
                    impl_->groups.group_of.size() * 8 + impl_->groups.weights.size() * 64;
    for (const auto& f : impl_->fields) b += f.bytes();
    return b;
}

std::size_t Deformer::kept_frame_bytes() const { return impl_->pool->kept_bytes(); }
void Deformer::release_frame_memory() { impl_->pool->trim(); }

DeformedVolume Deformer::frame(BoneMatrices matrices, const DeformOptions& options, const Progress& progress,
                               const std::array<std::int64_t, 6>* box) {
    return impl_->frame(matrices, options, progress, box);
}

DeformedVolume Deformer::Impl::frame(BoneMatrices matrices, const DeformOptions& o, const Progress& progress,
                                     const std::array<std::int64_t, 6>* fixed_box) {
    check_options(o, n);
    const std::vector<Motion> motions = bone_motions(matrices, bone_count, grid);
    const bool smooth = o.mode != DeformMode::Rigid && has_weights;
    build(smooth, o, progress);
    const double s2[3] = {grid.spacing[0] * grid.spacing[0], grid.spacing[1] * grid.spacing[1],
                          grid.spacing[2] * grid.spacing[2]};
    const double T = threshold();
    const bool nearest = o.proximity == Proximity::Nearest;

    // Every field's motion: its bone's, or its group's blend.
    std::vector<Motion> fmot(motions);
    for (std::size_t k = 0; k < groups.weights.size(); ++k)
        fmot.push_back(blended_motion(motions, groups.weights[k], groups.owner[k], o.mode, grid, groups.pivot[k]));

    // Images of every allocated rest block (dilated by one cell: cube corners) in the posed lattice.
    struct BlockBox {
        std::uint32_t bone;
        std::array<double, 6> box;
    };
    std::vector<BlockBox> images;
    for (std::size_t b = 0; b < fields.size(); ++b) {
        const Affine& fw = fmot[b].forward;
        for (const auto& blk : fields[b].blocks) {
            BlockBox bb{static_cast<std::uint32_t>(b), {kInf, kInf, kInf, -kInf, -kInf, -kInf}};
            for (int c = 0; c < 8; ++c) {
                const double x[3] = {static_cast<double>(blk[0] + ((c & 1) ? kBlock : -1)),
                                     static_cast<double>(blk[1] + (((c >> 1) & 1) ? kBlock : -1)),
                                     static_cast<double>(blk[2] + (((c >> 2) & 1) ? kBlock : -1))};
                double y[3];
                fw.apply(x, y);
                for (int a = 0; a < 3; ++a) {
                    bb.box[a] = std::min(bb.box[a], y[a]);
                    bb.box[3 + a] = std::max(bb.box[3 + a], y[a]);
                }
            }
            images.push_back(bb);
        }
    }
    // The output box: the bounding box of the lattice points the posed balls hold. Per sphere and axis, the nearest
    // lattice line to the centre along the axis gives the extreme planes exactly (the squared distance is a sum of
    // one term per axis). A tolerance far below the open balls' margin keeps it on the safe side; should a plane
    // still be empty, the frame is cropped at the end.
    Vec3d lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    const double smax = std::max({grid.spacing[0], grid.spacing[1], grid.spacing[2]});
    for (std::size_t b = 0; b < fields.size(); ++b) {
        for (const auto& sp : fields[b].sph) {
            if (!(sp.lim > 0)) continue;
            double y[3], m[3];
            fmot[b].forward.apply(sp.c, y);
            for (int a = 0; a < 3; ++a) {
                const double d = std::nearbyint(y[a]) - y[a];
                m[a] = s2[a] * d * d;
            }
            // Tolerance: rounding, and the fixed-point map's error (Pull: below 1e-9 voxel per voxel of reach).
            const double tol = 1e-9 * (2 + std::abs(y[0]) + std::abs(y[1]) + std::abs(y[2])) * smax;
            const double lim = std::pow(std::sqrt(sp.lim) * (1 + 1e-9) + tol, 2);
            if (!(m[0] + m[1] + m[2] < lim)) continue;  // no lattice point inside
            for (int a = 0; a < 3; ++a) {
                const double h = std::sqrt(std::max(0.0, lim - m[(a + 1) % 3] - m[(a + 2) % 3]) / s2[a]);
                const double x0 = std::min(std::floor(y[a] - h) + 1, std::nearbyint(y[a])),
                             x1 = std::max(std::ceil(y[a] + h) - 1, std::nearbyint(y[a]));
                lo[a] = std::min(lo[a], x0);
                hi[a] = std::max(hi[a], x1);
            }
        }
    }
    const std::array<std::int64_t, 6> bx = fixed_box ? *fixed_box : box_of(lo, hi);
    check_box_reach(bx);
    DeformedVolume out = frame_on(grid, bx);
    const std::int64_t nx = bx[3], ny = bx[4], nz = bx[5];
    out.stats.blended_spheres = blended_spheres;
    const auto total = static_cast<std::size_t>(nx * ny * nz);
    // Recycled output memory: only what earlier frames wrote is zeroed again (marked as it is written).
    if (o.values) out.values = pool->take<float>(total);
    out.bone = pool->take<std::int16_t>(total);

    report(progress, 0.55);

    // Candidate bones of each output block.
    const std::int64_t obx = (nx + kBlock - 1) / kBlock, oby = (ny + kBlock - 1) / kBlock, obz = (nz + kBlock - 1) / kBlock;
    const std::size_t words = (fields.size() + 63) / 64;
    std::vector<std::uint64_t> bits(static_cast<std::size_t>(obx * oby * obz) * words, 0);
    for (const auto& im : images) {
        std::int64_t a[3], e[3];
        const std::int64_t ob[3] = {obx, oby, obz};
        bool empty = false;
        for (int k = 0; k < 3; ++k) {
            a[k] = std::max<std::int64_t>(0, (static_cast<std::int64_t>(std::floor(im.box[k])) - bx[k] - 1) / kBlock);
            const std::int64_t top = static_cast<std::int64_t>(std::ceil(im.box[3 + k])) - bx[k] + 1;
            if (top < 0) empty = true;
            e[k] = std::min<std::int64_t>(ob[k] - 1, top / kBlock);
            if (e[k] < a[k]) empty = true;
        }
        if (empty) continue;
        for (std::int64_t z = a[2]; z <= e[2]; ++z)
            for (std::int64_t y = a[1]; y <= e[1]; ++y)
                for (std::int64_t x = a[0]; x <= e[0]; ++x)
                    bits[static_cast<std::size_t>((z * oby + y) * obx + x) * words + im.bone / 64] |= std::uint64_t{1} << (im.bone % 64);
    }

    // The quantised range of field b's power over the preimages of the output voxels q0 + [0, side)³ (absolute
    // lattice): over the rest cubes holding them, from the bounding box of the preimage in fixed point (exact: the
    // lookups' cells are the integer parts of the very same values).
    auto preimage_range = [&](std::int32_t b, const std::int64_t* q0, std::int64_t side) {
        const Pull& pl = fmot[static_cast<std::size_t>(b)].pull;
        std::int64_t p0[3], ra[3], rb[3];
        pl.fixed(q0, p0);
        for (int a = 0; a < 3; ++a) {
            std::int64_t lo_f = p0[a], hi_f = p0[a];
            for (int j = 0; j < 3; ++j) {
                const std::int64_t d = pl.a[3 * a + j] * (side - 1);
                (d < 0 ? lo_f : hi_f) += d;
            }
            ra[a] = lo_f >> Pull::kBits;
            rb[a] = hi_f >> Pull::kBits;
        }
        return fields[static_cast<std::size_t>(b)].range_bounds(ra, rb);
    };

    // The bones whose rest data the preimage of output block (kx, ky, kz) meets.
    // With each, the range of its power over the block (from the rest cubes its preimage can reach).
    auto block_candidates = [&](std::int64_t kx, std::int64_t ky, std::int64_t kz, std::vector<std::int32_t>& cb,
                                std::vector<CellBounds>& range) {
        cb.clear();
        range.clear();
        const std::size_t blk = static_cast<std::size_t>((kz * oby + ky) * obx + kx);
        for (std::size_t w = 0; w < words; ++w) {
            std::uint64_t m = bits[blk * words + w];
            while (m) {
                const int t = __builtin_ctzll(m);
                const auto b = static_cast<std::int32_t>(w * 64 + static_cast<std::size_t>(t));
                m &= m - 1;
                double plo[3] = {kInf, kInf, kInf}, phi[3] = {-kInf, -kInf, -kInf};
                for (int c = 0; c < 8; ++c) {
                    const std::int64_t q[3] = {bx[0] + kx * kBlock + ((c & 1) ? kBlock : 0),
                                               bx[1] + ky * kBlock + (((c >> 1) & 1) ? kBlock : 0),
                                               bx[2] + kz * kBlock + (((c >> 2) & 1) ? kBlock : 0)};
                    double r[3];
                    fmot[static_cast<std::size_t>(b)].pull.apply(q, r);
                    for (int a = 0; a < 3; ++a) {
                        plo[a] = std::min(plo[a], r[a]);
                        phi[a] = std::max(phi[a], r[a]);
                    }
                }
                const std::int64_t ca[3] = {static_cast<std::int64_t>(std::floor(plo[0])) - 1,
                                            static_cast<std::int64_t>(std::floor(plo[1])) - 1,
                                            static_cast<std::int64_t>(std::floor(plo[2])) - 1};
                const std::int64_t cc[3] = {static_cast<std::int64_t>(std::floor(phi[0])) + 1,
                                            static_cast<std::int64_t>(std::floor(phi[1])) + 1,
                                            static_cast<std::int64_t>(std::floor(phi[2])) + 1};
                if (!fields[static_cast<std::size_t>(b)].any_block(ca, cc)) continue;
                const std::int64_t q0[3] = {bx[0] + kx * kBlock, bx[1] + ky * kBlock, bx[2] + kz * kBlock};
                const CellBounds rg = preimage_range(b, q0, kBlock);
                if (rg.lo >= 0) continue;
                cb.push_back(b);
                range.push_back(rg);
            }
        }
    };

    auto exact_covered = [&](Cand& c, std::int64_t& n_q) {
        ++n_q;
        Best seed;
        if (c.local != kNone) seed = {c.U, c.local, c.global};
        const Best e = exact(fields[static_cast<std::size_t>(c.bone)], c.p, grid.spacing.data(), s2, false, seed);
        c.L = c.U = e.key;
        c.local = e.local;
        c.global = e.global;
        c.has_L = c.has_U = true;
        return e.key < 0;
    };
    auto set_upper = [&](Cand& c, bool any_negative) {
        const BoneField& f = fields[static_cast<std::size_t>(c.bone)];
        c.U = least_over_labels(f, c.cube.lab, c.p, s2, any_negative, c.local);
        c.global = f.global[c.local];
        c.has_U = !any_negative || !(c.U < 0);  // a cut-short minimum is only an upper bound of the upper bound
    };
    auto set_lower = [&](Cand& c) {
        if (c.has_L) return;
        c.L = lower_bound(fields[static_cast<std::size_t>(c.bone)], c.cube, c.p, s2, T);
        c.has_L = true;
    };
    // Whether a candidate covers its point: from the bounds when they decide, else exactly.
    auto covers = [&](Cand& c, std::int64_t& n_q) {
        if (c.has_U && c.U < 0) return true;
        if (!c.has_U) {
            set_upper(c, true);
            if (c.U < 0) return true;
        }
        set_lower(c);
        if (!(c.L < 0)) return false;
        ++n_q;
        const BoneField& f = fields[static_cast<std::size_t>(c.bone)];
        const double pw[3] = {c.p[0] * grid.spacing[0], c.p[1] * grid.spacing[1], c.p[2] * grid.spacing[2]};
        return !f.nodes.empty() && any_cover(f, pw, c.p, s2);
    };

    // The winning candidate at posed lattice point m3 (output index idx), or null when no sphere covers it.
    auto resolve = [&](const std::int32_t* cb, std::size_t n_cb, const std::int64_t* m3, std::vector<Cand>& cands,
                       std::int64_t& n_q) -> const Cand* {
        cands.clear();
        for (std::size_t kb = 0; kb < n_cb; ++kb) {
            const std::int32_t b = cb[kb];
            cands.emplace_back();
            Cand& c = cands.back();
            c.bone = b;
            fmot[static_cast<std::size_t>(b)].pull.apply(m3, c.p);
            const BoneField& f = fields[static_cast<std::size_t>(b)];
            if (!fetch_cube(f, c.p, c.cube)) {
                cands.pop_back();
                continue;
            }
            c.has_U = c.has_L = false;
            c.local = kNone;
            c.covered = false;
            if (c.cube.same || c.cube.closed) {  // exact where negative: one sphere's on the whole cube, or closed
                c.L = c.U = least_over_labels(f, c.cube.lab, c.p, s2, false, c.local);
                if (!(c.U < 0)) {
                    cands.pop_back();
                    continue;
                }
                c.global = f.global[c.local];
                c.has_U = c.has_L = true;
            }
        }
        if (cands.empty()) return nullptr;
        if (cands.size() == 1) return covers(cands[0], n_q) ? &cands[0] : nullptr;
        auto before = [](const Cand& a, const Cand& b) { return a.U < b.U || (a.U == b.U && a.global < b.global); };
        if (!nearest) {
            for (auto& c : cands)
                if (!c.has_U) set_upper(c, false);
            std::size_t bi = 0;
            for (std::size_t k = 1; k < cands.size(); ++k)
                if (before(cands[k], cands[bi])) bi = k;
            // Certified when the best upper bound is negative and below every other candidate's lower bound.
            bool certain = cands[bi].U < 0;
            for (std::size_t k = 0; k < cands.size() && certain; ++k) {
                if (k == bi) continue;
                set_lower(cands[k]);
                if (!(cands[bi].U < cands[k].L)) certain = false;
            }
            if (certain) return &cands[bi];
            const double bound = cands[bi].U;
            for (auto& c : cands) {
                set_lower(c);
                if (c.L == c.U || c.L > bound || !(c.L < 0)) continue;
                exact_covered(c, n_q);
            }
            const Cand* win = nullptr;
            for (const auto& c : cands)
                if (c.U < 0 && (!win || before(c, *win))) win = &c;
            return win;
        }
        // Nearest centre: coverage first, then the nearest covering centre.
        std::size_t ncov = 0;
        for (auto& c : cands) {
            c.covered = c.covered || covers(c, n_q);
            ncov += c.covered;
        }
        const Cand* win = nullptr;
        for (auto& c : cands) {
            if (!c.covered) continue;
            if (ncov > 1) {
                const Best e = exact(fields[static_cast<std::size_t>(c.bone)], c.p, grid.spacing.data(), s2, true);
                ++n_q;
                c.U = e.key;
                c.global = e.global;
            }
            if (!win || before(c, *win)) win = &c;
        }
        return win;
    };

    // Gather, block by block: the candidates' cube ranges of all the block's voxels first (independent loads), then
    // the decisions over the whole block in int16 lanes, then the few undecided voxels one by one, then the samples,
    // written straight into the output.
    struct Tier {
        std::int32_t field;
        double U, L;
        std::uint32_t local;  // the sphere giving U; its global index breaks ties (fetched only then)
        bool exact, tight, closed;
        std::int64_t pf[3];  // the voxel's preimage (fixed point)
    };
    static const Tier kUndecided{};
    constexpr std::int32_t kEmpty = -1, kOpen = -2;  // per voxel: no candidate covers it / the ranges do not decide
    struct Local {
        std::vector<Tier> tiers;
        std::int64_t lo[3] = {std::numeric_limits<std::int64_t>::max(), std::numeric_limits<std::int64_t>::max(),
                              std::numeric_limits<std::int64_t>::max()};
        std::int64_t hi[3] = {-1, -1, -1};
        std::int64_t covered = 0, queries = 0, by[4] = {0, 0, 0, 0};  // block, cube, sphere, search
        // scratch
        std::vector<std::int32_t> cb, running;  // candidates still in the running (indices into cb, or fields)
        std::vector<CellBounds> range, range_sub;
        std::vector<std::uint8_t> live;
        std::vector<Cand> cands;
        // per candidate, per voxel of the block: the cube holding its preimage, split into lanes
        std::vector<std::int16_t> clo, chi;
        std::vector<std::uint32_t> cidx;  // the cells themselves, for their words
        std::int16_t u[512], mo[512], ml[512];  // least hi, least lo of the others, least lo
        std::int16_t arg[512];                  // the candidate with the least hi
        std::int32_t win[512];                  // per voxel: the winning field, kEmpty or kOpen
        std::uint64_t layer[8];                 // covered voxels, one bit per (dy, dx) per dz
    };
    tbb::enumerable_thread_specific<Local> locals;
    with_sampler(source, [&](auto sampler) {
        // The second tier (power proximity): for the n_run candidates in loc.running (indices into loc.cb), each one's
        // power at posed point m3 from its cube's first-corner sphere: exact when the cube is that sphere's alone,
        // else an upper bound; below it, the cube's quantised range, sharpened when needed from the corner powers
        // (concave_lower). Returns the winner, null when none covers, or &kUndecided.
        auto second_tier = [&](Local& loc, std::size_t n_run, std::size_t li, const std::int64_t* m3) -> const Tier* {
            Tier* const tiers = loc.tiers.data();
            std::size_t n_t = 0;
            for (std::size_t r = 0; r < n_run; ++r) {
                const std::int32_t k = loc.running[r];
                const std::size_t at = static_cast<std::size_t>(k) * 512 + li;
                const std::int32_t fi = loc.cb[static_cast<std::size_t>(k)];
                const BoneField& f = fields[static_cast<std::size_t>(fi)];
                const std::uint32_t word = f.words[loc.cidx[at]];
                const std::uint32_t lab = label_of(word);
                if (lab == kNone) return &kUndecided;
                Tier& t = tiers[n_t++];
                t.field = fi;
                fmot[static_cast<std::size_t>(fi)].pull.fixed(m3, t.pf);
                const double p[3] = {Pull::to_double(t.pf[0]), Pull::to_double(t.pf[1]), Pull::to_double(t.pf[2])};
                t.U = power_of(f, lab, p, s2);
                t.local = lab;
                t.exact = same_of(word);
                t.closed = !t.exact && closed_of(word);
                t.L = t.exact ? t.U : (loc.clo[at] == kBoundMin ? -kInf : loc.clo[at] * bound_step);
                t.tight = t.exact;
            }
            // A closed cube's exact answer: the least power over its corners' labels.
            auto sharpen = [&](Tier& t) {
                t.U = t.L = least_over_corners(fields[static_cast<std::size_t>(t.field)], t.pf, s2, t.local);
                t.exact = t.tight = true;
            };
            // The sharper lower bound, when the cube's range is not enough: exact in a closed cube, else from the
            // cube's corner powers.
            auto lower = [&](Tier& t, double beat) {
                if (t.tight || t.L > beat) return;
                if (t.closed) return sharpen(t);
                t.L = std::max(t.L, fields[static_cast<std::size_t>(t.field)].corner_lower(t.pf, s2));
                t.tight = true;
            };
            auto global = [&](const Tier& t) { return fields[static_cast<std::size_t>(t.field)].global[t.local]; };
            auto beats = [&](const Tier& w, const Tier& t) { return w.U < t.U || (w.U == t.U && global(w) < global(t)); };
            auto pick = [&] {
                std::size_t a = 0;
                for (std::size_t k = 1; k < n_t; ++k)
                    if (beats(tiers[k], tiers[a])) a = k;
                return a;
            };
            std::size_t a = pick();
            if (!(tiers[a].U < 0)) {  // none covers when every lower bound is >= 0
                bool open = false;
                for (std::size_t k = 0; k < n_t; ++k) {
                    lower(tiers[k], 0.0);
                    open = open || !(tiers[k].L >= 0);
                }
                a = pick();  // a closed cube's exact answer may cover
                if (!(tiers[a].U < 0)) return open ? &kUndecided : nullptr;
            }
            // Certain when the least upper bound (negative: a cover) is below every rival's lower bound; failing
            // that, once more with the closed cubes' exact answers (which may also lower the best upper bound).
            for (int round = 0; round < 2; ++round) {
                const Tier& w = tiers[a];
                bool certain = true;
                for (std::size_t k = 0; k < n_t && certain; ++k) {
                    if (k == a) continue;
                    Tier& t = tiers[k];
                    if (!t.exact) lower(t, w.U);
                    certain = t.exact ? beats(w, t) : w.U < t.L;
                }
                if (certain) return &w;
                bool sharper = false;
                for (std::size_t k = 0; k < n_t; ++k)
                    if (tiers[k].closed && !tiers[k].exact) {
                        sharpen(tiers[k]);
                        sharper = true;
                    }
                if (!sharper) break;
                a = pick();
            }
            return &kUndecided;
        };
        // The decision over a block or sub-block from each candidate's power range r[k] over its preimage: whether
        // candidate k can cover there and not lose to a certain cover (live[k * stride]); returns the index of a
        // candidate that covers all of it and wins everywhere, kEmpty when none can cover, or kOpen.
        auto settle = [&](const CellBounds* r, std::size_t K, std::uint8_t* live, std::size_t stride) -> std::int32_t {
            std::size_t a = 0;
            for (std::size_t k = 1; k < K; ++k)
                if (r[k].hi < r[a].hi) a = k;
            const std::int16_t ua = r[a].hi;
            std::size_t n_live = 0;
            for (std::size_t k = 0; k < K; ++k) {
                const bool l = r[k].lo < 0 && (nearest || !(ua < 0) || k == a || !(r[k].lo > ua));
                live[k * stride] = l;
                n_live += l;
            }
            if (n_live == 1 && ua < 0 && live[a * stride]) return static_cast<std::int32_t>(a);
            return n_live ? kOpen : kEmpty;
        };
        auto sub_origin = [](int sb) { return std::array<std::int64_t, 3>{(sb & 1) * 4, ((sb >> 1) & 1) * 4, (sb >> 2) * 4}; };
        // Per voxel of the block, for the sub-blocks and candidates marked live: the cubes' range lookups, the
        // decisions in int16 lanes, then the undecided voxels one by one (into win).
        auto decide_voxels = [&](Local& loc, std::size_t K, const std::int64_t* base, std::int64_t ex, std::int64_t ey,
                                 std::int64_t ez) {
            const auto& cb = loc.cb;
            const auto& live = loc.live;
            std::int32_t* const win = loc.win;
            loc.clo.resize(K * 512);
            loc.chi.resize(K * 512);
            loc.cidx.resize(K * 512);
            if (loc.running.size() < K) {
                loc.running.resize(K);
                loc.tiers.resize(K);
            }
            for (std::size_t k = 0; k < K; ++k) {
                // Stepping the fixed-point preimage by the map's columns: exactly the direct evaluation.
                const Pull& pl = fmot[static_cast<std::size_t>(cb[k])].pull;
                const BoneField& f = fields[static_cast<std::size_t>(cb[k])];
                std::uint32_t* at = loc.cidx.data() + k * 512;
                std::fill(at, at + 512, kNoCell);
                for (int sb = 0; sb < 8; ++sb) {
                    if (!live[k * 8 + static_cast<std::size_t>(sb)]) continue;
                    const auto s0 = sub_origin(sb);
                    const std::int64_t q0[3] = {base[0] + s0[0], base[1] + s0[1], base[2] + s0[2]};
                    const std::int64_t e[3] = {std::min<std::int64_t>(4, ex - s0[0]), std::min<std::int64_t>(4, ey - s0[1]),
                                               std::min<std::int64_t>(4, ez - s0[2])};
                    std::uint32_t* sat = at + (s0[2] * 8 + s0[1]) * 8 + s0[0];
                    std::int64_t pz[3];
                    pl.fixed(q0, pz);
                    for (std::int64_t dz = 0; dz < e[2]; ++dz) {
                        std::int64_t py[3] = {pz[0], pz[1], pz[2]};
                        for (std::int64_t dy = 0; dy < e[1]; ++dy) {
                            std::int64_t px[3] = {py[0], py[1], py[2]};
                            for (std::int64_t dx = 0; dx < e[0]; ++dx) {
                                sat[(dz * 8 + dy) * 8 + dx] = f.cube_cell(px);
                                px[0] += pl.a[0];
                                px[1] += pl.a[3];
                                px[2] += pl.a[6];
                            }
                            py[0] += pl.a[1];
                            py[1] += pl.a[4];
                            py[2] += pl.a[7];
                        }
                        pz[0] += pl.a[2];
                        pz[1] += pl.a[5];
                        pz[2] += pl.a[8];
                    }
                }
                // The loads, apart from the address arithmetic: independent, so that many are in flight at once.
                std::int16_t* klo = loc.clo.data() + k * 512;
                std::int16_t* khi = loc.chi.data() + k * 512;
                const CellBounds* cells = f.bounds.data();
                for (std::size_t li = 0; li < 512; ++li) {
                    const CellBounds c = cells[at[li]];
                    klo[li] = c.lo;
                    khi[li] = c.hi;
                }
            }
            // Decisions in lanes: u = least hi (candidate a), mo = least lo of the others, ml = least lo.
            std::int16_t* const u = loc.u;
            std::int16_t* const mo = loc.mo;
            std::int16_t* const ml = loc.ml;
            std::int16_t* const arg = loc.arg;
            {
                const std::int16_t* khi = loc.chi.data();
                const std::int16_t* klo = loc.clo.data();
                for (std::size_t li = 0; li < 512; ++li) {
                    u[li] = khi[li];
                    arg[li] = 0;
                    ml[li] = klo[li];
                    mo[li] = kBoundMax;
                }
            }
            for (std::size_t k = 1; k < K; ++k) {
                const std::int16_t* khi = loc.chi.data() + k * 512;
                const std::int16_t* klo = loc.clo.data() + k * 512;
                const auto kk = static_cast<std::int16_t>(k);
                for (std::size_t li = 0; li < 512; ++li) {
                    const bool lt = khi[li] < u[li];
                    u[li] = lt ? khi[li] : u[li];
                    arg[li] = lt ? kk : arg[li];
                    ml[li] = std::min(ml[li], klo[li]);
                }
            }
            for (std::size_t k = 0; k < K && K > 1; ++k) {
                const std::int16_t* klo = loc.clo.data() + k * 512;
                const auto kk = static_cast<std::int16_t>(k);
                for (std::size_t li = 0; li < 512; ++li)
                    mo[li] = arg[li] == kk ? mo[li] : std::min(mo[li], klo[li]);
            }
            // Certain: the least hi is negative and below every other candidate's lo (nearest centre: no other
            // candidate can cover at all).
            std::int64_t certain = 0;
            for (std::size_t li = 0; li < 512; ++li) {
                const bool sure = u[li] < 0 && (nearest ? mo[li] >= 0 : mo[li] > u[li]);
                const std::int32_t w = ml[li] >= 0 ? kEmpty : (sure ? cb[static_cast<std::size_t>(arg[li])] : kOpen);
                certain += sure && ml[li] < 0;
                win[li] = w;
            }
            loc.by[1] += certain;
            // The undecided voxels, one by one.
            for (std::size_t li = 0; li < 512; ++li) {
                if (win[li] != kOpen) continue;
                const std::int64_t dx = static_cast<std::int64_t>(li & 7), dy = static_cast<std::int64_t>((li >> 3) & 7),
                                   dz = static_cast<std::int64_t>(li >> 6);
                const std::int64_t m3[3] = {base[0] + dx, base[1] + dy, base[2] + dz};
                // Candidates whose least power exceeds a certain covering power cannot win.
                std::size_t n_run = 0;
                for (std::size_t k = 0; k < K; ++k) {
                    const std::int16_t l = loc.clo[k * 512 + li];
                    loc.running[n_run] = static_cast<std::int32_t>(k);
                    n_run += l < 0 && (nearest || !(u[li] < 0) || !(l > u[li]));
                }
                // Second tier: each one's power at the voxel from the sphere labelling its cube's first corner,
                // exact when that sphere holds the whole cube.
                const Tier* tw = nearest ? &kUndecided : second_tier(loc, n_run, li, m3);
                if (tw != &kUndecided) {
                    win[li] = tw ? tw->field : kEmpty;
                    loc.by[2] += tw != nullptr;
                    continue;
                }
                for (std::size_t r = 0; r < n_run; ++r) loc.running[r] = cb[static_cast<std::size_t>(loc.running[r])];
                const Cand* w = resolve(loc.running.data(), n_run, m3, loc.cands, loc.queries);
                win[li] = w ? w->bone : kEmpty;
                loc.by[3] += w != nullptr;
            }
        };
        auto gather_block = [&](Local& loc, std::int64_t kx, std::int64_t ky, std::int64_t kz) {
            auto& cb = loc.cb;
            auto& range = loc.range;
            auto& live = loc.live;
            block_candidates(kx, ky, kz, cb, range);
            if (cb.empty()) return;
            const std::int64_t ex = std::min(kBlock, nx - kx * kBlock), ey = std::min(kBlock, ny - ky * kBlock),
                               ez = std::min(kBlock, nz - kz * kBlock);
            if (cb.size() > 32767) throw Error("deform: more than 32767 bones or weight groups meet one output block");
            const std::int64_t base[3] = {kx * kBlock + bx[0], ky * kBlock + bx[1], kz * kBlock + bx[2]};
            std::int32_t* const win = loc.win;
            std::uint64_t* const layer = loc.layer;
            std::fill(layer, layer + 8, std::uint64_t{0});
            // The whole block first: a candidate that cannot win anywhere in it drops out, and one covering all of it
            // and winning everywhere fills it with no lookups.
            live.resize(cb.size());
            const std::int32_t whole = settle(range.data(), cb.size(), live.data(), 1);
            if (whole >= 0) {
                std::fill(win, win + 512, kEmpty);
                for (std::int64_t dz = 0; dz < ez; ++dz)
                    for (std::int64_t dy = 0; dy < ey; ++dy)
                        std::fill(win + (dz * 8 + dy) * 8, win + (dz * 8 + dy) * 8 + ex, cb[static_cast<std::size_t>(whole)]);
                loc.by[0] += ex * ey * ez;
            } else {
                std::size_t K = 0;
                for (std::size_t k = 0; k < cb.size(); ++k)
                    if (live[k]) cb[K++] = cb[k];
                cb.resize(K);
                // Then each 4³ sub-block, from each candidate's range over the sub-block's preimage: decided whole
                // the same way, or looked up voxel by voxel for the candidates live there.
                std::int32_t sub_win[8];  // kOpen: decided voxel by voxel; else kEmpty or the winning field
                live.assign(K * 8, 0);
                bool any_open = false;
                auto& sr = loc.range_sub;
                sr.resize(K);
                for (int sb = 0; sb < 8; ++sb) {
                    const auto s0 = sub_origin(sb);
                    sub_win[sb] = kEmpty;
                    if (s0[0] >= ex || s0[1] >= ey || s0[2] >= ez) continue;
                    const std::int64_t q0[3] = {base[0] + s0[0], base[1] + s0[1], base[2] + s0[2]};
                    for (std::size_t k = 0; k < K; ++k) sr[k] = preimage_range(cb[k], q0, 4);
                    std::uint8_t* lv = live.data() + sb;
                    const std::int32_t w = settle(sr.data(), K, lv, 8);
                    if (w >= 0) {
                        sub_win[sb] = cb[static_cast<std::size_t>(w)];
                        lv[static_cast<std::size_t>(w) * 8] = 0;
                    } else {
                        sub_win[sb] = w;
                        any_open = any_open || w == kOpen;
                    }
                }
                if (any_open)
                    decide_voxels(loc, K, base, ex, ey, ez);
                else
                    std::fill(win, win + 512, kEmpty);
                for (int sb = 0; sb < 8; ++sb) {  // the sub-blocks decided whole
                    if (sub_win[sb] == kOpen) continue;
                    const auto s0 = sub_origin(sb);
                    const std::int64_t x1 = std::min(s0[0] + 4, ex);
                    if (x1 <= s0[0]) continue;
                    for (std::int64_t dz = s0[2]; dz < std::min(s0[2] + 4, ez); ++dz)
                        for (std::int64_t dy = s0[1]; dy < std::min(s0[1] + 4, ey); ++dy) {
                            std::fill(win + (dz * 8 + dy) * 8 + s0[0], win + (dz * 8 + dy) * 8 + x1, sub_win[sb]);
                            if (sub_win[sb] >= 0) loc.by[0] += x1 - s0[0];
                        }
                }
            }
            // The covered voxels, straight into the output row by row: the bone label, and the sample through the
            // winning field's map, as the decisions saw it (along a row, a run of one field steps its preimage by a
            // column).
            std::int64_t ncov = 0;
            std::int16_t* const bone_out = out.bone.data();
            float* const value_out = o.values ? out.values.data() : nullptr;
            for (std::int64_t dz = 0; dz < ez; ++dz)
                for (std::int64_t dy = 0; dy < ey; ++dy) {
                    const std::int32_t* wrow = win + (dz * 8 + dy) * 8;
                    const auto row = static_cast<std::size_t>(((kz * kBlock + dz) * ny + ky * kBlock + dy) * nx + kx * kBlock);
                    std::int32_t run = -1;  // the field of the previous voxel in the row, -1 after a gap
                    std::int64_t pf[3] = {0, 0, 0};
                    std::uint64_t xs = 0;
                    for (std::int64_t dx = 0; dx < ex; ++dx) {
                        const std::int32_t w = wrow[dx];
                        if (w < 0) {
                            run = -1;
                            continue;
                        }
                        xs |= std::uint64_t{1} << dx;
                        bone_out[row + static_cast<std::size_t>(dx)] =
                            static_cast<std::int16_t>(field_owner[static_cast<std::size_t>(w)] + 1);
                        if (!value_out) continue;
                        const Pull& pl = fmot[static_cast<std::size_t>(w)].pull;
                        if (w == run) {
                            pf[0] += pl.a[0];
                            pf[1] += pl.a[3];
                            pf[2] += pl.a[6];
                        } else {
                            const std::int64_t m3[3] = {base[0] + dx, base[1] + dy, base[2] + dz};
                            pl.fixed(m3, pf);
                            run = w;
                        }
                        value_out[row + static_cast<std::size_t>(dx)] = sampler.sample(pf, o.sampling);
                    }
                    if (!xs) continue;
                    ncov += __builtin_popcountll(xs);
                    layer[dz] |= xs << (8 * dy);
                    const auto x0 = static_cast<std::size_t>(__builtin_ctzll(xs)), x1 = static_cast<std::size_t>(64 - __builtin_clzll(xs));
                    out.bone.mark_written(row + x0, row + x1);
                    if (value_out) out.values.mark_written(row + x0, row + x1);
                }
            if (!ncov) return;
            loc.covered += ncov;
            // The block's covered extent, from the bit layers.
            std::uint64_t all = 0;
            std::int64_t z0 = -1, z1 = -1;
            for (std::int64_t dz = 0; dz < ez; ++dz)
                if (layer[dz]) {
                    all |= layer[dz];
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
                               e1[3] = {63 - __builtin_clzll(cols), 63 - __builtin_clzll(rows), z1},
                               b0[3] = {kx * kBlock, ky * kBlock, kz * kBlock};
            for (int a = 0; a < 3; ++a) {
                loc.lo[a] = std::min(loc.lo[a], b0[a] + e0[a]);
                loc.hi[a] = std::max(loc.hi[a], b0[a] + e1[a]);
            }
        };
        // One pass over all blocks (no barriers); the calling thread reports progress as blocks complete, and a
        // cancel from it unwinds the whole loop.
        const std::int64_t total_blocks = obx * oby * obz;
        std::atomic<std::int64_t> done{0};
        const std::thread::id caller = std::this_thread::get_id();
        std::int64_t next_report = total_blocks / 40;
        tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, total_blocks, 64), [&](const tbb::blocked_range<std::int64_t>& rg) {
            Local& loc = locals.local();
            for (std::int64_t blk = rg.begin(); blk != rg.end(); ++blk)
                gather_block(loc, blk % obx, (blk / obx) % oby, blk / (obx * oby));
            const std::int64_t now = done.fetch_add(static_cast<std::int64_t>(rg.size())) + static_cast<std::int64_t>(rg.size());
            if (progress && std::this_thread::get_id() == caller && now >= next_report) {
                next_report = now + total_blocks / 40;
                report(progress, 0.55 + 0.4 * static_cast<double>(now) / static_cast<double>(total_blocks));
            }
        });
        report(progress, 0.95);
    });
    std::int64_t covered = 0, queries = 0, lo3[3] = {nx, ny, nz}, hi3[3] = {-1, -1, -1};
    for (const Local& loc : locals) {
        covered += loc.covered;
        queries += loc.queries;
        out.stats.by_block += loc.by[0];
        out.stats.by_cube += loc.by[1];
        out.stats.by_sphere += loc.by[2];
        out.stats.by_search += loc.by[3];
        for (int a = 0; a < 3; ++a) {
            lo3[a] = std::min(lo3[a], loc.lo[a]);
            hi3[a] = std::max(hi3[a], loc.hi[a]);
        }
    }
    if (!fixed_box) {  // crop to the covered voxels (one voxel when none is covered)
        for (int a = 0; a < 3; ++a)
            if (hi3[a] < lo3[a]) lo3[a] = hi3[a] = 0;
        crop(out, {lo3[0], lo3[1], lo3[2], hi3[0] - lo3[0] + 1, hi3[1] - lo3[1] + 1, hi3[2] - lo3[2] + 1}, &grid);
    }
    report(progress, 1.0);
    out.stats.covered = covered;
    out.stats.exact_queries = queries;
    return out;
}

void crop_to_covered(DeformedVolume& f) {
    const std::int64_t nx = f.grid.dims[0], ny = f.grid.dims[1], nz = f.grid.dims[2];
    std::int64_t lo[3] = {nx, ny, nz}, hi[3] = {-1, -1, -1};
    for (std::int64_t z = 0; z < nz; ++z)
        for (std::int64_t y = 0; y < ny; ++y) {
            const std::int16_t* row = f.bone.data() + static_cast<std::size_t>((z * ny + y) * nx);
            for (std::int64_t x = 0; x < nx; ++x) {
                if (!row[x]) continue;
                const std::int64_t v[3] = {x, y, z};
                for (int a = 0; a < 3; ++a) {
                    lo[a] = std::min(lo[a], v[a]);
                    hi[a] = std::max(hi[a], v[a]);
                }
            }
        }
    for (int a = 0; a < 3; ++a)
        if (hi[a] < lo[a]) lo[a] = hi[a] = 0;
    crop(f, {lo[0], lo[1], lo[2], hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1});
}

// ---- the literal thesis algorithm --------------------------------------------------------------------------

DeformedVolume deform_reference(const VolumeView& source, const BoundSpheres& s, BoneMatrices matrices,
                                const DeformOptions& o, const Progress& progress,
                                const std::array<std::int64_t, 6>* fixed_box) {
    const Grid& grid = source.grid;
    check_spheres(grid, s);
    check_options(o, s.n);
    const std::vector<Motion> motions = bone_motions(matrices, s.bone_count, grid);
    const std::vector<double> radii = scaled_radii(s, o);
    const bool smooth = o.mode != DeformMode::Rigid && s.weight_offsets;
    const double s2[3] = {grid.spacing[0] * grid.spacing[0], grid.spacing[1] * grid.spacing[1],
                          grid.spacing[2] * grid.spacing[2]};
    std::vector<Motion> mot(s.n);
    std::vector<std::array<double, 3>> centre(s.n), rest(s.n);
    const SmoothGroups groups = smooth ? smooth_groups(s, grid) : SmoothGroups{};
    Vec3d lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    for (std::size_t i = 0; i < s.n; ++i) {
        const std::int32_t k = smooth ? groups.group_of[i] : -1;
        mot[i] = k < 0 ? motions[static_cast<std::size_t>(smooth ? groups.bone_of[i] : s.bone[i])]
                       : blended_motion(motions, groups.weights[static_cast<std::size_t>(k)], s.bone[i], o.mode, grid,
                                        groups.pivot[static_cast<std::size_t>(k)]);
        rest[i] = {static_cast<double>(s.ijk[3 * i + 2]), static_cast<double>(s.ijk[3 * i + 1]),
                   static_cast<double>(s.ijk[3 * i])};
        mot[i].forward.apply(rest[i].data(), centre[i].data());
        if (!(radii[i] > 0)) continue;
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], centre[i][a] - radii[i] / grid.spacing[a]);
            hi[a] = std::max(hi[a], centre[i][a] + radii[i] / grid.spacing[a]);
        }
    }
    const std::array<std::int64_t, 6> bx = fixed_box ? *fixed_box : box_of(lo, hi);
    check_box_reach(bx);
    DeformedVolume out = frame_on(grid, bx);
    const std::int64_t nx = bx[3], ny = bx[4], nz = bx[5];
    const auto total = static_cast<std::size_t>(nx * ny * nz);
    std::vector<double> P(total, kInf);        // the proximity buffer
    std::vector<std::int64_t> who(total, -1);  // the sphere that wrote each voxel
    if (o.values) out.values = ZeroedArray<float>(total);
    out.bone = ZeroedArray<std::int16_t>(total);
    const bool nearest = o.proximity == Proximity::Nearest;
    with_sampler(source, [&](auto sampler) {
        // Parallel over z slabs; within a slab the spheres are scattered in index order, as in the thesis.
        tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz, 4), [&](const tbb::blocked_range<std::int64_t>& rg) {
            for (std::size_t i = 0; i < s.n; ++i) {
                const double r = radii[i];
                if (!(r > 0)) continue;
                const double lim = open_ball_limit_sq(r);
                const double cx = centre[i][0] - static_cast<double>(bx[0]),
                             cy = centre[i][1] - static_cast<double>(bx[1]),
                             cz = centre[i][2] - static_cast<double>(bx[2]);
                const auto za = std::max<std::int64_t>(rg.begin(), static_cast<std::int64_t>(std::floor(cz - r / grid.spacing[2])));
                const auto zb = std::min<std::int64_t>(rg.end() - 1, static_cast<std::int64_t>(std::ceil(cz + r / grid.spacing[2])));
                const auto ya = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor(cy - r / grid.spacing[1])));
                const auto yb = std::min<std::int64_t>(ny - 1, static_cast<std::int64_t>(std::ceil(cy + r / grid.spacing[1])));
                const auto xa = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor(cx - r / grid.spacing[0])));
                const auto xb = std::min<std::int64_t>(nx - 1, static_cast<std::int64_t>(std::ceil(cx + r / grid.spacing[0])));
                for (std::int64_t z = za; z <= zb; ++z)
                    for (std::int64_t y = ya; y <= yb; ++y)
                        for (std::int64_t x = xa; x <= xb; ++x) {
                            const std::int64_t q[3] = {x + bx[0], y + bx[1], z + bx[2]};
                            const double d2 = moved_length2(mot[i], rest[i].data(), q, s2);
                            if (!(d2 < lim)) continue;
                            const double key = nearest ? d2 : d2 - lim;
                            const auto idx = static_cast<std::size_t>((z * ny + y) * nx + x);
                            if (key < P[idx]) {  // mark q, R(q) = S(T⁻¹q), P(q) = proximity: as the thesis writes it
                                P[idx] = key;
                                who[idx] = static_cast<std::int64_t>(i);
                                out.bone[idx] = static_cast<std::int16_t>(s.bone[i] + 1);
                                if (o.values) {
                                    std::int64_t p[3];
                                    mot[i].pull.fixed(q, p);
                                    out.values[idx] = sampler.sample(p, o.sampling);
                                }
                            }
                        }
            }
        });
    });
    for (std::size_t k = 0; k < total; ++k) out.stats.covered += who[k] >= 0;
    report(progress, 1.0);
    return out;
}

std::vector<float> inverse_warp(const VolumeView& source, const double* matrix, Sampling sampling,
                                const Progress& progress, const std::array<std::int64_t, 6>* box) {
    const Grid& g = source.grid;
    check_grid(g, dtype_size(source.dtype), std::numeric_limits<std::uint64_t>::max(), "inverse_warp");
    const Motion m = bone_motions(matrix, 1, g)[0];
    const std::array<std::int64_t, 6> bx = box ? *box : std::array<std::int64_t, 6>{0, 0, 0, g.dims[0], g.dims[1], g.dims[2]};
    const std::int64_t nx = bx[3], ny = bx[4], nz = bx[5];
    if (nx <= 0 || ny <= 0 || nz <= 0) throw Error("inverse_warp: the output box must have positive dimensions");
    check_box_reach(bx);
    std::vector<float> out(static_cast<std::size_t>(nx * ny * nz));
    with_sampler(source, [&](auto sampler) {
        tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& rg) {
            for (std::int64_t z = rg.begin(); z != rg.end(); ++z)
                for (std::int64_t y = 0; y < ny; ++y) {
                    float* row = out.data() + (z * ny + y) * nx;
                    for (std::int64_t x = 0; x < nx; ++x) {
                        const std::int64_t q[3] = {x + bx[0], y + bx[1], z + bx[2]};
                        std::int64_t p[3];
                        m.pull.fixed(q, p);
                        row[x] = sampler.sample(p, sampling);
                    }
                }
        });
    });
    report(progress, 1.0);
    return out;
}

}  // namespace volrig

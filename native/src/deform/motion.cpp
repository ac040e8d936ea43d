#include "deform/motion.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <string>

namespace volrig::deform_detail {

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

Motion motion_of(const Eigen::Matrix3d& R, const Eigen::Vector3d& d, const Grid& g) {
    Motion m;
    m.R = R;
    m.d = d;
    m.forward = index_affine(R, d, g);
    const Eigen::Matrix3d Rt = R.transpose();
    m.pull = pull_of(index_affine(Rt, -(Rt * d), g));
    return m;
}

void check_box_reach(const Box& bx) {
    for (int a = 0; a < 3; ++a)
        if (std::abs(bx[a]) > kMaxCoordinate || std::abs(bx[a] + bx[3 + a]) > kMaxCoordinate)
            throw Error("deform: the posed volume lies millions of voxels away: check the bone matrices' "
                        "translations and units");
}

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

Rigid blend_rigid(const std::vector<Motion>& bones, const std::vector<std::pair<std::int32_t, double>>& w,
                  std::int32_t owner, DeformMode mode, const Eigen::Vector3d& pivot) {
    if (mode == DeformMode::Linear) {
        Eigen::Matrix3d L = Eigen::Matrix3d::Zero();
        Eigen::Vector3d d = Eigen::Vector3d::Zero();
        for (const auto& [b, f] : w) {
            L += f * bones[static_cast<std::size_t>(b)].R;
            d += f * bones[static_cast<std::size_t>(b)].d;
        }
        Eigen::JacobiSVD<Eigen::Matrix3d> svd(L, Eigen::ComputeFullU | Eigen::ComputeFullV);
        Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
        if (R.determinant() < 0) {  // a blend of opposite rotations: keep a proper rotation
            Eigen::Matrix3d U = svd.matrixU();
            U.col(2) = -U.col(2);
            R = U * svd.matrixV().transpose();
        }
        return {R, L * pivot + d - R * pivot};
    }
    const Eigen::Quaterniond ref(bones[static_cast<std::size_t>(owner)].R);
    Eigen::Vector4d real = Eigen::Vector4d::Zero(), dual = Eigen::Vector4d::Zero();
    for (const auto& [b, f] : w) {
        const Motion& m = bones[static_cast<std::size_t>(b)];
        Eigen::Quaterniond r(m.R);
        if (r.coeffs().dot(ref.coeffs()) < 0) r.coeffs() = -r.coeffs();
        const Eigen::Quaterniond t(0, m.d[0], m.d[1], m.d[2]);
        Eigen::Quaterniond rd = t * r;
        rd.coeffs() *= 0.5;
        real += f * r.coeffs();
        dual += f * rd.coeffs();
    }
    const double n = real.norm();
    Eigen::Quaterniond qr, qd;
    qr.coeffs() = real / n;
    qd.coeffs() = dual / n;
    const Eigen::Quaterniond tq = qd * qr.conjugate();
    return {qr.toRotationMatrix(), 2.0 * tq.vec()};
}

Motion blended_motion(const std::vector<Motion>& bones, const Weights& w, std::int32_t owner, DeformMode mode,
                      const Grid& g, const Eigen::Vector3d& pivot) {
    double total = 0;
    for (const auto& [b, q] : w) total += q;
    std::vector<std::pair<std::int32_t, double>> f;
    f.reserve(w.size());
    for (const auto& [b, q] : w) f.emplace_back(b, q / total);
    const Rigid r = blend_rigid(bones, f, owner, mode, pivot);
    return motion_of(r.R, r.d, g);
}

}  // namespace volrig::deform_detail

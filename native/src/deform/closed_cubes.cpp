#include "deform/closed_cubes.hpp"

#include <algorithm>
#include <cmath>

namespace volrig::deform_detail {

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

void NearSpheres::keep_meeting(const NearSpheres& from, const double* lo, double size, const double* s2) {
    const std::size_t n = from.id.size();
    id.resize(n);
    for (auto& v : c) v.resize(n);
    lim.resize(n);
    const double h = 0.5 * size, mid[3] = {lo[0] + h, lo[1] + h, lo[2] + h};
    std::size_t m = 0;
    for (std::size_t k = 0; k < n; ++k) {  // every sphere copied to the next free place, which moves on when it meets
        const double l = from.lim[k];
        id[m] = from.id[k];
        c[0][m] = from.c[0][k];
        c[1][m] = from.c[1][k];
        c[2][m] = from.c[2][k];
        lim[m] = l;
        m += ball_reaches(cube_distance2(from.c[0][k], from.c[1][k], from.c[2][k], mid, h, s2), l);
    }
    id.resize(m);
    for (auto& v : c) v.resize(m);
    lim.resize(m);
}

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
    // Which balls meet the cube (ball_meets_box's test: a negative gap), over all of them at once.
    const std::size_t n = near.id.size();
    near.gap.resize(n);
    const double mid[3] = {base[0] + 0.5, base[1] + 0.5, base[2] + 0.5};
    {
        const double *cx = near.c[0].data(), *cy = near.c[1].data(), *cz = near.c[2].data(), *lim = near.lim.data();
        double* gap = near.gap.data();
        for (std::size_t k = 0; k < n; ++k) gap[k] = ball_gap(cube_distance2(cx[k], cy[k], cz[k], mid, 0.5, s2), lim[k]);
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

}  // namespace volrig::deform_detail

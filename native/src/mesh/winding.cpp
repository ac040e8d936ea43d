// mesh/winding.cpp: the generalized winding number of a triangle soup (volrig/mesh.hpp), and the closed-mesh test.
//
// w(q) = (1 / 4 pi) sum over triangles of the signed solid angle the triangle subtends at q (Jacobson, Kavan and
// Sorkine-Hornung 2013, "Robust inside-outside segmentation using generalized winding numbers"): 1 inside and 0
// outside a closed outward-oriented surface, and a smooth, harmonic function off the surface of an open one, so a
// hole lets it pass from 1 to 0 gradually across the hole rather than letting the inside leak out.
//
// Fast evaluation after Barill, Dickson, Schmidt, Levin and Jacobson 2018 ("Fast winding numbers for soups and
// clouds"): a bounding-volume hierarchy over the triangles (median splits, up to kLeafSize triangles per leaf);
// a cluster seen from farther than beta times its radius (the largest distance from its area-weighted centroid p
// to one of its vertices) contributes the Taylor expansion of (x - q) / |x - q|^3 about p to second order,
//     4 pi w_c ~= N . r / |r|^3 + tr(M) / |r|^3 - 3 r^T M r / |r|^5 + 1/2 T : H(r),        r = p - q,
// with N = sum a_i (a_i: area vector, half the cross product of two edges), M = sum a_i (c_i - p)^T (c_i: the
// triangle's centroid), T = sum n_i (x) (integral over the triangle of (x - p)(x - p)^T) and H the kernel's
// Hessian (terms up to the second moments, Barill et al.'s order 2); nearer clusters are opened, and the triangles
// of leaves are summed exactly with Van Oosterom and Strackee's formula
//     tan(Omega / 2) = a.(b x c) / (|a||b||c| + (a.b)|c| + (a.c)|b| + (b.c)|a|),
// the half angles of a query's leaf triangles summed as the argument of their product (mesh_detail::AngleSum, one
// atan2 a query rather than one a triangle: atan2 was a quarter of a winding-number voxelization).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "mesh/angle_sum.hpp"
#include "volrig/mesh.hpp"

namespace volrig {

namespace {

struct V3 {
    double x, y, z;
};
inline V3 operator-(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V3 operator+(const V3& a, const V3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 operator*(const V3& a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline double dot(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 cross(const V3& a, const V3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double norm(const V3& a) { return std::sqrt(dot(a, a)); }

constexpr double kFourPi = 4.0 * M_PI;

/// Half the signed solid angle triangle (A, B, C) subtends at q (positive when q is behind the triangle, i.e. on the
/// side opposite to (B - A) x (C - A)) is atan2(num, den) of this pair (num, den).
inline std::pair<double, double> half_solid_angle(const V3& A, const V3& B, const V3& C, const V3& q) {
    const V3 a = A - q, b = B - q, c = C - q;
    const double la = norm(a), lb = norm(b), lc = norm(c);
    const double num = dot(a, cross(b, c));
    const double den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
    return {num, den};
}

#if defined(__SSE2__)
/// The triangles' corners by coordinate (corner[3 v + axis][k]: triangle k's corner v), for half_solid_angles.
using Corners = std::array<std::vector<double>, 9>;

/// half_solid_angle of triangles k and k + 1 at once (SSE2: the same operations in the same order, so the same
/// numbers), added to `angles` in that order.
inline void add_half_solid_angles(const Corners& t, std::uint32_t k, const V3& q, mesh_detail::AngleSum& angles) {
    const auto at = [&t, k](std::size_t i, double qi) {
        return _mm_sub_pd(_mm_loadu_pd(t[i].data() + k), _mm_set1_pd(qi));
    };
    const __m128d ax = at(0, q.x), ay = at(1, q.y), az = at(2, q.z), bx = at(3, q.x), by = at(4, q.y),
                  bz = at(5, q.z), cx = at(6, q.x), cy = at(7, q.y), cz = at(8, q.z);
    const auto mul = [](__m128d a, __m128d b) { return _mm_mul_pd(a, b); };
    const auto add = [](__m128d a, __m128d b) { return _mm_add_pd(a, b); };
    const auto dot = [&](__m128d x0, __m128d y0, __m128d z0, __m128d x1, __m128d y1, __m128d z1) {
        return add(add(mul(x0, x1), mul(y0, y1)), mul(z0, z1));
    };
    const __m128d la = _mm_sqrt_pd(dot(ax, ay, az, ax, ay, az)), lb = _mm_sqrt_pd(dot(bx, by, bz, bx, by, bz)),
                  lc = _mm_sqrt_pd(dot(cx, cy, cz, cx, cy, cz));
    const __m128d ex = _mm_sub_pd(mul(by, cz), mul(bz, cy)), ey = _mm_sub_pd(mul(bz, cx), mul(bx, cz)),
                  ez = _mm_sub_pd(mul(bx, cy), mul(by, cx));
    const __m128d num = dot(ax, ay, az, ex, ey, ez);
    const __m128d den = add(add(add(mul(mul(la, lb), lc), mul(dot(ax, ay, az, bx, by, bz), lc)),
                                mul(dot(ax, ay, az, cx, cy, cz), lb)),
                            mul(dot(bx, by, bz, cx, cy, cz), la));
    double y[2], x[2];
    _mm_storeu_pd(y, num);
    _mm_storeu_pd(x, den);
    angles.add(y[0], x[0]);
    angles.add(y[1], x[1]);
}
#endif

/// The signed solid angle triangle (A, B, C) subtends at q (the exact sum's terms).
inline double solid_angle(const V3& A, const V3& B, const V3& C, const V3& q) {
    const auto [num, den] = half_solid_angle(A, B, C, q);
    return 2.0 * std::atan2(num, den);
}

constexpr std::size_t kLeafSize = 8;

}  // namespace

struct WindingNumber::Impl {
    struct Tri {
        V3 a, b, c;
    };
    struct Node {
        V3 p;                    // area-weighted centroid
        double radius2 = 0;      // squared largest distance from p to a vertex of the cluster
        V3 n{0, 0, 0};           // sum of area vectors
        double m[9] = {};        // sum a_i (c_i - p)^T, row-major (m[3 j + k] = sum a_ij (c_i - p)_k)
        double t[27] = {};       // sum n_i (x) integral over T_i of (x - p)(x - p)^T (t[9 j + 3 k + l])
        std::uint32_t first = 0; // leaf: first triangle; inner: index of the right child (the left follows)
        std::uint32_t count = 0; // leaf: number of triangles; 0 for inner nodes
    };
    /// What the traversal reads of a node: its centre, reach and children (Node's first, count, radius2).
    struct Hot {
        V3 p;
        double radius2;
        std::uint32_t first, count;
    };
    /// A node's far-field expansion reduced to what the sum needs (far_field): n; tr M; the symmetric part of M as
    /// the coefficients of r^T M r (xx, yy, zz, xy, xz, yz); the vector c with c . r = 2 sum_jl t_jjl r_l +
    /// sum_jk t_jkk r_j; and the ten coefficients of the cubic form t[r, r, r] (xxx, yyy, zzz, xxy, xxz, yyx, yyz,
    /// zzx, zzy, xyz). 23 numbers instead of 39 summed term by term: the same expansion, its sums in another order
    /// (so equal up to rounding; voxelize's masks came out byte for byte the same on the 32 shared characters).
    struct Far {
        double n[3], trace_m, m[6], c[3], t[10];
    };
    std::vector<Tri> tris;  // in leaf order
#if defined(__SSE2__)
    Corners corners;  // the same, by coordinate
#endif
    std::vector<Node> nodes;  // while building; then reduced to hot and far (same index) and freed
    std::vector<Hot> hot;
    std::vector<Far> far;
    double beta = 2;

    static Far reduced(const Node& n) {
        Far f{};
        f.n[0] = n.n.x, f.n[1] = n.n.y, f.n[2] = n.n.z;
        f.trace_m = n.m[0] + n.m[4] + n.m[8];
        const double* m = n.m;
        const double ms[6] = {m[0], m[4], m[8], m[1] + m[3], m[2] + m[6], m[5] + m[7]};
        std::copy(ms, ms + 6, f.m);
        auto t = [&n](int j, int k, int l) { return n.t[9 * j + 3 * k + l]; };
        for (int l = 0; l < 3; ++l)
            f.c[l] = 2.0 * (t(0, 0, l) + t(1, 1, l) + t(2, 2, l)) + t(l, 0, 0) + t(l, 1, 1) + t(l, 2, 2);
        auto sym3 = [&t](int a, int b) { return t(a, a, b) + t(a, b, a) + t(b, a, a); };  // coefficient of r_a^2 r_b
        const double ts[10] = {t(0, 0, 0), t(1, 1, 1), t(2, 2, 2), sym3(0, 1), sym3(0, 2), sym3(1, 0), sym3(1, 2),
                               sym3(2, 0), sym3(2, 1),
                               t(0, 1, 2) + t(0, 2, 1) + t(1, 0, 2) + t(1, 2, 0) + t(2, 0, 1) + t(2, 1, 0)};
        std::copy(ts, ts + 10, f.t);
        return f;
    }

    /// hot and far from nodes (after build).
    void reduce() {
        hot.resize(nodes.size());
        far.resize(nodes.size());
        for (std::size_t i = 0; i < nodes.size(); ++i) {
            hot[i] = {nodes[i].p, nodes[i].radius2, nodes[i].first, nodes[i].count};
            far[i] = reduced(nodes[i]);
        }
    }

    /// 4 pi times the cluster's far-field winding number at q, r = p - q, d2 = |r|^2 (the expansion of the opening
    /// comment, second order: 1/2 sum_jkl t_jkl H_jkl = 1/2 (-3 (2 sum_jl t_jjl r_l + sum_jk t_jkk r_j) / |r|^5 +
    /// 15 t[r, r, r] / |r|^7)).
    static double far_field(const Far& f, const V3& r, double d2) {
        const double inv_d2 = 1.0 / d2, inv_d3 = inv_d2 / std::sqrt(d2);
        const double x = r.x, y = r.y, z = r.z, xx = x * x, yy = y * y, zz = z * z;
        const double rmr = f.m[0] * xx + f.m[1] * yy + f.m[2] * zz + f.m[3] * x * y + f.m[4] * x * z + f.m[5] * y * z;
        const double cr = f.c[0] * x + f.c[1] * y + f.c[2] * z;
        const double trrr = f.t[0] * xx * x + f.t[1] * yy * y + f.t[2] * zz * z + f.t[3] * xx * y + f.t[4] * xx * z +
                            f.t[5] * yy * x + f.t[6] * yy * z + f.t[7] * zz * x + f.t[8] * zz * y + f.t[9] * x * y * z;
        const double second = 0.5 * inv_d2 * (-3.0 * cr + 15.0 * trrr * inv_d2);
        return (f.n[0] * x + f.n[1] * y + f.n[2] * z + f.trace_m - 3.0 * rmr * inv_d2 + second) * inv_d3;
    }

    /// Builds the node over tris[begin, end); returns its index.
    std::uint32_t build(std::size_t begin, std::size_t end, std::vector<V3>& centroid) {
        const auto index = static_cast<std::uint32_t>(nodes.size());
        nodes.emplace_back();
        if (end - begin > kLeafSize) {
            V3 lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
            for (std::size_t k = begin; k < end; ++k) {
                const V3& c = centroid[k];
                lo = {std::min(lo.x, c.x), std::min(lo.y, c.y), std::min(lo.z, c.z)};
                hi = {std::max(hi.x, c.x), std::max(hi.y, c.y), std::max(hi.z, c.z)};
            }
            const V3 ext = hi - lo;
            const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
            auto key = [axis](const V3& v) { return axis == 0 ? v.x : axis == 1 ? v.y : v.z; };
            const std::size_t mid = begin + (end - begin) / 2;
            // sort triangles and centroids together through a permutation
            std::vector<std::uint32_t> perm(end - begin);
            for (std::size_t k = 0; k < perm.size(); ++k) perm[k] = static_cast<std::uint32_t>(k);
            std::nth_element(perm.begin(), perm.begin() + static_cast<std::ptrdiff_t>(mid - begin), perm.end(),
                             [&](std::uint32_t x, std::uint32_t y) {
                                 return key(centroid[begin + x]) < key(centroid[begin + y]);
                             });
            std::vector<Tri> t(perm.size());
            std::vector<V3> c(perm.size());
            for (std::size_t k = 0; k < perm.size(); ++k) {
                t[k] = tris[begin + perm[k]];
                c[k] = centroid[begin + perm[k]];
            }
            std::copy(t.begin(), t.end(), tris.begin() + static_cast<std::ptrdiff_t>(begin));
            std::copy(c.begin(), c.end(), centroid.begin() + static_cast<std::ptrdiff_t>(begin));
            build(begin, mid, centroid);
            const std::uint32_t right = build(mid, end, centroid);
            nodes[index].first = right;
        } else {
            nodes[index].first = static_cast<std::uint32_t>(begin);
            nodes[index].count = static_cast<std::uint32_t>(end - begin);
        }
        // Moments of the cluster, from its triangles (O(n) per level).
        V3 n{0, 0, 0}, weighted{0, 0, 0}, plain{0, 0, 0};
        double area = 0, s[9] = {};
        for (std::size_t k = begin; k < end; ++k) {
            const Tri& tr = tris[k];
            const V3 a = cross(tr.b - tr.a, tr.c - tr.a) * 0.5;
            const double len = norm(a);
            const V3& c = centroid[k];
            n = n + a;
            weighted = weighted + c * len;
            plain = plain + c;
            area += len;
            const double av[3] = {a.x, a.y, a.z}, cv[3] = {c.x, c.y, c.z};
            for (int j = 0; j < 3; ++j)
                for (int i = 0; i < 3; ++i) s[3 * j + i] += av[j] * cv[i];
        }
        Node& node = nodes[index];
        node.p = area > 0 ? weighted * (1.0 / area) : plain * (1.0 / static_cast<double>(end - begin));
        node.n = n;
        const double nv[3] = {n.x, n.y, n.z}, pv[3] = {node.p.x, node.p.y, node.p.z};
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i) node.m[3 * j + i] = s[3 * j + i] - nv[j] * pv[i];
        double r2 = 0;
        for (std::size_t k = begin; k < end; ++k) {
            // integral over the triangle of u u^T = area / 12 (sum of u_v u_v^T over its corners + s s^T), u = x - p,
            // s the sum of the corners' u; times the unit normal: the area vector / 12.
            const Tri& tr = tris[k];
            const V3 a = cross(tr.b - tr.a, tr.c - tr.a) * (0.5 / 12.0);
            const V3 u0 = tr.a - node.p, u1 = tr.b - node.p, u2 = tr.c - node.p, sum = u0 + u1 + u2;
            double q[9];
            const V3* us[4] = {&u0, &u1, &u2, &sum};
            for (int kk = 0; kk < 3; ++kk)
                for (int l = 0; l < 3; ++l) {
                    double acc = 0;
                    for (const V3* u : us) {
                        const double uv[3] = {u->x, u->y, u->z};
                        acc += uv[kk] * uv[l];
                    }
                    q[3 * kk + l] = acc;
                }
            const double av[3] = {a.x, a.y, a.z};
            for (int j = 0; j < 3; ++j)
                for (int kl = 0; kl < 9; ++kl) node.t[9 * j + kl] += av[j] * q[kl];
            for (const V3* v : {&tr.a, &tr.b, &tr.c}) {
                const V3 d = *v - node.p;
                r2 = std::max(r2, dot(d, d));
            }
        }
        node.radius2 = r2;
        return index;
    }

    double fast(const V3& q) const {
        const double beta2 = beta * beta;
        std::uint32_t stack[128];
        int top = 0;
        stack[top++] = 0;
        double sum = 0;
        mesh_detail::AngleSum near;  // the leaves' triangles: half their solid angles, one atan2 in all
        while (top > 0) {
            const std::uint32_t i = stack[--top];
            const Hot& n = hot[i];
            const V3 r = n.p - q;
            const double d2 = dot(r, r);
            if (d2 > beta2 * n.radius2) {
                sum += far_field(far[i], r, d2);
            } else if (n.count > 0) {
                std::uint32_t k = n.first;
#if defined(__SSE2__)
                for (; k + 2 <= n.first + n.count; k += 2) add_half_solid_angles(corners, k, q, near);
#endif
                for (; k < n.first + n.count; ++k) near.add(half_solid_angle(tris[k].a, tris[k].b, tris[k].c, q));
            } else {
                stack[top++] = n.first;
                stack[top++] = i + 1;
            }
        }
        return (sum + 2.0 * near.total()) / kFourPi;
    }

    double exact(const V3& q) const {
        double sum = 0;
        for (const Tri& t : tris) sum += solid_angle(t.a, t.b, t.c, q);
        return sum / kFourPi;
    }
};

WindingNumber::WindingNumber(const Mesh& mesh, double beta) : impl_(std::make_unique<Impl>()) {
    if (!(beta >= 1)) throw Error("winding number: the accuracy beta must be at least 1");
    if (mesh.triangles.empty()) throw Error("winding number: the mesh has no triangles");
    if (mesh.triangles.size() >= (std::size_t(1) << 31)) throw Error("winding number: too many triangles");
    impl_->beta = beta;
    auto& tris = impl_->tris;
    tris.reserve(mesh.triangles.size());
    std::vector<V3> centroid;
    centroid.reserve(mesh.triangles.size());
    for (const auto& t : mesh.triangles) {
        Impl::Tri tr;
        V3* corner[3] = {&tr.a, &tr.b, &tr.c};
        for (int k = 0; k < 3; ++k) {
            if (t[k] >= mesh.vertices.size()) throw Error("winding number: a triangle uses a vertex out of range");
            const auto& v = mesh.vertices[t[k]];
            *corner[k] = {v[0], v[1], v[2]};
        }
        tris.push_back(tr);
        centroid.push_back((tr.a + tr.b + tr.c) * (1.0 / 3.0));
    }
    impl_->nodes.reserve(4 * tris.size() / kLeafSize + 4);
    impl_->build(0, tris.size(), centroid);
    impl_->reduce();
#if defined(__SSE2__)
    for (std::size_t i = 0; i < 9; ++i) impl_->corners[i].resize(tris.size());
    for (std::size_t k = 0; k < tris.size(); ++k) {
        const V3* v[3] = {&tris[k].a, &tris[k].b, &tris[k].c};
        for (std::size_t c = 0; c < 3; ++c) {
            impl_->corners[3 * c][k] = v[c]->x;
            impl_->corners[3 * c + 1][k] = v[c]->y;
            impl_->corners[3 * c + 2][k] = v[c]->z;
        }
    }
#endif
    impl_->nodes.clear();
    impl_->nodes.shrink_to_fit();
}

WindingNumber::~WindingNumber() = default;
WindingNumber::WindingNumber(WindingNumber&&) noexcept = default;
WindingNumber& WindingNumber::operator=(WindingNumber&&) noexcept = default;

double WindingNumber::operator()(const std::array<double, 3>& q) const { return impl_->fast({q[0], q[1], q[2]}); }

double WindingNumber::exact(const std::array<double, 3>& q) const { return impl_->exact({q[0], q[1], q[2]}); }

bool is_closed(const Mesh& mesh) {
    std::vector<std::uint64_t> edges;
    edges.reserve(3 * mesh.triangles.size());
    for (const auto& t : mesh.triangles)
        for (int k = 0; k < 3; ++k) {
            const std::uint64_t a = t[k], b = t[(k + 1) % 3];
            if (a == b) continue;  // a degenerate triangle's collapsed edge
            edges.push_back(std::min(a, b) << 32 | std::max(a, b));
        }
    if (edges.empty()) return false;
    std::sort(edges.begin(), edges.end());
    for (std::size_t i = 0; i < edges.size();) {
        std::size_t j = i;
        while (j < edges.size() && edges[j] == edges[i]) ++j;
        if (j - i != 2) return false;  // a boundary edge (1) or a non-manifold one (3 or more)
        i = j;
    }
    return true;
}

}  // namespace volrig

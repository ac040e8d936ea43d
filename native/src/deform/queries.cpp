#include "deform/queries.hpp"

#include <cmath>

namespace volrig::deform_detail {

namespace {

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


}  // namespace

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

Best exact(const BoneField& f, const double* p_index, const double* s, const double* s2, bool nearest,
           const Best& seed) {
    Best b = seed;
    if (f.nodes.empty()) return b;
    const double pw[3] = {p_index[0] * s[0], p_index[1] * s[1], p_index[2] * s[2]};
    query(f, pw, p_index, s2, nearest, b);
    return b;
}

}  // namespace volrig::deform_detail

// The medial surface mesh of medial_surface.hpp (the rods: medial/rods.cpp), and medial_surface itself.
#include "volrig/medial_surface.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "medial/geometry.hpp"
#include "volrig/medial.hpp"

namespace volrig {

namespace {

using namespace medial_detail;


/// Cells (2x2x2 voxel centres) are named by their lowest corner, -1 .. dims - 1 on each axis.
struct Cells {
    std::int64_t cx, cy;
    explicit Cells(const Grid& g) : cx(g.dims[0] + 1), cy(g.dims[1] + 1) {}
    std::int64_t id(std::int64_t x, std::int64_t y, std::int64_t z) const { return ((z + 1) * cy + (y + 1)) * cx + (x + 1); }
};

/// One plane-like edge from X = M - e_axis to M: its bisector point and the plate's thickness there.
struct Crossing {
    std::int64_t m;
    int axis;
    P3 point;
    double thickness;
    double cosine;  ///< of the angle at the point between the directions to its two nearest boundary voxels
};

Crossing crossing_of(const Grid& g, const std::vector<std::int64_t>& ft, std::int64_t m, int axis) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    const std::int64_t x = m % nx, y = (m / nx) % ny, z = m / (nx * ny);
    const std::int64_t step[3] = {1, nx, nx * ny};
    const P3 M = at(g, double(x), double(y), double(z));
    P3 X = M;
    X[axis] -= g.spacing[axis];
    const P3 a = feature_centre(g, ft[static_cast<std::size_t>(m - step[axis])]);
    const P3 b = feature_centre(g, ft[static_cast<std::size_t>(m)]);
    // q = X + s (M - X) equidistant from a and b: 2 q.(b - a) = |b|^2 - |a|^2.
    const P3 ba = sub(b, a), e = sub(M, X);
    const double den = dot(e, ba);
    double s = 0.5;
    if (std::abs(den) > 1e-12) s = ((dot(b, b) - dot(a, a)) * 0.5 - dot(X, ba)) / den;
    s = std::clamp(s, 0.0, 1.0);
    const P3 q = {X[0] + s * e[0], X[1] + s * e[1], X[2] + s * e[2]};
    const P3 qa = sub(a, q), qb = sub(b, q);
    const double cosine = dot(qa, qb) / std::sqrt(std::max(dot(qa, qa) * dot(qb, qb), 1e-300));
    return {m, axis, q, boundary_distance(g, q, a) + boundary_distance(g, q, b), cosine};
}

/// The four cells around the edge of `c`, in cyclic order.
std::array<std::int64_t, 4> cells_around(const Grid& g, const Cells& cells, const Crossing& c) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    std::array<std::int64_t, 3> L = {c.m % nx, (c.m / nx) % ny, c.m / (nx * ny)};
    L[static_cast<std::size_t>(c.axis)] -= 1;
    const int b = (c.axis + 1) % 3, d = (c.axis + 2) % 3;
    const int offs[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    std::array<std::int64_t, 4> out{};
    for (int k = 0; k < 4; ++k) {
        auto p = L;
        p[static_cast<std::size_t>(b)] -= offs[k][0];
        p[static_cast<std::size_t>(d)] -= offs[k][1];
        out[static_cast<std::size_t>(k)] = cells.id(p[0], p[1], p[2]);
    }
    return out;
}

/// Peels, from the free boundary of the quad mesh inwards, the crossings whose two nearest boundary voxels are
/// seen from the crossing point under less than kAngle: not two sides of a plate but one side's boundary, where a
/// coarse (anisotropic) grid's terraces make the nearest voxel jump further than t (a flap hanging off the surface),
/// or the rounded rim of a plate, where the sides close in (the surface would run on past the rim by up to a
/// voxel). Only boundary quads go, so no hole is punched into a surface: plane-like edges inside stay whatever
/// their angle. `around` holds each crossing's four cells; returns the crossings kept.
std::vector<std::uint8_t> peel(const std::vector<Crossing>& cr, const std::vector<std::array<std::int64_t, 4>>& around) {
    constexpr double kCos = -0.5;  // kAngle = 120 degrees
    struct Side {
        std::int64_t lo, hi, quad;
        bool operator<(const Side& o) const { return lo != o.lo ? lo < o.lo : hi != o.hi ? hi < o.hi : quad < o.quad; }
    };
    std::vector<Side> sides;
    sides.reserve(around.size() * 4);
    for (std::size_t k = 0; k < around.size(); ++k)
        for (int i = 0; i < 4; ++i) {
            const std::int64_t a = around[k][static_cast<std::size_t>(i)], b = around[k][static_cast<std::size_t>((i + 1) % 4)];
            sides.push_back({std::min(a, b), std::max(a, b), static_cast<std::int64_t>(k)});
        }
    tbb::parallel_sort(sides.begin(), sides.end());
    // Groups of equal sides: their quads, and per quad its four groups.
    std::vector<std::size_t> start;
    std::vector<std::array<std::size_t, 4>> group_of(around.size());
    std::vector<int> filled(around.size(), 0);
    for (std::size_t i = 0; i < sides.size(); ++i) {
        if (i == 0 || sides[i].lo != sides[i - 1].lo || sides[i].hi != sides[i - 1].hi) start.push_back(i);
        const auto q = static_cast<std::size_t>(sides[i].quad);
        group_of[q][static_cast<std::size_t>(filled[q]++)] = start.size() - 1;
    }
    start.push_back(sides.size());
    std::vector<std::int64_t> alive_in(start.size() - 1);
    for (std::size_t gi = 0; gi + 1 < start.size(); ++gi) alive_in[gi] = static_cast<std::int64_t>(start[gi + 1] - start[gi]);
    std::vector<std::uint8_t> alive(around.size(), 1);
    auto removable = [&](std::size_t q) {
        if (!alive[q] || cr[q].cosine <= kCos) return false;
        for (std::size_t gi : group_of[q])
            if (alive_in[gi] == 1) return true;
        return false;
    };
    std::vector<std::size_t> stack;
    for (std::size_t q = 0; q < around.size(); ++q)
        if (removable(q)) stack.push_back(q);
    while (!stack.empty()) {
        const std::size_t q = stack.back();
        stack.pop_back();
        if (!removable(q)) continue;
        alive[q] = 0;
        for (std::size_t gi : group_of[q]) {
            --alive_in[gi];
            for (std::size_t i = start[gi]; i < start[gi + 1]; ++i)
                if (removable(static_cast<std::size_t>(sides[i].quad))) stack.push_back(static_cast<std::size_t>(sides[i].quad));
        }
    }
    return alive;
}

/// Undirected edges of a triangle mesh with the faces using them: (low, high, face, forward).
struct EdgeUse {
    std::int64_t lo, hi, face;
    bool forward;
    bool operator<(const EdgeUse& o) const { return lo != o.lo ? lo < o.lo : hi != o.hi ? hi < o.hi : face < o.face; }
};

std::vector<EdgeUse> edge_uses(const std::vector<std::array<std::int64_t, 3>>& faces) {
    std::vector<EdgeUse> e;
    e.reserve(faces.size() * 3);
    for (std::size_t f = 0; f < faces.size(); ++f)
        for (int k = 0; k < 3; ++k) {
            const std::int64_t u = faces[f][static_cast<std::size_t>(k)], v = faces[f][static_cast<std::size_t>((k + 1) % 3)];
            e.push_back({std::min(u, v), std::max(u, v), static_cast<std::int64_t>(f), u < v});
        }
    tbb::parallel_sort(e.begin(), e.end());
    return e;
}

/// Starts of the runs of equal edges in `e` (sorted), and its size at the end.
std::vector<std::size_t> edge_groups(const std::vector<EdgeUse>& e) {
    std::vector<std::size_t> starts;
    for (std::size_t i = 0; i < e.size(); ++i)
        if (i == 0 || e[i].lo != e[i - 1].lo || e[i].hi != e[i - 1].hi) starts.push_back(i);
    starts.push_back(e.size());
    return starts;
}

/// At edges of more than two faces (a flap of a few quads hanging off a surface, where a rod's axis strip meets a
/// plate, or a real junction of plates), keeps the two faces that continue each other best (the most nearly
/// opposite in-plane directions away from the edge) and drops the others.
bool drop_fins(const std::vector<P3>& v, std::vector<std::array<std::int64_t, 3>>& faces, const std::vector<EdgeUse>& e) {
    const std::vector<std::size_t> groups = edge_groups(e);
    std::vector<std::uint8_t> drop(faces.size(), 0);
    for (std::size_t k = 0; k + 1 < groups.size(); ++k) {
        const std::size_t i = groups[k], n = groups[k + 1] - i;
        if (n <= 2) continue;
        const P3& a = v[static_cast<std::size_t>(e[i].lo)];
        const P3 d = sub(v[static_cast<std::size_t>(e[i].hi)], a);
        const double dd = std::max(dot(d, d), 1e-300);
        std::vector<P3> w(n);  // unit in-plane direction from the edge into each face
        for (std::size_t j = 0; j < n; ++j) {
            const auto& f = faces[static_cast<std::size_t>(e[i + j].face)];
            std::int64_t o = f[0];
            for (std::int64_t x : f)
                if (x != e[i].lo && x != e[i].hi) o = x;
            P3 r = sub(v[static_cast<std::size_t>(o)], a);
            const double s = dot(r, d) / dd;
            for (int c = 0; c < 3; ++c) r[c] -= s * d[c];
            const double l = std::sqrt(std::max(dot(r, r), 1e-300));
            w[j] = {r[0] / l, r[1] / l, r[2] / l};
        }
        std::size_t best0 = 0, best1 = 1;
        for (std::size_t x = 0; x < n; ++x)
            for (std::size_t y = x + 1; y < n; ++y)
                if (dot(w[x], w[y]) < dot(w[best0], w[best1])) best0 = x, best1 = y;
        for (std::size_t j = 0; j < n; ++j)
            if (j != best0 && j != best1) drop[static_cast<std::size_t>(e[i + j].face)] = 1;
    }
    std::size_t out = 0;
    for (std::size_t f = 0; f < faces.size(); ++f)
        if (!drop[f]) faces[out++] = faces[f];
    const bool changed = out != faces.size();
    faces.resize(out);
    return changed;
}

/// Gives each fan of faces around a vertex (faces linked over edges shared by two faces) a vertex of its own:
/// where two sheets touch at a point only (a pinch), they no longer share it.
bool split_fans(std::vector<P3>& v, std::vector<double>& thickness, std::vector<std::array<std::int64_t, 3>>& faces,
                const std::vector<EdgeUse>& e) {
    const std::size_t before = v.size();
    const std::vector<std::size_t> groups = edge_groups(e);
    // Union-find over face corners (face * 3 + k): corners of the same vertex in faces sharing a two-face edge.
    std::vector<std::int64_t> up(faces.size() * 3);
    std::iota(up.begin(), up.end(), 0);
    auto root = [&](std::int64_t a) {
        while (up[static_cast<std::size_t>(a)] != a) a = up[static_cast<std::size_t>(a)] = up[static_cast<std::size_t>(up[static_cast<std::size_t>(a)])];
        return a;
    };
    auto corner = [&](std::int64_t f, std::int64_t vert) {
        const auto& t = faces[static_cast<std::size_t>(f)];
        return f * 3 + (t[0] == vert ? 0 : t[1] == vert ? 1 : 2);
    };
    for (std::size_t k = 0; k + 1 < groups.size(); ++k) {
        if (groups[k + 1] - groups[k] != 2) continue;
        const EdgeUse& a = e[groups[k]];
        const EdgeUse& b = e[groups[k] + 1];
        for (std::int64_t vert : {a.lo, a.hi}) {
            const std::int64_t x = root(corner(a.face, vert)), y = root(corner(b.face, vert));
            up[static_cast<std::size_t>(x)] = y;
        }
    }
    // The first fan of a vertex keeps it; each further fan gets a copy.
    std::vector<std::int64_t> fan_vertex(up.size(), -1);
    std::vector<std::uint8_t> taken(v.size(), 0);
    for (std::size_t f = 0; f < faces.size(); ++f)
        for (std::size_t k = 0; k < 3; ++k) {
            const auto r = static_cast<std::size_t>(root(static_cast<std::int64_t>(f * 3 + k)));
            const auto vert = static_cast<std::size_t>(faces[f][k]);
            if (fan_vertex[r] < 0) {
                if (!taken[vert]) {
                    taken[vert] = 1;
                    fan_vertex[r] = static_cast<std::int64_t>(vert);
                } else {
                    fan_vertex[r] = static_cast<std::int64_t>(v.size());
                    v.push_back(v[vert]);
                    thickness.push_back(thickness[vert]);
                    taken.push_back(1);
                }
            }
            faces[f][k] = fan_vertex[r];
        }
    return v.size() != before;
}

/// Drops connected components (over shared edges) of fewer than `min_faces` faces, and unused vertices.
bool drop_specks(std::vector<P3>& v, std::vector<double>& thickness, std::vector<std::array<std::int64_t, 3>>& faces,
                 const std::vector<EdgeUse>& e, std::size_t min_faces) {
    std::vector<std::int64_t> up(faces.size());
    std::iota(up.begin(), up.end(), 0);
    auto root = [&](std::int64_t a) {
        while (up[static_cast<std::size_t>(a)] != a) a = up[static_cast<std::size_t>(a)] = up[static_cast<std::size_t>(up[static_cast<std::size_t>(a)])];
        return a;
    };
    for (std::size_t i = 0; i + 1 < e.size(); ++i)
        if (e[i].lo == e[i + 1].lo && e[i].hi == e[i + 1].hi) {
            const std::int64_t x = root(e[i].face), y = root(e[i + 1].face);
            up[static_cast<std::size_t>(x)] = y;
        }
    std::vector<std::size_t> size(faces.size(), 0);
    for (std::size_t f = 0; f < faces.size(); ++f) ++size[static_cast<std::size_t>(root(static_cast<std::int64_t>(f)))];
    bool any = false;
    for (std::size_t f = 0; f < faces.size() && !any; ++f) any = size[static_cast<std::size_t>(root(static_cast<std::int64_t>(f)))] < min_faces;
    if (!any) return false;  // (every vertex is used: each comes from a kept quad, or a fan of one)
    std::vector<std::int64_t> remap(v.size(), -1);
    std::vector<P3> nv;
    std::vector<double> nt;
    std::size_t out = 0;
    for (std::size_t f = 0; f < faces.size(); ++f) {
        if (size[static_cast<std::size_t>(root(static_cast<std::int64_t>(f)))] < min_faces) continue;
        auto t = faces[f];
        for (auto& x : t) {
            auto& r = remap[static_cast<std::size_t>(x)];
            if (r < 0) {
                r = static_cast<std::int64_t>(nv.size());
                nv.push_back(v[static_cast<std::size_t>(x)]);
                nt.push_back(thickness[static_cast<std::size_t>(x)]);
            }
            x = r;
        }
        faces[out++] = t;
    }
    faces.resize(out);
    v.swap(nv);
    thickness.swap(nt);
    return true;
}

/// Orients faces consistently across edges shared by exactly two faces (breadth first per component); returns
/// false when some component cannot be (non-orientable, or junction edges close an odd loop).
bool orient(std::vector<std::array<std::int64_t, 3>>& faces, const std::vector<EdgeUse>& e) {
    std::vector<std::vector<std::pair<std::int64_t, bool>>> adj(faces.size());  // (neighbour, same direction)
    const std::vector<std::size_t> groups = edge_groups(e);
    for (std::size_t k = 0; k + 1 < groups.size(); ++k) {
        if (groups[k + 1] - groups[k] != 2) continue;
        const EdgeUse& a = e[groups[k]];
        const EdgeUse& b = e[groups[k] + 1];
        const bool same = a.forward == b.forward;
        adj[static_cast<std::size_t>(a.face)].push_back({b.face, same});
        adj[static_cast<std::size_t>(b.face)].push_back({a.face, same});
    }
    std::vector<std::int8_t> flip(faces.size(), -1);
    bool ok = true;
    std::vector<std::int64_t> stack;
    for (std::size_t s = 0; s < faces.size(); ++s) {
        if (flip[s] >= 0) continue;
        flip[s] = 0;
        stack.push_back(static_cast<std::int64_t>(s));
        while (!stack.empty()) {
            const auto f = static_cast<std::size_t>(stack.back());
            stack.pop_back();
            for (const auto& [n, same] : adj[f]) {
                const std::int8_t want = static_cast<std::int8_t>(flip[f] ^ (same ? 1 : 0));
                auto& fn = flip[static_cast<std::size_t>(n)];
                if (fn < 0) {
                    fn = want;
                    stack.push_back(n);
                } else if (fn != want) {
                    ok = false;
                }
            }
        }
    }
    for (std::size_t f = 0; f < faces.size(); ++f)
        if (flip[f] == 1) std::swap(faces[f][1], faces[f][2]);
    return ok;
}

}  // namespace

namespace {

/// The plane-like edges (value above t; the caller zeroes those it does not want) as crossings.
std::vector<Crossing> crossings(const Grid& g, const std::vector<std::int64_t>& ft, const std::vector<float>& edge,
                                double t) {
    std::vector<std::int64_t> slots;
    for (std::size_t i = 0; i < edge.size(); ++i)
        if (edge[i] > t) slots.push_back(static_cast<std::int64_t>(i));
    std::vector<Crossing> cr(slots.size());
    tbb::parallel_for(std::size_t{0}, slots.size(), [&](std::size_t k) {
        cr[k] = crossing_of(g, ft, slots[k] / 3, static_cast<int>(slots[k] % 3));
    });
    return cr;
}

/// One vertex per cell touched by a kept crossing, at the mean of its crossings' points (their thickness
/// averaged); returns the cells, ascending (vertex i is cell ids[i]).
std::vector<std::int64_t> cell_vertices(const Grid& g, const std::vector<Crossing>& cr,
                                        const std::vector<std::array<std::int64_t, 4>>& around,
                                        const std::vector<std::uint8_t>& kept, MedialSurface& out) {
    std::vector<std::pair<std::int64_t, std::int64_t>> touch;  // (cell, crossing)
    touch.reserve(cr.size() * 4);
    for (std::size_t k = 0; k < cr.size(); ++k)
        if (kept[k])
            for (std::int64_t c : around[k]) touch.push_back({c, static_cast<std::int64_t>(k)});
    tbb::parallel_sort(touch.begin(), touch.end());
    std::vector<std::int64_t> ids;
    out.vertices.clear();
    out.thickness.clear();
    for (std::size_t i = 0; i < touch.size();) {
        std::size_t j = i;
        P3 sum{0, 0, 0};
        double th = 0;
        for (; j < touch.size() && touch[j].first == touch[i].first; ++j) {
            const Crossing& c = cr[static_cast<std::size_t>(touch[j].second)];
            for (int a = 0; a < 3; ++a) sum[a] += c.point[a];
            th += c.thickness;
        }
        const double n = double(j - i);
        ids.push_back(touch[i].first);
        out.vertices.push_back({sum[0] / n + g.origin[0], sum[1] / n + g.origin[1], sum[2] / n + g.origin[2]});
        out.thickness.push_back(th / n);
        i = j;
    }
    return ids;
}

/// A quad around each kept crossing, split along its shorter diagonal.
void quad_faces(const std::vector<std::int64_t>& ids, const std::vector<std::array<std::int64_t, 4>>& around,
                const std::vector<std::uint8_t>& kept, MedialSurface& out) {
    auto vid = [&](std::int64_t cell) {
        return static_cast<std::int64_t>(std::lower_bound(ids.begin(), ids.end(), cell) - ids.begin());
    };
    auto len = [&](std::int64_t a, std::int64_t b) {
        const P3 d = sub(out.vertices[static_cast<std::size_t>(a)], out.vertices[static_cast<std::size_t>(b)]);
        return dot(d, d);
    };
    out.faces.clear();
    out.faces.reserve(around.size() * 2);
    for (std::size_t k = 0; k < around.size(); ++k) {
        if (!kept[k]) continue;
        const auto& q = around[k];
        const std::int64_t v[4] = {vid(q[0]), vid(q[1]), vid(q[2]), vid(q[3])};
        if (len(v[0], v[2]) <= len(v[1], v[3])) {
            out.faces.push_back({v[0], v[1], v[2]});
            out.faces.push_back({v[0], v[2], v[3]});
        } else {
            out.faces.push_back({v[0], v[1], v[3]});
            out.faces.push_back({v[1], v[2], v[3]});
        }
    }
}

/// Clean up to a manifold: fins off, pinches split, specks of a few quads (smaller than t across: no plate the
/// measure could see) dropped, then one orientation per component. Each step sorts the edges again only when the
/// one before changed the faces.
void clean_up(const Grid& g, double t, MedialSurface& out) {
    std::vector<EdgeUse> e = edge_uses(out.faces);
    if (drop_fins(out.vertices, out.faces, e)) e = edge_uses(out.faces);
    if (split_fans(out.vertices, out.thickness, out.faces, e)) e = edge_uses(out.faces);
    const double cell = std::max({g.spacing[0], g.spacing[1], g.spacing[2]});
    const auto min_faces = static_cast<std::size_t>(2 * std::ceil(t / cell) * std::ceil(t / cell));
    if (drop_specks(out.vertices, out.thickness, out.faces, e, min_faces)) e = edge_uses(out.faces);
    orient(out.faces, e);
}

}  // namespace

void mesh_plane_edges(const Grid& g, const std::vector<std::int64_t>& ft, const std::vector<float>& edge, double t,
                      MedialSurface& out) {
    const std::vector<Crossing> cr = crossings(g, ft, edge, t);
    const Cells cells(g);
    std::vector<std::array<std::int64_t, 4>> around(cr.size());
    tbb::parallel_for(std::size_t{0}, cr.size(), [&](std::size_t k) { around[k] = cells_around(g, cells, cr[k]); });
    const std::vector<std::uint8_t> kept = peel(cr, around);
    const std::vector<std::int64_t> ids = cell_vertices(g, cr, around, kept, out);
    quad_faces(ids, around, kept, out);
    clean_up(g, t, out);
}

namespace {

/// Keeps plane-like voxels (upper voxels of plane-like edges) in a surface-like neighbourhood: a voxel with at least
/// kCore plane-like 26-neighbours is a core voxel (on a digital plane a voxel has 8; along a strip one or two voxels
/// wide, the most a rod's axis gets when its circumference exceeds t, at most 5), and the plane-like voxels
/// 26-adjacent to a core voxel are kept with it (the rim of a plate). Returns one byte per voxel.
std::vector<std::uint8_t> surface_voxels(const Grid& g, std::vector<float>& edge, double t) {
    constexpr int kCore = 6;
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2], n = g.voxel_count();
    std::vector<std::uint8_t> plane(static_cast<std::size_t>(n)), core(static_cast<std::size_t>(n), 0),
        keep(static_cast<std::size_t>(n), 0);
    tbb::parallel_for(std::int64_t(0), n, [&](std::int64_t i) {
        const auto k = static_cast<std::size_t>(3 * i);
        plane[static_cast<std::size_t>(i)] = edge[k] > t || edge[k + 1] > t || edge[k + 2] > t;
    });
    auto count = [&](const std::vector<std::uint8_t>& m, std::int64_t i) {
        const std::int64_t x = i % nx, y = (i / nx) % ny, z = i / (nx * ny);
        int c = 0;
        for (std::int64_t dz = -1; dz <= 1; ++dz)
            for (std::int64_t dy = -1; dy <= 1; ++dy)
                for (std::int64_t dx = -1; dx <= 1; ++dx) {
                    const std::int64_t X = x + dx, Y = y + dy, Z = z + dz;
                    if ((dx || dy || dz) && X >= 0 && Y >= 0 && Z >= 0 && X < nx && Y < ny && Z < nz)
                        c += m[static_cast<std::size_t>(g.index(X, Y, Z))] != 0;
                }
        return c;
    };
    tbb::parallel_for(std::int64_t(0), n, [&](std::int64_t i) {
        if (plane[static_cast<std::size_t>(i)]) core[static_cast<std::size_t>(i)] = count(plane, i) >= kCore;
    });
    tbb::parallel_for(std::int64_t(0), n, [&](std::int64_t i) {
        const auto u = static_cast<std::size_t>(i);
        keep[u] = plane[u] && (core[u] || count(core, i) > 0);
        if (!keep[u]) edge[3 * u] = edge[3 * u + 1] = edge[3 * u + 2] = 0.0f;  // not meshed either
    });
    return keep;
}

}  // namespace

namespace {

/// The object's Euclidean DT read off the feature transform: the distance to the nearest background voxel's centre.
std::vector<float> dt_of(const Grid& g, const std::uint8_t* mask, const std::vector<std::int64_t>& ft) {
    std::vector<float> dt(ft.size());
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    tbb::parallel_for(std::int64_t(0), g.voxel_count(), [&](std::int64_t i) {
        if (!mask[i]) {
            dt[static_cast<std::size_t>(i)] = 0.0f;
            return;
        }
        const P3 d = sub(at(g, double(i % nx), double((i / nx) % ny), double(i / (nx * ny))),
                         feature_centre(g, ft[static_cast<std::size_t>(i)]));
        dt[static_cast<std::size_t>(i)] = static_cast<float>(std::sqrt(dot(d, d)));
    });
    return dt;
}

}  // namespace

std::vector<std::uint8_t> medial_skeleton(const Grid& g, const std::uint8_t* mask, double t, const Progress& progress) {
    PlaneEdges e = plane_edges(g, mask, t, progress_span(progress, 0.0, 0.5));
    const std::vector<std::uint8_t> anchors = surface_voxels(g, e.edge, t);
    const std::vector<float> dt = dt_of(g, mask, e.feature);
    return thin_skeleton(g, mask, anchors.data(), dt.data(), progress_span(progress, 0.55, 1.0));
}

MedialSurface medial_surface(const Grid& g, const std::uint8_t* mask, double t, const Progress& progress) {
    PlaneEdges e = plane_edges(g, mask, t, progress_span(progress, 0.0, 0.5));
    const std::vector<std::uint8_t> anchors = surface_voxels(g, e.edge, t);
    MedialSurface out;
    {
        const std::vector<float> dt = dt_of(g, mask, e.feature);
        report(progress, 0.55);
        out.skeleton = thin_skeleton(g, mask, anchors.data(), dt.data(), progress_span(progress, 0.55, 0.85));
    }
    mesh_plane_edges(g, e.feature, e.edge, t, out);
    report(progress, 0.95);
    add_rods(g, out.skeleton, e.feature, t, out);
    report(progress, 1.0);
    return out;
}

namespace {

/// Vertices whose faces, linked over the two-face edges at the vertex (`links`), form more than one fan.
std::int64_t fan_breaks(std::size_t vertex_count, const std::vector<std::array<std::int64_t, 3>>& faces,
                        const std::vector<std::vector<std::pair<std::int64_t, std::int64_t>>>& links) {
    std::vector<std::vector<std::int64_t>> at_vertex(vertex_count);
    for (std::size_t f = 0; f < faces.size(); ++f)
        for (std::int64_t v : faces[f]) at_vertex[static_cast<std::size_t>(v)].push_back(static_cast<std::int64_t>(f));
    std::int64_t breaks = 0;
    for (std::size_t v = 0; v < vertex_count; ++v) {
        const auto& fs = at_vertex[v];
        std::vector<std::int64_t> up(fs.size());
        std::iota(up.begin(), up.end(), 0);
        auto local = [&](std::int64_t f) { return static_cast<std::int64_t>(std::find(fs.begin(), fs.end(), f) - fs.begin()); };
        auto r = [&](std::int64_t x) {
            while (up[static_cast<std::size_t>(x)] != x) x = up[static_cast<std::size_t>(x)];
            return x;
        };
        for (const auto& [a, b] : links[v]) up[static_cast<std::size_t>(r(local(a)))] = r(local(b));
        std::int64_t fans = 0;
        for (std::size_t k = 0; k < fs.size(); ++k) fans += r(static_cast<std::int64_t>(k)) == static_cast<std::int64_t>(k);
        breaks += fans > 1;
    }
    return breaks;
}

}  // namespace

MeshTopology mesh_topology(std::size_t vertex_count, const std::vector<std::array<std::int64_t, 3>>& faces) {
    MeshTopology m;
    for (const auto& f : faces)
        for (std::int64_t v : f)
            if (v < 0 || static_cast<std::size_t>(v) >= vertex_count) throw Error("mesh topology: a face refers to no vertex");
    for (const auto& f : faces)
        if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) m.degenerate_faces = true;
    std::vector<std::array<std::int64_t, 3>> sorted = faces;
    for (auto& f : sorted) std::sort(f.begin(), f.end());
    std::sort(sorted.begin(), sorted.end());
    m.duplicate_faces = std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end();
    const std::vector<EdgeUse> e = edge_uses(faces);
    // Union-find of faces over shared edges (components); the two-face edges at each vertex (fans).
    std::vector<std::int64_t> parent(faces.size());
    std::iota(parent.begin(), parent.end(), 0);
    auto root = [&](std::int64_t a) {
        while (parent[static_cast<std::size_t>(a)] != a) a = parent[static_cast<std::size_t>(a)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(a)])];
        return a;
    };
    std::vector<std::vector<std::pair<std::int64_t, std::int64_t>>> fan_links(vertex_count);
    const std::vector<std::size_t> groups = edge_groups(e);
    for (std::size_t gi = 0; gi + 1 < groups.size(); ++gi) {
        const std::size_t i = groups[gi], j = groups[gi + 1], n = j - i;
        m.boundary_edges += n == 1;
        m.nonmanifold_edges += n > 2;
        if (n == 2) {
            const EdgeUse& a = e[i];
            const EdgeUse& b = e[i + 1];
            if (a.forward == b.forward) m.consistent = false;
            for (std::int64_t v : {a.lo, a.hi}) fan_links[static_cast<std::size_t>(v)].push_back({a.face, b.face});
        }
        for (std::size_t k = i; k + 1 < j; ++k) {
            const std::int64_t a = root(e[k].face), b = root(e[k + 1].face);
            parent[static_cast<std::size_t>(a)] = b;
        }
    }
    for (std::size_t f = 0; f < faces.size(); ++f) m.components += root(static_cast<std::int64_t>(f)) == static_cast<std::int64_t>(f);
    m.nonmanifold_vertices = fan_breaks(vertex_count, faces, fan_links);
    std::vector<std::uint8_t> used(vertex_count, 0);
    for (const auto& f : faces)
        for (std::int64_t v : f) used[static_cast<std::size_t>(v)] = 1;
    const auto edges = static_cast<std::int64_t>(groups.size()) - 1;
    m.euler = std::count(used.begin(), used.end(), 1) - edges + static_cast<std::int64_t>(faces.size());
    return m;
}

}  // namespace volrig

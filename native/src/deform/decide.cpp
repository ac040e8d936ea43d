#include "deform/decide.hpp"

#include <algorithm>

namespace volrig::deform_detail {

std::int32_t Decider::settle(const CellBounds* r, std::size_t K, std::uint8_t* live, std::size_t stride) const {
    std::size_t a = 0;
    for (std::size_t k = 1; k < K; ++k)
        if (r[k].hi < r[a].hi) a = k;
    const std::int16_t ua = r[a].hi;
    std::size_t n_live = 0;
    for (std::size_t k = 0; k < K; ++k) {
        const bool l = k == a ? r[k].lo < 0 : in_running(r[k].lo, ua, s_.nearest);
        live[k * stride] = l;
        n_live += l;
    }
    if (n_live == 1 && ua < 0 && live[a * stride]) return static_cast<std::int32_t>(a);
    return n_live ? kOpen : kEmpty;
}

/// Loads candidate c's preimage of m3 and its cube; false when the field cannot cover it (no corner label, or a
/// same or closed cube whose exact answer is not a cover). A field without lattice tables (a blend group's) is
/// searched exactly at once.
bool Decider::load_cube(Candidate& c, const std::int64_t* m3, std::int64_t& queries) const {
    s_.pull(c.field).fixed(m3, c.pf);
    Pull::to_double(c.pf, c.p);
    const BoneField& f = s_.field(c.field);
    if (!f.lattice) {
        c.covered = false;
        c.local = kNone;
        return exact_cover(c, queries);
    }
    if (!fetch_cube(f, c.p, c.cube)) return false;
    c.has_U = c.sharp_L = c.exact = c.covered = false;
    c.local = kNone;
    c.L = -kInf;
    if (c.cube.same || c.cube.closed) {  // exact where negative: one sphere's on the whole cube, or closed
        c.L = c.U = least_over_labels(f, c.cube.lab, c.p, s_.s2, false, c.local);
        if (!(c.U < 0)) return false;
        c.has_U = c.sharp_L = c.exact = true;
    }
    return true;
}

/// U from the cube's corner labels; with `any_negative` it stops at the first cover, and a cut-short minimum is
/// only an upper bound of the upper bound (has_U stays false).
void Decider::set_upper(Candidate& c, bool any_negative) const {
    c.U = least_over_labels(s_.field(c.field), c.cube.lab, c.p, s_.s2, any_negative, c.local);
    c.has_U = !any_negative || !(c.U < 0);
}

void Decider::set_lower(Candidate& c) const {
    if (c.sharp_L) return;
    c.L = lower_bound(s_.field(c.field), c.cube, c.p, s_.s2, s_.T);
    c.sharp_L = true;
}

/// The field's exact power at the voxel (seeded by the sphere giving U); whether it covers.
bool Decider::exact_cover(Candidate& c, std::int64_t& queries) const {
    ++queries;
    Best seed;
    if (c.local != kNone) seed = {c.U, c.local, global(c)};
    const Best e = exact(s_.field(c.field), c.p, s_.spacing, s_.s2, false, seed);
    c.L = c.U = e.key;
    c.local = e.local;
    c.has_U = c.sharp_L = c.exact = true;
    return e.key < 0;
}

/// Whether the candidate covers its point: from the bounds when they decide, else by a k-d search.
bool Decider::covers(Candidate& c, std::int64_t& queries) const {
    if (c.has_U && c.U < 0) return true;
    if (!c.has_U) {
        set_upper(c, true);
        if (c.U < 0) return true;
    }
    set_lower(c);
    if (!(c.L < 0)) return false;
    ++queries;
    const BoneField& f = s_.field(c.field);
    const double pw[3] = {c.p[0] * s_.spacing[0], c.p[1] * s_.spacing[1], c.p[2] * s_.spacing[2]};
    return !f.nodes.empty() && any_cover(f, pw, c.p, s_.s2);
}

std::int32_t Decider::resolve(const std::int32_t* running, std::size_t n, const std::int64_t* m3, Candidate* c,
                              std::int64_t& queries) const {
    std::size_t m = 0;
    for (std::size_t k = 0; k < n; ++k) {
        c[m].field = running[k];
        m += load_cube(c[m], m3, queries);
    }
    if (m == 0) return kEmpty;
    if (m == 1) return covers(c[0], queries) ? c[0].field : kEmpty;
    return s_.nearest ? resolve_nearest(c, m, queries) : resolve_power(c, m, queries);
}

std::int32_t Decider::resolve_power(Candidate* c, std::size_t n, std::int64_t& queries) const {
    for (std::size_t k = 0; k < n; ++k)
        if (!c[k].has_U) set_upper(c[k], false);
    const std::size_t a = best(c, n);
    bool sure = c[a].U < 0;
    for (std::size_t k = 0; k < n && sure; ++k) {
        if (k == a) continue;
        set_lower(c[k]);
        sure = certain(c[a].U, c[k].L, false);
    }
    if (sure) return c[a].field;
    const double bound = c[a].U;
    for (std::size_t k = 0; k < n; ++k) {
        set_lower(c[k]);
        if (c[k].L == c[k].U || c[k].L > bound || !(c[k].L < 0)) continue;
        exact_cover(c[k], queries);
    }
    const Candidate* win = nullptr;
    for (std::size_t k = 0; k < n; ++k)
        if (c[k].U < 0 && (!win || beats(c[k], *win))) win = &c[k];
    return win ? win->field : kEmpty;
}

/// Nearest centre: coverage first, then the nearest covering centre.
std::int32_t Decider::resolve_nearest(Candidate* c, std::size_t n, std::int64_t& queries) const {
    std::size_t ncov = 0;
    for (std::size_t k = 0; k < n; ++k) {
        c[k].covered = c[k].covered || covers(c[k], queries);
        ncov += c[k].covered;
    }
    const Candidate* win = nullptr;
    for (std::size_t k = 0; k < n; ++k) {
        Candidate& x = c[k];
        if (!x.covered) continue;
        if (ncov > 1) {
            const Best e = exact(s_.field(x.field), x.p, s_.spacing, s_.s2, true);
            ++queries;
            x.U = e.key;
            x.local = e.local;
        }
        if (!win || beats(x, *win)) win = &x;
    }
    return win ? win->field : kEmpty;
}

}  // namespace volrig::deform_detail

// deform/gather_powers.cpp: the Gather members (deform/gatherer.hpp) that give sphere candidates their powers per
// voxel of a sub-block (exact, ball and blend powers) and that bound the candidates' cube lookups in int16 lanes.
#include "deform/gatherer.hpp"

#include <algorithm>
#include <cmath>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "deform/closed_cubes.hpp"
#include "deform/sampler.hpp"
#include "deform/value_out.hpp"

namespace volrig::deform_detail {

namespace {

/// Calls f(li, pf) for each voxel of sub-block sb of the block with its preimage under pull pl (fixed point,
/// stepping by the map's columns: exactly the direct evaluation).
template <class F>
void for_sub_block(const Pull& pl, const std::int64_t* base, const std::int64_t* e_block, int sb, F&& f) {
    const auto s0 = sub_origin(sb);
    const std::int64_t q0[3] = {base[0] + s0[0], base[1] + s0[1], base[2] + s0[2]};
    const std::int64_t e[3] = {std::min<std::int64_t>(4, e_block[0] - s0[0]), std::min<std::int64_t>(4, e_block[1] - s0[1]),
                               std::min<std::int64_t>(4, e_block[2] - s0[2])};
    const std::size_t first = static_cast<std::size_t>((s0[2] * 8 + s0[1]) * 8 + s0[0]);
    std::int64_t pz[3];
    pl.fixed(q0, pz);
    for (std::int64_t dz = 0; dz < e[2]; ++dz, pl.step(pz, 2)) {
        std::int64_t py[3] = {pz[0], pz[1], pz[2]};
        for (std::int64_t dy = 0; dy < e[1]; ++dy, pl.step(py, 1)) {
            std::int64_t px[3] = {py[0], py[1], py[2]};
            for (std::int64_t dx = 0; dx < e[0]; ++dx, pl.step(px, 0))
                f(first + static_cast<std::size_t>((dz * 8 + dy) * 8 + dx), px);
        }
    }
}

/// The preimages under pull pl of the voxels of sub-block sb (as doubles, exact) and their places in the block; returns
/// their count nv and repeats the first at nv (least_powers takes two voxels at a time; that result is not read).
int sub_block_preimages(const Pull& pl, const std::int64_t* base, const std::int64_t* e_block, int sb, double* px,
                        double* py, double* pz, std::uint16_t* at) {
    int nv = 0;
    for_sub_block(pl, base, e_block, sb, [&](std::size_t li, const std::int64_t* pf) {
        px[nv] = Pull::to_double(pf[0]);
        py[nv] = Pull::to_double(pf[1]);
        pz[nv] = Pull::to_double(pf[2]);
        at[nv++] = static_cast<std::uint16_t>(li);
    });
    px[nv] = px[0];
    py[nv] = py[0];
    pz[nv] = pz[0];
    return nv;
}

}  // namespace

/// Candidate k's cells of the cubes holding its sub-block sb's preimages.
void Gather::cube_cells(const Block& b, Local& loc, std::size_t k, int sb) const {
    const BoneField& f = s_.field(loc.fields[k]);
    std::uint32_t* at = loc.cube_cell.data() + k * 512;
    for_sub_block(s_.pull(loc.fields[k]), b.base, b.e, sb, [&](std::size_t li, const std::int64_t* p) { at[li] = f.cube_cell(p); });
}

/// Candidate k's exact power over sub-block sb, where one sphere's power is its field's: the power of that sphere
/// at each preimage (the very expression tier 3 evaluates), and its quantised range for the lanes.
void Gather::exact_powers(const Block& b, Local& loc, std::size_t k, int sb) const {
    const BoneField& f = s_.field(loc.fields[k]);
    const std::uint32_t one = loc.single[k * 8 + static_cast<std::size_t>(sb)];
    double* pw = loc.exact.data() + k * 512;
    std::int16_t* klo = loc.cube_lo.data() + k * 512;
    std::int16_t* khi = loc.cube_hi.data() + k * 512;
    const double inv_step = 1.0 / s_.bound_step;
    for_sub_block(s_.pull(loc.fields[k]), b.base, b.e, sb, [&](std::size_t li, const std::int64_t* pf) {
        double p[3];
        Pull::to_double(pf, p);
        pw[li] = power_of(f, one, p, s_.s2);
        const CellBounds r = exact_bounds(pw[li], inv_step);
        klo[li] = r.lo;
        khi[li] = r.hi;
    });
    ++loc.exact_pairs;
}

namespace {

/// Lowers best[v] (with arg[v]) to the power at (px, py, pz)[v] of the sphere (centre c, limit lim) numbered id
/// where that is less (with kTies, or equal and id less than arg[v]), for v < nv (rounded up to even: the arrays
/// hold one more). The very operations of power_of, two voxels at a time where SSE2 is at hand (the compiler does
/// not vectorise the selects).
template <bool kTies>
inline void least_powers(const double* c, double lim, double id, const double* px, const double* py, const double* pz,
                         int nv, const double* s2, double* best, double* arg) {
#if defined(__SSE2__)
    const __m128d c0 = _mm_set1_pd(c[0]), c1 = _mm_set1_pd(c[1]), c2 = _mm_set1_pd(c[2]);
    const __m128d w0 = _mm_set1_pd(s2[0]), w1 = _mm_set1_pd(s2[1]), w2 = _mm_set1_pd(s2[2]);
    const __m128d limv = _mm_set1_pd(lim), idv = _mm_set1_pd(id);
    for (int v = 0; v < nv; v += 2) {
        const __m128d dx = _mm_sub_pd(_mm_load_pd(px + v), c0), dy = _mm_sub_pd(_mm_load_pd(py + v), c1),
                      dz = _mm_sub_pd(_mm_load_pd(pz + v), c2);
        const __m128d d2 = _mm_add_pd(_mm_add_pd(_mm_mul_pd(_mm_mul_pd(w0, dx), dx), _mm_mul_pd(_mm_mul_pd(w1, dy), dy)),
                                      _mm_mul_pd(_mm_mul_pd(w2, dz), dz));
        const __m128d pw = _mm_sub_pd(d2, limv), old = _mm_load_pd(best + v), old_arg = _mm_load_pd(arg + v);
        __m128d lt = _mm_cmplt_pd(pw, old);
        if (kTies) lt = _mm_or_pd(lt, _mm_and_pd(_mm_cmpeq_pd(pw, old), _mm_cmplt_pd(idv, old_arg)));
        _mm_store_pd(best + v, _mm_or_pd(_mm_and_pd(lt, pw), _mm_andnot_pd(lt, old)));
        _mm_store_pd(arg + v, _mm_or_pd(_mm_and_pd(lt, idv), _mm_andnot_pd(lt, old_arg)));
    }
#else
    for (int v = 0; v < nv; ++v) {
        const double pw = length2(px[v] - c[0], py[v] - c[1], pz[v] - c[2], s2) - lim;
        if (pw < best[v] || (kTies && pw == best[v] && id < arg[v])) {
            best[v] = pw;
            arg[v] = id;
        }
    }
#endif
}

}  // namespace

/// Ball candidate k's exact power over sub-block sb: the least power at each preimage over the spheres that may give
/// it there (in increasing global index, so that a tie keeps the lower), as tier 3 takes it, and its quantised
/// range for the lanes (none where it does not cover: the field's power is not negative there). Sphere by sphere
/// over all the voxels at once, so that the loop vectorises.
void Gather::ball_powers(const Block& b, Local& loc, std::size_t k, int sb) const {
    const BoneField& f = s_.field(loc.fields[k]);
    const auto span = loc.sub_span[k * 8 + static_cast<std::size_t>(sb)];
    alignas(16) double px[65], py[65], pz[65];  // the preimages (and one more: least_powers takes two at a time)
    alignas(16) double best[65], arg[65];       // the least power and its sphere (a double, exact: best's lanes)
    std::uint16_t at[64];                       // the voxels' places in the block
    std::fill(best, best + 65, kInf);
    std::fill(arg, arg + 65, 0.0);
    const int nv = sub_block_preimages(s_.pull(loc.fields[k]), b.base, b.e, sb, px, py, pz, at);
    for (std::uint32_t i = span[0]; i < span[1]; ++i) {
        const auto& sp = f.sph[loc.sub_balls[i]];
        least_powers<false>(sp.c, sp.lim, loc.sub_balls[i], px, py, pz, nv, s_.s2, best, arg);
    }
    std::uint32_t* who = loc.exact_local.data() + k * 512;
    for (int v = 0; v < nv; ++v) who[at[v]] = static_cast<std::uint32_t>(arg[v]);
    keep_exact(loc, k, at, nv, best);
}

/// The blend candidate k's exact power over sub-block sb: the least power at each voxel over the posed spheres
/// that may give it there, each through its own group's map (the preimages once per group present), ties to the
/// lower global index (the spheres come group by group, so the comparison carries the index); per voxel the field
/// and the sphere giving it.
void Gather::blend_powers(const Block& b, Local& loc, std::size_t k, int sb) const {
    const auto span = loc.sub_span[k * 8 + static_cast<std::size_t>(sb)];
    const std::uint32_t* list = loc.sub_balls.data();
    alignas(16) double px[65], py[65], pz[65];  // the preimages under the group at hand (and one more: pairs)
    alignas(16) double best[65], arg[65];       // the least power and its posed sphere (index into posed_.ball)
    std::uint16_t at[64];
    std::fill(best, best + 65, kInf);
    std::fill(arg, arg + 65, 0.0);
    int nv = 0;
    for (std::uint32_t i = span[0]; i < span[1]; ++i) {
        const std::int32_t f = posed_.ball[list[i]].field;
        bool seen = false;
        for (std::uint32_t j = span[0]; j < i && !seen; ++j) seen = posed_.ball[list[j]].field == f;
        if (seen) continue;
        nv = sub_block_preimages(s_.pull(f), b.base, b.e, sb, px, py, pz, at);  // the same voxels for every group
        const BoneField& field = s_.field(f);
        for (std::uint32_t j = i; j < span[1]; ++j) {
            const PosedBall& pb = posed_.ball[list[j]];
            if (pb.field != f) continue;
            const auto& sp = field.sph[pb.local];
            least_powers<true>(sp.c, sp.lim, list[j], px, py, pz, nv, s_.s2, best, arg);
        }
    }
    std::uint32_t* who = loc.exact_local.data() + k * 512;
    std::int32_t* whose = loc.exact_field.data() + k * 512;
    for (int v = 0; v < nv; ++v) {
        const PosedBall& pb = posed_.ball[static_cast<std::size_t>(arg[v])];
        who[at[v]] = pb.local;
        whose[at[v]] = pb.field;
    }
    keep_exact(loc, k, at, nv, best);
}

/// Candidate k's exact powers best[v] at voxels at[v] of a sub-block, and their quantised ranges for the lanes
/// (none where it does not cover: its power is not negative there).
void Gather::keep_exact(Local& loc, std::size_t k, const std::uint16_t* at, int nv, const double* best) const {
    double* pw = loc.exact.data() + k * 512;
    std::int16_t* klo = loc.cube_lo.data() + k * 512;
    std::int16_t* khi = loc.cube_hi.data() + k * 512;
    const double inv_step = 1.0 / s_.bound_step;
    for (int v = 0; v < nv; ++v) {
        const std::size_t li = at[v];
        pw[li] = best[v];
        // where it covers, a range of a few quanta around it, without exact_bounds' floors (it runs per voxel);
        // branch-free: covered or not is as good as random here
        const bool covers = best[v] < 0;
        const auto x = static_cast<std::int32_t>(std::min(std::max(best[v] * inv_step, -32766.0), 0.0));  // ceil
        klo[li] = covers ? static_cast<std::int16_t>(x - 2) : kBoundMax;
        khi[li] = covers ? static_cast<std::int16_t>(x + 1) : kBoundMax;
    }
    ++loc.exact_pairs;
}

/// Tier 2, over the block's voxels in int16 lanes: u = the least upper bound (candidate arg's), mo = the least
/// lower bound of the others, ml = the least lower bound; a voxel is empty when ml >= 0, won for certain by arg
/// when certain(u, mo), else open. One pass over the candidates: mo is the second least lower bound where the
/// least is arg's own, else the least.
void Gather::lanes(Local& loc) const {
    const std::size_t K = loc.fields.size();
    std::int16_t* const u = loc.least_hi;
    std::int16_t* const mo = loc.rival_lo;
    std::int16_t* const ml = loc.least_lo;
    std::int16_t* const arg = loc.best;
    std::int16_t* const arg_lo = loc.least_lo_arg;
    std::int16_t* const m2 = loc.second_lo;
    const std::int16_t* khi = loc.cube_hi.data();
    const std::int16_t* klo = loc.cube_lo.data();
    for (std::size_t li = 0; li < 512; ++li) {
        u[li] = khi[li];
        arg[li] = 0;
        ml[li] = klo[li];
        arg_lo[li] = 0;
        m2[li] = kBoundMax;
    }
    for (std::size_t k = 1; k < K; ++k) {
        const std::int16_t* hk = khi + k * 512;
        const std::int16_t* lk = klo + k * 512;
        const auto kk = static_cast<std::int16_t>(k);
#if defined(__SSE2__)  // eight lanes at a time (the compiler does not vectorise the selects)
        const __m128i kv = _mm_set1_epi16(kk);
        auto select = [](__m128i m, __m128i a, __m128i b) { return _mm_or_si128(_mm_and_si128(m, a), _mm_andnot_si128(m, b)); };
        for (std::size_t li = 0; li < 512; li += 8) {
            auto at = [li](std::int16_t* x) { return reinterpret_cast<__m128i*>(x + li); };
            const __m128i h = _mm_loadu_si128(reinterpret_cast<const __m128i*>(hk + li));
            const __m128i l = _mm_loadu_si128(reinterpret_cast<const __m128i*>(lk + li));
            const __m128i uo = _mm_loadu_si128(at(u)), mlo = _mm_loadu_si128(at(ml));
            const __m128i lt = _mm_cmplt_epi16(h, uo), below = _mm_cmplt_epi16(l, mlo);
            _mm_storeu_si128(at(u), _mm_min_epi16(h, uo));
            _mm_storeu_si128(at(arg), select(lt, kv, _mm_loadu_si128(at(arg))));
            _mm_storeu_si128(at(m2), select(below, mlo, _mm_min_epi16(_mm_loadu_si128(at(m2)), l)));
            _mm_storeu_si128(at(ml), _mm_min_epi16(l, mlo));
            _mm_storeu_si128(at(arg_lo), select(below, kv, _mm_loadu_si128(at(arg_lo))));
        }
#else
        for (std::size_t li = 0; li < 512; ++li) {
            const bool lt = hk[li] < u[li];
            u[li] = lt ? hk[li] : u[li];
            arg[li] = lt ? kk : arg[li];
            const bool below = lk[li] < ml[li];
            m2[li] = below ? ml[li] : std::min(m2[li], lk[li]);
            ml[li] = below ? lk[li] : ml[li];
            arg_lo[li] = below ? kk : arg_lo[li];
        }
#endif
    }
    for (std::size_t li = 0; li < 512; ++li) mo[li] = arg_lo[li] == arg[li] ? m2[li] : ml[li];
    const bool nearest = s_.nearest;
    std::int64_t sure_count = 0;
    for (std::size_t li = 0; li < 512; ++li) {
        const bool sure = certain(u[li], mo[li], nearest);
        loc.win[li] = ml[li] >= 0 ? kEmpty : (sure ? field_at(loc, static_cast<std::size_t>(arg[li]), li) : kOpen);
        sure_count += sure && ml[li] < 0;
    }
    loc.by[1] += sure_count;
}

}  // namespace volrig::deform_detail

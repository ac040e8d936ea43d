// deform/decide.hpp: the tiered decision of which field (a bone, or a group of blended spheres) wins an output
// voxel, or a block of them. Every tier applies the same two rules (common.hpp: `certain` and `beats`) to sharper
// and dearer bounds of each candidate's power:
//   1. settle:        the power's quantised range over a block's or sub-block's preimage (no per-voxel work);
//   2. (gather.cpp)   the range of the lattice cube holding the voxel's preimage, in int16 lanes;
//   3. by_first_label: the power of the sphere labelling the cube's first corner (exact when the cube is that
//                     sphere's alone), below it the cube's range sharpened by the corner powers, or the exact
//                     answer of a closed cube;
//   4. resolve:       the least power over the cube's corner labels, a lower bound from their exact corner powers,
//                     and the k-d searches that settle the rest exactly.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "deform/bend.hpp"
#include "deform/bone_field.hpp"
#include "deform/queries.hpp"

namespace volrig::deform_detail {

/// The frame's fields with their motions, and what every tier needs to measure powers.
struct FieldSet {
    const std::vector<BoneField>& fields;
    const std::vector<Motion>& motions;  // one per field: its bone's, or its group's blend
    const double* spacing;
    double s2[3];       // squared spacing
    double T;           // the power at or above which nothing is covered
    double bound_step;  // the quantum of the fields' power ranges
    bool nearest;       // nearest-centre proximity (else power)
    const FieldContacts* contacts = nullptr;  // per field its contact planes (bend.hpp, sliding contact), or none

    const BoneField& field(std::int32_t f) const { return fields[static_cast<std::size_t>(f)]; }
    const Pull& pull(std::int32_t f) const { return motions[static_cast<std::size_t>(f)].pull; }
};

/// A field that may cover an output voxel, with what is known of its power there.
struct Candidate {
    Candidate() {}        // members are set as they are computed: no zero-filling per voxel
    std::int32_t field;
    double U, L;          // bounds of its power at the voxel (equal when exact; the nearest-centre key later)
    std::uint32_t local;  // the sphere giving U (local index); its global index breaks ties
    std::int64_t pf[3];   // the voxel's preimage under the field's motion, fixed point
    double p[3];          // the same as doubles
    bool exact;           // U is the field's power
    bool has_U;           // U is computed (resolve computes it when needed)
    bool sharp_L;         // L is as sharp as the cube's corner powers make it
    bool closed;          // the cube holding p is closed (closed_cube)
    bool covered;         // proved covered (nearest centre)
    Cube cube;            // the cube's corner labels (resolve)
};

class Decider {
public:
    explicit Decider(const FieldSet& set) : s_(set) {}

    /// Tier 1, over a block or sub-block from each candidate's power range r[k] over its preimage: marks in
    /// live[k * stride] whether candidate k may cover there and not lose to a certain cover; returns the index of
    /// a candidate that covers all of it and wins everywhere, kEmpty when none can cover, or kOpen.
    std::int32_t settle(const CellBounds* r, std::size_t K, std::uint8_t* live, std::size_t stride) const;

    /// Tier 3 (power proximity), on candidates loaded with their first-corner sphere's power (U, local, exact),
    /// their cube's quantised lower bound (L) and closed flag: the winning field, kEmpty, or kOpen.
    std::int32_t by_first_label(Candidate* c, std::size_t n) const;

    /// Tier 4, exact: the winning field at posed lattice point m3 among the fields in `running`, or kEmpty.
    /// `scratch` holds at least n candidates; `queries` counts the k-d searches.
    std::int32_t resolve(const std::int32_t* running, std::size_t n, const std::int64_t* m3, Candidate* scratch,
                         std::int64_t& queries) const;

    /// Whether a beats b at the voxel (their U), ties to the lower global index.
    bool beats(const Candidate& a, const Candidate& b) const {
        return deform_detail::beats(a.U, b.U, [&] { return global(a) < global(b); });
    }

private:
    std::uint32_t global(const Candidate& c) const { return s_.field(c.field).global[c.local]; }
    std::size_t best(const Candidate* c, std::size_t n) const;
    bool load_cube(Candidate& c, const std::int64_t* m3, std::int64_t& queries) const;
    void sharpen(Candidate& c) const;
    void sharpen_lower(Candidate& c, double beat) const;
    void set_upper(Candidate& c, bool any_negative) const;
    void set_lower(Candidate& c) const;
    bool exact_cover(Candidate& c, std::int64_t& queries) const;
    bool covers(Candidate& c, std::int64_t& queries) const;
    std::int32_t resolve_power(Candidate* c, std::size_t n, std::int64_t& queries) const;
    std::int32_t resolve_nearest(Candidate* c, std::size_t n, std::int64_t& queries) const;

    const FieldSet& s_;
};

// Tier 3 runs for a fifth of the covered voxels: defined here, so that the gather inlines it.

inline std::size_t Decider::best(const Candidate* c, std::size_t n) const {
    std::size_t a = 0;
    for (std::size_t k = 1; k < n; ++k)
        if (beats(c[k], c[a])) a = k;
    return a;
}

/// A closed cube's exact answer: the least power over its corners' labels.
inline void Decider::sharpen(Candidate& c) const {
    c.U = c.L = least_over_corners(s_.field(c.field), c.pf, s_.s2, c.local);
    c.exact = c.sharp_L = true;
}

/// The sharper lower bound, when the cube's range does not beat `beat`: exact in a closed cube, else from the
/// cube's corner powers.
inline void Decider::sharpen_lower(Candidate& c, double beat) const {
    if (c.sharp_L || c.L > beat) return;
    if (c.closed) return sharpen(c);
    c.L = std::max(c.L, s_.field(c.field).corner_lower(c.pf, s_.s2));
    c.sharp_L = true;
}

inline std::int32_t Decider::by_first_label(Candidate* c, std::size_t n) const {
    std::size_t a = best(c, n);
    if (!(c[a].U < 0)) {  // none covers when every lower bound is >= 0
        bool open = false;
        for (std::size_t k = 0; k < n; ++k) {
            sharpen_lower(c[k], 0.0);
            open = open || !(c[k].L >= 0);
        }
        a = best(c, n);  // a closed cube's exact answer may cover
        if (!(c[a].U < 0)) return open ? kOpen : kEmpty;
    }
    // Certain when the least upper bound (a cover) beats every rival's lower bound; failing that, once more with
    // the closed cubes' exact answers (which may also lower the best upper bound).
    for (int round = 0; round < 2; ++round) {
        const Candidate& w = c[a];
        bool sure = true;
        for (std::size_t k = 0; k < n && sure; ++k) {
            if (k == a) continue;
            if (!c[k].exact) sharpen_lower(c[k], w.U);
            sure = c[k].exact ? beats(w, c[k]) : certain(w.U, c[k].L, false);
        }
        if (sure) return w.field;
        bool sharper = false;
        for (std::size_t k = 0; k < n; ++k)
            if (c[k].closed && !c[k].exact) {
                sharpen(c[k]);
                sharper = true;
            }
        if (!sharper) break;
        a = best(c, n);
    }
    return kOpen;
}

}  // namespace volrig::deform_detail

// rig/bones/fitter.hpp: the fitter of rig_to_bones (volrig/rig.hpp): a role-named rig's limb joints moved to the
// articulations its bone tissue shows. bone_rig.cpp places them and the hinges (contacts, narrowest sections, the
// limb's profile, symmetry); heads.cpp the heads in their sockets and the seeds a long bone's shaft gives.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <optional>
#include <string>

#include "rig/bones/bones.hpp"

namespace volrig::rig_detail {

/// A limb joint: the head of bone `child`, whose parent long bone is `parent` ("" for hips and shoulders, where
/// the socket's segment is whichever lies nearest but the `distal` bone's); `ball`: a head in a socket. Elbows
/// and knees come first: a head lies at its long bone's end away from them.
struct LimbJoint {
    const char* child;
    const char* parent;
    const char* name;
    bool ball;
    const char* distal;
    double along;  ///< a hinge (knee, elbow, ankle): its share of the limb from the parent's head to the child's
                   ///< tail (Drillis-Contini: thigh 0.245 / shin 0.246, upper arm 0.186 / forearm 0.146, shin 0.246
                   ///< / foot 0.11; autorig's hand and foot bones end at the knuckles and the ball of the foot),
                   ///< where it is searched when hidden; 0 for the others
};

/// The limb joints, elbows and knees first (bone_rig.cpp).
extern const LimbJoint kLimbJoints[6];

/// Distance from q to the segment a..b.
inline double to_segment(const P3& q, const P3& a, const P3& b) { return norm(sub(q, lerp(a, b, share_along(q, a, b)))); }

/// The voxel box around the points a and b grown by r (mm), clamped to the grid.
inline void box_of(const Grid& g, const P3& a, const P3& b, double r, std::array<std::int64_t, 3>& lo,
                   std::array<std::int64_t, 3>& hi) {
    for (int k = 0; k < 3; ++k) {
        const double l = std::min(a[k], b[k]) - r, h = std::max(a[k], b[k]) + r;
        lo[k] = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor((l - g.origin[k]) / g.spacing[k])));
        hi[k] = std::min<std::int64_t>(g.dims[k] - 1,
                                       static_cast<std::int64_t>(std::ceil((h - g.origin[k]) / g.spacing[k])));
    }
}

/// Calls f(index, position) for every voxel of the box lo..hi.
template <class F>
void for_box(const Grid& g, const std::array<std::int64_t, 3>& lo, const std::array<std::int64_t, 3>& hi, F&& f) {
    for (std::int64_t z = lo[2]; z <= hi[2]; ++z)
        for (std::int64_t y = lo[1]; y <= hi[1]; ++y)
            for (std::int64_t x = lo[0]; x <= hi[0]; ++x) {
                const std::int64_t i = g.index(x, y, z);
                f(i, voxel_position(g, i));
            }
}

/// The share of its limb a hinge with child bone `child` lies at (kLimbJoints' along; 0 when none is known).
double along_of(const std::string& child);

/// How far from the limb (mm) and from the share its proportions put a hidden hinge at it is sought.
constexpr double kLimbRadius = 60.0, kLimbBand = 0.15;  // (kLimbRadius an adult's: times BoneParams::scale)

/// A rig's limb joints fitted to its bone segments (rig_to_bones); run() once.
class Fitter {
public:
    /// `voxels`: the bone's voxels (ascending), whose segments `segs` are.
    /// `sampled`: the spacing the scan sampled the bone at (g's own, or the slices' where g interpolates them).
    Fitter(const Grid& g, const std::array<double, 3>& sampled, const BoneParams& p, const Rig& rig,
           BoneSegments&& segs, const std::vector<std::int64_t>& voxels)
        : g_(g), sampled_(sampled), p_(p), out_{rig, {}, std::move(segs), {}} {
        for (std::size_t b = 0; b < rig.names.size(); ++b) index_[rig.names[b]] = static_cast<int>(b);
        cell_ = std::max({g.spacing[0], g.spacing[1], g.spacing[2]});
        members_.resize(out_.segments.sizes.size() + 1);
        for (std::int64_t i : voxels)
            if (const std::int32_t s = out_.segments.labels[static_cast<std::size_t>(i)]; s > 0)
                members_[static_cast<std::size_t>(s)].push_back(i);
    }

    /// The limb joints placed (place, then the wrists' and ankles' symmetry and shaft seeds), each bone's segment.
    BoneRig run();

private:
    int bone(const std::string& name) const {
        const auto it = index_.find(name);
        return it == index_.end() ? -1 : it->second;
    }
    P3 head(int b) const { return out_.rig.joints[static_cast<std::size_t>(out_.rig.bones[b][0])]; }
    P3 tail(int b) const { return out_.rig.joints[static_cast<std::size_t>(out_.rig.bones[b][1])]; }
    double length(int b) const { return norm(sub(tail(b), head(b))); }
    /// The window (mm) a joint is sought in: 0.3 of the shorter bone's `span`, 3 voxels to 60 mm (an adult's).
    double window(double span) const { return std::clamp(0.3 * span, 3 * cell_, std::max(3 * cell_, 60.0 * p_.scale)); }

    /// The segment the middle half of bone b runs through: the one with most voxels near that stretch.
    std::int32_t segment_of(int b) const { return segment_along(b, 0.25, 0.75); }

    /// The segment with most voxels near the stretch of bone b between the shares `from` and `to` of its length.
    std::int32_t segment_along(int b, double from, double to) const {
        const P3 a = lerp(head(b), tail(b), from), e = lerp(head(b), tail(b), to);
        const double r = std::clamp(0.1 * length(b), 3 * cell_, std::max(3 * cell_, 40.0 * p_.scale));
        std::array<std::int64_t, 3> lo{}, hi{};
        box_of(g_, a, e, r, lo, hi);
        std::map<std::int32_t, std::int64_t> votes;
        for_box(g_, lo, hi, [&](std::int64_t i, const P3& q) {
            const std::int32_t s = out_.segments.labels[static_cast<std::size_t>(i)];
            if (s > 0 && to_segment(q, a, e) <= r) ++votes[s];
        });
        std::int32_t best = 0;
        std::int64_t most = 0;
        for (const auto& [s, v] : votes)
            if (v > most) most = v, best = s;
        return best;
    }

    /// The segments with voxels within w of c, and how many.
    std::map<std::int32_t, int> segments_near(const P3& c, double w) const {
        std::array<std::int64_t, 3> lo{}, hi{};
        box_of(g_, c, c, w, lo, hi);
        std::map<std::int32_t, int> seen;
        for_box(g_, lo, hi, [&](std::int64_t i, const P3& q) {
            const std::int32_t t = out_.segments.labels[static_cast<std::size_t>(i)];
            if (t > 0 && norm(sub(q, c)) <= w) ++seen[t];
        });
        return seen;
    }

    /// The segment other than s and `exclude` (the hinge's child; the mirror limb's bone: the other femur, fused
    /// with its hemipelvis at the voxel size, meets this one's at the symphysis) nearest to s around the point c
    /// (within radius w): the socket of a head.
    std::int32_t socket_of(std::int32_t s, const std::array<std::int32_t, 2>& exclude, const P3& c, double w,
                           const Patch& own) const {
        std::int32_t best = 0;
        double gap = p_.reach;
        for (const auto& [t, count] : segments_near(c, w)) {
            if (t == s || t == exclude[0] || t == exclude[1] || count < 8) continue;
            const Contact k = contact_of(g_, own, patch_of(g_, out_.segments.labels, t, c, w), p_.reach, cell_);
            if (k.found && k.gap < gap) gap = k.gap, best = t;
        }
        return best;
    }

    void place(const LimbJoint& lj, const std::string& sfx);
    void centre_hinge(BoneJoint& j, int pb, int cb);
    void mirror_length(const LimbJoint& lj);
    void seed_kept(const LimbJoint& lj);
    P3 axis_of(int b) const;
    std::optional<P3> bone_top(const BoneJoint& j, int pb, int cb, double along) const;
    bool place_in_section(BoneJoint& j, int pb, int cb, double w);
    bool place_in_limb(BoneJoint& j, int pb, int cb, double along, bool seeded = false);
    bool hidden_in_parent(BoneJoint& j, int pb, int cb, double along);
    /// Whether the outer shape's joint between bones pb and cb lies further than kLimbBand from the share `along`
    /// the limb's proportions put it at (never when along is 0: no share known).
    bool off_proportion(int pb, int cb, double along) const;
    double slab_along(const P3& axis) const;
    double slab_sampled(const P3& axis) const;
    /// Whether the grid interpolates the scan's slices (rig_detail::Refined).
    bool interpolated() const { return sampled_ != g_.spacing; }
    Patch child_side(const BoneJoint& j, const Patch& parent, const P3& at, const P3& axis, double w) const;
    bool place_hinge(BoneJoint& j, int pb, int cb, double w);
    void fused_beyond(BoneJoint& j, int pb, int cb, double w);
    bool place_ball(BoneJoint& j, int cb, int db, double w);
    bool reseed_hinge(BoneJoint& j, int pb, int cb, double w);
    bool reseed_shared(BoneJoint& j, int pb, int cb, double w);
    /// Whether rig joint `joint` was placed from the bones already.
    bool placed_joint(std::int32_t joint) const {
        return std::any_of(out_.joints.begin(), out_.joints.end(),
                           [&](const BoneJoint& k) { return k.joint == joint && k.how != "kept"; });
    }
    const BoneJoint* placed(const std::string& name) const {
        for (const BoneJoint& k : out_.joints)
            if (k.name == name && k.how != "kept") return &k;
        return nullptr;
    }
    bool seed_ball(BoneJoint& j, int cb, int db);
    struct ShaftHead {
        P3 at;
        double length;
    };
    std::optional<ShaftHead> shaft_head(std::int32_t s, int db) const;
    std::optional<P3> along_shaft(std::int32_t s, const P3& k, double expect) const;
    std::optional<P3> distal_seed(const BoneJoint& j, int pb, int cb) const;
    bool place_seeded(BoneJoint& j, int pb, int cb, double along, double w, bool last);
    std::optional<ShaftHead> seed_by_shaft(BoneJoint& j, int cb, int db, double w);
    /// A ball joint's limb hinge (the knee of a hip, the elbow of a shoulder), when placed.
    const BoneJoint* hinge_of(const std::string& name) const {
        return placed(std::string(name.rfind("hip", 0) == 0 ? "knee" : "elbow") + name.substr(name.size() - 2));
    }
    /// A ball joint's long bone: the segment its limb's hinge found on its near side, else `own`.
    std::int32_t hinge_segment(const std::string& name, std::int32_t own) const {
        const BoneJoint* mid = hinge_of(name);
        return mid && mid->parent_segment > 0 ? mid->parent_segment : own;
    }
    /// The segment the mirror limb's bone of cb runs through (thigh.R for thigh.L), 0 when it has none.
    std::int32_t mirror_segment(int cb) const {
        const std::string& name = out_.rig.names[cb];
        const int mirror = bone(name.substr(0, name.size() - 1) + (name.back() == 'L' ? "R" : "L"));
        return mirror >= 0 ? segment_of(mirror) : 0;
    }
    /// The segment at point q (its nearest voxel's; 0 outside the grid or the segments).
    std::int32_t segment_at(const P3& q) const {
        std::int64_t v[3];
        for (int a = 0; a < 3; ++a) {
            v[a] = static_cast<std::int64_t>(std::llround((q[a] - g_.origin[a]) / g_.spacing[a]));
            if (v[a] < 0 || v[a] >= g_.dims[a]) return 0;
        }
        return out_.segments.labels[static_cast<std::size_t>(g_.index(v[0], v[1], v[2]))];
    }
    /// Whether segment s has a voxel within w of c.
    bool near_segment(std::int32_t s, const P3& c, double w) const {
        const auto seen = segments_near(c, w);
        const auto it = seen.find(s);
        return it != seen.end() && it->second > 0;
    }
    bool fit_ball(BoneJoint& j, int cb, const std::array<std::int32_t, 2>& exclude, double w);
    std::optional<P3> thickest(std::int32_t s, const P3& c, double w) const;
    void split(std::int32_t s, int cb, const P3& at, const P3& axis);
    void move(BoneJoint& j, int cb, const P3& to, const char* how);

    const Grid& g_;
    std::array<double, 3> sampled_;
    BoneParams p_;
    BoneRig out_;
    std::map<std::string, int> index_;
    double cell_ = 1;
    /// Each segment's voxels (linear indices, ascending; [0] unused), kept with the labels through splits.
    std::vector<std::vector<std::int64_t>> members_;
};

}  // namespace volrig::rig_detail

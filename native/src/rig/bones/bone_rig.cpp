// rig/bones/bone_rig.cpp: a role-named rig's limb joints moved to the articulations its bone tissue shows
// (volrig/rig.hpp rig_to_bones): limb bones matched to segments, joints at contacts, heads, narrowest sections.
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <optional>

#include "rig/autorig/templates.hpp"
#include "rig/bones/bones.hpp"
#include "volrig/error.hpp"

namespace volrig::rig_detail {

namespace {

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
const LimbJoint kLimbJoints[] = {
    {"forearm", "upper_arm", "elbow", false, "", 0.56},
    {"upper_arm", "", "shoulder", true, "forearm", 0},
    {"hand", "forearm", "wrist", false, "", kArmProportions[2] / (kArmProportions[2] + kArmProportions[3] * kHandToKnuckles)},
    {"shin", "thigh", "knee", false, "", 0.5},
    {"thigh", "", "hip", true, "shin", 0},
    {"foot", "shin", "ankle", false, "", kLegProportions[2] / (kLegProportions[2] + kLegProportions[3] * kFootToBall)},
};


/// Distance from q to the segment a..b.
double to_segment(const P3& q, const P3& a, const P3& b) { return norm(sub(q, lerp(a, b, share_along(q, a, b)))); }

/// The voxel box around the points a and b grown by r (mm), clamped to the grid.
void box_of(const Grid& g, const P3& a, const P3& b, double r, std::array<std::int64_t, 3>& lo,
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

double along_of(const std::string& child);

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

    BoneRig run() {
        for (const char* sfx : {".L", ".R"})
            for (const LimbJoint& lj : kLimbJoints) place(lj, sfx);
        for (const LimbJoint& lj : kLimbJoints)
            if (!lj.ball && along_of(lj.parent) > 0) mirror_length(lj);  // wrists and ankles
        for (const LimbJoint& lj : kLimbJoints)
            if (!lj.ball && along_of(lj.parent) > 0) seed_kept(lj);
        out_.bone_segment.assign(out_.rig.bones.size(), 0);
        for (std::size_t b = 0; b < out_.rig.bones.size(); ++b) out_.bone_segment[b] = segment_of(static_cast<int>(b));
        check_rig(out_.rig);
        return std::move(out_);
    }

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

void Fitter::place(const LimbJoint& lj, const std::string& sfx) {
    const int cb = bone(lj.child + sfx);
    const int pb = *lj.parent ? bone(lj.parent + sfx) : -1;
    if (cb < 0 || (*lj.parent && pb < 0)) return;
    BoneJoint j;
    j.joint = out_.rig.bones[cb][0];
    j.name = lj.name + sfx;
    j.from = j.to = head(cb);
    j.how = "kept";
    const double w = window(pb >= 0 ? std::min(length(cb), length(pb)) : length(cb));
    j.child_segment = segment_of(cb);
    // the parent's segment at the joint's end of it (a forearm parted mid-shaft where slices lie far apart: the
    // wrist's is the lower piece)
    j.parent_segment = pb >= 0 ? segment_along(pb, 0.5, 0.95) : 0;
    bool done = false;
    if (lj.ball) j.child_segment = hinge_segment(j.name, j.child_segment);
    if (!lj.ball && lj.along > 0 && j.parent_segment > 0 && place_seeded(j, pb, cb, lj.along, w, false)) done = true;
    else if (lj.ball && j.child_segment == 0) j.why = "no bone segment along " + out_.rig.names[cb];
    else if (lj.ball) done = place_ball(j, cb, *lj.distal ? bone(lj.distal + sfx) : -1, w);
    else if (j.parent_segment == 0) j.why = "no bone segment along " + out_.rig.names[pb];
    else if (j.parent_segment == j.child_segment) {  // near the outer shape's joint unless that is far off, and
        // along the limb; the limb first on slices interpolated (place_in_limb says why)
        const bool limb_first = interpolated() && lj.along > 0;
        done = (limb_first && place_in_limb(j, pb, cb, lj.along)) ||
               (!off_proportion(pb, cb, lj.along) && !bone_top(j, pb, cb, lj.along) && place_in_section(j, pb, cb, w)) ||
               (!limb_first && lj.along > 0 && place_in_limb(j, pb, cb, lj.along)) || reseed_shared(j, pb, cb, w);
    }
    else  // a child without a segment of its own: whatever meets the parent
        done = place_hinge(j, pb, cb, w) || (lj.along > 0 && hidden_in_parent(j, pb, cb, lj.along)) ||
               reseed_hinge(j, pb, cb, w);
    if (!done && j.why.empty()) j.why = "the bones show no articulation there";
    out_.joints.push_back(j);
}

/// How far from the joint the far end of a shared segment may lie, in the parent bone's expected length.
constexpr double kTopSpan[2] = {0.5, 2.0};

/// A hinge whose parent bone's head the outer shape put off their shared segment, and not from the bones (a
/// shoulder guessed inside the chest): the shared segment's far end from the child's tail (its principal axis'
/// end), when it lies between kTopSpan of the parent's expected length (the limb's proportions against the child
/// bone) from the joint; nothing otherwise.
std::optional<P3> Fitter::bone_top(const BoneJoint& j, int pb, int cb, double along) const {
    if (along <= 0 || along >= 1 || placed_joint(out_.rig.bones[pb][0])) return std::nullopt;
    const double w = window(std::min(length(cb), length(pb)));
    if (near_segment(j.child_segment, head(pb), w)) return std::nullopt;
    const SegmentEnds e = segment_ends(g_, members_[static_cast<std::size_t>(j.child_segment)]);
    if (!e.found) return std::nullopt;
    const P3 far = norm(sub(e.a, tail(cb))) > norm(sub(e.b, tail(cb))) ? e.a : e.b;
    const double expect = along / (1 - along) * length(cb), span = norm(sub(far, head(cb)));
    if (span < kTopSpan[0] * expect || span > kTopSpan[1] * expect) return std::nullopt;
    return far;
}

/// Bilateral symmetry (a wrist's or an ankle's pair): where the forearms or shins, measured between the joints
/// placed, differ by more than kMirrorSlack while the bones above them (upper arms, thighs) agree within it, one of
/// the two distal joints is off (a left ankle whose outer shape lay in the foot and whose section lies in the foot's
/// bones, 82 mm low on 8 mm slices). Each side's narrowest section is sought along its parent bone at either side's
/// length (all segments within kMirrorWindow of that length around it): the length whose two valleys are deeper
/// together is the joint's, and the other side's joint moves to its section there when its own valley there is
/// deeper than at its own length (its segments stay as they were split).
constexpr double kMirrorSlack = 0.05, kMirrorWindow = 0.1;
void Fitter::mirror_length(const LimbJoint& lj) {
    BoneJoint* side[2] = {nullptr, nullptr};
    for (BoneJoint& k : out_.joints)
        if (k.name == std::string(lj.name) + ".L") side[0] = &k;
        else if (k.name == std::string(lj.name) + ".R") side[1] = &k;
    if (!side[0] || !side[1]) return;
    const bool kept[2] = {side[0]->how == "kept", side[1]->how == "kept"};
    if (kept[0] && kept[1]) return;
    int pb[2], cb[2];
    for (int s = 0; s < 2; ++s) {
        const std::string sfx = s == 0 ? ".L" : ".R";
        pb[s] = bone(lj.parent + sfx), cb[s] = bone(lj.child + sfx);
        if (pb[s] < 0 || cb[s] < 0) return;
    }
    const double len[2] = {length(pb[0]), length(pb[1])};
    const int up[2] = {out_.rig.parents[pb[0]], out_.rig.parents[pb[1]]};  // the bones above (upper arm, thigh)
    if (up[0] < 0 || up[1] < 0 ||
        std::abs(length(up[0]) - length(up[1])) > kMirrorSlack * std::min(length(up[0]), length(up[1])))
        return;
    if (!kept[0] && !kept[1] && std::abs(len[0] - len[1]) <= kMirrorSlack * std::min(len[0], len[1])) return;
    // each side's section at either length: the length whose sections are deeper on both sides is the joint's
    Section at[2][2];  // [side][length]
    double score[2] = {0, 0};
    for (int s = 0; s < 2; ++s)
        for (int l = 0; l < 2; ++l) {
            const P3 axis = axis_of(pb[s]), c = add(head(pb[s]), {len[l] * axis[0], len[l] * axis[1], len[l] * axis[2]});
            const double half = kMirrorWindow * len[l];
            Patch p;
            for (const auto& [t, count] : segments_near(c, half)) {
                const Patch q = patch_of(g_, out_.segments.labels, t, c, 2 * half);
                p.pos.insert(p.pos.end(), q.pos.begin(), q.pos.end());
                p.surface.insert(p.surface.end(), q.surface.begin(), q.surface.end());
                p.index.insert(p.index.end(), q.index.begin(), q.index.end());
            }
            at[s][l] = narrowest_section(p, c, axis, half, slab_along(axis));
            score[l] += at[s][l].found ? at[s][l].share : 0;
        }
    // a side the bones did not place (a hand without a segment of its own, its outer shape's wrist far out) takes
    // its section at the other side's length; else the length whose sections are deeper
    const int l = kept[0] ? 1 : kept[1] ? 0 : score[0] >= score[1] ? 0 : 1;
    const int s = 1 - l;  // the side whose length lost
    if (kept[s]) {
        if (!at[s][l].found) return;
        move(*side[s], cb[s], at[s][l].centre, "section");
        side[s]->why.clear();
        return;
    }
    if (!at[s][l].found || at[s][l].share <= at[s][s].share) return;
    move(*side[s], cb[s], at[s][l].centre, "section");
}

/// A wrist or an ankle still where the outer shape put it after the symmetry check: sought where its parent's
/// shaft puts it (place_seeded, `last`: a raised hand whose bones do not reach the outer shape's wrist).
void Fitter::seed_kept(const LimbJoint& lj) {
    for (BoneJoint& j : out_.joints) {
        const std::string sfx = j.name.substr(j.name.size() - 2);
        const int pb = bone(lj.parent + sfx), cb = bone(lj.child + sfx);
        if (j.name != lj.name + sfx || j.how != "kept" || j.parent_segment <= 0 || pb < 0 || cb < 0) continue;
        place_seeded(j, pb, cb, lj.along, window(std::min(length(cb), length(pb))), true);
    }
}

P3 Fitter::axis_of(int b) const { return unit(sub(tail(b), head(b))); }

/// How thick a section's slabs are along `axis` on voxels of `spacing`: the largest of the spacing times the axis'
/// share on each grid axis, at least the finest spacing.
double slab_of(const std::array<double, 3>& spacing, const P3& axis) {
    double slab = std::min({spacing[0], spacing[1], spacing[2]});
    for (int a = 0; a < 3; ++a) slab = std::max(slab, std::abs(axis[a]) * spacing[a]);
    return slab;
}

/// How thick a section's slabs are along `axis`: a voxel's longest extent along it (its spacing times the axis'
/// share on each grid axis, the largest), at least the finest spacing. On a grid with slices 8 mm apart a slab
/// along the slices' normal is 8 mm thick: thinner slabs would fall between the slices and read as valleys.
double Fitter::slab_along(const P3& axis) const { return slab_of(g_.spacing, axis); }

/// slab_along for the scan's own voxels where the grid interpolates between its slices: a valley thinner than a
/// slice there is the interpolation's (fused_end on a raised arm's humerus took the olecranon fossa, a thin plate
/// of bone between two slices, for a bone fused on to its end, and pulled the elbow 30 mm up the humerus).
double Fitter::slab_sampled(const P3& axis) const { return slab_of(sampled_, axis); }

bool Fitter::place_in_section(BoneJoint& j, int pb, int cb, double w) {
    const P3 axis = axis_of(pb), at = head(cb);
    const Section s = narrowest_section(patch_of(g_, out_.segments.labels, j.child_segment, at, 1.5 * w), at, axis, w,
                                        slab_along(axis));
    if (!s.found) {
        j.why = "one segment spans the joint without a narrower section";
        return false;
    }
    split(j.child_segment, cb, s.centre, axis);
    j.child_segment = static_cast<std::int32_t>(out_.segments.sizes.size());
    move(j, cb, s.centre, "section");
    return true;
}

/// How far from the limb (mm) and from the share its proportions put a hidden hinge at it is sought.
constexpr double kLimbRadius = 60.0, kLimbBand = 0.15;  // (kLimbRadius an adult's: times BoneParams::scale)

/// A knee or an elbow whose parent's segment runs on into the child bone's first stretch (slices too far apart to
/// part them there: the humerus fused with the top of the forearm), where the bones show no contact near the outer
/// shape's joint, itself where the limb's proportions put it: the joint is sought inside the parent's segment along
/// the limb (place_in_limb).
bool Fitter::off_proportion(int pb, int cb, double along) const {
    const double upper = length(pb), share = upper / std::max(upper + length(cb), 1e-9);
    return along > 0 && std::abs(share - along) > kLimbBand;
}

bool Fitter::hidden_in_parent(BoneJoint& j, int pb, int cb, double along) {
    // Only where the outer shape's joint sits where the limb's proportions put it: a joint far off (a knee guessed
    // 15 cm too high sits inside the femur) is the reseed's to repair.
    if (off_proportion(pb, cb, along) || segment_along(cb, 0.05, 0.3) != j.parent_segment) return false;
    const std::int32_t child = j.child_segment;
    j.child_segment = j.parent_segment;
    if (place_in_limb(j, pb, cb, along)) return true;
    j.child_segment = child;
    return false;
}

/// A knee, an elbow, a wrist or an ankle whose two bones run through one segment (slices too far apart to show the
/// joint space): sought along the whole limb, from the parent's head through the outer shape's joint to the child's tail, within kLimbBand of the share
/// its proportions put the joint at and kLimbRadius of the limb (limb_section: its deepest valley, else its bulge,
/// the condyles and the plateau or the epicondyles), where the segment is split. On slices interpolated it is
/// tried before the search near the outer shape's joint: the interpolation bridges the joint spaces the slices
/// missed, so valleys near that joint are the bone's shape, not a joint (the outer shape's knee of legs held apart
/// lies 60 mm off, and its window's deepest valley 100 mm up the femur), while the limb's proportions hold for any
/// adult's limb. Where the grid is the scan's own, a valley near a joint the outer shape placed well is the finer
/// guide (on the 4 mm labels a talus fused with the tibia: its valley 1 mm from the ankle, the limb's bulge 28 mm).
bool Fitter::place_in_limb(BoneJoint& j, int pb, int cb, double along, bool seeded) {
    const std::optional<P3> far = seeded ? std::nullopt : bone_top(j, pb, cb, along);
    const P3 top = far ? *far : head(pb);
    // seeded (place_seeded): the limb runs straight on past the seed, which lies at the share `along` of it
    const P3 d = sub(head(cb), top);
    const double f = (1 - along) / along;
    const P3 on = add(head(cb), {f * d[0], f * d[1], f * d[2]});
    const Limb limb{top, head(cb), seeded ? on : tail(cb), along - kLimbBand, along + kLimbBand};
    const double length = norm(sub(limb.k, limb.a)) + norm(sub(limb.b, limb.k));
    const P3 mid = lerp(limb.a, limb.b, 0.5);
    const P3 axis = unit(add(unit(sub(limb.k, limb.a)), unit(sub(limb.b, limb.k))));  // splits upper from lower
    const Patch p = patch_of(g_, out_.segments.labels, j.child_segment, mid, 0.5 * length + kLimbRadius * p_.scale);
    const Section s = limb_section(p, limb, kLimbRadius * p_.scale, slab_along(axis));
    if (!s.found) return false;
    const std::int32_t shared = j.child_segment;
    move(j, cb, s.centre, s.bulge ? "bulge" : "section");
    split(shared, cb, s.centre, axis);
    j.child_segment = static_cast<std::int32_t>(out_.segments.sizes.size());
    j.why.clear();
    return true;
}

/// The child's side of a hinge at `at`: its own segment and the other segments meeting the parent's patch there
/// that lie beyond the joint along the parent's axis (an ulna beside the radius, a talus under the tibia).
Patch Fitter::child_side(const BoneJoint& j, const Patch& parent, const P3& at, const P3& axis, double w) const {
    Patch out;
    for (const auto& [t, count] : segments_near(at, w)) {
        if (t == j.parent_segment || count < 8) continue;
        Patch p = patch_of(g_, out_.segments.labels, t, at, w);
        P3 c{0, 0, 0};
        for (const P3& q : p.pos)
            for (int a = 0; a < 3; ++a) c[a] += q[a] / static_cast<double>(p.pos.size());
        if (t != j.child_segment && dot(sub(c, at), axis) <= 0) continue;
        if (!contact_of(g_, p, parent, p_.reach, cell_).found) continue;
        out.pos.insert(out.pos.end(), p.pos.begin(), p.pos.end());
        out.surface.insert(out.surface.end(), p.surface.begin(), p.surface.end());
        out.index.insert(out.index.end(), p.index.begin(), p.index.end());
    }
    return out;
}

bool Fitter::place_hinge(BoneJoint& j, int pb, int cb, double w) {
    const P3 at = head(cb);
    const Patch parent = patch_of(g_, out_.segments.labels, j.parent_segment, at, w);
    const Patch child = child_side(j, parent, at, axis_of(pb), w);
    const Contact k = contact_of(g_, parent, child, p_.reach, std::max(1.5 * cell_, 4.0 * p_.scale));
    if (!k.found) {
        j.why = "no segment meets segment " + std::to_string(j.parent_segment) + " there";
        return false;
    }
    move(j, cb, k.centre, "contact");
    fused_beyond(j, pb, cb, w);
    return true;
}

/// How deep a valley in the parent's segment just before a hinge's contact must be (over its lower wall) to mark a
/// bone fused on to the parent's end (fused_end): the tibia and the talus fused on 8 mm slices leave 10-25%.
constexpr double kFusedValley = 0.1;

/// A hinge at a contact whose parent segment holds, within the window w behind it (along the parent bone), a valley
/// of at least kFusedValley and more bone between that valley and the contact (the talus and calcaneus joined to
/// the tibia where slices lie far apart, whose contact with the forefoot is the next joint down): the joint moves to
/// the valley, and the parent's segment is split there (the part beyond goes with the child bone).
void Fitter::fused_beyond(BoneJoint& j, int pb, int cb, double w) {
    const P3 at = head(cb), axis = axis_of(pb);
    const Patch p = patch_of(g_, out_.segments.labels, j.parent_segment, at, 1.5 * w);
    const Section s = fused_end(p, at, axis, w, w, 0.5 * w, slab_sampled(axis), kFusedValley);
    if (!s.found) return;
    split(j.parent_segment, cb, s.centre, axis);
    move(j, cb, s.centre, "section");
}

/// A hinge the outer shape put beyond the window of its bones' contact: started again between the facing ends of
/// the two segments (the parent's end nearer the child's centroid, and the child's nearer the parent's).
bool Fitter::reseed_hinge(BoneJoint& j, int pb, int cb, double w) {
    if (j.child_segment == 0) return false;
    const SegmentEnds p = segment_ends(g_, members_[static_cast<std::size_t>(j.parent_segment)]);
    const SegmentEnds c = segment_ends(g_, members_[static_cast<std::size_t>(j.child_segment)]);
    if (!p.found || !c.found) return false;
    const auto nearer = [](const SegmentEnds& e, const P3& q) { return norm(sub(e.a, q)) < norm(sub(e.b, q)) ? e.a : e.b; };
    const P3 pe = nearer(p, c.centroid), ce = nearer(c, p.centroid);
    const P3 seed{0.5 * (pe[0] + ce[0]), 0.5 * (pe[1] + ce[1]), 0.5 * (pe[2] + ce[2])};
    if (norm(sub(seed, head(cb))) > 0.5 * (length(pb) + length(cb))) return false;  // not this limb's bones
    const BoneJoint before = j;
    const std::int64_t point = out_.rig.joint_points.empty() ? -1 : out_.rig.joint_points[static_cast<std::size_t>(j.joint)];
    move(j, cb, seed, "seed");
    if (place_hinge(j, pb, cb, w)) {
        j.from = before.from;
        j.why.clear();
        return true;
    }
    move(j, cb, before.from, "kept");
    if (!out_.rig.joint_points.empty()) out_.rig.joint_points[static_cast<std::size_t>(j.joint)] = point;
    j.why = before.why;
    return false;
}

/// Parent and child bones run through one segment with no narrower section between (the outer shape's joint far
/// from the bones'): the child keeps it, and the parent takes the largest segment meeting it at its end nearer the
/// joint (a femur, not the patella or the fibula).
bool Fitter::reseed_shared(BoneJoint& j, int pb, int cb, double w) {
    const SegmentEnds e = segment_ends(g_, members_[static_cast<std::size_t>(j.child_segment)]);
    if (!e.found) return false;
    const P3 end = norm(sub(e.a, head(cb))) < norm(sub(e.b, head(cb))) ? e.a : e.b;
    const Patch own = patch_of(g_, out_.segments.labels, j.child_segment, end, w);
    std::int32_t other = 0;
    int most = 0;
    for (const auto& [t, count] : segments_near(end, w))
        if (t != j.child_segment && count > most &&
            contact_of(g_, own, patch_of(g_, out_.segments.labels, t, end, w), p_.reach, cell_).found)
            most = count, other = t;
    if (other == 0) return false;
    const std::string why = j.why;
    j.parent_segment = other;
    j.why.clear();
    if (reseed_hinge(j, pb, cb, w)) return true;
    j.why = why;
    return false;
}

/// A head the outer shape put nearer its limb's middle joint (knee, elbow: bone db's head) than half its long
/// bone's length (a hip below the knee) starts again at the long bone's end away from that joint.
bool Fitter::seed_ball(BoneJoint& j, int cb, int db) {
    const SegmentEnds e = segment_ends(g_, members_[static_cast<std::size_t>(j.child_segment)]);
    if (!e.found) return false;
    const P3 k = head(db);
    const P3 far = norm(sub(e.a, k)) > norm(sub(e.b, k)) ? e.a : e.b;
    const double bone_length = norm(sub(far, k));
    if (norm(sub(head(cb), k)) >= 0.5 * bone_length) return false;
    // a femur about as long as the tibia, a humerus as the forearm: else the segment is not this limb's
    if (bone_length < 0.5 * length(db) || bone_length > 2.0 * length(db)) return false;
    move(j, cb, far, "seed");
    return true;
}

/// The share of its limb a hinge with child bone `child` lies at (kLimbJoints' along; 0 when none is known).
double along_of(const std::string& child) {
    for (const LimbJoint& lj : kLimbJoints)
        if (!lj.ball && child == lj.child) return lj.along;
    return 0.0;
}

/// Where a head lies by its long bone's shaft: up the shaft from its hinge (the bone's principal axis over its
/// voxels within kShaftReach of its expected length of the hinge), at that length, the limb's proportions against
/// the bone below (an upper arm 0.56 / 0.44 of the forearm, a thigh as long as the shin). The bone's far end is no
/// guide: a humerus fused with the scapula at the voxel size ends at the spine.
constexpr double kShaftReach = 0.6, kShaftSlack = 0.25, kShaftWindow = 0.4;
constexpr double kShaftAgree = 0.7071;  // cos 45 degrees: a distal seed's shaft against the outer shape's bone
std::optional<Fitter::ShaftHead> Fitter::shaft_head(std::int32_t s, int db) const {
    const std::string distal = out_.rig.names[db];
    const double along = along_of(distal.substr(0, distal.size() - 2));
    if (along <= 0 || along >= 1) return std::nullopt;
    const double expect = along / (1 - along) * length(db);
    const std::optional<P3> at = along_shaft(s, head(db), expect);
    return at ? std::optional<ShaftHead>(ShaftHead{*at, expect}) : std::nullopt;
}

/// Where the shaft of segment s puts the far end of a long bone from its hinge k: the principal axis of the
/// segment's voxels within kShaftReach of `expect` (mm) of k, at `expect` on their side of k.
std::optional<P3> Fitter::along_shaft(std::int32_t s, const P3& k, double expect) const {
    const Patch p = patch_of(g_, out_.segments.labels, s, k, kShaftReach * expect);
    if (p.pos.size() < 8) return std::nullopt;
    P3 c{0, 0, 0};
    const P3 axis = principal_axis(p.pos, c);
    const double sign = dot(sub(c, k), axis) >= 0 ? 1.0 : -1.0;
    return add(k, {sign * expect * axis[0], sign * expect * axis[1], sign * expect * axis[2]});
}

/// Where a wrist or an ankle lies by its parent bone's shaft (shaft_head the other way): where the bones placed the
/// elbow or knee and the shoulder or hip above it, the forearm or shin is expected at the limb's proportions against
/// the bone above (0.44 / 0.56 of the upper arm, as long as the thigh), down the shaft of the segment the hinge found
/// beyond it. Nothing where those joints are not the bones' or the shaft runs more than 45 degrees (kShaftAgree)
/// off the outer shape's bone.
std::optional<P3> Fitter::distal_seed(const BoneJoint& j, int pb, int cb) const {
    const int up = out_.rig.parents[static_cast<std::size_t>(pb)];
    if (up < 0 || !placed_joint(out_.rig.bones[up][0])) return std::nullopt;
    const auto mid = std::find_if(out_.joints.begin(), out_.joints.end(),
                                  [&](const BoneJoint& k) { return k.joint == out_.rig.bones[pb][0] && k.how != "kept"; });
    if (mid == out_.joints.end()) return std::nullopt;
    const std::string& name = out_.rig.names[pb];
    const double share = along_of(name.substr(0, name.size() - 2));  // the elbow's or the knee's
    if (share <= 0 || share >= 1) return std::nullopt;
    const double expect = (1 - share) / share * length(up);
    const std::int32_t s = mid->child_segment > 0 ? mid->child_segment : j.parent_segment;
    const std::optional<P3> at = along_shaft(s, head(pb), expect);
    // a shaft across the outer shape's bone is some other bone's (the segment holds more than the forearm or shin)
    if (!at || dot(unit(sub(*at, head(pb))), unit(sub(head(cb), head(pb)))) < kShaftAgree) return std::nullopt;
    return at;
}

/// A wrist or an ankle sought where its parent's shaft puts it (distal_seed): at the parent segment's contact nearest
/// there when the outer shape's joint lies further than kShaftSlack of the expected length from it (a wrist out on
/// the hand: the carpals' contact lay outside its window); also along the limb straight down the shaft (the seed at
/// the proportions' share) when the outer joint lies kLimbRadius off the shaft's line (an ankle on the toes: the limb
/// ran across the foot) or nothing else placed it (`last`). Else it stays: the seed is the proportions', not the bones'.
bool Fitter::place_seeded(BoneJoint& j, int pb, int cb, double along, double w, bool last) {
    const std::optional<P3> seed = distal_seed(j, pb, cb);
    if (!seed) return false;
    const P3 k = head(pb), o = head(cb);
    const bool far = norm(sub(o, *seed)) > kShaftSlack * norm(sub(*seed, k));
    const P3 d = unit(sub(*seed, k)), v = sub(o, k);
    const double t = dot(v, d);
    const bool off_line = norm(sub(v, {t * d[0], t * d[1], t * d[2]})) > kLimbRadius * p_.scale;
    if (!last && !far && !off_line) return false;
    const BoneJoint before = j;
    const std::int64_t point = out_.rig.joint_points.empty() ? -1 : out_.rig.joint_points[static_cast<std::size_t>(j.joint)];
    move(j, cb, *seed, "seed");
    j.child_segment = segment_of(cb);
    j.parent_segment = segment_along(pb, 0.5, 0.95);
    bool done = j.parent_segment > 0 && j.parent_segment != j.child_segment && place_hinge(j, pb, cb, w);
    if (!done && (last || off_line) && j.parent_segment > 0) {
        j.child_segment = j.parent_segment;
        done = place_in_limb(j, pb, cb, along, true);
    }
    if (done) {
        j.why.clear();
        return true;
    }
    move(j, cb, before.to, before.how.c_str());
    j = before;
    if (!out_.rig.joint_points.empty()) out_.rig.joint_points[static_cast<std::size_t>(j.joint)] = point;
    return false;
}

/// A head the outer shape put off its long bone altogether (a raised arm's shoulder out on the arm, where the arm's
/// medial axis leaves the trunk) starts again where its shaft puts it; one further than kShaftSlack of the bone's
/// expected length from there (a hip high on the flank of legs held apart) is sought from where it is. Either way
/// its head is then sought within kShaftWindow of that length, not just near the outer shape's joint. Returns where
/// the shaft puts the head, or nothing when the outer shape's joint lies there.
std::optional<Fitter::ShaftHead> Fitter::seed_by_shaft(BoneJoint& j, int cb, int db, double w) {
    const auto e = shaft_head(j.child_segment, db);
    if (!e) return std::nullopt;
    const bool off = !near_segment(j.child_segment, head(cb), w);
    if (!off && norm(sub(head(cb), e->at)) <= kShaftSlack * e->length) return std::nullopt;
    if (off) move(j, cb, e->at, "seed");
    return e;
}

bool Fitter::place_ball(BoneJoint& j, int cb, int db, double w) {
    const BoneJoint* mid = hinge_of(j.name);
    const std::array<std::int32_t, 2> exclude{mid ? mid->child_segment : (db >= 0 ? segment_of(db) : 0),
                                             mirror_segment(cb)};
    bool seeded = db >= 0 && seed_ball(j, cb, db);
    std::optional<ShaftHead> shaft;
    if (seeded) w = window(norm(sub(head(cb), head(db))));  // the long bone's length
    else if (db >= 0 && (shaft = seed_by_shaft(j, cb, db, w)))
        w = std::max(w, kShaftWindow * shaft->length), seeded = true;
    if (!fit_ball(j, cb, exclude, w)) return false;
    for (int pass = 0; seeded && pass < 3 && j.how == "contact"; ++pass)  // from the socket, the head's sphere
        fit_ball(j, cb, exclude, w);
    // a socket far from where the shaft puts the head is another joint's (a sacroiliac joint where the femur fused
    // with its hemipelvis at the voxel size): the head is then that fused bone's thickest there. Whether the outer
    // shape's joint was near the shaft's head or not: a socket found near it may still be the wrong joint.
    if (!shaft && db >= 0 && !seeded) shaft = shaft_head(j.child_segment, db);
    if (shaft && norm(sub(head(cb), shaft->at)) > kShaftSlack * shaft->length) {
        const auto c = thickest(j.child_segment, shaft->at, w);
        if (!c) return false;
        j.parent_segment = 0;
        move(j, cb, *c, "thickest");
    }
    return true;
}

/// A ball joint from where bone cb's head lies now: the sphere of its head, else the contact with its socket, else
/// (no socket apart from it) its thickest bone.
bool Fitter::fit_ball(BoneJoint& j, int cb, const std::array<std::int32_t, 2>& exclude, double w) {
    const P3 at = head(cb);
    const Patch own = patch_of(g_, out_.segments.labels, j.child_segment, at, w);
    j.parent_segment = socket_of(j.child_segment, exclude, at, w, own);
    if (j.parent_segment == 0) {  // the head fused with its socket at this voxel size: its thickest bone
        const auto c = thickest(j.child_segment, at, w);
        if (c) move(j, cb, *c, "thickest");
        else j.why = "no bone of segment " + std::to_string(j.child_segment) + " near the joint";
        return c.has_value();
    }
    const Patch other = patch_of(g_, out_.segments.labels, j.parent_segment, at, w);
    const Contact k = contact_of(g_, own, other, p_.reach, cell_);
    // the head's surface facing its socket, a few voxels deep into the gap
    const Contact cap = contact_of(g_, own, other, p_.reach, std::max(3 * cell_, 6.0 * p_.scale));
    const Sphere s = fit_sphere(cap.a);

    if (s.radius >= 2 * cell_ && s.radius <= w && norm(sub(s.centre, k.centre)) <= 1.5 * s.radius)
        move(j, cb, s.centre, "ball");
    else
        move(j, cb, k.centre, "contact");
    return true;
}

/// The thickest bone of segment s near c (thickest_point within w), climbed where it lies in the outer half of the
/// window (thicker bone may lie past the window's edge): sought again around what it found while that moves by more
/// than a voxel (at most kClimbSteps times), so that a head a window away from the outer shape's joint is reached (a
/// hip put 92 mm low, whose window held the femur's neck at most). One in the inner half is a local thickest at the
/// window's scale, and stays (climbing from there took a head fused with its socket to the fused mass, 21 mm off).
constexpr int kClimbSteps = 4;
std::optional<P3> Fitter::thickest(std::int32_t s, const P3& c, double w) const {
    std::optional<P3> at = thickest_point(g_, out_.segments.labels, s, c, w);
    if (!at || norm(sub(*at, c)) <= 0.5 * w) return at;
    for (int step = 0; step < kClimbSteps; ++step) {
        const std::optional<P3> next = thickest_point(g_, out_.segments.labels, s, *at, w);
        if (!next || norm(sub(*next, *at)) <= cell_) break;
        at = next;
    }
    return at;
}

/// Voxels of segment s beyond the plane (at, axis) and near bone cb become a new segment.
void Fitter::split(std::int32_t s, int cb, const P3& at, const P3& axis) {
    const double r = window(length(cb));
    // the child bone and the bones below it (a shin and its foot: a foot fused with the tibia goes with it)
    std::vector<int> below{cb};
    for (std::size_t k = 0; k < below.size(); ++k)
        for (std::size_t b = 0; b < out_.rig.parents.size(); ++b)
            if (out_.rig.parents[b] == below[k]) below.push_back(static_cast<int>(b));
    const auto fresh = static_cast<std::int32_t>(out_.segments.sizes.size() + 1);
    std::int64_t moved = 0;
    for (const int b : below) {
        std::array<std::int64_t, 3> lo{}, hi{};
        box_of(g_, head(b), tail(b), r, lo, hi);
        for_box(g_, lo, hi, [&](std::int64_t i, const P3& q) {
            std::int32_t& l = out_.segments.labels[static_cast<std::size_t>(i)];
            if (l == s && dot(sub(q, at), axis) > 0 && to_segment(q, head(b), tail(b)) <= r) l = fresh, ++moved;
        });
    }
    out_.segments.sizes[static_cast<std::size_t>(s - 1)] -= moved;
    out_.segments.sizes.push_back(moved);
    std::vector<std::int64_t>& from = members_[static_cast<std::size_t>(s)];
    std::vector<std::int64_t> gone;
    const auto kept = std::stable_partition(from.begin(), from.end(), [&](std::int64_t i) {
        return out_.segments.labels[static_cast<std::size_t>(i)] == s;
    });
    gone.assign(kept, from.end());
    from.erase(kept, from.end());
    members_.push_back(std::move(gone));
}

/// Moves the head of bone cb to `to`; an end bone (its tail no bone's head) keeps its direction and length.
void Fitter::move(BoneJoint& j, int cb, const P3& to, const char* how) {
    auto& rig = out_.rig;
    const P3 d = sub(to, rig.joints[static_cast<std::size_t>(j.joint)]);
    rig.joints[static_cast<std::size_t>(j.joint)] = to;
    const std::int32_t t = rig.bones[cb][1];
    const bool end = std::none_of(rig.bones.begin(), rig.bones.end(), [&](const auto& b) { return b[0] == t; });
    if (end)
        for (int k = 0; k < 3; ++k) rig.joints[static_cast<std::size_t>(t)][k] += d[k];
    if (!rig.joint_points.empty()) rig.joint_points[static_cast<std::size_t>(j.joint)] = -1;
    j.to = to;
    j.how = how;
}

}  // namespace

}  // namespace volrig::rig_detail

namespace volrig {

namespace {

BoneRig fit_on(const Grid& grid, const std::array<double, 3>& sampled, const std::uint8_t* bone, const Rig& rig,
              const BoneRigOptions& opt) {
    using namespace rig_detail;
    const std::vector<std::int64_t> voxels = bone_voxels(grid, bone);
    const BoneParams p = bone_params(grid, opt, voxels.size());
    return Fitter(grid, sampled, p, rig, segments_of(grid, voxels, p), voxels).run();
}

}  // namespace

BoneRig rig_to_bones(const Grid& grid, const std::uint8_t* bone, const Rig& rig, const BoneRigOptions& opt) {
    check_rig(rig);
    // slices far apart: fitted on the bone interpolated between them (rig_detail::Refined says why), the segments
    // given back on the scan's own grid
    const std::optional<rig_detail::Refined> fine = rig_detail::refine_slices(grid, bone);
    if (!fine) return fit_on(grid, grid.spacing, bone, rig, opt);
    BoneRig out = fit_on(fine->grid, grid.spacing, fine->bone.data(), rig, opt);
    out.segments = rig_detail::on_slices(*fine, grid, out.segments);
    return out;
}

}  // namespace volrig

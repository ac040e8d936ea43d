// rig/bones/bones.hpp: the stages of rigs from a scan's bones (volrig/rig.hpp rig_to_bones): bone voxels near a
// joint, the contact between two segments, a sphere fitted to a head, the narrowest section of a segment.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

#include "volrig/rig.hpp"

namespace volrig::rig_detail {

using P3 = std::array<double, 3>;

inline P3 sub(const P3& a, const P3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline P3 add(const P3& a, const P3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
inline double dot(const P3& a, const P3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline double norm(const P3& a) { return std::sqrt(dot(a, a)); }
inline double dist2(const P3& a, const P3& b) { return dot(sub(a, b), sub(a, b)); }
inline P3 unit(const P3& a) {
    const double n = norm(a);
    return n > 0 ? P3{a[0] / n, a[1] / n, a[2] / n} : P3{0, 0, 0};
}
/// Where on the segment a..b the point nearest q lies: its share t of the way from a (0..1).
inline double share_along(const P3& q, const P3& a, const P3& b) {
    const P3 d = sub(b, a);
    const double len2 = dot(d, d);
    return len2 > 0 ? std::clamp(dot(sub(q, a), d) / len2, 0.0, 1.0) : 0.0;
}
/// The point t of the way from a to b.
inline P3 lerp(const P3& a, const P3& b, double t) { return {a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])}; }

/// The bone's bounding box grown by `pad` voxels of background along each axis (it may reach past the grid), the
/// bone copied in (0/1 bytes). Throws Error for an empty bone mask.
struct Crop {
    Grid grid;
    std::array<std::int64_t, 3> lo{};  ///< the crop's voxel (0, 0, 0) in the full grid (may be negative)
    std::vector<std::uint8_t> bone;
};
Crop crop_of(const Grid& g, const std::uint8_t* bone, const std::array<std::int64_t, 3>& pad);

/// The bone's voxels (linear indices of its non-zero bytes, ascending), found slice by slice in parallel.
std::vector<std::int64_t> bone_voxels(const Grid& g, const std::uint8_t* bone);

/// The defaults scale with the skeleton: its size is the cube root of its bone's volume (190 mm for an adult's, 87
/// for the frog's, 3.5 for a mouse-sized one), and the opening, a segment's least volume and the reach are an adult's
/// (4 mm, 1000 mm^3, 20 mm) or these shares of it, whichever is smaller; both shares leave the adult's and the
/// frog's defaults as they were.
inline constexpr double kAdultOpening = 4.0, kAdultMinVolume = 1000.0, kAdultReach = 20.0;
inline constexpr double kOpeningShare = 1.0 / 20, kMinVolumeShare = 1.0 / 600, kReachShare = 1.0 / 4;

/// The options with their defaults filled in for `grid` and a bone of `bone_voxels` voxels (opening in voxels at
/// least 1).
struct BoneParams {
    int erode_steps = 1;
    std::int64_t min_voxels = 8;
    double reach = 20.0;
    /// The skeleton's size against an adult's (at most 1; the frog's is 1): the fitter's windows in mm shrink by it.
    double scale = 1.0;
};
BoneParams bone_params(const Grid& grid, const BoneRigOptions& opt, std::size_t bone_voxels);

/// bone_segments of the bone voxels `voxels` (bone_voxels).
BoneSegments segments_of(const Grid& grid, const std::vector<std::int64_t>& voxels, const BoneParams& p);

/// Bone voxels of a segment near a point: world positions, and whether each lies on the segment's surface (a
/// 6-neighbour outside the segment).
struct Patch {
    std::vector<P3> pos;
    std::vector<std::uint8_t> surface;
    std::vector<std::int64_t> index;  ///< linear voxel index
};

/// The voxels of segment `s` within `radius` (mm) of `centre`.
Patch patch_of(const Grid& grid, const std::vector<std::int32_t>& labels, std::int32_t s, const P3& centre,
               double radius);

/// The contact between two patches of `grid`: the surface voxels of each within `tolerance` of the closest
/// distance between them (searched up to `reach`); found = false when they lie farther apart.
struct Contact {
    bool found = false;
    double gap = 0;                  ///< closest distance between surface voxel centres (mm)
    std::vector<P3> a, b;            ///< the contact voxels of each side
    P3 centre{0, 0, 0};              ///< midpoint of the two sides' centroids
};
Contact contact_of(const Grid& grid, const Patch& a, const Patch& b, double reach, double tolerance);

/// Least-squares sphere through points: centre and radius; radius <= 0 when the fit is degenerate.
struct Sphere {
    P3 centre{0, 0, 0};
    double radius = 0;
};
Sphere fit_sphere(const std::vector<P3>& pts);

/// The narrowest section of a patch along `axis` (unit) through `centre`, within a cylinder of radius and half
/// length `half_length`: the deepest valley of its slab profile (slabs `slab` thick, the wall on each side the
/// most bone there) and its centroid; found = false when the profile has no valley.
struct Section {
    bool found = false;
    P3 centre{0, 0, 0};
    bool bulge = false;  ///< limb_section: the bulge, no valley
    double share = 0;    ///< narrowest_section: the valley's depth over its lower wall
};
Section narrowest_section(const Patch& p, const P3& centre, const P3& axis, double half_length, double slab);

/// A bone fused on to the end of a segment (a talus and calcaneus joined to the tibia on slices 8 mm apart, the
/// contact found then the next joint down): the deepest valley of the patch's slab profile along `axis` (unit,
/// pointing away from the segment's body) between `back` behind `at` and `ahead` beyond it, within `radius` of the
/// axis, when it lies behind `at` and is at least `least` of its lower wall; its centroid. found = false otherwise.
Section fused_end(const Patch& p, const P3& at, const P3& axis, double radius, double back, double ahead, double slab,
                  double least);

/// A limb as the outer shape guessed it: from the parent bone's head a through the guessed joint k to the child
/// bone's tail b; its joint is searched between the shares `from` and `to` of its length from a.
struct Limb {
    P3 a, k, b;
    double from, to;
};

/// Where a long hinge lies along a limb (between its shares; arc length from a; voxels within `radius` of it): the
/// deepest valley of its slab profile when it is at least kLimbValley of its lower wall (a joint space the slices
/// show), else the bulge: the centroid of the run of slabs around the widest holding at least kLimbBulge of its
/// bone (the joint's wide ends fused at the voxel size). found = false for too short a limb or no bone.
inline constexpr double kLimbValley = 0.25, kLimbBulge = 0.7;
Section limb_section(const Patch& p, const Limb& limb, double radius, double slab);

/// The centre of the thickest bone of segment `s` within `radius` of `centre`: the centroid of the voxels whose
/// distance to the segment's surface lies within a voxel of the largest (a head's centre, where no gap shows it).
/// Nothing when the segment has no voxel there.
std::optional<P3> thickest_point(const Grid& grid, const std::vector<std::int32_t>& labels, std::int32_t s,
                                 const P3& centre, double radius);

/// The points' centroid (into `centre`) and principal axis (unit: the direction of their largest spread).
P3 principal_axis(const std::vector<P3>& pts, P3& centre);

/// A segment's (its voxels' linear indices) two ends along its principal axis (the centroids of its voxels within
/// a few percent of its length of either extreme) and its centroid; found = false for an empty segment.
struct SegmentEnds {
    bool found = false;
    P3 a{0, 0, 0}, b{0, 0, 0}, centroid{0, 0, 0};
};
SegmentEnds segment_ends(const Grid& grid, const std::vector<std::int64_t>& voxels);

/// A bone mask on slices far apart, interpolated between them (shape-based interpolation: each slice's signed
/// distance to its outline, in mm, blended linearly along the slices' normal; bone where the blend is inside).
/// Its slices `factor` times as close as the grid's (the coarsest spacing over the finer in-plane one, rounded
/// down), on the bone's box grown by a voxel (`lo`: the box's voxel (0, 0, 0) in the grid; every factor-th slice
/// along `axis` is one of the grid's, its own bone). rig_to_bones fits on it: the opening and the contacts'
/// tolerances then hold the same millimetres along the slices as across them, whether a slice falls on a joint or
/// 8 mm off it (on the 8 mm grid itself a 6-neighbour erosion step is 8 mm along the slices' normal: the 4 mm
/// opening ate 16 mm of bone along it, more than a horizontal humerus' half-thickness).
struct Refined {
    Grid grid;
    int axis = 2;
    int factor = 1;
    std::array<std::int64_t, 3> lo{};
    std::vector<std::uint8_t> bone;
};
/// Nothing when the grid's slices are less than twice as far apart as its in-plane spacing (the frog's 1.5 mm
/// slices over 1 mm pixels keep their grid).
std::optional<Refined> refine_slices(const Grid& g, const std::uint8_t* bone);
/// Segments on the refined grid back on the grid `g` it was made from (its own slices'; sizes recounted).
BoneSegments on_slices(const Refined& r, const Grid& g, const BoneSegments& fine);

/// World position of a voxel index (origin + spacing * ijk, as bind and autorig place points).
P3 voxel_position(const Grid& grid, std::int64_t index);

}  // namespace volrig::rig_detail

// deform/bend.hpp: volume kept at bends in the smooth modes (issue 18; docs/ALGORITHMS.md §7, "Volume at bends").
// Per frame, each blend group (a slab of the limb across a joint: spheres sharing one blended transform) gets a
// radius factor from a bent-tube model. Near a joint the limb is a stack of slabs, each a disc of the limb's radius R
// (the largest of its side's groups') perpendicular to its side's limb axis t (the rest gradient of the blend weight
// over that side's spheres), moved by the group's blended transform. Per unit of rest length the tube holds (the
// slabs' spacing along the posed axis) x (the disc's area on its own side of the bend's bisector plane): the part
// past that plane lies in the other limb's tissue (exactly so for two rigid tube halves), and the spacing is the
// blend's own stretch or squeeze. The factor g scales the disc so that this equals the rest area:
//     stretch · (π g²R² − segment(h, gR)) = πR²,
// h the distance in the disc from its centre to the bisector plane (the plane mirroring the two arms onto each other,
// through the joint's centre). The bisector term applies to slabs within two limb radii of the joint's centre that
// lie wholly on their own side at rest (a limb straight at the joint); other slabs (shoulders, hips, limbs bent at
// rest) keep only the stretch term. Groups blending three or more bones (junctions) and weight-1 spheres never
// change.
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <vector>

#include "deform/common.hpp"
#include "deform/motion.hpp"
#include "deform/spheres.hpp"

namespace volrig::deform_detail {

/// What the bend model keeps of one blend group (per rig).
struct BendGroup {
    std::int32_t a = -1, b = -1;  ///< the group's two heaviest bones (a < b); a = -1: no model (factor 1)
    double w = 0;                 ///< the weight on b of the two, w_b / (w_a + w_b)
    double radius = 0;            ///< the group's largest radius: the tube's at its slab
    std::size_t pair = 0;         ///< index of (a, b) in BendModel::gradient
    bool junction = false;        ///< weights on more than two bones: no model (factor 1)
};

/// The bend model of a rig's blend groups, built with the fields (per rig).
struct BendModel {
    std::vector<BendGroup> groups;
    /// Per bone pair, per side (a: w <= 1/2, b: w >= 1/2): the rest-space (world) gradient of w, least squares over
    /// that side's blended sphere centres. Its direction is the side's limb axis at the joint (zero when the
    /// spheres do not determine it).
    std::vector<std::array<Eigen::Vector3d, 2>> gradient;
    /// Per bone pair, per side: the limb's radius there, the largest of the side's groups'.
    std::vector<std::array<double, 2>> radius;
    /// Per bone pair: the joint's centre by the weights (world, rest): the mean centre of the blended spheres within
    /// 1/16 of w = ½. The bisector plane passes through it, posed by the half-way blend.
    std::vector<Eigen::Vector3d> centre;
};

BendModel bend_model(const BoundSpheres& s, const SmoothGroups& groups, const std::vector<double>& radii,
                     const Grid& g);

/// A slab's radius factor stays within [kMinBend, kMaxBend]: past +40% the few balls of a slab (at a coarse point
/// count) stand out of the limb as fins rather than swelling it (the bend test's cylinder never needs more).
constexpr double kMinBend = 0.5, kMaxBend = 1.4;

/// Per group, the radius factor (in [kMinBend, kMaxBend]) that keeps its slab's volume in this pose. `bones`: the
/// frame's bone motions.
std::vector<double> bend_factors(const BendModel& m, const SmoothGroups& groups, const std::vector<Motion>& bones,
                                 DeformMode mode);

/// The reference's way (the Deformer sets its blend fields' radii instead): each blended sphere's radius in `radii`
/// (radius_scale'd) times its group's factor in this pose.
void bend_radii(const BoundSpheres& s, const SmoothGroups& groups, const std::vector<Motion>& bones, DeformMode mode,
                const Grid& g, std::vector<double>& radii);
/// The same with the bend model built already (from these radii).
void bend_radii(const BendModel& m, const BoundSpheres& s, const SmoothGroups& groups,
                const std::vector<Motion>& bones, DeformMode mode, std::vector<double>& radii);

/// A blended sphere's radius in a frame: its (radius_scale'd) radius times its group's factor. The one expression
/// the Deformer and the reference both use.
inline double bent_radius(double r, double factor) { return r * factor; }

// ---- sliding contact -----------------------------------------------------------------------------------------
// Where the two limbs of a bent joint meet, each yields to the other past the bend's bisector plane: within a zone
// round the joint, a voxel past the plane taken by a limb's own spheres (its bone's, and the blend groups whose
// slabs the bend model cuts off at the plane) goes to any other field that covers it. The proximity key becomes
// (yields, power): the radical planes of the limbs' balls no longer decide where one ends and the other begins, the
// bisector does, and the part of a limb past it is the other limb's tissue (as the bend model counts it, growing
// the slabs to keep their volume). Where nothing else covers, a limb keeps its own voxels (no hole opens). The zone
// grows with the bend from nothing at rest (contact_of), so that rest frames and twists are untouched.

/// One contact plane of a field in a pose, in index space of the source lattice.
struct Contact {
    double joint[3];   ///< the joint's posed centre
    double normal[3];  ///< the plane's world normal times the spacing, towards the side the field yields on
    double reach2;     ///< the zone: squared world distance from the joint
};
/// Per field (the bones' first, then the blend groups'), its contact planes in this pose.
using FieldContacts = std::vector<std::vector<Contact>>;

/// The contact planes of this pose (keep_volume, smooth modes): for each bone pair whose limb is straight at rest
/// and bent in the pose, both bones' fields and the groups cut off at the bisector (none at rest). Per field:
/// bone_count + the groups.
FieldContacts contacts(const BendModel& m, const SmoothGroups& groups, const std::vector<Motion>& bones,
                       DeformMode mode, std::size_t bone_count, const Grid& g);

/// Whether a field with these planes yields at output lattice point q (absolute index): past one of them, within
/// its zone. The one expression the Deformer and the reference both use.
inline bool yields(const std::vector<Contact>& planes, const std::int64_t* q, const double* s2) {
    for (const Contact& c : planes) {
        const double d[3] = {static_cast<double>(q[0]) - c.joint[0], static_cast<double>(q[1]) - c.joint[1],
                             static_cast<double>(q[2]) - c.joint[2]};
        if (c.normal[0] * d[0] + c.normal[1] * d[1] + c.normal[2] * d[2] > 0 && length2(d[0], d[1], d[2], s2) < c.reach2)
            return true;
    }
    return false;
}

/// The unit disc's area beyond a chord at signed distance y from its centre (0 for y >= 1, π for y <= -1).
double disc_segment(double y);
/// The factor g in [kMinBend, kMaxBend] solving stretch · g² (π − disc_segment(x / g)) = π (x: the bisector's
/// distance from the disc's centre in radii, inf when it does not cut it); exactly 1 when the slab neither stretches
/// nor crosses the bisector.
double slab_factor(double x, double stretch);

}  // namespace volrig::deform_detail

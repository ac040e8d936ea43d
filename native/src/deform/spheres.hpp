// deform/spheres.hpp: the deformation's inputs: the source's samples and the bound spheres checked, scaled radii, and the
// smooth-mode groups (spheres whose rounded weights agree share one blended transform, so that smooth modes use
// the per-bone machinery).
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <vector>

#include "deform/motion.hpp"
#include "volrig/deform.hpp"

namespace volrig::deform_detail {

/// An owned copy of bound spheres (BoundSpheres only views them): what the Deformer and the Collider keep.
struct SphereStore {
    std::size_t n = 0, bone_count = 0;
    std::vector<std::int32_t> ijk, bone, weight_bones;
    std::vector<float> radius, weights;
    std::vector<std::int64_t> weight_offsets;
    bool has_weights = false;

    void assign(const BoundSpheres& s);       ///< copies everything
    void set_binding(const BoundSpheres& s);  ///< copies the bones and weights only (a rebind)
    BoundSpheres view() const;
    std::size_t memory_bytes() const;
};

/// Throws when a floating-point source holds a NaN or an infinite sample (`who` names the caller).
void check_source(const VolumeView& v, const char* who);
/// Throws unless the spheres fit the grid: centres inside, radii finite and >= 0, bones and weights valid.
void check_spheres(const Grid& g, const BoundSpheres& s);
/// Throws unless the options fit n spheres (radius_scale: empty or n factors in [0, 100]).
void check_options(const DeformOptions& o, std::size_t n);
/// Each sphere's radius times its radius_scale.
std::vector<double> scaled_radii(const BoundSpheres& s, const DeformOptions& o);

/// A sphere's smooth weights rounded to kWeightSteps-ths of their sum (spheres whose rounded weights agree share one
/// blended transform, which is what lets smooth modes use the per-bone machinery).
Weights quantized_weights(const BoundSpheres& s, std::size_t i);

/// Smooth-mode groups: spheres whose rounded weights and owner agree share one blended transform (for linear
/// blending, made rigid about the group's centroid).
struct SmoothGroups {
    std::vector<std::int32_t> group_of;  ///< per sphere: its group, or -1 when one bone moves it
    std::vector<std::int32_t> bone_of;   ///< per sphere: that bone (when group_of is -1)
    std::vector<Weights> weights;
    std::vector<std::int32_t> owner;
    std::vector<Eigen::Vector3d> pivot;  ///< world centroid of each group's centres
};

SmoothGroups smooth_groups(const BoundSpheres& s, const Grid& g);

}  // namespace volrig::deform_detail

// volrig/collide.hpp: collision detection between animated volumes, and a body against itself (docs/ALGORITHMS.md
// §8), without reconstructing either frame.
//
// A rigged volume's deformed reconstruction is the union of its moved reconstruction balls (volrig/deform.hpp:
// open balls |q − Tᵢcᵢ| < rᵢ, Tᵢ the sphere's bone transform or, in smooth modes, its blended transform). The answer
// is exact on A's lattice: a contact voxel is a lattice point q of A's source lattice that lies inside a moved ball
// of A (so it belongs to A's deformed frame, voxel for voxel as Deformer::frame gives it) and inside a moved ball of
// B. When A and B share a grid this is the intersection of the two deformed frames, voxel for voxel.
//
// Hierarchy. The thesis grows the reconstruction spheres of a few thinness levels into bounding spheres linked by
// intersection; those bounds hold only while the bones they straddle keep their rest relation. volrig instead
// builds, once per rig, one ball tree per *field* (the spheres one bone moves rigidly, or one smooth-mode group of
// spheres sharing a blended transform): a binary tree of bounding spheres over the field's balls in rest space. A
// field moves rigidly, so its tree stays a bound under any pose without rebuilding. Per test: the fields' posed root
// spheres are paired by a sweep along x, each overlapping pair of fields is descended as a dual tree in the first
// field's rest frame, and only the lattice points in the boxes of intersecting ball pairs are decided exactly.
//
// Self-contact counts lattice points inside two moved balls of one body whose bones lie at least
// `min_bone_distance` bones apart in the rig's tree (2: not parent and child) and, with `ignore_rest_contact`,
// are not joined at rest: two bones whose balls already intersect in the rest pose are one piece of tissue (the
// trunk's bones and the thighs around the hips, the shoulders), whose overlap when the joint between them bends is
// the joint's own compression, not one part passing through another. A hand that does not touch the thigh at rest
// and is swung through it is a contact.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "volrig/deform.hpp"

namespace volrig {

/// How a test moves one body's spheres: the deformation mode (smooth modes need the binding's weights) and the
/// bulge/pinch factors (empty, or one per sphere), as in DeformOptions.
struct CollideOptions {
    DeformMode mode = DeformMode::Rigid;
    std::vector<float> radius_scale;
    bool keep_volume = true;  ///< smooth modes: the blend groups' radii follow the pose, as DeformOptions::keep_volume
};

struct CollideStats {
    std::int64_t field_pairs = 0;   ///< pairs of fields whose posed bounding spheres overlap
    std::int64_t node_pairs = 0;    ///< ball-tree node pairs tested
    std::int64_t sphere_pairs = 0;  ///< pairs of reconstruction balls that intersect (their lattice points decided)
    std::int64_t lattice_tests = 0; ///< lattice points decided one by one (the ends of rows through a ball)
};

/// The answer of one test. Bones are indices into the rigs' bone lists.
struct Collision {
    bool hit = false;             ///< voxels > 0
    std::int64_t voxels = 0;      ///< contact voxels: A's lattice points inside both deformed volumes
    std::vector<std::int32_t> bones_a, bones_b;  ///< sorted bones whose balls hold a contact voxel
    /// (bone of A, bone of B) for every pair of balls sharing a contact voxel, sorted, unique. For self-contact
    /// each pair is listed once, lower bone first.
    std::vector<std::pair<std::int32_t, std::int32_t>> bone_pairs;
    /// World bounding box of the contact voxels' centres: min x, y, z, max x, y, z (zeros when there is none).
    std::array<double, 6> box{0, 0, 0, 0, 0, 0};
    /// The contact voxels as lattice indices (x, y, z) of A's grid, sorted by z, y, x; only when asked for.
    std::vector<std::array<std::int64_t, 3>> points;
    CollideStats stats;
};

/// Per-rig data for collision tests: a copy of the bound spheres and one ball tree per field (built once; a test
/// only moves them). `grid` is the source grid the spheres' centres index (its dims bound the centres);
/// `parents` gives the rig's tree for self-contact (one entry per bone, -1 for roots; may be empty when only
/// two-body tests are wanted).
class Collider {
public:
    Collider(const Grid& grid, const BoundSpheres& spheres, std::vector<std::int32_t> parents = {});
    ~Collider();
    Collider(Collider&&) noexcept;
    Collider& operator=(Collider&&) noexcept;

    std::size_t bone_count() const;
    std::size_t sphere_count() const;
    std::size_t field_count(DeformMode mode) const;
    std::size_t memory_bytes() const;

    struct Impl;
    const Impl& impl() const { return *impl_; }

private:
    std::unique_ptr<Impl> impl_;
};

/// Contact between two posed bodies (rest-to-pose matrices as in Deformer::frame, one per bone of each rig).
/// `keep_points`: also list the contact voxels (Collision::points).
Collision collide(const Collider& a, BoneMatrices matrices_a, const CollideOptions& options_a, const Collider& b,
                  BoneMatrices matrices_b, const CollideOptions& options_b, bool keep_points = false);

/// Contact of a posed body with itself (see the header comment for which ball pairs count); min_bone_distance
/// must be at least 1.
Collision self_collide(const Collider& a, BoneMatrices matrices, const CollideOptions& options,
                       int min_bone_distance = 2, bool ignore_rest_contact = true, bool keep_points = false);

/// Brute force for tests: every lattice point of the posed bounding box against every moved ball (points always
/// listed).
Collision collide_reference(const Collider& a, BoneMatrices matrices_a, const CollideOptions& options_a,
                            const Collider& b, BoneMatrices matrices_b, const CollideOptions& options_b);
Collision self_collide_reference(const Collider& a, BoneMatrices matrices, const CollideOptions& options,
                                 int min_bone_distance = 2, bool ignore_rest_contact = true);

/// Bone distances in the rig's tree (bones to climb and descend from one to the other; unrelated roots are
/// infinitely far apart: INT32_MAX). Row-major bone_count x bone_count.
std::vector<std::int32_t> bone_distances(const std::vector<std::int32_t>& parents);

}  // namespace volrig

// collide/posed.hpp: the Collider's per-rig data (spheres, fields, ball trees) and one body's pose for one test
// (each field's motion, the scaled radii), shared by the fast path and the brute-force reference.
#pragma once

#include <cstdint>
#include <vector>

#include "collide/ball_tree.hpp"
#include "deform/motion.hpp"
#include "deform/spheres.hpp"
#include "volrig/collide.hpp"

namespace volrig::collide_detail {

using deform_detail::Motion;

/// A set of spheres sharing one transform: a bone's (group < 0) or a smooth-mode group's.
struct Field {
    std::int32_t bone = -1;   ///< the bone that moves it (group < 0)
    std::int32_t group = -1;  ///< the smooth group (SmoothGroups index)
    std::int32_t owner = -1;  ///< the owning bone of all its spheres (-1: they differ)
    BallTree tree;
};

/// The fields of one way of moving the spheres (rigid: by owning bone; smooth: by blend group).
struct Partition {
    deform_detail::SmoothGroups groups;  ///< smooth partitions only
    std::vector<Field> fields;
    std::vector<std::int32_t> field_of;  ///< per sphere
};

}  // namespace volrig::collide_detail

namespace volrig {

struct Collider::Impl : deform_detail::SphereStore {
    Grid grid;
    std::vector<std::int32_t> parents, distance;  ///< the rig's tree and its bone distances (empty without parents)
    std::vector<std::uint8_t> joined;  ///< bone pairs whose balls intersect at rest (bone_count x bone_count)
    std::vector<collide_detail::Vec3> rest_world, rest_index;  ///< per sphere (x, y, z)
    collide_detail::Partition rigid, smooth;

    bool joined_bones(std::int32_t x, std::int32_t y) const {
        return joined[static_cast<std::size_t>(x) * bone_count + static_cast<std::size_t>(y)] != 0;
    }
    const collide_detail::Partition& partition(DeformMode mode) const {
        return mode != DeformMode::Rigid && has_weights ? smooth : rigid;
    }
};

}  // namespace volrig

namespace volrig::collide_detail {

/// One body in one test: the motion of each field and each sphere's radius.
struct Posed {
    const Collider::Impl* c = nullptr;
    const Partition* part = nullptr;
    std::vector<Motion> motion;   ///< per field
    std::vector<double> radius;   ///< per sphere, scaled
    double scale = 1.0;           ///< the largest radius_scale factor (1 without scaling)
    double s2[3] = {1, 1, 1};     ///< squared spacing

    const Motion& of(std::uint32_t sphere) const {
        return motion[static_cast<std::size_t>(part->field_of[sphere])];
    }
    std::int32_t owner(std::uint32_t sphere) const { return c->bone[sphere]; }
    /// World position of a rest world point moved by field f.
    Vec3 posed(std::size_t f, const Vec3& p) const;
    /// Whether lattice point q of this body's lattice lies inside sphere i's moved open ball: the very test
    /// deform_reference makes.
    bool covers(std::uint32_t i, const std::int64_t* q) const;
};

Posed pose(const Collider::Impl& c, BoneMatrices matrices, const CollideOptions& o);

/// Throws unless a self-contact test can run: min_bone_distance >= 1 and the rig's parents known.
void check_self_options(const Collider& a, int min_bone_distance);

/// Whether two grids put lattice points at the same places (then B's test of A's lattice point is B's own).
bool same_lattice(const Grid& a, const Grid& b);

/// Whether A's lattice point q (index space of A) lies inside B's moved ball j: B's own test when the lattices
/// agree, otherwise a world distance.
bool covers_from(const Posed& a, const Posed& b, std::uint32_t j, const std::int64_t* q, bool same);

/// Whether spheres i and j of one body may form a self-contact: their bones at least min_bone_distance apart and,
/// with ignore_rest_contact, not joined at rest.
bool eligible(const Posed& p, std::uint32_t i, std::uint32_t j, int min_bone_distance, bool ignore_rest_contact);

/// The lattice box {lo x, y, z, hi x, y, z} (inclusive) of body p's moved ball i, on lattice `g` (posed world
/// centre `w`).
std::array<std::int64_t, 6> ball_box(const Grid& g, const Vec3& w, double r);

}  // namespace volrig::collide_detail

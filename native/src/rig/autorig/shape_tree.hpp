// rig/autorig/shape_tree.hpp: autorig's first stage, from skeleton points and their tree to the level-set tree that
// carries the shape (internal to the core; tested alone in tests/native/test_rig_autorig.cpp).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include "volrig/tree.hpp"

namespace volrig::rig_detail {

using Vec = Eigen::Vector3d;
constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

/// v without its component along the unit vector `axis`.
inline Vec perp(const Vec& v, const Vec& axis) { return v - v.dot(axis) * axis; }

/// Scale-axis filter (after Giesen et al.'s scale axis transform): 1 for the points kept, 0 for those whose ball
/// lies inside the ball, scaled by kScaleAxis, of a point at least twice as large. Near-surface points of a noisy
/// boundary lie inside their limb's axis balls and go; axes and genuine sheets stay.
constexpr double kScaleAxis = 1.25;
std::vector<std::uint8_t> scale_axis(const Grid& g, const PointSet& pts);

/// The level-set tree of one part of the skeleton: points binned by geodesic distance from the part's
/// largest-radius points (over a neighbour graph), each bin split into connected pieces; a piece is a node
/// (centroid, largest radius, representative point nearest the centroid) and pieces joined by graph edges are
/// linked, then reduced to a spanning tree by centroid distance. Unlike paths in a minimum spanning tree, which
/// wander inside a skeleton several voxels thick, the nodes follow the middle of each branch. Node sizes follow the
/// band, not the point count: the same object gives about the same nodes however many points are kept.
struct LevelSetTree {
    std::vector<Vec> centroid;
    std::vector<double> radius;
    std::vector<std::uint32_t> rep;
    std::vector<std::array<std::uint32_t, 2>> edges;
    std::vector<std::uint32_t> node_of_point;  // kNone outside the part
};

/// The strength below which a link between level pieces counts as weakest (level_set_tree).
constexpr double kWeakestLink = 0.05;

/// Radii this close (relative) to the largest count as the largest: level_set_tree measures its levels from all.
constexpr double kTiedRadius = 1e-5;

/// The level-set tree of the points with in_part[i] != 0, levels `band` (world units) apart.
LevelSetTree level_set_tree(const Grid& g, const PointSet& pts, const SkeletonGraph& graph,
                            const std::vector<std::uint8_t>& in_part, double band);

/// The whole first stage: the scale axis of `pts`, joined by the tree's edges among its points, by contained cone
/// edges reaching across each point's ball and by bridges between fragments (up to 8 default edges); the connected
/// part with the largest ball volume; its level-set tree with bands of a fifth of its median radius (at least a
/// voxel diagonal). Representative points and node_of_point refer to `pts`.
LevelSetTree shape_tree(const Grid& g, const std::uint8_t* mask, const PointSet& pts,
                        const std::vector<std::array<std::uint32_t, 2>>& tree_edges, const Progress& progress);

}  // namespace volrig::rig_detail

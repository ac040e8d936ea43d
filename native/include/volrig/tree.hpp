// volrig/tree.hpp: the skeleton-tree (docs/ALGORITHMS.md §5).
//
// Skeleton points are connected by edges that stay inside the object: an edge i-j exists only when every voxel of
// the discrete 3D line from i to j is an object voxel and |i - j| <= E (the maximum edge length). Each edge weighs
// w = alpha * |i - j| + (1 - alpha) * |r_i - r_j| (r = sphere radius); the skeleton-tree is the minimum spanning
// forest of that graph. Disjoint parts may be bridged (an MST over the components that ignores containment).
//
// Not all pairs within E are tested: around each point the nearest contained neighbour in each of 26 direction
// cones (the Yao graph of the 26 voxel directions) is kept, which keeps every short connection a spanning tree
// needs (each cone's nearest neighbour is what an MST would use) while testing a few lines per point. A spatial
// grid finds the candidates.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

/// Skeleton points on a mask's grid (non-owning). Every point must be an object voxel of the mask.
struct PointSet {
    const std::int32_t* ijk = nullptr;  ///< n x 3 voxel indices [z, y, x]
    const float* radius = nullptr;      ///< n sphere radii, world units
    std::size_t n = 0;
};

/// Checks a point set against its mask (indices inside the grid and on object voxels, radii finite and >= 0);
/// throws Error naming the first bad point and `what`.
void check_points(const Grid& grid, const std::uint8_t* mask, const PointSet& pts, const char* what);

/// World position (x, y, z) of point i.
std::array<double, 3> point_position(const Grid& grid, const PointSet& pts, std::size_t i);

/// True when every voxel of the discrete 3D line (Bresenham) from voxel a to voxel b ([z, y, x]) is inside the
/// grid and non-zero in `mask`.
bool line_inside(const Grid& grid, const std::uint8_t* mask, const std::int32_t* a, const std::int32_t* b);

/// The default maximum edge length: 4 voxel diagonals of the grid (world units).
double default_max_edge(const Grid& grid);

/// An undirected graph over the points in compressed rows: the neighbours of i are
/// targets[offsets[i] .. offsets[i + 1]), with Euclidean lengths (world units) alongside.
struct SkeletonGraph {
    std::vector<std::uint32_t> offsets;  ///< n + 1
    std::vector<std::uint32_t> targets;
    std::vector<float> lengths;
    std::size_t edge_count() const { return targets.size() / 2; }
};

/// The contained 26-cone neighbour graph (see the header comment). max_edge 0 selects default_max_edge; a negative one is refused.
SkeletonGraph skeleton_graph(const Grid& grid, const std::uint8_t* mask, const PointSet& pts, double max_edge,
                             const Progress& progress = {});

/// The graph with the given undirected edges (i < j) over the points, lengths = world distances.
SkeletonGraph graph_of_edges(const Grid& grid, const PointSet& pts,
                             const std::vector<std::array<std::uint32_t, 2>>& edges);

/// Multi-source Dijkstra: the sources are the points whose dist is finite on entry; on return dist holds the
/// shortest path length from any source. With `label`, each point takes the label of its nearest source; with
/// `allowed`, paths only pass through points whose flag is non-zero.
void shortest_paths(const SkeletonGraph& graph, std::vector<double>& dist, std::vector<std::int32_t>* label = nullptr,
                    const std::vector<std::uint8_t>* allowed = nullptr);

struct TreeOptions {
    double alpha = 0.9;     ///< connectivity parameter, 0..1
    double max_edge = 0.0;  ///< E in world units; 0 selects default_max_edge, < 0 is refused
    bool bridge = false;    ///< join the components of the forest by their closest point pairs
};

struct SkeletonTree {
    std::vector<std::array<std::uint32_t, 2>> edges;  ///< (i, j), i < j, in the order Kruskal accepted them
    std::vector<double> weights;                      ///< per edge
    std::vector<std::uint8_t> bridged;                ///< per edge: 1 when added by bridging (may leave the object)
    std::vector<std::uint32_t> component;             ///< per point: component id, 0 = most points
    std::size_t component_count = 0;                  ///< after bridging: 1 (for n > 0)
    double max_edge = 0.0;                            ///< E actually used
};

/// Minimum spanning forest of the contained graph with weights alpha*dist + (1-alpha)*|dr|.
SkeletonTree skeleton_tree(const Grid& grid, const std::uint8_t* mask, const PointSet& pts, const TreeOptions& opt,
                           const Progress& progress = {});

/// The undirected cone edges (i < j, sorted, unique) behind skeleton_graph. With `ball_rule` (radii required) a
/// point searches up to max(e, min(its radius, 3 e)): its own ball lies inside the object, so a sparse axis of
/// large balls stays connected; lines inside the ball need no test. Progress is reported from p0 to p1.
std::vector<std::array<std::uint32_t, 2>> cone_edges(const Grid& grid, const std::uint8_t* mask, const PointSet& pts,
                                                     double e, bool ball_rule, const Progress& progress, double p0,
                                                     double p1);

/// Edges that join the components of the graph `edges` over the points: Boruvka rounds in which every component
/// but the one with most points adds its closest pair (i, j) to another component, with |i - j| <= max_dist and,
/// when `mask` is given, the line i-j inside the object (the nearest 64 candidates of each point are tested).
/// Stops when one component is left or none can join. `cell_size` (world units) sizes the search grid.
std::vector<std::array<std::uint32_t, 2>> bridge_components(const Grid& grid, const std::uint8_t* mask,
                                                            const PointSet& pts,
                                                            const std::vector<std::array<std::uint32_t, 2>>& edges,
                                                            double max_dist, double cell_size);

/// Components of a forest given by its edges over n points, numbered by descending size (ties: smallest point).
std::vector<std::uint32_t> forest_components(std::size_t n, const std::vector<std::array<std::uint32_t, 2>>& edges,
                                             std::size_t* count = nullptr);

}  // namespace volrig

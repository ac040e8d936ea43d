// volrig/medial_surface.hpp: the medial surface of plates as a mesh, the rods as polylines, and the homotopic
// voxel skeleton they come from (docs/ALGORITHMS.md §11, issue 22).
//
// From the plane-like measure per lattice edge (medial.hpp, plane_edges): a lattice edge between two object voxels
// whose nearest boundary voxels lie more than t apart along the boundary crosses the medial surface of a plate.
//
// * Voxel skeleton (medial_skeleton): the object thinned, deleting simple points only (26-connected object,
//   6-connected background) in order of increasing DT, never deleting an anchor: the upper voxel of every plane-like
//   edge (the plane-like set of plane_measure) or a curve end (one 26-neighbour left). Simple deletions keep the
//   object's topology, so plates keep no holes and stay connected; anchors keep the plates' medial surface; ends
//   keep rods. Each kept voxel is classified: Surface (an anchor, or a voxel in a sheet of the skeleton: two lines
//   through it with skeleton voxels at both ends, a membrane kept across a gap of the plane-like set), Curve (the
//   rest: kept for topology or as a rod), Junction (a curve voxel 26-adjacent to a surface voxel: where a rod
//   meets a plate).
// * Mesh (medial_surface): dual contouring of the plane-like edges (surface nets): one vertex per 2x2x2 cell of
//   voxel centres holding a plane-like edge, at the mean of the points of its plane-like edges equidistant from the
//   two nearest boundary voxels (the exact bisector on the edge), and a quad (two triangles, the shorter diagonal)
//   around every plane-like edge. Vertices are shared by construction, each quad is unique; faces are then
//   oriented consistently over edges shared by two faces. Where the plate is a 2-manifold the mesh is one: the
//   plane-like edges separate the voxels nearer one side of the plate from those nearer the other. This replaces the
//   paper's 256-case table on thinned voxels: its vertices sit at voxel centres (a staircase whose area is up to
//   sqrt(3) too large on oblique plates) and its junction cases are open (the paper's "open problem").
// * Thickness: per vertex 2x the distance to the object's boundary: on each plane-like edge, the distances from its
//   bisector point to the two nearest background voxel centres, each less half a voxel along its direction (the
//   boundary lies between the last object and the first background voxel), averaged over the vertex's edges. A plate
//   n voxels thick reads n voxels; 2 DT (to background voxel centres) reads up to one voxel more (thickness.hpp).
// * Rods: the curve and junction voxels of the skeleton, traced between their ends and branch points as polylines of
//   voxel centres, with radii measured as the thickness is (half of it). Spurs (chains of curve voxels from a free
//   end to a branch point or the surface, shorter than t) are pruned from the skeleton first, one simple point at
//   a time; chains shorter than t lying along the surface (all junction voxels) are not reported as rods.
//
// Positions are in the grid frame (origin + spacing * index, as every volrig result; the add-on applies the
// volume's grid-to-world matrix).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

enum class SkeletonClass : std::uint8_t { None = 0, Surface = 1, Curve = 2, Junction = 3 };

/// True when object voxel (x, y, z) of `mask` (26-connected object, 6-connected background; outside the array is
/// background) can be deleted without changing the topology (Bertrand and Malandain's characterisation: one
/// 26-component of the object in its 26-neighbourhood, one 6-component of the background 6-adjacent to it in its
/// 18-neighbourhood).
bool is_simple(const Grid& grid, const std::uint8_t* mask, std::int64_t x, std::int64_t y, std::int64_t z);

/// Same, on a 3x3x3 neighbourhood given as 27 bits (bit (dz+1)*9 + (dy+1)*3 + (dx+1)); the centre bit is ignored.
bool is_simple27(std::uint32_t neighbourhood);

/// The homotopic skeleton of `mask` anchored on `anchors` (one byte per voxel, non-zero = keep), thinned in the
/// order of `dt` (the object's DT): one SkeletonClass per voxel.
std::vector<std::uint8_t> thin_skeleton(const Grid& grid, const std::uint8_t* mask, const std::uint8_t* anchors,
                                        const float* dt, const Progress& progress = {});

/// The homotopic skeleton of `mask` anchored on its plane-like voxels for threshold `t` (world units), spurs not
/// pruned (medial_surface's skeleton has them pruned).
std::vector<std::uint8_t> medial_skeleton(const Grid& grid, const std::uint8_t* mask, double t,
                                          const Progress& progress = {});

struct MedialSurface {
    std::vector<std::array<double, 3>> vertices;         ///< grid frame, world units
    std::vector<std::array<std::int64_t, 3>> faces;      ///< vertex indices
    std::vector<double> thickness;                       ///< per vertex, world units
    std::vector<std::vector<std::array<double, 3>>> rods;  ///< polylines of voxel centres
    std::vector<std::vector<double>> rod_radii;          ///< per rod point, world units
    std::vector<std::uint8_t> skeleton;                  ///< SkeletonClass per voxel
};

/// Medial surface mesh, rods and classified skeleton of `mask` for the plane-like threshold `t` (world units).
MedialSurface medial_surface(const Grid& grid, const std::uint8_t* mask, double t, const Progress& progress = {});

/// Mesh of the plane-like edges alone (see above); `feature` and `edge` as plane_edges gives them.
void mesh_plane_edges(const Grid& grid, const std::vector<std::int64_t>& feature, const std::vector<float>& edge,
                      double t, MedialSurface& out);

/// Euler characteristic V - E + F of a triangle mesh and whether every edge has one or two faces and every
/// vertex a single fan (a 2-manifold, possibly with boundary); `consistent` when shared edges are traversed in
/// opposite directions by their two faces.
struct MeshTopology {
    std::int64_t euler = 0, boundary_edges = 0, nonmanifold_edges = 0, nonmanifold_vertices = 0, components = 0;
    bool consistent = true, duplicate_faces = false, degenerate_faces = false;
    bool manifold() const { return nonmanifold_edges == 0 && nonmanifold_vertices == 0; }
};
MeshTopology mesh_topology(std::size_t vertex_count, const std::vector<std::array<std::int64_t, 3>>& faces);

}  // namespace volrig

// volrig/centerline.hpp: centerlines of tubular objects, centerline trees and straightening (issue 20;
// docs/ALGORITHMS.md §9, §14).
//
// A centerline is the minimal path between two object voxels on the 26-connected voxel graph where a step from a to
// b costs |a - b| * (f(a) + f(b)) / 2 with f = (h / DT)^power (h = the smallest spacing, DT the Euclidean distance
// transform): the discrete form of VMTK's minimal integral of 1/R^power, which keeps the path on the ridge of the DT
// and away from narrow bridges. The voxel path is smoothed (Gaussian along arc length), moved into the centroid of
// its cross-section (the mask resampled trilinearly on the plane normal to the curve, the connected piece around
// the point), smoothed lightly again and resampled at equal arc length; the radius at a sample is the DT there
// (trilinear).
//
// A centerline tree follows TEASAR (Sato et al. 2000): from the root, the farthest voxel (geodesic length) not yet
// covered is joined to the tree by the minimal-cost path above; every voxel within scale * DT + const of the new
// path is covered; until every voxel is. Terminal branches shorter than `prune` local radii (the DT at their
// branch point) are spurs and are removed.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

using Vec3d = std::array<double, 3>;

struct CenterlineOptions {
    double power = 4.0;        ///< cost exponent k in (h / DT)^k; 0 gives plain geodesic paths
    double step = 0.0;         ///< sample spacing along the curve, world units; 0 = the smallest voxel spacing
    double smoothing = 2.0;    ///< Gaussian sigma of the first smoothing, in smallest-spacing units
    int refine = 2;            ///< cross-section centroid iterations (0 = none)
};

struct Centerline {
    std::vector<Vec3d> points;    ///< world (x, y, z), equal arc-length steps
    std::vector<double> radii;    ///< DT (world units) at each point, trilinear
    double length = 0.0;          ///< arc length, world units
    std::vector<std::int64_t> voxels;  ///< the minimal voxel path (linear indices), start to end
};

/// The object's voxels as a graph (compact ids, 26 neighbours inside the grid). Built once per mask.
struct VoxelGraph {
    Grid grid;
    std::vector<std::int64_t> voxel;  ///< id -> linear index
    std::vector<std::int32_t> id;     ///< linear index -> id, -1 for background
    std::vector<float> dt;            ///< per id: DT (world units)
    const float* dense_dt = nullptr;  ///< the DT per voxel it was built from (not owned; must outlive the graph)
    std::size_t size() const { return voxel.size(); }
};

/// Builds the graph of a mask (non-zero = object) with its Euclidean DT (grid.voxel_count() values, world units).
/// Throws Error when the mask is empty or the DT is not finite.
VoxelGraph voxel_graph(const Grid& grid, const std::uint8_t* mask, const float* dt);

/// Dijkstra from `sources` (ids). power < 0: plain lengths; otherwise the centerline cost with that power.
/// `dist` gets +inf where unreachable; `pred` (if given) the predecessor id (-1 at sources and unreachable ids).
/// With a `target` >= 0 the search stops once the target is settled (farther voxels keep partial distances).
void voxel_distances(const VoxelGraph& g, const std::vector<std::int32_t>& sources, double power,
                     std::vector<double>& dist, std::vector<std::int32_t>* pred = nullptr, std::int32_t target = -1);

/// The id of the object voxel nearest the world point p within `max_distance` (world units); throws Error naming
/// `what` when p is not finite, outside the grid by more than max_distance, or no object voxel is that near.
std::int32_t snap_to_object(const VoxelGraph& g, const Vec3d& p, double max_distance, const char* what);

/// The tip of the object farthest (geodesic length) from `from`: the object voxel nearest the centroid of the
/// voxels within one voxel of the greatest distance that are connected to the farthest one (a tube's cap centre,
/// not a rim corner). `dist` = plain distances from `from`.
std::int32_t far_tip(const VoxelGraph& g, const std::vector<double>& dist);

/// Centerline between two world points (null = found automatically: the two ends of the object farthest apart
/// along it, by a double sweep of geodesic distance). Throws Error on an empty mask, endpoints off the object or
/// in different parts of it. `progress` (optional) gets the fraction done after each search and at the end;
/// returning false cancels (throws Cancelled).
Centerline centerline(const VoxelGraph& g, const std::uint8_t* mask, const Vec3d* start, const Vec3d* end,
                      const CenterlineOptions& opt = {}, const Progress& progress = {});

/// What happens to an end of a curve: kept where it is (a branch point), moved into the middle of its cross-section
/// (a point given by the user), or, at a tip of the object, cut back to where the curve is at least a radius from
/// the end and continued straight along its tangent to the object's surface (the centre of a tube's cap, the apex
/// of a rounded end), since the voxel path ends at a far voxel of the cap, not at its centre.
enum class EndMode { Fixed, Free, Tip };

/// A voxel path (ids) turned into a smooth, centred, resampled centerline (see the header comment).
Centerline curve_of_path(const VoxelGraph& g, const std::uint8_t* mask, const std::vector<std::int32_t>& path,
                         const CenterlineOptions& opt, EndMode start, EndMode end);

struct TreeCenterlineOptions {
    CenterlineOptions line;
    double scale = 2.0;   ///< TEASAR covering radius = scale * DT + constant
    double constant = 0.0;  ///< world units; 0 = 2 smallest spacings
    double prune = 3.0;   ///< terminal branches shorter than prune * DT(branch point) are removed
};

struct CenterlineTree {
    std::vector<Centerline> branches;   ///< each from its branch point (or the root) to its end
    std::vector<std::int32_t> parents;  ///< per branch, -1 for the root branch
    std::vector<std::int32_t> generations;  ///< 0 for the root branch
    std::int32_t root = -1;             ///< root voxel id
};

/// TEASAR centerline tree of the part of the object holding the root (world point; null = the end of the thickest
/// terminal branch of a first tree grown from the object's farthest voxel). `progress` (optional) gets the fraction
/// done as the tree covers the object and its branches are made into curves; returning false cancels.
CenterlineTree centerline_tree(const VoxelGraph& g, const std::uint8_t* mask, const Vec3d* root,
                               const TreeCenterlineOptions& opt = {}, const Progress& progress = {});

/// Rotation-minimising frames (double reflection, Wang et al. 2008) along points: per point the unit tangent t,
/// normal u and binormal v = t x u.
void rotation_minimising_frames(const std::vector<Vec3d>& points, std::vector<Vec3d>& t, std::vector<Vec3d>& u,
                                std::vector<Vec3d>& v);

/// Curved planar reformation: out[k][b][a] = volume (trilinear, `fill` outside the grid) at
/// points[k] + (a - m) * step * u[k] + (b - m) * step * v[k], a, b in 0..2m. `values` is a float32 volume on `grid`.
std::vector<float> straighten(const Grid& grid, const float* values, const std::vector<Vec3d>& points,
                              const std::vector<Vec3d>& u, const std::vector<Vec3d>& v, std::int64_t m, double step,
                              float fill);

/// Trilinear sample of a float volume at a world point (`fill` outside the grid's voxel centres' hull).
double trilinear(const Grid& grid, const float* values, const Vec3d& p, double fill);

}  // namespace volrig

// The centerline between two points, or between the object's two ends farthest apart (volrig/centerline.hpp).
#include <algorithm>
#include <cmath>

#include "centerline/detail.hpp"
#include "volrig/centerline.hpp"

namespace volrig {

using namespace centerline_detail;

namespace {

/// The ids from `to` back along pred to the source, returned source first.
std::vector<std::int32_t> trace(const std::vector<std::int32_t>& pred, std::int32_t to) {
    std::vector<std::int32_t> path;
    for (std::int32_t p = to; p >= 0; p = pred[static_cast<std::size_t>(p)]) path.push_back(p);
    std::reverse(path.begin(), path.end());
    return path;
}

void check_options(const CenterlineOptions& opt) {
    if (!std::isfinite(opt.power) || opt.power < 0.0 || opt.power > 16.0)
        throw Error("centerline: power must be 0 to 16, got " + std::to_string(opt.power));
    if (!std::isfinite(opt.step) || opt.step < 0.0) throw Error("centerline: step must be >= 0 and finite");
    if (!std::isfinite(opt.smoothing) || opt.smoothing < 0.0 || opt.smoothing > 100.0)
        throw Error("centerline: smoothing must be 0 to 100 voxels");
    if (opt.refine < 0 || opt.refine > 10) throw Error("centerline: refine must be 0 to 10");
}

}  // namespace

Centerline centerline(const VoxelGraph& g, const std::uint8_t* mask, const Vec3d* start, const Vec3d* end,
                      const CenterlineOptions& opt, const Progress& progress) {
    check_options(opt);
    report(progress, 0.0);
    const double snap = 2.0 * std::max({g.grid.spacing[0], g.grid.spacing[1], g.grid.spacing[2]});
    std::int32_t a = start ? snap_to_object(g, *start, snap, "centerline start") : -1;
    const EndMode ma = start ? EndMode::Free : EndMode::Tip, mb = end ? EndMode::Free : EndMode::Tip;
    std::int32_t b = end ? snap_to_object(g, *end, snap, "centerline end") : -1;
    std::vector<double> dist;
    if (a < 0 || b < 0) {  // double sweep of geodesic length: the object's two ends farthest apart
        const std::int32_t seed = a >= 0 ? a : (b >= 0 ? b : thickest(g));
        voxel_distances(g, {seed}, -1.0, dist);
        report(progress, 0.25);
        const std::int32_t far = far_tip(g, dist);
        if (a < 0 && b < 0) {
            a = far;
            voxel_distances(g, {a}, -1.0, dist);
            report(progress, 0.5);
            b = far_tip(g, dist);
        } else if (a < 0) {
            a = far;
        } else {
            b = far;
        }
    }
    std::vector<std::int32_t> pred;
    voxel_distances(g, {a}, opt.power, dist, &pred, b);
    if (!std::isfinite(dist[static_cast<std::size_t>(b)]))
        throw Error("centerline: start and end lie in different parts of the object (no path inside it joins them)");
    if (a == b) throw Error("centerline: start and end are the same voxel");
    report(progress, 0.75);
    Centerline c = curve_of_path(g, mask, trace(pred, b), opt, ma, mb);
    report(progress, 1.0);
    return c;
}

}  // namespace volrig

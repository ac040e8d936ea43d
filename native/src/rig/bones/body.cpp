// rig/bones/body.cpp: when the flesh is missing (volrig/rig.hpp bare_bone_share, bone_body): how much of a body's
// surface is bare bone, and the bone grown into a body whose shape the body-plan search can read.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "rig/bones/bones.hpp"
#include "volrig/components.hpp"
#include "volrig/distance.hpp"
#include "volrig/error.hpp"

namespace volrig {

namespace {

/// Whether voxel (x, y, z) of `body` lies on its surface: a 6-neighbour outside the body. Voxels on the grid's
/// border count only through their neighbours inside the grid (a body cut by the field of view is not bare there).
bool on_surface(const Grid& g, const std::uint8_t* body, std::int64_t x, std::int64_t y, std::int64_t z) {
    const std::int64_t d[3] = {x, y, z};
    for (int a = 0; a < 3; ++a)
        for (const int s : {-1, 1}) {
            std::int64_t n[3] = {d[0], d[1], d[2]};
            n[a] += s;
            if (n[a] < 0 || n[a] >= g.dims[a]) continue;
            if (!body[g.index(n[0], n[1], n[2])]) return true;
        }
    return false;
}

/// The median of `dt` over the voxels of `mask` (0 for an empty mask).
double median_over(const std::vector<float>& dt, const std::uint8_t* mask) {
    std::vector<float> v;
    for (std::size_t i = 0; i < dt.size(); ++i)
        if (mask[i]) v.push_back(dt[i]);
    if (v.empty()) return 0.0;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
}

/// Per voxel of `grid`: the distance (mm) to the nearest bone voxel where it is at most `reach`, infinity
/// elsewhere. The distance transform runs on the bone's bounding box padded past `reach` (the transform counts
/// the outside of its grid as background: the padding keeps the grid's faces from looking like bone).
std::vector<float> distance_to(const Grid& grid, const std::uint8_t* bone, double reach) {
    std::int64_t lo[3] = {grid.dims[0], grid.dims[1], grid.dims[2]}, hi[3] = {-1, -1, -1};
    for (std::int64_t z = 0; z < grid.dims[2]; ++z)
        for (std::int64_t y = 0; y < grid.dims[1]; ++y)
            for (std::int64_t x = 0; x < grid.dims[0]; ++x)
                if (bone[grid.index(x, y, z)]) {
                    const std::int64_t v[3] = {x, y, z};
                    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], v[a]), hi[a] = std::max(hi[a], v[a]);
                }
    Grid box = grid;
    std::int64_t start[3];
    for (int a = 0; a < 3; ++a) {
        const auto pad = static_cast<std::int64_t>(std::ceil(reach / grid.spacing[a])) + 2;
        start[a] = lo[a] - pad;
        box.dims[a] = hi[a] - lo[a] + 1 + 2 * pad;
    }
    std::vector<std::uint8_t> outside(static_cast<std::size_t>(box.voxel_count()), 1);
    for (std::int64_t z = std::max<std::int64_t>(start[2], 0); z <= hi[2]; ++z)
        for (std::int64_t y = std::max<std::int64_t>(start[1], 0); y <= hi[1]; ++y)
            for (std::int64_t x = std::max<std::int64_t>(start[0], 0); x <= hi[0]; ++x)
                if (bone[grid.index(x, y, z)]) outside[box.index(x - start[0], y - start[1], z - start[2])] = 0;
    const std::vector<float> dt = distance_transform(box, outside.data(), Metric::Euclidean);
    std::vector<float> out(static_cast<std::size_t>(grid.voxel_count()), std::numeric_limits<float>::infinity());
    for (std::int64_t z = 0; z < grid.dims[2]; ++z)
        for (std::int64_t y = 0; y < grid.dims[1]; ++y)
            for (std::int64_t x = 0; x < grid.dims[0]; ++x) {
                const std::int64_t bx = x - start[0], by = y - start[1], bz = z - start[2];
                if (bx < 0 || by < 0 || bz < 0 || bx >= box.dims[0] || by >= box.dims[1] || bz >= box.dims[2]) continue;
                const float d = dt[static_cast<std::size_t>(box.index(bx, by, bz))];
                if (d <= reach) out[static_cast<std::size_t>(grid.index(x, y, z))] = d;
            }
    return out;
}

/// The bone's median depth: its voxels' median distance to the nearest non-bone voxel (or the grid's outside).
double bone_depth(const Grid& grid, const std::uint8_t* bone) {
    return median_over(distance_transform(grid, bone, Metric::Euclidean), bone);
}

}  // namespace

double bare_bone_share(const Grid& grid, const std::uint8_t* body, const std::uint8_t* bone) {
    const std::int64_t nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2];
    using Counts = std::array<std::int64_t, 2>;  // surface voxels, of them bone
    const Counts c = tbb::parallel_reduce(
        tbb::blocked_range<std::int64_t>(0, nz), Counts{0, 0},
        [&](const tbb::blocked_range<std::int64_t>& r, Counts acc) {
            for (std::int64_t z = r.begin(); z != r.end(); ++z)
                for (std::int64_t y = 0; y < ny; ++y)
                    for (std::int64_t x = 0; x < nx; ++x) {
                        const std::int64_t i = grid.index(x, y, z);
                        if (!body[i] || !on_surface(grid, body, x, y, z)) continue;
                        ++acc[0];
                        acc[1] += bone[i] != 0;
                    }
            return acc;
        },
        [](Counts a, const Counts& b) { return Counts{a[0] + b[0], a[1] + b[1]}; });
    return c[0] > 0 ? static_cast<double>(c[1]) / static_cast<double>(c[0]) : 0.0;
}

BoneBody bone_body(const Grid& grid, const std::uint8_t* bone) {
    const std::size_t n = static_cast<std::size_t>(grid.voxel_count());
    std::int64_t bone_voxels = 0;
    for (std::size_t i = 0; i < n; ++i) bone_voxels += bone[i] != 0;
    if (bone_voxels == 0) throw Error("bone body: the bone mask is empty");
    // The bone's own depth (median distance of its voxels to its surface) sets the first radius.
    const double first = std::max(2.0 * bone_depth(grid, bone),
                                  kBoneBodyMinVoxels * std::max({grid.spacing[0], grid.spacing[1], grid.spacing[2]}));
    const std::vector<float> to_bone = distance_to(grid, bone, first * std::pow(kBoneBodyGrowth, kBoneBodySteps - 1));
    BoneBody out;
    double radius = first;
    std::vector<std::uint8_t> grown(n);
    for (int k = 0; k < kBoneBodySteps; ++k, radius *= kBoneBodyGrowth) {
        for (std::size_t i = 0; i < n; ++i) grown[i] = (bone[i] || to_bone[i] <= radius) ? 1 : 0;
        Components c = label_components(grid, grown.data());
        std::int64_t held = 0;  // bone voxels in the largest component
        for (std::size_t i = 0; i < n; ++i) held += bone[i] && c.labels[i] == 1;
        out.radius = radius;
        out.joined = static_cast<double>(held) / static_cast<double>(bone_voxels);
        out.mask.assign(n, 0);
        for (std::size_t i = 0; i < n; ++i) out.mask[i] = c.labels[i] == 1;
        if (out.joined >= kBoneBodyJoined) break;
    }
    return out;
}

}  // namespace volrig

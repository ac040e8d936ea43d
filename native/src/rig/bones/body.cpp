// rig/bones/body.cpp: when the flesh is missing (volrig/rig.hpp bare_bone_share, bone_body): how much of a body's
// surface is bare bone, and the bone grown into a body whose shape the body-plan search can read.
#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <tbb/blocked_range.h>
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

/// The bone's crop (rig_detail::crop_of) padded past `pad` mm along every axis.
rig_detail::Crop padded(const Grid& grid, const std::uint8_t* bone, double pad) {
    std::array<std::int64_t, 3> steps{};
    for (int a = 0; a < 3; ++a) steps[a] = static_cast<std::int64_t>(std::ceil(pad / grid.spacing[a])) + 2;
    return rig_detail::crop_of(grid, bone, steps);
}

/// Whether crop voxel (x, y, z) lies inside the full grid.
bool in_grid(const rig_detail::Crop& c, const Grid& g, std::int64_t x, std::int64_t y, std::int64_t z) {
    const std::int64_t v[3] = {x + c.lo[0], y + c.lo[1], z + c.lo[2]};
    for (int a = 0; a < 3; ++a)
        if (v[a] < 0 || v[a] >= g.dims[a]) return false;
    return true;
}

/// The bone's median depth: its voxels' median distance to the nearest voxel that is not bone (the box's padding
/// holds none, so a bone cut by the grid's face is as deep there as the grid's outside makes it).
double bone_depth(const rig_detail::Crop& b) {
    const std::vector<float> dt = distance_transform(b.grid, b.bone.data(), Metric::Euclidean);
    std::vector<float> v;
    for (std::size_t i = 0; i < dt.size(); ++i)
        if (b.bone[i]) v.push_back(dt[i]);
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
}

/// Per box voxel, its distance (mm) to the nearest bone voxel. The box is padded past every radius tried: the
/// transform counts the outside of its grid as background, and the padding keeps the box's faces from looking like
/// bone.
std::vector<float> distance_to_bone(const rig_detail::Crop& b) {
    std::vector<std::uint8_t> outside(b.bone.size());
    for (std::size_t i = 0; i < outside.size(); ++i) outside[i] = b.bone[i] ? 0 : 1;
    return distance_transform(b.grid, outside.data(), Metric::Euclidean);
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
    const double most = std::max({grid.spacing[0], grid.spacing[1], grid.spacing[2]});
    // The first radius needs the bone's depth (measured in a crop padded by two voxels; crop_of refuses an empty
    // bone); the crop the body grows in is padded past the last.
    const double first = std::max(2.0 * bone_depth(padded(grid, bone, 0.0)), kBoneBodyMinVoxels * most);
    const rig_detail::Crop b = padded(grid, bone, first * std::pow(kBoneBodyGrowth, kBoneBodySteps - 1));
    const Grid& box = b.grid;
    const std::vector<float> to_bone = distance_to_bone(b);
    const auto bone_voxels = static_cast<double>(std::count(b.bone.begin(), b.bone.end(), 1));
    std::vector<std::uint8_t> grown(b.bone.size());
    Components c;
    BoneBody out;
    for (int k = 0; k < kBoneBodySteps; ++k) {
        out.radius = first * std::pow(kBoneBodyGrowth, k);
        for (std::int64_t z = 0; z < box.dims[2]; ++z)
            for (std::int64_t y = 0; y < box.dims[1]; ++y)
                for (std::int64_t x = 0; x < box.dims[0]; ++x) {
                    const auto i = static_cast<std::size_t>(box.index(x, y, z));
                    grown[i] = in_grid(b, grid, x, y, z) && to_bone[i] <= out.radius;
                }
        c = label_components(box, grown.data());
        std::int64_t held = 0;  // bone voxels in the largest component
        for (std::size_t i = 0; i < grown.size(); ++i) held += b.bone[i] && c.labels[i] == 1;
        out.joined = static_cast<double>(held) / bone_voxels;
        if (out.joined >= kBoneBodyJoined) break;
    }
    out.mask.assign(static_cast<std::size_t>(grid.voxel_count()), 0);
    for (std::int64_t z = 0; z < box.dims[2]; ++z)
        for (std::int64_t y = 0; y < box.dims[1]; ++y)
            for (std::int64_t x = 0; x < box.dims[0]; ++x)
                if (c.labels[static_cast<std::size_t>(box.index(x, y, z))] == 1)
                    out.mask[static_cast<std::size_t>(grid.index(x + b.lo[0], y + b.lo[1], z + b.lo[2]))] = 1;
    return out;
}

}  // namespace volrig

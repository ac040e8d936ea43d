// rig/bones/segments.cpp: the bone tissue split into rigid segments at its articulations (volrig/rig.hpp
// bone_segments): an opening parts bones that touch across a joint at the voxel size.
#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "rig/bones/bones.hpp"
#include "volrig/components.hpp"
#include "volrig/error.hpp"

namespace volrig::rig_detail {

BoneParams bone_params(const Grid& grid, const BoneRigOptions& opt) {
    if (!(opt.opening >= 0) || !(opt.min_volume >= 0) || !(opt.reach >= 0))
        throw Error("bone rig: opening, min_volume and reach must be non-negative");
    BoneParams p;
    const double opening = opt.opening > 0 ? opt.opening : 4.0;
    p.erode_steps = std::max(1, static_cast<int>(std::lround(opening / grid.min_spacing())));
    const double cell = grid.spacing[0] * grid.spacing[1] * grid.spacing[2];
    const double volume = opt.min_volume > 0 ? opt.min_volume : 1000.0;
    p.min_voxels = std::max<std::int64_t>(8, static_cast<std::int64_t>(std::ceil(volume / cell)));
    p.reach = opt.reach > 0 ? opt.reach : 20.0;
    return p;
}

namespace {

/// One 6-neighbour erosion step of `in` into `out` (voxels at the grid's border erode).
void erode6(const Grid& g, const std::vector<std::uint8_t>& in, std::vector<std::uint8_t>& out) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];  // (a lambda captures them: no binding)
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t z = r.begin(); z != r.end(); ++z)
            for (std::int64_t y = 0; y < ny; ++y)
                for (std::int64_t x = 0; x < nx; ++x) {
                    const std::int64_t i = g.index(x, y, z);
                    const bool inside = x > 0 && y > 0 && z > 0 && x + 1 < nx && y + 1 < ny && z + 1 < nz;
                    out[static_cast<std::size_t>(i)] =
                        in[static_cast<std::size_t>(i)] && inside && in[static_cast<std::size_t>(i - 1)] &&
                        in[static_cast<std::size_t>(i + 1)] && in[static_cast<std::size_t>(i - nx)] &&
                        in[static_cast<std::size_t>(i + nx)] && in[static_cast<std::size_t>(i - nx * ny)] &&
                        in[static_cast<std::size_t>(i + nx * ny)];
                }
    });
}

/// Labels of the eroded bone's components with at least min_voxels voxels (others cleared), largest first.
Components kept_cores(const Grid& g, const std::uint8_t* bone, const BoneParams& p) {
    const auto n = static_cast<std::size_t>(g.voxel_count());
    std::vector<std::uint8_t> a(bone, bone + n), b(n);
    for (std::size_t i = 0; i < n; ++i) a[i] = a[i] != 0;
    for (int s = 0; s < p.erode_steps; ++s) {
        erode6(g, a, b);
        a.swap(b);
    }
    Components c = label_components(g, a.data());
    std::size_t keep = 0;
    while (keep < c.sizes.size() && c.sizes[keep] >= p.min_voxels) ++keep;
    const auto last = static_cast<std::int32_t>(keep);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i)
            if (c.labels[i] > last) c.labels[i] = 0;
    });
    c.sizes.resize(keep);
    return c;
}

/// Labels on the crop placed back on the full grid (0 outside the crop).
std::vector<std::int32_t> uncropped(const Grid& g, const Crop& c, const std::vector<std::int32_t>& labels) {
    std::vector<std::int32_t> out(static_cast<std::size_t>(g.voxel_count()), 0);
    for (std::int64_t z = 1; z + 1 < c.grid.dims[2]; ++z)
        for (std::int64_t y = 1; y + 1 < c.grid.dims[1]; ++y)
            for (std::int64_t x = 1; x + 1 < c.grid.dims[0]; ++x)
                out[static_cast<std::size_t>(g.index(x + c.lo[0], y + c.lo[1], z + c.lo[2]))] =
                    labels[static_cast<std::size_t>(c.grid.index(x, y, z))];
    return out;
}

}  // namespace

Crop crop_of(const Grid& g, const std::uint8_t* bone, const std::array<std::int64_t, 3>& pad) {
    std::array<std::int64_t, 3> lo{g.dims[0], g.dims[1], g.dims[2]}, hi{-1, -1, -1};
    for (std::int64_t z = 0; z < g.dims[2]; ++z)
        for (std::int64_t y = 0; y < g.dims[1]; ++y) {
            const std::uint8_t* row = bone + g.index(0, y, z);
            for (std::int64_t x = 0; x < g.dims[0]; ++x)
                if (row[x]) {
                    const std::array<std::int64_t, 3> v{x, y, z};
                    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], v[a]), hi[a] = std::max(hi[a], v[a]);
                }
        }
    if (hi[0] < 0) throw Error("bone: the bone mask is empty (no bone voxels to rig from)");
    Crop c;
    c.grid = g;
    for (int a = 0; a < 3; ++a) {
        c.lo[a] = lo[a] - pad[a];
        c.grid.dims[a] = hi[a] - lo[a] + 1 + 2 * pad[a];
        c.grid.origin[a] = g.origin[a] + g.spacing[a] * static_cast<double>(c.lo[a]);
    }
    c.bone.assign(static_cast<std::size_t>(c.grid.voxel_count()), 0);
    for (std::int64_t z = lo[2]; z <= hi[2]; ++z)
        for (std::int64_t y = lo[1]; y <= hi[1]; ++y)
            for (std::int64_t x = lo[0]; x <= hi[0]; ++x)
                c.bone[static_cast<std::size_t>(c.grid.index(x - c.lo[0], y - c.lo[1], z - c.lo[2]))] =
                    bone[g.index(x, y, z)] != 0;
    return c;
}

}  // namespace volrig::rig_detail

namespace volrig {

BoneSegments bone_segments(const Grid& grid, const std::uint8_t* bone, const BoneRigOptions& opt) {
    using namespace rig_detail;
    const BoneParams p = bone_params(grid, opt);
    const Crop crop = crop_of(grid, bone, {1, 1, 1});  // the bone's box and a voxel round it: a whole body's bone is 40% less
    Components cores = kept_cores(crop.grid, crop.bone.data(), p);
    if (cores.sizes.empty())
        throw Error("bone segments: no bone is thicker than the opening (" + std::to_string(p.erode_steps) +
                    " voxels); give a smaller opening");
    // Every bone voxel takes the core reached in fewest steps through the bone.
    const auto m = crop.bone.size();
    std::vector<std::uint8_t> code(m);
    for (std::size_t i = 0; i < m; ++i) code[i] = cores.labels[i] ? 1 : (crop.bone[i] ? 2 : 0);
    const std::vector<std::int64_t> pairs = nearest_seed_fill(crop.grid, code.data());
    for (std::size_t k = 0; k + 1 < pairs.size(); k += 2)
        cores.labels[static_cast<std::size_t>(pairs[k])] = cores.labels[static_cast<std::size_t>(pairs[k + 1])];
    BoneSegments out;
    out.labels = uncropped(grid, crop, cores.labels);
    out.sizes.assign(cores.sizes.size(), 0);
    for (std::int32_t s : cores.labels)
        if (s > 0) ++out.sizes[static_cast<std::size_t>(s - 1)];
    return out;
}

}  // namespace volrig

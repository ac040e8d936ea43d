// rig/bones/segments.cpp: the bone tissue split into rigid segments at its articulations (volrig/rig.hpp
// bone_segments): an opening parts bones that touch across a joint at the voxel size. Every pass but the output's
// allocation visits the bone's voxels alone (1% of a whole body's box).
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <string>
#include <utility>

#include <tbb/parallel_for.h>

#include "common/neighbourhood.hpp"
#include "rig/bones/bones.hpp"
#include "volrig/error.hpp"

namespace volrig::rig_detail {

BoneParams bone_params(const Grid& grid, const BoneRigOptions& opt, std::size_t bone_voxels) {
    if (!(opt.opening >= 0) || !(opt.min_volume >= 0) || !(opt.reach >= 0))
        throw Error("bone rig: opening, min_volume and reach must be non-negative");
    const double cell = grid.spacing[0] * grid.spacing[1] * grid.spacing[2];
    const double volume = static_cast<double>(bone_voxels) * cell, size = std::cbrt(volume);
    BoneParams p;
    p.scale = std::min(1.0, kOpeningShare * size / kAdultOpening);
    const double opening = opt.opening > 0 ? opt.opening : std::min(kAdultOpening, kOpeningShare * size);
    p.erode_steps = std::max(1, static_cast<int>(std::lround(opening / grid.min_spacing())));
    const double least = opt.min_volume > 0 ? opt.min_volume : std::min(kAdultMinVolume, kMinVolumeShare * volume);
    p.min_voxels = std::max<std::int64_t>(8, static_cast<std::int64_t>(std::ceil(least / cell)));
    p.reach = opt.reach > 0 ? opt.reach : std::min(kAdultReach, kReachShare * size);
    return p;
}

std::vector<std::int64_t> bone_voxels(const Grid& g, const std::uint8_t* bone) {
    const std::int64_t slice = g.dims[0] * g.dims[1];
    std::vector<std::vector<std::int64_t>> per(static_cast<std::size_t>(g.dims[2]));
    tbb::parallel_for(std::int64_t{0}, g.dims[2], [&](std::int64_t z) {
        const std::uint8_t* s = bone + z * slice;
        for (const std::uint8_t* p = std::find_if(s, s + slice, [](std::uint8_t v) { return v != 0; }); p != s + slice;
             p = std::find_if(p + 1, s + slice, [](std::uint8_t v) { return v != 0; }))
            per[static_cast<std::size_t>(z)].push_back(z * slice + (p - s));
    });
    std::vector<std::int64_t> out;
    for (auto& v : per) out.insert(out.end(), v.begin(), v.end());
    return out;
}

namespace {

using common_detail::Neighbourhood;

/// Per-voxel state while the segments are found, on the output labels: 0 background, -1 - k a bone voxel that
/// survived k erosion steps, > 0 the segment a voxel has joined.
constexpr std::int32_t depth_mark(int k) { return -1 - k; }

/// `steps` 6-neighbour erosion steps of the bone voxels `voxels` (voxels at the grid's border erode): marks each
/// with the steps it survived; returns the survivors (ascending).
std::vector<std::int64_t> erode(const Grid& g, std::vector<std::int32_t>& state, std::vector<std::int64_t> voxels,
                                int steps) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    for (int k = 1; k <= steps; ++k) {
        const std::int32_t kept = depth_mark(k - 1);
        std::vector<std::uint8_t> keep(voxels.size());
        tbb::parallel_for(std::size_t{0}, voxels.size(), [&](std::size_t n) {
            const std::int64_t i = voxels[n], x = i % nx, y = (i / nx) % ny, z = i / (nx * ny);
            if (x == 0 || y == 0 || z == 0 || x + 1 == nx || y + 1 == ny || z + 1 == nz) return;
            bool all = true;
            for (std::int64_t d : {std::int64_t{1}, nx, nx * ny})
                all = all && state[static_cast<std::size_t>(i - d)] <= kept && state[static_cast<std::size_t>(i + d)] <= kept;
            keep[n] = all;
        });
        std::size_t m = 0;
        for (std::size_t n = 0; n < voxels.size(); ++n)
            if (keep[n]) voxels[m++] = voxels[n];
        voxels.resize(m);
        for (std::int64_t i : voxels) state[static_cast<std::size_t>(i)] = depth_mark(k);
    }
    return voxels;
}

/// The 26-connected components of the cores (the voxels marked `core`, ascending), numbered by descending size
/// (ties in order of their first voxel); those of at least min_voxels become segments 1.., the others bone again.
std::vector<std::int64_t> number_cores(const Grid& g, std::vector<std::int32_t>& state,
                                       const std::vector<std::int64_t>& cores, std::int32_t core, std::int64_t min_voxels) {
    const Neighbourhood nb(g);
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    std::vector<std::int64_t> sizes, stack;
    for (std::int64_t i : cores) {
        if (state[static_cast<std::size_t>(i)] != core) continue;
        const auto label = static_cast<std::int32_t>(sizes.size() + 1);
        std::int64_t size = 0;
        state[static_cast<std::size_t>(i)] = label;
        for (stack.push_back(i); !stack.empty(); ++size) {
            const std::int64_t v = stack.back();
            stack.pop_back();
            nb.visit(v % nx, (v / nx) % ny, v / (nx * ny), v, [&](int, std::int64_t j) {
                if (j >= 0 && state[static_cast<std::size_t>(j)] == core) state[static_cast<std::size_t>(j)] = label, stack.push_back(j);
            });
        }
        sizes.push_back(size);
    }
    std::vector<std::int32_t> rank(sizes.size());
    std::iota(rank.begin(), rank.end(), 0);
    std::stable_sort(rank.begin(), rank.end(), [&](std::int32_t a, std::int32_t b) { return sizes[a] > sizes[b]; });
    std::vector<std::int32_t> relabel(sizes.size() + 1, depth_mark(0));
    std::vector<std::int64_t> kept;
    for (std::size_t r = 0; r < rank.size() && sizes[static_cast<std::size_t>(rank[r])] >= min_voxels; ++r) {
        relabel[static_cast<std::size_t>(rank[r]) + 1] = static_cast<std::int32_t>(r + 1);
        kept.push_back(sizes[static_cast<std::size_t>(rank[r])]);
    }
    for (std::int64_t i : cores) state[static_cast<std::size_t>(i)] = relabel[static_cast<std::size_t>(state[static_cast<std::size_t>(i)])];
    return kept;
}

/// Every other bone voxel joins the segment whose core it reaches in fewest 26-neighbour steps through the bone
/// (the first layer in voxel order, each taking its first neighbouring core; then breadth first); bone reaching
/// no core is cleared.
void fill_from_cores(const Grid& g, std::vector<std::int32_t>& state, const std::vector<std::int64_t>& voxels) {
    const Neighbourhood nb(g);
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    const auto around = [&](std::int64_t v, auto&& f) { nb.visit(v % nx, (v / nx) % ny, v / (nx * ny), v, f); };
    std::vector<std::pair<std::int64_t, std::int32_t>> queue;
    for (std::int64_t i : voxels) {
        if (state[static_cast<std::size_t>(i)] > 0) continue;
        std::int32_t seed = 0;
        around(i, [&](int, std::int64_t j) {
            if (!seed && j >= 0 && state[static_cast<std::size_t>(j)] > 0) seed = state[static_cast<std::size_t>(j)];
        });
        if (seed) queue.emplace_back(i, seed);
    }
    for (const auto& [i, s] : queue) state[static_cast<std::size_t>(i)] = s;
    for (std::size_t head = 0; head < queue.size(); ++head) {
        const auto [v, s] = queue[head];
        around(v, [&, s = s](int, std::int64_t j) {
            if (j >= 0 && state[static_cast<std::size_t>(j)] < 0) state[static_cast<std::size_t>(j)] = s, queue.emplace_back(j, s);
        });
    }
    for (std::int64_t i : voxels) state[static_cast<std::size_t>(i)] = std::max(state[static_cast<std::size_t>(i)], 0);
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

namespace volrig::rig_detail {

BoneSegments segments_of(const Grid& grid, const std::vector<std::int64_t>& voxels, const BoneParams& p) {
    if (voxels.empty()) throw Error("bone: the bone mask is empty (no bone voxels to rig from)");
    BoneSegments out;  // the labels hold each voxel's state until the segments are found (depth_mark)
    out.labels.assign(static_cast<std::size_t>(grid.voxel_count()), 0);
    for (std::int64_t i : voxels) out.labels[static_cast<std::size_t>(i)] = depth_mark(0);
    const std::vector<std::int64_t> cores = erode(grid, out.labels, voxels, p.erode_steps);
    const std::vector<std::int64_t> sizes = number_cores(grid, out.labels, cores, depth_mark(p.erode_steps), p.min_voxels);
    if (sizes.empty())
        throw Error("bone segments: no bone is thicker than the opening (" + std::to_string(p.erode_steps) +
                    " voxels); give a smaller opening");
    fill_from_cores(grid, out.labels, voxels);
    out.sizes.assign(sizes.size(), 0);
    for (std::int64_t i : voxels)
        if (const std::int32_t s = out.labels[static_cast<std::size_t>(i)]; s > 0) ++out.sizes[static_cast<std::size_t>(s - 1)];
    return out;
}

}  // namespace volrig::rig_detail

namespace volrig {

BoneSegments bone_segments(const Grid& grid, const std::uint8_t* bone, const BoneRigOptions& opt) {
    using namespace rig_detail;
    const std::vector<std::int64_t> voxels = bone_voxels(grid, bone);
    return segments_of(grid, voxels, bone_params(grid, opt, voxels.size()));
}

}  // namespace volrig

// rig/bones/slices.cpp: a bone mask on slices far apart (an anisotropic scan) interpolated between its slices, so
// that rig_to_bones reasons about the bone's shape in millimetres, whatever the slices' phase (volrig/rig.hpp).
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <tbb/parallel_for.h>

#include "rig/bones/bones.hpp"
#include "volrig/distance.hpp"

namespace volrig::rig_detail {

namespace {

/// The voxel (x, y, z) of grid g at position u along `axis` and (v, w) along the other two axes, in order.
std::int64_t index_on(const Grid& g, int axis, std::int64_t u, std::int64_t v, std::int64_t w) {
    std::array<std::int64_t, 3> x{};
    x[static_cast<std::size_t>(axis)] = u;
    x[static_cast<std::size_t>((axis + 1) % 3)] = v;
    x[static_cast<std::size_t>((axis + 2) % 3)] = w;
    return g.index(x[0], x[1], x[2]);
}

/// Each slice's signed distance to its bone's outline, in mm within the slice: positive inside (the distance to
/// the nearest voxel outside), negative outside (minus the distance to the nearest bone), both at least a step,
/// so that the outline lies halfway between voxel centres. A slice without bone is -infinity (nothing to grow).
/// The distance transform counts what lies outside its array as background, which for the distance to the bone
/// would be bone all round the slice: a voxel whose distance to the bone is the distance to that edge or more has
/// no bone within it, and is -infinity too (no interpolated bone grows from the array's edge).
std::vector<float> slice_distances(const Grid& g, const std::vector<std::uint8_t>& bone, int axis) {
    const int va = (axis + 1) % 3, wa = (axis + 2) % 3;
    const std::int64_t nv = g.dims[static_cast<std::size_t>(va)], nw = g.dims[static_cast<std::size_t>(wa)];
    std::vector<float> out(bone.size(), -std::numeric_limits<float>::infinity());
    tbb::parallel_for(std::int64_t{0}, g.dims[static_cast<std::size_t>(axis)], [&](std::int64_t u) {
        Grid s;  // the slice, padded by a voxel of background all round
        s.dims = {nv + 2, nw + 2, 1};
        s.spacing = {g.spacing[static_cast<std::size_t>(va)], g.spacing[static_cast<std::size_t>(wa)], 1.0};
        std::vector<std::uint8_t> in(static_cast<std::size_t>(s.voxel_count()), 0), off(in.size(), 1);
        bool any = false;
        for (std::int64_t w = 0; w < nw; ++w)
            for (std::int64_t v = 0; v < nv; ++v)
                if (bone[static_cast<std::size_t>(index_on(g, axis, u, v, w))]) {
                    in[static_cast<std::size_t>(s.index(v + 1, w + 1, 0))] = 1;
                    off[static_cast<std::size_t>(s.index(v + 1, w + 1, 0))] = 0;
                    any = true;
                }
        if (!any) return;
        std::vector<float> din(in.size()), dout(in.size());
        euclidean_distance_transform(s, in.data(), din.data());
        euclidean_distance_transform(s, off.data(), dout.data());
        const double sv = s.spacing[0], sw = s.spacing[1];
        for (std::int64_t w = 0; w < nw; ++w)
            for (std::int64_t v = 0; v < nv; ++v) {
                const auto k = static_cast<std::size_t>(s.index(v + 1, w + 1, 0));
                const double edge = std::min({static_cast<double>(v + 2) * sv, static_cast<double>(nv + 1 - v) * sv,
                                              static_cast<double>(w + 2) * sw, static_cast<double>(nw + 1 - w) * sw});
                float& o = out[static_cast<std::size_t>(index_on(g, axis, u, v, w))];
                if (in[k]) o = din[k];
                else if (dout[k] < edge - 1e-3 * sv) o = -dout[k];
            }
    });
    return out;
}

}  // namespace

std::optional<Refined> refine_slices(const Grid& g, const std::uint8_t* bone) {
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (g.spacing[static_cast<std::size_t>(a)] > g.spacing[static_cast<std::size_t>(axis)]) axis = a;
    const double in_plane = std::max(g.spacing[static_cast<std::size_t>((axis + 1) % 3)],
                                     g.spacing[static_cast<std::size_t>((axis + 2) % 3)]);
    // whole steps only, so that every factor-th interpolated slice is one of the scan's (the tolerance: 8 / 2 mm
    // computed as 3.9999999 is 4)
    const auto factor = static_cast<int>(std::floor(g.spacing[static_cast<std::size_t>(axis)] / in_plane + 1e-6));
    if (factor < 2) return std::nullopt;
    std::array<std::int64_t, 3> pad{1, 1, 1};
    const Crop c = crop_of(g, bone, pad);  // a slice of background before the first and after the last
    const std::vector<float> sd = slice_distances(c.grid, c.bone, axis);
    Refined r;
    r.axis = axis;
    r.factor = factor;
    r.lo = c.lo;
    r.grid = c.grid;
    const auto ax = static_cast<std::size_t>(axis);
    r.grid.dims[ax] = (c.grid.dims[ax] - 1) * factor + 1;
    r.grid.spacing[ax] = c.grid.spacing[ax] / factor;
    r.bone.assign(static_cast<std::size_t>(r.grid.voxel_count()), 0);
    const std::int64_t nv = c.grid.dims[(ax + 1) % 3], nw = c.grid.dims[(ax + 2) % 3];
    tbb::parallel_for(std::int64_t{0}, r.grid.dims[ax], [&](std::int64_t f) {
        const std::int64_t u = f / factor, k = f % factor;
        const double t = static_cast<double>(k) / factor;
        for (std::int64_t w = 0; w < nw; ++w)
            for (std::int64_t v = 0; v < nv; ++v) {
                const float s0 = sd[static_cast<std::size_t>(index_on(c.grid, axis, u, v, w))];
                // on a slice, its own bone; between two, where the distances' blend is inside
                const bool inside = k == 0 ? s0 > 0 : [&] {
                    const float s1 = sd[static_cast<std::size_t>(index_on(c.grid, axis, u + 1, v, w))];
                    return (s0 > 0 || s1 > 0) && (1 - t) * s0 + t * s1 > 0;
                }();
                r.bone[static_cast<std::size_t>(index_on(r.grid, axis, f, v, w))] = inside;
            }
    });
    return r;
}

BoneSegments on_slices(const Refined& r, const Grid& g, const BoneSegments& fine) {
    BoneSegments out;
    out.labels.assign(static_cast<std::size_t>(g.voxel_count()), 0);
    out.sizes.assign(fine.sizes.size(), 0);
    const auto ax = static_cast<std::size_t>(r.axis);
    for (std::int64_t z = 0; z < g.dims[2]; ++z)
        for (std::int64_t y = 0; y < g.dims[1]; ++y)
            for (std::int64_t x = 0; x < g.dims[0]; ++x) {
                std::array<std::int64_t, 3> f{x - r.lo[0], y - r.lo[1], z - r.lo[2]};
                f[ax] *= r.factor;
                bool in = true;
                for (std::size_t a = 0; a < 3; ++a) in = in && f[a] >= 0 && f[a] < r.grid.dims[a];
                if (!in) continue;
                const std::int32_t s = fine.labels[static_cast<std::size_t>(r.grid.index(f[0], f[1], f[2]))];
                out.labels[static_cast<std::size_t>(g.index(x, y, z))] = s;
                if (s > 0) ++out.sizes[static_cast<std::size_t>(s - 1)];
            }
    return out;
}

}  // namespace volrig::rig_detail

// deform/reference.cpp: the literal thesis algorithm (the brute-force scatter the fast path must equal voxel for
// voxel) and the plain inverse warp (the speed reference).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "deform/bend.hpp"
#include "deform/frame_box.hpp"
#include "deform/motion.hpp"
#include "deform/sampler.hpp"
#include "deform/spheres.hpp"
#include "volrig/deform.hpp"
#include "volrig/reconstruct.hpp"

namespace volrig {

using namespace deform_detail;

DeformedVolume deform_reference(const VolumeView& source, const BoundSpheres& s, BoneMatrices matrices,
                                const DeformOptions& o, const Progress& progress,
                                const Box* fixed_box) {
    const Grid& grid = source.grid;
    check_source(source, "deform_reference");
    check_spheres(grid, s);
    check_options(o, s.n);
    const std::vector<Motion> motions = bone_motions(matrices, s.bone_count, grid);
    std::vector<double> radii = scaled_radii(s, o);
    const bool smooth = o.mode != DeformMode::Rigid && s.weight_offsets;
    const double s2[3] = {grid.spacing[0] * grid.spacing[0], grid.spacing[1] * grid.spacing[1],
                          grid.spacing[2] * grid.spacing[2]};
    std::vector<Motion> mot(s.n);
    std::vector<std::array<double, 3>> centre(s.n), rest(s.n);
    const SmoothGroups groups = smooth ? smooth_groups(s, grid) : SmoothGroups{};
    // keep_volume: the bend model's radii, and its contact planes (sliding contact) per field
    FieldContacts planes;
    if (smooth && o.keep_volume) {
        const BendModel model = bend_model(s, groups, radii, grid);
        planes = contacts(model, groups, motions, o.mode, s.bone_count, grid);
        bend_radii(model, s, groups, motions, o.mode, radii);
    }
    const std::vector<Contact> none;
    auto planes_of = [&](std::size_t i) -> const std::vector<Contact>& {
        if (planes.empty()) return none;
        const std::int32_t k = groups.group_of[i];
        return planes[k < 0 ? static_cast<std::size_t>(groups.bone_of[i]) : s.bone_count + static_cast<std::size_t>(k)];
    };
    Vec3d lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    for (std::size_t i = 0; i < s.n; ++i) {
        const std::int32_t k = smooth ? groups.group_of[i] : -1;
        mot[i] = k < 0 ? motions[static_cast<std::size_t>(smooth ? groups.bone_of[i] : s.bone[i])]
                       : blended_motion(motions, groups.weights[static_cast<std::size_t>(k)], s.bone[i], o.mode, grid,
                                        groups.pivot[static_cast<std::size_t>(k)]);
        rest[i] = {static_cast<double>(s.ijk[3 * i + 2]), static_cast<double>(s.ijk[3 * i + 1]),
                   static_cast<double>(s.ijk[3 * i])};
        mot[i].forward.apply(rest[i].data(), centre[i].data());
        if (!(radii[i] > 0)) continue;
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], centre[i][a] - radii[i] / grid.spacing[a]);
            hi[a] = std::max(hi[a], centre[i][a] + radii[i] / grid.spacing[a]);
        }
    }
    const Box bx = fixed_box ? *fixed_box : box_of(lo, hi);
    check_box_reach(bx);
    DeformedVolume out = frame_on(grid, bx);
    const std::int64_t nx = bx[3], ny = bx[4], nz = bx[5];
    const auto total = static_cast<std::size_t>(nx * ny * nz);
    std::vector<double> P(total, kInf);        // the proximity buffer
    std::vector<std::uint8_t> Y(total, 1);     // ... and its first key: whether the writer yields (sliding contact)
    std::vector<std::int64_t> who(total, -1);  // the sphere that wrote each voxel
    if (o.values) out.values = ZeroedArray<float>(total);
    out.bone = ZeroedArray<std::int16_t>(total);
    const bool nearest = o.proximity == Proximity::Nearest;
    with_sampler(source, [&](auto sampler) {
        // Parallel over z slabs; within a slab the spheres are scattered in index order, as in the thesis.
        tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz, 4), [&](const tbb::blocked_range<std::int64_t>& rg) {
            for (std::size_t i = 0; i < s.n; ++i) {
                const double r = radii[i];
                if (!(r > 0)) continue;
                const double lim = open_ball_limit_sq(r);
                const std::vector<Contact>& yield_planes = planes_of(i);
                const double cx = centre[i][0] - static_cast<double>(bx[0]),
                             cy = centre[i][1] - static_cast<double>(bx[1]),
                             cz = centre[i][2] - static_cast<double>(bx[2]);
                const auto za = std::max<std::int64_t>(rg.begin(), static_cast<std::int64_t>(std::floor(cz - r / grid.spacing[2])));
                const auto zb = std::min<std::int64_t>(rg.end() - 1, static_cast<std::int64_t>(std::ceil(cz + r / grid.spacing[2])));
                const auto ya = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor(cy - r / grid.spacing[1])));
                const auto yb = std::min<std::int64_t>(ny - 1, static_cast<std::int64_t>(std::ceil(cy + r / grid.spacing[1])));
                const auto xa = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor(cx - r / grid.spacing[0])));
                const auto xb = std::min<std::int64_t>(nx - 1, static_cast<std::int64_t>(std::ceil(cx + r / grid.spacing[0])));
                for (std::int64_t z = za; z <= zb; ++z)
                    for (std::int64_t y = ya; y <= yb; ++y)
                        for (std::int64_t x = xa; x <= xb; ++x) {
                            const std::int64_t q[3] = {x + bx[0], y + bx[1], z + bx[2]};
                            const double d2 = moved_length2(mot[i], rest[i].data(), q, s2);
                            if (!(d2 < lim)) continue;
                            const double key = nearest ? d2 : d2 - lim;
                            const auto idx = static_cast<std::size_t>((z * ny + y) * nx + x);
                            const std::uint8_t yk = !yield_planes.empty() && yields(yield_planes, q, s2);
                            // mark q, R(q) = S(T⁻¹q), P(q) = proximity: as the thesis writes it, the key (yields, key)
                            if (yk < Y[idx] || (yk == Y[idx] && key < P[idx])) {
                                Y[idx] = yk;
                                P[idx] = key;
                                who[idx] = static_cast<std::int64_t>(i);
                                out.bone[idx] = static_cast<std::int16_t>(s.bone[i] + 1);
                                if (o.values) {
                                    std::int64_t p[3];
                                    mot[i].pull.fixed(q, p);
                                    out.values[idx] = sampler.sample(p, o.sampling);
                                }
                            }
                        }
            }
        });
    });
    for (std::size_t k = 0; k < total; ++k) out.stats.covered += who[k] >= 0;
    report(progress, 1.0);
    return out;
}

std::vector<float> inverse_warp(const VolumeView& source, const double* matrix, Sampling sampling,
                                const Progress& progress, const std::array<std::int64_t, 6>* box) {
    const Grid& g = source.grid;
    check_grid(g, dtype_size(source.dtype), std::numeric_limits<std::uint64_t>::max(), "inverse_warp");
    check_source(source, "inverse_warp");
    const Motion m = bone_motions(matrix, 1, g)[0];
    const Box bx = box ? *box : Box{0, 0, 0, g.dims[0], g.dims[1], g.dims[2]};
    const std::int64_t nx = bx[3], ny = bx[4], nz = bx[5];
    if (nx <= 0 || ny <= 0 || nz <= 0) throw Error("inverse_warp: the output box must have positive dimensions");
    check_box_reach(bx);
    std::vector<float> out(static_cast<std::size_t>(nx * ny * nz));
    with_sampler(source, [&](auto sampler) {
        tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nz), [&](const tbb::blocked_range<std::int64_t>& rg) {
            for (std::int64_t z = rg.begin(); z != rg.end(); ++z)
                for (std::int64_t y = 0; y < ny; ++y) {
                    float* row = out.data() + (z * ny + y) * nx;
                    for (std::int64_t x = 0; x < nx; ++x) {
                        const std::int64_t q[3] = {x + bx[0], y + bx[1], z + bx[2]};
                        std::int64_t p[3];
                        m.pull.fixed(q, p);
                        row[x] = sampler.sample(p, sampling);
                    }
                }
        });
    });
    report(progress, 1.0);
    return out;
}

}  // namespace volrig

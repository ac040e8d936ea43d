#include "deform/frame_box.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace volrig::deform_detail {

Box box_of(const Vec3d& lo, const Vec3d& hi) {
    Box b{};
    std::uint64_t count = 1;
    for (int a = 0; a < 3; ++a) {
        if (!(lo[a] <= hi[a])) {  // nothing to place
            b[a] = 0;
            b[3 + a] = 1;
            continue;
        }
        b[a] = static_cast<std::int64_t>(std::floor(lo[a]));
        b[3 + a] = static_cast<std::int64_t>(std::ceil(hi[a])) - b[a] + 1;
        count *= static_cast<std::uint64_t>(b[3 + a]);
    }
    if (count > (std::uint64_t{1} << 31))
        throw Error("deform: the posed spheres span " + std::to_string(count) +
                    " voxels (more than 2^31): check the bone matrices' translations and units");
    return b;
}

/// Per sphere and axis, the nearest lattice line to the posed centre along the axis gives the extreme planes
/// exactly (the squared distance is a sum of one term per axis). A tolerance far below the open balls' margin keeps
/// it on the safe side; should a plane still be empty, the frame is cropped at the end.
Box posed_box(const std::vector<BoneField>& fields, const std::vector<Motion>& motions, const Grid& g) {
    Vec3d lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    const double s2[3] = {g.spacing[0] * g.spacing[0], g.spacing[1] * g.spacing[1], g.spacing[2] * g.spacing[2]};
    const double smax = std::max({g.spacing[0], g.spacing[1], g.spacing[2]});
    for (std::size_t b = 0; b < fields.size(); ++b) {
        for (const auto& sp : fields[b].sph) {
            if (!(sp.lim > 0)) continue;
            double y[3], m[3];
            motions[b].forward.apply(sp.c, y);
            for (int a = 0; a < 3; ++a) {
                const double d = std::nearbyint(y[a]) - y[a];
                m[a] = s2[a] * d * d;
            }
            // Tolerance: rounding, and the fixed-point map's error (Pull: below 1e-9 voxel per voxel of reach).
            const double tol = 1e-9 * (2 + std::abs(y[0]) + std::abs(y[1]) + std::abs(y[2])) * smax;
            const double lim = std::pow(std::sqrt(sp.lim) * (1 + 1e-9) + tol, 2);
            if (!(m[0] + m[1] + m[2] < lim)) continue;  // no lattice point inside
            for (int a = 0; a < 3; ++a) {
                const double h = std::sqrt(std::max(0.0, lim - m[(a + 1) % 3] - m[(a + 2) % 3]) / s2[a]);
                const double x0 = std::min(std::floor(y[a] - h) + 1, std::nearbyint(y[a])),
                             x1 = std::max(std::ceil(y[a] + h) - 1, std::nearbyint(y[a]));
                lo[a] = std::min(lo[a], x0);
                hi[a] = std::max(hi[a], x1);
            }
        }
    }
    return box_of(lo, hi);
}

DeformedVolume frame_on(const Grid& source, const Box& bx) {
    for (int a = 0; a < 3; ++a)
        if (bx[3 + a] <= 0) throw Error("deform: the output box must have positive dimensions");
    DeformedVolume out;
    out.offset = {bx[0], bx[1], bx[2]};
    out.grid.dims = {bx[3], bx[4], bx[5]};
    out.extent = {0, 0, 0, bx[3], bx[4], bx[5]};
    out.grid.spacing = source.spacing;
    for (int a = 0; a < 3; ++a) out.grid.origin[a] = source.origin[a] + source.spacing[a] * static_cast<double>(bx[a]);
    return out;
}

void crop(DeformedVolume& f, const Box& sub, const Grid* source) {
    const std::int64_t nx = f.grid.dims[0], ny = f.grid.dims[1];
    if (sub[0] == 0 && sub[1] == 0 && sub[2] == 0 && sub[3] == nx && sub[4] == ny && sub[5] == f.grid.dims[2]) return;
    const std::int64_t ox = sub[3], oy = sub[4], oz = sub[5];
    const auto total = static_cast<std::size_t>(ox * oy * oz);
    ZeroedArray<float> values(f.values.empty() ? 0 : total);
    ZeroedArray<std::int16_t> bone(total);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, oz), [&](const tbb::blocked_range<std::int64_t>& rg) {
        for (std::int64_t z = rg.begin(); z != rg.end(); ++z)
            for (std::int64_t y = 0; y < oy; ++y) {
                const auto from = static_cast<std::size_t>(((z + sub[2]) * ny + y + sub[1]) * nx + sub[0]);
                const auto to = static_cast<std::size_t>((z * oy + y) * ox);
                const std::int16_t* b = f.bone.data() + from;
                // Copy only rows with a covered voxel: the others stay untouched zero pages.
                if (std::all_of(b, b + ox, [](std::int16_t v) { return v == 0; })) continue;
                std::copy(b, b + ox, bone.data() + to);
                if (!values.empty()) std::copy(f.values.data() + from, f.values.data() + from + ox, values.data() + to);
            }
    });
    f.values = std::move(values);
    f.bone = std::move(bone);
    for (int a = 0; a < 3; ++a) {
        f.offset[a] += sub[a];
        f.grid.dims[a] = sub[3 + a];
        f.extent[a] = 0;
        f.extent[3 + a] = sub[3 + a];
        f.grid.origin[a] = source ? source->origin[a] + source->spacing[a] * static_cast<double>(f.offset[a])
                                  : f.grid.origin[a] + f.grid.spacing[a] * static_cast<double>(sub[a]);
    }
}

Box brick_aligned(const Box& bx) {
    Box out;
    for (int a = 0; a < 3; ++a) {
        out[a] = bx[a] - (((bx[a] % kBlock) + kBlock) % kBlock);
        out[3 + a] = (bx[a] + bx[3 + a] - out[a] + kBlock - 1) / kBlock * kBlock;
    }
    return out;
}

void set_extent(DeformedVolume& f, const std::int64_t* lo, const std::int64_t* hi) {
    f.bricks = true;
    const bool none = hi[0] < lo[0] || hi[1] < lo[1] || hi[2] < lo[2];
    for (int a = 0; a < 3; ++a) {
        f.extent[a] = none ? 0 : lo[a];
        f.extent[3 + a] = none ? 0 : hi[a] - lo[a] + 1;
    }
}

void crop_to_extent(DeformedVolume& f, const std::int64_t* lo, const std::int64_t* hi, const Grid* source) {
    Box sub;
    for (int a = 0; a < 3; ++a) {
        const bool none = hi[a] < lo[a];
        sub[a] = none ? 0 : lo[a];
        sub[3 + a] = none ? 1 : hi[a] - lo[a] + 1;
    }
    crop(f, sub, source);
}

}  // namespace volrig::deform_detail

namespace volrig {

void crop_to_covered(DeformedVolume& f) {
    using namespace deform_detail;
    const std::int64_t nx = f.grid.dims[0], ny = f.grid.dims[1], nz = f.grid.dims[2];
    std::int64_t lo[3] = {nx, ny, nz}, hi[3] = {-1, -1, -1};
    for (std::int64_t z = 0; z < nz; ++z)
        for (std::int64_t y = 0; y < ny; ++y) {
            const std::int16_t* row = f.bone.data() + static_cast<std::size_t>((z * ny + y) * nx);
            for (std::int64_t x = 0; x < nx; ++x) {
                if (!row[x]) continue;
                const std::int64_t v[3] = {x, y, z};
                for (int a = 0; a < 3; ++a) {
                    lo[a] = std::min(lo[a], v[a]);
                    hi[a] = std::max(hi[a], v[a]);
                }
            }
        }
    crop_to_extent(f, lo, hi);
}

}  // namespace volrig

// deform/sampler.hpp: samples of the source at fixed-point rest positions (Pull), nearest or trilinear, for every
// element type.
#pragma once

#include <cstdint>
#include <type_traits>

#include "deform/motion.hpp"
#include "volrig/deform.hpp"

namespace volrig::deform_detail {

template <class T>
struct Sampler {
    const T* data;
    std::int64_t nx, ny, nz;

    float at(std::int64_t x, std::int64_t y, std::int64_t z) const { return element((z * ny + y) * nx + x); }
    float element(std::int64_t i) const { return static_cast<float>(data[i]); }
    /// A sample as a double: through float, as at() gives it (exactly, and in one conversion, for small integers).
    static double value(T v) {
        if constexpr (std::is_integral_v<T> && sizeof(T) <= 2) return static_cast<double>(v);
        else return static_cast<double>(static_cast<float>(v));
    }
    // Samples at a rest point in fixed point (Pull): the integer part is the lattice cell, the low bits the
    // fraction, so no rounding mode enters.
    static std::int64_t clamp_index(std::int64_t v, std::int64_t n) {
        const std::int64_t i = (v >> Pull::kBits) + ((v >> (Pull::kBits - 1)) & 1);  // round half up
        return i < 0 ? 0 : (i >= n ? n - 1 : i);
    }
    /// The element nearest() reads: its index into data.
    std::int64_t nearest_index(const std::int64_t* p) const {
        return (clamp_index(p[2], nz) * ny + clamp_index(p[1], ny)) * nx + clamp_index(p[0], nx);
    }
    float nearest(const std::int64_t* p) const { return element(nearest_index(p)); }
    static void cell(std::int64_t v, std::int64_t n, std::int64_t& i0, std::int64_t& i1, double& f) {
        i0 = v >> Pull::kBits;
        f = Pull::fraction(v);
        if (i0 < 0 || i0 >= n - 1) {  // clamped to the lattice
            i0 = i0 < 0 ? 0 : n - 1;
            f = 0;
        }
        i1 = i0 + 1 < n ? i0 + 1 : i0;
    }
    float trilinear(const std::int64_t* p) const {
        const std::int64_t x0 = p[0] >> Pull::kBits, y0 = p[1] >> Pull::kBits, z0 = p[2] >> Pull::kBits;
        if (static_cast<std::uint64_t>(x0) < static_cast<std::uint64_t>(nx - 1) &&
            static_cast<std::uint64_t>(y0) < static_cast<std::uint64_t>(ny - 1) &&
            static_cast<std::uint64_t>(z0) < static_cast<std::uint64_t>(nz - 1)) {
            // Inside the lattice (nearly always): the same arithmetic as below without clamping.
            const double fx = Pull::fraction(p[0]), fy = Pull::fraction(p[1]), fz = Pull::fraction(p[2]);
            const T* d = data + (z0 * ny + y0) * nx + x0;
            const std::int64_t sy = nx, sz = nx * ny;
            const double v000 = value(d[0]), v100 = value(d[1]);
            const double v010 = value(d[sy]), v110 = value(d[sy + 1]);
            const double v001 = value(d[sz]), v101 = value(d[sz + 1]);
            const double v011 = value(d[sz + sy]), v111 = value(d[sz + sy + 1]);
            const double c00 = v000 + fx * (v100 - v000);
            const double c10 = v010 + fx * (v110 - v010);
            const double c01 = v001 + fx * (v101 - v001);
            const double c11 = v011 + fx * (v111 - v011);
            const double c0 = c00 + fy * (c10 - c00), c1 = c01 + fy * (c11 - c01);
            return static_cast<float>(c0 + fz * (c1 - c0));
        }
        std::int64_t x1, y1, z1, xa, ya, za;
        double fx, fy, fz;
        cell(p[0], nx, xa, x1, fx);
        cell(p[1], ny, ya, y1, fy);
        cell(p[2], nz, za, z1, fz);
        const double c00 = at(xa, ya, za) + fx * (at(x1, ya, za) - at(xa, ya, za));
        const double c10 = at(xa, y1, za) + fx * (at(x1, y1, za) - at(xa, y1, za));
        const double c01 = at(xa, ya, z1) + fx * (at(x1, ya, z1) - at(xa, ya, z1));
        const double c11 = at(xa, y1, z1) + fx * (at(x1, y1, z1) - at(xa, y1, z1));
        const double c0 = c00 + fy * (c10 - c00), c1 = c01 + fy * (c11 - c01);
        return static_cast<float>(c0 + fz * (c1 - c0));
    }
    float sample(const std::int64_t* p, Sampling s) const {
        return s == Sampling::Nearest ? nearest(p) : trilinear(p);
    }
};

/// Calls f(Sampler<T>) for the source's element type.
template <class F>
void with_sampler(const VolumeView& v, F&& f) {
    const std::int64_t nx = v.grid.dims[0], ny = v.grid.dims[1], nz = v.grid.dims[2];
    switch (v.dtype) {
        case DType::UInt8: return f(Sampler<std::uint8_t>{static_cast<const std::uint8_t*>(v.data), nx, ny, nz});
        case DType::Int8: return f(Sampler<std::int8_t>{static_cast<const std::int8_t*>(v.data), nx, ny, nz});
        case DType::UInt16: return f(Sampler<std::uint16_t>{static_cast<const std::uint16_t*>(v.data), nx, ny, nz});
        case DType::Int16: return f(Sampler<std::int16_t>{static_cast<const std::int16_t*>(v.data), nx, ny, nz});
        case DType::UInt32: return f(Sampler<std::uint32_t>{static_cast<const std::uint32_t*>(v.data), nx, ny, nz});
        case DType::Int32: return f(Sampler<std::int32_t>{static_cast<const std::int32_t*>(v.data), nx, ny, nz});
        case DType::UInt64: return f(Sampler<std::uint64_t>{static_cast<const std::uint64_t*>(v.data), nx, ny, nz});
        case DType::Int64: return f(Sampler<std::int64_t>{static_cast<const std::int64_t*>(v.data), nx, ny, nz});
        case DType::Float32: return f(Sampler<float>{static_cast<const float*>(v.data), nx, ny, nz});
        case DType::Float64: return f(Sampler<double>{static_cast<const double*>(v.data), nx, ny, nz});
    }
}

}  // namespace volrig::deform_detail

// deform/value_out.hpp: where the stages that sample the source put a frame's values: float32, or IEEE half floats
// (DeformOptions::half, a bake's frames in bricks), rounded by OpenVDB's own conversion so that a frame written from
// half values is the file its floats would give.
#pragma once

#include <cstddef>
#include <cstdint>

#include <openvdb/Types.h>  // math::half

#include "volrig/deform.hpp"

namespace volrig::deform_detail {

struct ValueOut {
    float* f = nullptr;
    std::uint16_t* h = nullptr;

    /// The arrays a frame holds (neither: a binary frame).
    static ValueOut of(DeformedVolume& out) {
        return {out.values.empty() ? nullptr : out.values.data(), out.half_values.empty() ? nullptr : out.half_values.data()};
    }
    explicit operator bool() const { return f || h; }
    void put(std::size_t i, float v) const {
        if (h) h[i] = openvdb::math::half(v).bits();
        else f[i] = v;
    }
};

/// Marks elements [i0, i1) of the frame's value array written (pooled memory: volrig/memory.hpp).
inline void mark_values(DeformedVolume& out, std::size_t i0, std::size_t i1) {
    if (!out.values.empty()) out.values.mark_written(i0, i1);
    if (!out.half_values.empty()) out.half_values.mark_written(i0, i1);
}

}  // namespace volrig::deform_detail

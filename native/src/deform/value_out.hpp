// deform/value_out.hpp: where the stages put a frame's bone labels (int16, or bytes) and the samples of the source:
// float32, or IEEE half floats
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

/// Where they put its bone labels: int16, or bytes (DeformOptions::half with fewer than 255 bones).
struct BoneOut {
    std::int16_t* w = nullptr;
    std::uint8_t* b = nullptr;

    static BoneOut of(DeformedVolume& out) {
        return {out.bone.empty() ? nullptr : out.bone.data(), out.bone8.empty() ? nullptr : out.bone8.data()};
    }
    void put(std::size_t i, std::int32_t label) const {
        if (b) b[i] = static_cast<std::uint8_t>(label);
        else w[i] = static_cast<std::int16_t>(label);
    }
};

/// Marks elements [i0, i1) of the frame's value array written (pooled memory: volrig/memory.hpp).
inline void mark_values(DeformedVolume& out, std::size_t i0, std::size_t i1) {
    if (!out.values.empty()) out.values.mark_written(i0, i1);
    if (!out.half_values.empty()) out.half_values.mark_written(i0, i1);
}

/// Likewise its bone labels.
inline void mark_bones(DeformedVolume& out, std::size_t i0, std::size_t i1) {
    if (!out.bone.empty()) out.bone.mark_written(i0, i1);
    if (!out.bone8.empty()) out.bone8.mark_written(i0, i1);
}

}  // namespace volrig::deform_detail

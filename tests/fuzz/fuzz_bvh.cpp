// libFuzzer target for read_bvh: any input must either read or fail with a volrig::Error (a FileFormatError
// naming the input). Any other exception, crash, leak or sanitizer report is a finding. Built by scripts/fuzz.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "volrig/mocap.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const auto src = volrig::memory_source(data, size, "fuzz.bvh");
    volrig::ReadOptions opt;
    opt.max_bytes = std::uint64_t(64) << 20;
    try {
        const volrig::BvhMotion m = volrig::read_bvh(*src, opt);
        // What the reader promises: parents precede children, one finite number per channel and frame.
        std::uint64_t channels = 0;
        for (std::size_t j = 0; j < m.joints.size(); ++j) {
            if (m.joints[j].parent >= static_cast<std::int32_t>(j) || m.joints[j].channels.size() > 6) std::abort();
            channels += m.joints[j].channels.size();
        }
        if (channels != m.channel_count || m.frames.size() != m.frame_count * m.channel_count || m.frame_count == 0 ||
            !(m.frame_time > 0))
            std::abort();
        for (double v : m.frames)
            if (!std::isfinite(v)) std::abort();
    } catch (const volrig::Error&) {
    }
    return 0;
}

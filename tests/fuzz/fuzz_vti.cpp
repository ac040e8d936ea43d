// libFuzzer target for read_vti (VTK XML image data): any input must either read or fail with a volrig::Error (a
// FileFormatError naming the input). Any other exception, crash, leak or sanitizer report is a finding. Built by scripts/fuzz.
#include <cstddef>
#include <cstdint>

#include "volrig/io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const auto src = volrig::memory_source(data, size, "fuzz.vti");
    volrig::ReadOptions opt;
    opt.max_bytes = std::uint64_t(64) << 20;
    try {
        const volrig::Volume v = volrig::read_vti(*src, opt);
        (void)v;
    } catch (const volrig::Error&) {
    }
    return 0;
}

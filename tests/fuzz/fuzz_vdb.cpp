// libFuzzer target for read_vdb (OpenVDB's reader, which runs in a child process: io/isolate.cpp): any input must
// read or fail with a volrig::Error; an OpenVDB crash on a corrupt leaf must come back as a FileFormatError,
// never reach this process. read_vdb takes a path, so each input is written to a temporary file first. Built by
// scripts/fuzz (seeds: small float, half-float and int grids written by volrig).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

#include "volrig/io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const std::string path = "/tmp/volrig_fuzz_vdb_" + std::to_string(::getpid()) + ".vdb";
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return 0;
    const bool written = std::fwrite(data, 1, size, f) == size;
    std::fclose(f);
    if (!written) return 0;
    volrig::ReadOptions opt;
    opt.max_bytes = std::uint64_t(64) << 20;
    opt.max_bytes_given = true;
    try {
        const volrig::Volume v = volrig::read_vdb(path, "", opt);
        (void)v;
        (void)volrig::vdb_grids(path);
    } catch (const volrig::Error&) {
    }
    return 0;
}

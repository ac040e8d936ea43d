// libFuzzer target for the JPEG-family DICOM path (issue 55): the input is the one pixel data fragment of a fixed,
// well-formed JPEG Lossless DICOM file (16-bit grey, 4 x 4), so every run reaches GDCM's JPEG decoder, which runs
// in a child process (io/isolate.cpp). Any input must read or fail with a volrig::Error; a crash of the decoder
// must come back as a FileFormatError, never reach this process. Built by scripts/fuzz (seeds: a real JPEG
// Lossless stream from gdcmconv and the SOI-then-zeros stream that aborted GDCM).
#include <cstddef>
#include <cstdint>
#include <string>

#include "volrig/io.hpp"

namespace {

void u16(std::string& s, std::uint16_t v) {
    s += static_cast<char>(v & 0xff);
    s += static_cast<char>(v >> 8);
}
void u32(std::string& s, std::uint32_t v) {
    u16(s, static_cast<std::uint16_t>(v & 0xffff));
    u16(s, static_cast<std::uint16_t>(v >> 16));
}
// An explicit VR little endian element with a short (16-bit) length.
void element(std::string& s, std::uint16_t group, std::uint16_t elem, const char* vr, const std::string& value) {
    u16(s, group);
    u16(s, elem);
    s += vr;
    u16(s, static_cast<std::uint16_t>(value.size()));
    s += value;
}
std::string us(std::uint16_t v) {
    std::string s;
    u16(s, v);
    return s;
}

// The file: preamble, meta group, image pixel module, encapsulated pixel data (empty offset table, `fragment`).
std::string jpeg_file(const std::uint8_t* data, std::size_t size) {
    std::string f(128, '\0');
    f += "DICM";
    element(f, 0x0002, 0x0010, "UI", std::string("1.2.840.10008.1.2.4.70", 22));
    element(f, 0x0028, 0x0002, "US", us(1));
    element(f, 0x0028, 0x0004, "CS", "MONOCHROME2 ");
    element(f, 0x0028, 0x0010, "US", us(4));
    element(f, 0x0028, 0x0011, "US", us(4));
    element(f, 0x0028, 0x0100, "US", us(16));
    element(f, 0x0028, 0x0101, "US", us(16));
    element(f, 0x0028, 0x0102, "US", us(15));
    element(f, 0x0028, 0x0103, "US", us(0));
    u16(f, 0x7fe0);
    u16(f, 0x0010);
    f += "OB";
    u16(f, 0);
    u32(f, 0xffffffffu);  // undefined length: items follow
    u16(f, 0xfffe);
    u16(f, 0xe000);
    u32(f, 0);  // the basic offset table, empty
    const std::size_t padded = size + (size % 2);
    u16(f, 0xfffe);
    u16(f, 0xe000);
    u32(f, static_cast<std::uint32_t>(padded));
    f.append(reinterpret_cast<const char*>(data), size);
    if (padded != size) f += '\0';
    u16(f, 0xfffe);
    u16(f, 0xe0dd);
    u32(f, 0);
    return f;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size > (std::size_t(1) << 20)) return 0;
    const std::string file = jpeg_file(data, size);
    const auto src =
        volrig::memory_source(reinterpret_cast<const std::uint8_t*>(file.data()), file.size(), "fuzz_jpeg.dcm");
    volrig::ReadOptions opt;
    opt.max_bytes = std::uint64_t(64) << 20;
    try {
        const volrig::Volume v = volrig::read_dicom_file(*src, opt);
        (void)v;
    } catch (const volrig::Error&) {
    }
    return 0;
}

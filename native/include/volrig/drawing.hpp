// volrig/drawing.hpp: 2-D images (drawings to inflate): PNG through libpng.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "volrig/io.hpp"

namespace volrig {

/// An 8-bit RGBA image, rows top to bottom, 4 bytes per pixel (R, G, B, A).
struct Image {
    std::uint32_t width = 0, height = 0;
    std::vector<std::uint8_t> rgba;
};

/// Reads a PNG (any colour type and bit depth: grey, palette, RGB, with or without alpha or tRNS, 1..16 bits,
/// interlaced or not) as 8-bit RGBA through libpng's simplified API. Before allocating, the decoded size is
/// checked against opt.max_bytes and against what the file's compressed bytes could inflate to (a small file
/// declaring a huge image is refused). Every failure (not a PNG, truncated, corrupt data, absurd size) is a
/// FileFormatError naming the source and saying why.
Image read_png_file(const ByteSource& src, const ReadOptions& opt = {});
/// The same from a file path (FileNotFound when it does not exist).
Image read_png(const std::string& path, const ReadOptions& opt = {});

}  // namespace volrig

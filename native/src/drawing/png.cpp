// drawing/png.cpp: PNG images through libpng's simplified API (drawing.hpp says what is read and refused).
//
// The whole file is read into memory (it is checked against max_bytes first), libpng reads the header, the
// decoded size is checked (max_bytes; the deflate bound of the compressed bytes), then libpng decodes into an
// RGBA buffer of exactly that size. libpng's errors come back in png_image::message (its longjmp stays inside
// libpng's simplified API), never printed.
#include <png.h>

#include <cstring>

#include "io/zlib_inflate.hpp"
#include "io/io_detail.hpp"
#include "volrig/drawing.hpp"

namespace volrig {

namespace {

using io_detail::fail;
using io_detail::with_commas;

// A png_image that frees libpng's state however it is left.
class PngReader {
public:
    PngReader() {
        image_.version = PNG_IMAGE_VERSION;
        image_.opaque = nullptr;
    }
    ~PngReader() { png_image_free(&image_); }
    PngReader(const PngReader&) = delete;
    PngReader& operator=(const PngReader&) = delete;

    png_image& get() { return image_; }
    /// " (libpng: <message>)" when libpng said why, else "".
    std::string because() const {
        return image_.message[0] ? std::string(" (libpng: ") + image_.message + ")" : std::string();
    }

private:
    png_image image_{};
};

std::vector<std::uint8_t> file_bytes(const ByteSource& src, const ReadOptions& opt) {
    const std::uint64_t size = src.size();
    if (size > opt.max_bytes)
        fail(src.name(), "the file is " + with_commas(size) + " bytes, more than the limit of " +
                             with_commas(opt.max_bytes));
    if (size < 8) fail(src.name(), "not a PNG file: " + std::to_string(size) + " bytes");
    std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
    src.read(0, bytes.data(), bytes.size());
    if (png_sig_cmp(bytes.data(), 0, 8) != 0) fail(src.name(), "not a PNG file (no PNG signature)");
    return bytes;
}

// The decoded RGBA size; fails when it exceeds max_bytes or what `compressed` bytes can inflate to.
std::uint64_t checked_size(const ByteSource& src, const png_image& im, std::uint64_t compressed,
                           std::uint64_t bits_per_pixel, const ReadOptions& opt) {
    const std::uint64_t w = im.width, h = im.height;
    if (w == 0 || h == 0) fail(src.name(), "the image has no pixels");
    if (w > opt.max_bytes / 4 / h)  // w * h * 4 > max_bytes, without overflowing
        fail(src.name(), std::to_string(w) + " x " + std::to_string(h) + " pixels need " +
                             with_commas(static_cast<std::uint64_t>(static_cast<double>(w) * h * 4)) +
                             " bytes, more than the limit of " + with_commas(opt.max_bytes));
    const std::uint64_t bytes = w * h * 4;
    // The filtered rows the IDAT stream must hold: at least the pixels' bits (IHDR's bit depth x channels).
    const std::uint64_t least = (w * h * bits_per_pixel + 7) / 8;
    io_detail::check_inflate_bound(src.name(), least, compressed);
    io_detail::check_budget(src.name(), bytes, compressed, opt,
                            "the " + std::to_string(w) + " x " + std::to_string(h) + " RGBA pixels");
    return bytes;
}

// Bits per pixel of the file's own format, from IHDR (the first chunk, at byte 8): bit depth x channels.
std::uint64_t bits_per_pixel(const ByteSource& src, const std::vector<std::uint8_t>& bytes) {
    if (bytes.size() < 33 || std::memcmp(bytes.data() + 12, "IHDR", 4) != 0) fail(src.name(), "no IHDR chunk first");
    const unsigned depth = bytes[24], type = bytes[25];
    const unsigned channels = type == 0 ? 1 : type == 2 ? 3 : type == 3 ? 1 : type == 4 ? 2 : type == 6 ? 4 : 0;
    if (channels == 0 || depth == 0 || depth > 16) fail(src.name(), "IHDR colour type/bit depth is not valid");
    return std::uint64_t(depth) * channels;
}

}  // namespace

Image read_png_file(const ByteSource& src, const ReadOptions& opt) {
    const std::vector<std::uint8_t> bytes = file_bytes(src, opt);
    PngReader reader;
    png_image& im = reader.get();
    if (!png_image_begin_read_from_memory(&im, bytes.data(), bytes.size()))
        fail(src.name(), "not a PNG file libpng can read" + reader.because());
    im.format = PNG_FORMAT_RGBA;
    Image out;
    out.width = im.width;
    out.height = im.height;
    out.rgba.resize(static_cast<std::size_t>(checked_size(src, im, bytes.size(), bits_per_pixel(src, bytes), opt)));
    if (!png_image_finish_read(&im, nullptr, out.rgba.data(), 0, nullptr))
        fail(src.name(), "cannot decode the image" + reader.because());
    return out;
}

Image read_png(const std::string& path, const ReadOptions& opt) {
    io_detail::check_input_path(path);
    return read_png_file(*open_file(path), opt);
}

}  // namespace volrig

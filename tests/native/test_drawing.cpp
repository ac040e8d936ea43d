// Tests for read_png / read_png_file (drawing.hpp): images written here with libpng's simplified API (grey, grey +
// alpha, RGB, RGBA, 16-bit), read back as RGBA; truncated, corrupt, lying and oversized files refused with a
// FileFormatError naming the source; the fuzz corpus reads.
#include <catch2/catch.hpp>
#include <png.h>
#include <zlib.h>

#include <filesystem>
#include <string>
#include <vector>

#include "volrig/drawing.hpp"

using namespace volrig;
namespace fs = std::filesystem;

namespace {

// A w x h PNG of `format` (PNG_FORMAT_*) whose sample k is (k * 7) % 256 (16-bit: times 257).
std::vector<std::uint8_t> make_png(std::uint32_t w, std::uint32_t h, std::uint32_t format) {
    png_image im{};
    im.version = PNG_IMAGE_VERSION;
    im.width = w;
    im.height = h;
    im.format = format;
    const std::size_t samples = std::size_t(w) * h * PNG_IMAGE_SAMPLE_CHANNELS(format);
    std::vector<std::uint8_t> px8(samples);
    std::vector<std::uint16_t> px16(samples);
    for (std::size_t k = 0; k < samples; ++k) {
        px8[k] = static_cast<std::uint8_t>((k * 7) % 256);
        px16[k] = static_cast<std::uint16_t>(px8[k] * 257);
    }
    const void* px = (format & PNG_FORMAT_FLAG_LINEAR) ? static_cast<const void*>(px16.data()) : px8.data();
    png_alloc_size_t size = 0;
    REQUIRE(png_image_write_to_memory(&im, nullptr, &size, 0, px, 0, nullptr));
    std::vector<std::uint8_t> out(size);
    REQUIRE(png_image_write_to_memory(&im, out.data(), &size, 0, px, 0, nullptr));
    out.resize(size);
    return out;
}

Image read(const std::vector<std::uint8_t>& bytes, const std::string& name = "t.png", const ReadOptions& opt = {}) {
    return read_png_file(*memory_source(bytes.data(), bytes.size(), name), opt);
}

}  // namespace

TEST_CASE("read_png: RGBA and RGB images read back exactly, rows top first", "[png]") {
    const Image a = read(make_png(5, 3, PNG_FORMAT_RGBA));
    REQUIRE(a.width == 5);
    REQUIRE(a.height == 3);
    REQUIRE(a.rgba.size() == 5 * 3 * 4);
    for (std::size_t k = 0; k < a.rgba.size(); ++k) CHECK(a.rgba[k] == (k * 7) % 256);
    const Image b = read(make_png(4, 2, PNG_FORMAT_RGB));
    for (std::size_t p = 0; p < 8; ++p) {
        CHECK(b.rgba[4 * p] == (3 * p * 7) % 256);
        CHECK(b.rgba[4 * p + 3] == 255);  // opaque
    }
}

TEST_CASE("read_png: grey and grey + alpha become RGBA", "[png]") {
    const Image g = read(make_png(6, 2, PNG_FORMAT_GRAY));
    for (std::size_t p = 0; p < 12; ++p) {
        CHECK(g.rgba[4 * p] == (p * 7) % 256);
        CHECK(g.rgba[4 * p + 1] == g.rgba[4 * p]);
        CHECK(g.rgba[4 * p + 3] == 255);
    }
    const Image ga = read(make_png(3, 3, PNG_FORMAT_GA));
    CHECK(ga.rgba[3] == 7);  // the first pixel's alpha is sample 1
}

TEST_CASE("read_png: 16-bit images are read as 8-bit", "[png]") {
    const Image a = read(make_png(4, 4, PNG_FORMAT_LINEAR_RGB_ALPHA));
    REQUIRE(a.width == 4);
    CHECK(a.rgba[3] == 21);  // alpha is linear: sample 3 = 21 * 257 -> 21
}

TEST_CASE("read_png: bad files are refused naming the source", "[png]") {
    const std::vector<std::uint8_t> good = make_png(40, 30, PNG_FORMAT_RGBA);
    SECTION("not a PNG") {
        const std::vector<std::uint8_t> text = {'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd'};
        CHECK_THROWS_WITH(read(text, "hello.png"), Catch::StartsWith("hello.png: not a PNG file"));
        CHECK_THROWS_AS(read({0x89, 'P'}, "tiny.png"), FileFormatError);
    }
    SECTION("truncated") {
        for (std::size_t n : {std::size_t(8), std::size_t(20), std::size_t(40), good.size() / 2, good.size() - 13})
            CHECK_THROWS_WITH(read({good.begin(), good.begin() + static_cast<long>(n)}, "cut.png"),
                              Catch::StartsWith("cut.png: "));
    }
    SECTION("corrupt image data") {
        std::vector<std::uint8_t> bad = good;
        for (std::size_t k = 45; k < bad.size() - 20; k += 3) bad[k] ^= 0x5a;
        CHECK_THROWS_WITH(read(bad, "bad.png"), Catch::StartsWith("bad.png: "));
    }
    SECTION("a header that lies about the size") {
        std::vector<std::uint8_t> lying = good;  // IHDR width and height at bytes 16..23: 60000 x 60000
        for (int i : {16, 20}) {
            lying[i] = 0;
            lying[i + 1] = 0;
            lying[i + 2] = 0xea;
            lying[i + 3] = 0x60;
        }
        // the IHDR CRC no longer matches: libpng refuses it; with a matching CRC the size checks would
        CHECK_THROWS_WITH(read(lying, "lying.png"), Catch::StartsWith("lying.png: "));
    }
    SECTION("over the size limit") {
        ReadOptions opt;
        opt.max_bytes = 40 * 30 * 4 - 1;
        CHECK_THROWS_WITH(read(good, "big.png", opt), Catch::Contains("more than the limit"));
    }
    SECTION("a missing file") { CHECK_THROWS_AS(read_png("/nonexistent/x.png"), FileNotFound); }
}

TEST_CASE("read_png: a huge declared size with a valid CRC is refused before decoding", "[png]") {
    std::vector<std::uint8_t> big = make_png(40, 30, PNG_FORMAT_RGBA);
    for (int i : {16, 20}) {  // 30000 x 30000: 3.6 GB of RGBA from a few hundred bytes
        big[i] = 0;
        big[i + 1] = 0;
        big[i + 2] = 0x75;
        big[i + 3] = 0x30;
    }
    const std::uint32_t crc = static_cast<std::uint32_t>(crc32(0, big.data() + 12, 17));
    for (int k = 0; k < 4; ++k) big[29 + k] = static_cast<std::uint8_t>(crc >> (24 - 8 * k));
    CHECK_THROWS_WITH(read(big, "huge.png"), Catch::StartsWith("huge.png: ") &&
                                                 (Catch::Contains("limit") || Catch::Contains("inflate")));
    ReadOptions opt;
    opt.max_bytes = std::uint64_t(1) << 40;
    CHECK_THROWS_WITH(read(big, "huge.png", opt), Catch::Contains("can inflate to at most"));
}

TEST_CASE("read_png: the fuzz corpus reads", "[png]") {
    const fs::path corpus = fs::path(VOLRIG_FUZZ_CORPUS) / "png";
    int n = 0;
    for (const auto& e : fs::directory_iterator(corpus)) {
        const Image im = read_png(e.path().string());
        CHECK(im.rgba.size() == std::size_t(im.width) * im.height * 4);
        ++n;
    }
    CHECK(n >= 4);
}

// Tests for read_tiff / read_tiff_file (io.hpp): multi-page files and folders of numbered files written here with
// libtiff (strips and tiles, every sample type, resolution units), mismatched pages, colour, the fuzz corpus.
#include <catch2/catch.hpp>
#include <tiffio.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <unistd.h>
#include <vector>

#include "volrig/io.hpp"

using namespace volrig;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir(const std::string& name) {
    fs::path d = fs::temp_directory_path() / ("volrig_tiff_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

struct PageSpec {
    std::uint32_t width = 5, height = 3;
    std::uint16_t bits = 16, format = SAMPLEFORMAT_UINT, samples = 1;
    bool tiled = false;
    float xres = 0, yres = 0;  // 0: no resolution tags
    std::uint16_t unit = RESUNIT_CENTIMETER;
};

// Writes `pages` pages; sample i of page k is value(k, i) converted to the page's type.
void write_tiff(const fs::path& p, const PageSpec& s, int pages, const std::function<double(int, int)>& value) {
    TIFF* t = TIFFOpen(p.string().c_str(), "w");
    REQUIRE(t);
    const std::size_t esize = s.bits / 8;
    for (int k = 0; k < pages; ++k) {
        TIFFSetField(t, TIFFTAG_IMAGEWIDTH, s.width);
        TIFFSetField(t, TIFFTAG_IMAGELENGTH, s.height);
        TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, s.bits);
        TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, s.format);
        TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, s.samples);
        TIFFSetField(t, TIFFTAG_PHOTOMETRIC, s.samples == 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK);
        TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
        TIFFSetField(t, TIFFTAG_COMPRESSION, COMPRESSION_ADOBE_DEFLATE);
        if (s.xres > 0) {
            TIFFSetField(t, TIFFTAG_XRESOLUTION, s.xres);
            TIFFSetField(t, TIFFTAG_YRESOLUTION, s.yres);
            TIFFSetField(t, TIFFTAG_RESOLUTIONUNIT, s.unit);
        }
        const std::size_t row = s.width * esize * s.samples;
        std::vector<std::uint8_t> img(row * s.height);
        for (std::uint32_t i = 0; i < s.width * s.height * s.samples; ++i) {
            const double v = value(k, static_cast<int>(i));
            std::uint8_t* at = img.data() + i * esize;
            if (s.format == SAMPLEFORMAT_IEEEFP) {
                const float f = static_cast<float>(v);
                std::memcpy(at, &f, 4);
            } else if (s.bits == 8) {
                at[0] = static_cast<std::uint8_t>(static_cast<std::int64_t>(v));
            } else if (s.bits == 16) {
                const auto x = static_cast<std::uint16_t>(static_cast<std::int64_t>(v));
                std::memcpy(at, &x, 2);
            } else {
                const auto x = static_cast<std::uint32_t>(static_cast<std::int64_t>(v));
                std::memcpy(at, &x, 4);
            }
        }
        if (s.tiled) {
            TIFFSetField(t, TIFFTAG_TILEWIDTH, 16);
            TIFFSetField(t, TIFFTAG_TILELENGTH, 16);
            const std::size_t px = esize * s.samples;
            for (std::uint32_t y0 = 0; y0 < s.height; y0 += 16)
                for (std::uint32_t x0 = 0; x0 < s.width; x0 += 16) {
                    std::vector<std::uint8_t> tile(16 * 16 * px, 0);
                    for (std::uint32_t y = y0; y < std::min(y0 + 16, s.height); ++y)
                        std::memcpy(tile.data() + (y - y0) * 16 * px, img.data() + y * row + x0 * px,
                                    std::min<std::uint32_t>(16, s.width - x0) * px);
                    REQUIRE(TIFFWriteTile(t, tile.data(), x0, y0, 0, 0) > 0);
                }
        } else {
            TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, 2);
            for (std::uint32_t y = 0; y < s.height; ++y) REQUIRE(TIFFWriteScanline(t, img.data() + y * row, y, 0) == 1);
        }
        REQUIRE(TIFFWriteDirectory(t));
    }
    TIFFClose(t);
}

template <class T>
T at(const Volume& v, std::int64_t x, std::int64_t y, std::int64_t z) {
    T out;
    std::memcpy(&out, v.data.data() + v.grid.index(x, y, z) * sizeof(T), sizeof(T));
    return out;
}

}  // namespace

TEST_CASE("TIFF: a multi-page uint16 file; spacing from its resolution", "[tiff]") {
    const fs::path dir = temp_dir("pages");
    PageSpec s;
    s.xres = 40, s.yres = 20;  // pixels per cm: 0.25 mm by 0.5 mm
    write_tiff(dir / "stack.tif", s, 4, [](int k, int i) { return 1000 * k + i; });
    const Volume v = read_volume((dir / "stack.tif").string());
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{5, 3, 4});
    REQUIRE(v.dtype == DType::UInt16);
    CHECK(at<std::uint16_t>(v, 4, 2, 3) == 3000 + 2 * 5 + 4);
    CHECK(v.grid.spacing[0] == Approx(0.25));
    CHECK(v.grid.spacing[1] == Approx(0.5));
    CHECK(v.grid.spacing[2] == Approx(0.25));  // z = x unless given
    ReadOptions opt;
    opt.spacing = {0, 0, 2};
    const Volume z2 = read_volume((dir / "stack.tif").string(), opt);
    CHECK(z2.grid.spacing[0] == Approx(0.25));
    CHECK(z2.grid.spacing[2] == Approx(2));
    s.unit = RESUNIT_INCH;
    s.xres = s.yres = 254;  // 0.1 mm
    write_tiff(dir / "inch.tiff", s, 1, [](int, int i) { return i; });
    CHECK(read_volume((dir / "inch.tiff").string()).grid.spacing[1] == Approx(0.1));
    fs::remove_all(dir);
}

TEST_CASE("TIFF: a folder of numbered files in natural order, every sample type, tiles", "[tiff]") {
    const fs::path dir = temp_dir("folder");
    PageSpec s;
    s.bits = 16;
    s.format = SAMPLEFORMAT_INT;
    for (int k : {1, 2, 10, 9})
        write_tiff(dir / ("slice" + std::to_string(k) + ".tif"), s, 1, [k](int, int i) { return -100 * k - i; });
    const Volume v = read_volume(dir.string());
    REQUIRE(v.dtype == DType::Int16);
    CHECK(v.grid.dims[2] == 4);
    CHECK(at<std::int16_t>(v, 0, 0, 0) == -100);
    CHECK(at<std::int16_t>(v, 0, 0, 2) == -900);  // slice9 before slice10
    CHECK(at<std::int16_t>(v, 1, 0, 3) == -1001);
    fs::remove_all(dir);

    const fs::path types = temp_dir("types");
    const struct {
        std::uint16_t bits, format;
        DType want;
    } cases[] = {{8, SAMPLEFORMAT_UINT, DType::UInt8},   {8, SAMPLEFORMAT_INT, DType::Int8},
                 {32, SAMPLEFORMAT_UINT, DType::UInt32}, {32, SAMPLEFORMAT_INT, DType::Int32},
                 {32, SAMPLEFORMAT_IEEEFP, DType::Float32}};
    for (const auto& c : cases) {
        PageSpec t;
        t.bits = c.bits;
        t.format = c.format;
        t.tiled = c.bits == 32;
        t.width = 20;  // two tiles across
        const fs::path p = types / ("t" + std::to_string(c.bits) + "_" + std::to_string(c.format) + ".tif");
        write_tiff(p, t, 2, [](int k, int i) { return 50 * k + i % 50; });
        const Volume w = read_volume(p.string());
        CHECK(w.dtype == c.want);
        CHECK(w.grid.dims == std::array<std::int64_t, 3>{20, 3, 2});
        if (c.want == DType::Float32) CHECK(at<float>(w, 19, 2, 1) == Approx(50 + (2 * 20 + 19) % 50));
        if (c.want == DType::UInt32) CHECK(at<std::uint32_t>(w, 19, 2, 1) == 50 + (2 * 20 + 19) % 50);
    }
    fs::remove_all(types);
}

TEST_CASE("TIFF: mismatched pages, colour and junk are refused naming the file", "[tiff][errors]") {
    const fs::path dir = temp_dir("bad");
    PageSpec s;
    write_tiff(dir / "a1.tif", s, 1, [](int, int i) { return i; });
    s.width = 6;
    write_tiff(dir / "a2.tif", s, 1, [](int, int i) { return i; });
    CHECK_THROWS_WITH(read_volume(dir.string()),
                      Catch::Contains("a2.tif: page 1 is 6x3 uint16 where the first page is 5x3 uint16"));
    PageSpec rgb;
    rgb.bits = 8;
    rgb.samples = 3;
    write_tiff(dir / "rgb.tif", rgb, 1, [](int, int i) { return i; });
    CHECK_THROWS_WITH(read_volume((dir / "rgb.tif").string()),
                      Catch::Contains("rgb.tif: page 1: 3 samples per pixel"));
    const std::string junk = "II*\0garbage that is not a TIFF directory";
    auto src = memory_source(reinterpret_cast<const std::uint8_t*>(junk.data()), junk.size(), "junk.tif");
    CHECK_THROWS_WITH(read_tiff_file(*src), Catch::StartsWith("junk.tif: "));
    ReadOptions small;
    small.max_bytes = 20;
    CHECK_THROWS_WITH(read_volume((dir / "a1.tif").string(), small), Catch::Contains("exceeds the limit"));
    const fs::path empty = temp_dir("empty");
    CHECK_THROWS_WITH(read_tiff(empty.string()), Catch::Contains("no .tif or .tiff files"));
    fs::remove_all(empty);
    fs::remove_all(dir);
}

TEST_CASE("TIFF: the fuzz corpus never crashes the reader", "[tiff][fuzz]") {
    const fs::path corpus = fs::path(VOLRIG_FUZZ_CORPUS) / "tiff";
    REQUIRE(fs::is_directory(corpus));
    int n = 0, read = 0;
    for (const auto& e : fs::directory_iterator(corpus)) {
        std::ifstream f(e.path(), std::ios::binary);
        const std::vector<std::uint8_t> b((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
        auto src = memory_source(b.data(), b.size(), e.path().filename().string());
        try {
            read_tiff_file(*src);
            ++read;
        } catch (const FileFormatError&) {
        }
        ++n;
    }
    CHECK(n > 0);
    CHECK(read == n);  // the seeds are valid files
}

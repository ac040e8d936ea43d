// Tests for read_dicom / read_dicom_file / dicom_series (io.hpp): series written here byte by byte (explicit VR
// little endian Part-10 files), shuffled, rescaled, broken; the fuzz corpus never crashes the reader.
// (tests/python/test_io_dicom.py covers compressed series, written with pydicom and gdcmconv.)
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <unistd.h>
#include <vector>

#include "volrig/io.hpp"

using namespace volrig;
namespace fs = std::filesystem;

namespace {

using Bytes = std::vector<std::uint8_t>;

Bytes operator+(Bytes a, const Bytes& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

// One explicit VR little endian element; strings padded to even length (UI with NUL, others with a space).
void element(Bytes& out, std::uint16_t group, std::uint16_t elem, const char* vr, Bytes value) {
    if (value.size() % 2) value.push_back(std::strcmp(vr, "UI") == 0 ? 0 : ' ');
    auto put16 = [&](std::uint32_t v) { out.push_back(v & 0xff), out.push_back((v >> 8) & 0xff); };
    put16(group);
    put16(elem);
    out.push_back(static_cast<std::uint8_t>(vr[0]));
    out.push_back(static_cast<std::uint8_t>(vr[1]));
    const bool long_form = std::strcmp(vr, "OB") == 0 || std::strcmp(vr, "OW") == 0;
    if (long_form) {
        put16(0);
        put16(value.size() & 0xffff);
        put16(value.size() >> 16);
    } else {
        put16(static_cast<std::uint32_t>(value.size()));
    }
    out.insert(out.end(), value.begin(), value.end());
}
Bytes text(const std::string& s) { return Bytes(s.begin(), s.end()); }
Bytes us(std::uint16_t v) { return Bytes{static_cast<std::uint8_t>(v & 0xff), static_cast<std::uint8_t>(v >> 8)}; }

struct SliceSpec {
    std::string series = "1.2.3.4.5";
    std::string description = "test";
    std::uint16_t rows = 3, cols = 4;
    std::array<double, 3> position{0, 0, 0};
    std::string orientation = "1\\0\\0\\0\\1\\0";
    std::string spacing = "0.5\\0.25";  // row spacing (y), column spacing (x)
    std::string slope = "1", intercept = "-1024";
    std::int16_t first_value = 0;  // pixels: first_value, first_value + 1, ...
};

std::string ds(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

// A CT slice as a Part-10 file (preamble, DICM, meta group, data set).
Bytes slice_file(const SliceSpec& s) {
    Bytes meta;
    element(meta, 0x0002, 0x0001, "OB", Bytes{0, 1});
    element(meta, 0x0002, 0x0002, "UI", text("1.2.840.10008.5.1.4.1.1.2"));
    element(meta, 0x0002, 0x0003, "UI", text("1.2.3.9"));
    element(meta, 0x0002, 0x0010, "UI", text("1.2.840.10008.1.2.1"));
    Bytes out(128, 0);
    for (char c : std::string("DICM")) out.push_back(static_cast<std::uint8_t>(c));
    element(out, 0x0002, 0x0000, "UL", Bytes{static_cast<std::uint8_t>(meta.size()), 0, 0, 0});
    out.insert(out.end(), meta.begin(), meta.end());
    element(out, 0x0008, 0x0016, "UI", text("1.2.840.10008.5.1.4.1.1.2"));
    element(out, 0x0008, 0x0060, "CS", text("CT"));
    element(out, 0x0008, 0x103e, "LO", text(s.description));
    element(out, 0x0020, 0x000d, "UI", text("1.2.3"));
    element(out, 0x0020, 0x000e, "UI", text(s.series));
    element(out, 0x0020, 0x0032, "DS", text(ds(s.position[0]) + "\\" + ds(s.position[1]) + "\\" + ds(s.position[2])));
    element(out, 0x0020, 0x0037, "DS", text(s.orientation));
    element(out, 0x0028, 0x0002, "US", us(1));
    element(out, 0x0028, 0x0004, "CS", text("MONOCHROME2"));
    element(out, 0x0028, 0x0010, "US", us(s.rows));
    element(out, 0x0028, 0x0011, "US", us(s.cols));
    element(out, 0x0028, 0x0030, "DS", text(s.spacing));
    element(out, 0x0028, 0x0100, "US", us(16));
    element(out, 0x0028, 0x0101, "US", us(16));
    element(out, 0x0028, 0x0102, "US", us(15));
    element(out, 0x0028, 0x0103, "US", us(1));
    element(out, 0x0028, 0x1052, "DS", text(s.intercept));
    element(out, 0x0028, 0x1053, "DS", text(s.slope));
    Bytes pixels;
    for (int i = 0; i < s.rows * s.cols; ++i) {
        const auto v = static_cast<std::uint16_t>(static_cast<std::int16_t>(s.first_value + i));
        pixels.push_back(v & 0xff);
        pixels.push_back(v >> 8);
    }
    element(out, 0x7fe0, 0x0010, "OW", pixels);
    return out;
}

void write_file(const fs::path& p, const Bytes& b) {
    std::ofstream f(p, std::ios::binary);
    f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    REQUIRE(f.good());
}

fs::path temp_dir(const std::string& name) {
    fs::path d = fs::temp_directory_path() / ("volrig_dicom_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

// n axial slices (z = 10 + 2 k) in shuffled files; slice k's pixels start at 100 k.
fs::path write_series(const std::string& name, int n, SliceSpec s = {}) {
    const fs::path dir = temp_dir(name);
    std::vector<int> order(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) order[static_cast<std::size_t>(k)] = k;
    std::shuffle(order.begin(), order.end(), std::mt19937(3));
    for (int i = 0; i < n; ++i) {
        const int k = order[static_cast<std::size_t>(i)];
        s.position = {-5, 7, 10 + 2.0 * k};
        s.first_value = static_cast<std::int16_t>(100 * k);
        write_file(dir / ("f" + std::to_string(i)), slice_file(s));
    }
    return dir;
}

}  // namespace

TEST_CASE("DICOM: a shuffled axial series is sorted, spaced from positions and rescaled to int16", "[dicom]") {
    const fs::path dir = write_series("axial", 5);
    const Volume v = read_volume(dir.string());
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{4, 3, 5});
    CHECK(v.grid.spacing[0] == Approx(0.25));
    CHECK(v.grid.spacing[1] == Approx(0.5));
    CHECK(v.grid.spacing[2] == Approx(2));
    CHECK(v.grid.origin == std::array<double, 3>{-5, 7, 10});
    for (int i = 0; i < 9; ++i) CHECK(v.grid.direction[i] == Approx(kIdentity3[i]));
    REQUIRE(v.dtype == DType::Int16);
    const auto* p = reinterpret_cast<const std::int16_t*>(v.data.data());
    for (int k = 0; k < 5; ++k)
        for (int i = 0; i < 12; ++i) CHECK(p[k * 12 + i] == 100 * k + i - 1024);
    const auto series = dicom_series(dir.string());
    REQUIRE(series.size() == 1);
    CHECK(series[0].uid == "1.2.3.4.5");
    CHECK(series[0].modality == "CT");
    CHECK(series[0].dims == std::array<std::int64_t, 3>{4, 3, 5});
    fs::remove_all(dir);
}

TEST_CASE("DICOM: one file from memory; float32 for fractional rescale", "[dicom]") {
    SliceSpec s;
    s.slope = "0.5";
    s.intercept = "1.25";
    s.first_value = -3;
    const Bytes b = slice_file(s);
    auto src = memory_source(b.data(), b.size(), "one.dcm");
    const Volume v = read_dicom_file(*src);
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{4, 3, 1});
    REQUIRE(v.dtype == DType::Float32);
    const auto* p = reinterpret_cast<const float*>(v.data.data());
    for (int i = 0; i < 12; ++i) CHECK(p[i] == Approx((i - 3) * 0.5 + 1.25));
    ReadOptions small;
    small.max_bytes = 10;
    CHECK_THROWS_AS(read_dicom_file(*src, small), FileFormatError);
}

TEST_CASE("DICOM: bad series name the folder and the problem", "[dicom][errors]") {
    const fs::path dir = write_series("missing", 5);
    // f? holding slice 2 (z = 14) is removed: a gap of 4 where the others are 2.
    for (const auto& e : fs::directory_iterator(dir)) {
        std::ifstream f(e.path(), std::ios::binary);
        const std::string all((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
        if (all.find("-5\\7\\14") != std::string::npos) fs::remove(e.path());
    }
    CHECK_THROWS_WITH(read_volume(dir.string()),
                      Catch::StartsWith(dir.string() + ": incomplete series: no slice at 4 mm (-5, 7, 14) (along the "
                                                       "slice normal from ") &&
                          Catch::EndsWith("where the others are 2 mm apart"));
    SliceSpec other;
    other.cols = 5;
    other.position = {-5, 7, 30};
    write_file(dir / "wide", slice_file(other));
    CHECK_THROWS_WITH(read_volume(dir.string()), Catch::Contains("mixed slice sizes"));
    ReadOptions pick;
    pick.series = "7.7";
    CHECK_THROWS_WITH(read_dicom(dir.string(), pick), Catch::Contains("no series with SeriesInstanceUID '7.7'"));
    fs::remove_all(dir);

    const fs::path empty = temp_dir("empty");
    write_file(empty / "readme.txt", Bytes{'h', 'i'});
    CHECK_THROWS_WITH(read_dicom(empty.string()), Catch::Contains("no DICOM images found"));
    fs::remove_all(empty);
    const Bytes junk(200, 7);
    auto src = memory_source(junk.data(), junk.size(), "junk.dcm");
    CHECK_THROWS_WITH(read_dicom_file(*src), Catch::StartsWith("junk.dcm: "));
}

TEST_CASE("DICOM: the fuzz corpus never crashes the reader", "[dicom][fuzz]") {
    const fs::path corpus = fs::path(VOLRIG_FUZZ_CORPUS) / "dicom";
    REQUIRE(fs::is_directory(corpus));
    int n = 0;
    for (const auto& e : fs::directory_iterator(corpus)) {
        std::ifstream f(e.path(), std::ios::binary);
        const Bytes b((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
        auto src = memory_source(b.data(), b.size(), e.path().filename().string());
        try {
            read_dicom_file(*src);
        } catch (const FileFormatError&) {
        }
        ++n;
    }
    CHECK(n > 0);
}

TEST_CASE("DICOM: broken Part-10 structure is refused before GDCM sees it", "[dicom][errors]") {
    const Bytes good = slice_file(SliceSpec{});
    auto refuse = [](const Bytes& b, const std::string& what) {
        auto src = memory_source(b.data(), b.size(), "b.dcm");
        CHECK_THROWS_WITH(read_dicom_file(*src), Catch::StartsWith("b.dcm: ") && Catch::Contains(what));
    };
    // a meta element whose length runs past the end of the file (Debian's GDCM aborts on it)
    Bytes meta_past(128, 0);
    for (char c : std::string("DICM\x02\x00\x10\x00UI\xff\xff", 12)) meta_past.push_back(static_cast<std::uint8_t>(c));
    refuse(meta_past, "a file meta element runs past the end of the file");
    refuse(Bytes(good.begin(), good.begin() + 100), "not a DICOM Part-10 file");
    Bytes cut(good.begin(), good.end() - 5);  // pixel data shorter than its length
    refuse(cut, "an element's value runs past the end of the file");
    Bytes undefined = good;  // the modality (CS) with an undefined length
    const std::string cs("\x08\x00\x60\x00" "CS", 6);
    auto at = std::search(undefined.begin(), undefined.end(), cs.begin(), cs.end());
    REQUIRE(at != undefined.end());
    Bytes item = Bytes(undefined.begin(), at) + Bytes{0xfe, 0xff, 0x00, 0xe0, 0, 0, 0, 0} + Bytes(at, undefined.end());
    refuse(item, "an item tag where an element was expected");
    Bytes twice = good;  // the modality element repeated: GDCM would keep the first, the checks see the last
    at = std::search(twice.begin(), twice.end(), cs.begin(), cs.end());
    const std::size_t n = 8 + (static_cast<std::size_t>(at[6]) | (static_cast<std::size_t>(at[7]) << 8));
    twice = Bytes(twice.begin(), at + static_cast<std::ptrdiff_t>(n)) + Bytes(at, at + static_cast<std::ptrdiff_t>(n)) +
            Bytes(at + static_cast<std::ptrdiff_t>(n), twice.end());
    refuse(twice, "element (0008,0060) appears twice in one data set");
    Bytes bad_vr = good;
    at = std::search(bad_vr.begin(), bad_vr.end(), cs.begin(), cs.end());
    at[4] = 'c';
    refuse(bad_vr, "is not a DICOM VR");
}

TEST_CASE("DICOM: inputs that crashed GDCM are refused with an error", "[dicom][errors]") {
    const auto refuse = [](const char* name, const char* what) {
        std::ifstream f(fs::path(VOLRIG_FUZZ_CORPUS) / "dicom" / name, std::ios::binary);
        REQUIRE(f);
        const Bytes b((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
        auto src = memory_source(b.data(), b.size(), name);
        CHECK_THROWS_WITH(read_dicom_file(*src), Catch::Contains(what));
    };
    // A fuzzer's: RLE with Bits Allocated given twice, 4 then 16 (GDCM's RLE decoder asserted on the first).
    refuse("rle-duplicate-bits-allocated.dcm", "appears twice in one data set");
    // Another: the transfer syntax given twice in the meta group, RLE then a bogus UID (the RLE checks were skipped
    // for the second, GDCM decoded the broken frame as the first says and read out of bounds).
    refuse("rle-repeated-transfer-syntax.dcm", "element (0002,0010) appears twice in the file meta group");
}

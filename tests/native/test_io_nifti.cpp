// Tests for volrig/io.hpp's NIfTI-1 reader: hand-written headers for each feature and every kind of bad input.
#include <catch2/catch.hpp>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <string>
#include <sys/stat.h>
#include <unistd.h>
#include <vector>

#include "volrig/io.hpp"

#include "io_fixture.hpp"

using namespace volrig;
namespace fs = std::filesystem;

// =================================================================================================================
// NIfTI-1
// =================================================================================================================

TEST_CASE("NIfTI: single file, both byte orders, every datatype", "[io][nifti]") {
    const std::pair<std::int16_t, DType> types[] = {
        {2, DType::UInt8},     {4, DType::Int16},     {8, DType::Int32},    {16, DType::Float32}, {64, DType::Float64},
        {256, DType::Int8},    {512, DType::UInt16},  {768, DType::UInt32}, {1024, DType::Int64}, {1280, DType::UInt64}};
    for (bool big : {false, true}) {
        for (const auto& [code, t] : types) {
            INFO(dtype_name(t) << (big ? " big" : " little"));
            Nifti n;
            n.big = big;
            n.datatype = code;
            n.bitpix = static_cast<std::int16_t>(8 * dtype_size(t));
            const Volume ref = random_volume(t, {2, 3, 4}, code);
            Bytes data = ref.data;
            if (big)
                for (std::size_t i = 0; i < data.size(); i += dtype_size(t))
                    std::reverse(data.begin() + static_cast<std::ptrdiff_t>(i),
                                 data.begin() + static_cast<std::ptrdiff_t>(i + dtype_size(t)));
            const Volume v = read_mem(read_nifti, n.header() + data, "v.nii");
            CHECK(v.dtype == t);
            CHECK(v.grid.dims == std::array<std::int64_t, 3>{2, 3, 4});
            CHECK(v.grid.spacing == std::array<double, 3>{1.5, 2, 2.5});
            CHECK(v.data == ref.data);
        }
    }
}

TEST_CASE("NIfTI: scl_slope/scl_inter", "[io][nifti]") {
    Nifti n;
    n.dim[1] = 4;
    n.dim[2] = 1;
    n.dim[3] = 1;
    n.datatype = 4;
    n.bitpix = 16;
    const Bytes data = raw_of<std::int16_t>({-1000, 0, 1, 3000});
    SECTION("applied: float32 result") {
        n.slope = 0.5f;
        n.inter = -10;
        const Volume v = read_mem(read_nifti, n.header() + data, "s.nii");
        CHECK(v.dtype == DType::Float32);
        CHECK(values<float>(v) == std::vector<float>{-510.f, -10.f, -9.5f, 1490.f});
    }
    SECTION("applied, big endian") {
        n.big = true;
        n.slope = 2;
        n.inter = 1;
        const Volume v = read_mem(read_nifti, n.header() + raw_of<std::int16_t>({-1000, 0, 1, 3000}, true), "s.nii");
        CHECK(values<float>(v) == std::vector<float>{-1999.f, 1.f, 3.f, 6001.f});
    }
    SECTION("slope 0 or (1, 0): untouched") {
        n.slope = 0;
        n.inter = 5;
        CHECK(read_mem(read_nifti, n.header() + data, "s.nii").dtype == DType::Int16);
        n.slope = 1;
        n.inter = 0;
        CHECK(values<std::int16_t>(read_mem(read_nifti, n.header() + data, "s.nii")) ==
              std::vector<std::int16_t>{-1000, 0, 1, 3000});
    }
    SECTION("float64 stays float64; too large for float32: float64; beyond double: refused") {
        n.datatype = 64;
        n.bitpix = 64;
        n.slope = 3;
        const Volume v = read_mem(read_nifti, n.header() + raw_of<double>({1, 2, 1e300, -1}), "d.nii");
        CHECK(v.dtype == DType::Float64);
        CHECK(values<double>(v) == std::vector<double>{3, 6, 3e300, -3});
        n.datatype = 1280;
        n.slope = 3e38f;
        const Volume w = read_mem(read_nifti, n.header() + raw_of<std::uint64_t>({0, 1, 2, ~0ull}), "u.nii");
        CHECK(w.dtype == DType::Float64);  // it was float32 with inf: a silently wrong volume (issue 55)
        CHECK(values<double>(w) == std::vector<double>{0, double(3e38f), 2 * double(3e38f),
                                                       static_cast<double>(~0ull) * double(3e38f)});
        n.datatype = 64;
        n.bitpix = 64;
        std::string what;
        try {
            read_mem(read_nifti, n.header() + raw_of<double>({1, 1e300, 0, -1}), "o.nii");
        } catch (const FileFormatError& e) {
            what = e.what();
        }
        CHECK(what == "o.nii: scl_slope/scl_inter 3.0000000054977558e+38/0 take the stored values -1 to 1e+300 beyond "
                      "the range of a double");
    }
    SECTION("NaN or infinite slope is refused") {
        n.slope = std::numeric_limits<float>::quiet_NaN();
        expect_error([&] { read_mem(read_nifti, n.header() + data, "nan.nii"); }, {"nan.nii", "scl_slope", "nan"});
        n.slope = std::numeric_limits<float>::infinity();
        expect_error([&] { read_mem(read_nifti, n.header() + data, "inf.nii"); }, {"inf.nii", "scl_slope", "inf"});
        n.slope = 2;
        n.inter = std::numeric_limits<float>::infinity();
        expect_error([&] { read_mem(read_nifti, n.header() + data, "inf.nii"); }, {"inf.nii", "scl_inter"});
    }
}

TEST_CASE("NIfTI: origin from sform or qform, extensions, 4-D with one volume", "[io][nifti]") {
    Nifti n;
    n.qoffset[0] = 1;
    n.qoffset[1] = 2;
    n.qoffset[2] = 3;
    n.srow[0][3] = -10;
    n.srow[1][3] = -20;
    n.srow[2][3] = -30;
    const Bytes data(24, 5);
    // no qform/sform code: NIfTI's "method 1", the qoffsets as given, no rotation
    CHECK(read_mem(read_nifti, n.header() + data, "0.nii").grid.origin == std::array<double, 3>{1, 2, 3});
    // NIfTI's RAS becomes LPS: x and y negated (tests/native/test_io_orientation.cpp tests rotations)
    n.qform = 1;
    const Grid q = read_mem(read_nifti, n.header() + data, "q.nii").grid;
    CHECK(q.origin == std::array<double, 3>{-1, -2, 3});
    CHECK(q.direction == Matrix3{-1, 0, 0, 0, -1, 0, 0, 0, 1});
    n.sform = 2;
    const Grid sf = read_mem(read_nifti, n.header() + data, "s.nii").grid;
    CHECK(sf.origin == std::array<double, 3>{10, 20, -30});
    CHECK(sf.direction == Matrix3{-1, 0, 0, 0, -1, 0, 0, 0, 1});
    n.vox_offset = 496;  // header extensions before the data
    n.pixdim[1] = -1.5f;  // negative pixdim: spacing is |pixdim|
    n.dim[0] = 5;
    const Volume v = read_mem(read_nifti, n.header() + data, "e.nii");
    CHECK(v.data == data);
    CHECK(v.grid.spacing[0] == 1.5);
    n.dim[0] = 2;  // 2-D: pixdim[3] is ignored even when 0
    n.dim[3] = 7;
    n.pixdim[3] = 0;
    CHECK(read_mem(read_nifti, n.header() + Bytes(6, 5), "2d.nii").grid.dims == std::array<std::int64_t, 3>{2, 3, 1});
}

TEST_CASE("NIfTI: .hdr/.img pair and .nii.gz", "[io][nifti]") {
    TempDir dir;
    Nifti n;
    n.magic = "ni1";
    n.vox_offset = 0;
    n.datatype = 512;
    n.bitpix = 16;
    const Volume ref = random_volume(DType::UInt16, {2, 3, 4}, 5);
    write_file(dir / "pair.hdr", n.header(false));
    write_file(dir / "pair.img", ref.data);
    CHECK(read_volume(dir / "pair.hdr").data == ref.data);
    write_file(dir / "UP.HDR", n.header(false));
    write_file(dir / "UP.IMG", ref.data);
    CHECK(read_volume(dir / "UP.HDR").data == ref.data);
    write_file(dir / "lonely.hdr", n.header(false));
    expect_error<FileNotFound>([&] { read_volume(dir / "lonely.hdr"); }, {"lonely.hdr", "lonely.img"});
    expect_error([&] { read_mem(read_nifti, n.header(false), "mem.hdr"); }, {"mem.hdr", "detached data files are not available"});
    write_file(dir / "short.hdr", n.header(false));
    write_file(dir / "short.img", Bytes(10, 0));
    expect_error([&] { read_volume(dir / "short.hdr"); }, {"short.hdr", "2x3x4 uint16 = 48 bytes but data file", "short.img holds 10"});

    Nifti s;
    s.datatype = 512;
    s.bitpix = 16;
    s.big = true;
    Bytes be = ref.data;
    for (std::size_t i = 0; i < be.size(); i += 2) std::swap(be[i], be[i + 1]);
    write_file(dir / "v.nii.gz", gzip(s.header() + be));
    const Volume v = read_volume(dir / "v.nii.gz");
    CHECK(v.data == ref.data);
    CHECK(v.grid.spacing == std::array<double, 3>{1.5, 2, 2.5});
    // a .nii that is gzip-compressed anyway is recognised by its bytes
    write_file(dir / "actually_gz.nii", gzip(s.header() + be));
    CHECK(read_volume(dir / "actually_gz.nii").data == ref.data);
}

TEST_CASE("NIfTI: bad headers name the file and the problem", "[io][nifti][errors]") {
    auto err = [&](const Nifti& n, std::initializer_list<std::string> parts, const Bytes& data = Bytes(24, 0)) {
        expect_error([&] { read_mem(read_nifti, n.header() + data, "bad.nii"); }, parts);
    };
    expect_error([&] { read_mem(read_nifti, Bytes(100, 0), "tiny.nii"); }, {"tiny.nii", "holds 100 bytes, less than the 348-byte"});
    expect_error([&] { read_mem(read_nifti, Bytes{}, "empty.nii"); }, {"empty.nii", "holds 0 bytes"});
    {
        Nifti n;
        n.sizeof_hdr = 540;
        err(n, {"bad.nii", "NIfTI-2", "not supported"});
        n.big = true;
        err(n, {"bad.nii", "NIfTI-2"});
        n.sizeof_hdr = 12345;
        err(n, {"bad.nii", "not a NIfTI-1 file", "sizeof_hdr"});
    }
    {
        Nifti n;
        n.magic = "abc";
        err(n, {"bad.nii", "Analyze 7.5"});
    }
    {
        Nifti n;
        n.dim[0] = 4;
        n.dim[4] = 5;
        err(n, {"bad.nii", "4-D NIfTI (5 volumes) not supported"});
        n.dim[0] = 8;
        err(n, {"bad.nii", "dim[0] = 8"});
        n.dim[0] = 3;
        n.dim[2] = -3;
        err(n, {"bad.nii", "dim[2] = -3 must be positive"});
        n.dim[2] = 0;
        err(n, {"bad.nii", "dim[2] = 0"});
        n.dim[1] = n.dim[2] = n.dim[3] = 32767;
        err(n, {"bad.nii", "exceeds the limit"});
    }
    {
        Nifti n;
        n.datatype = 32;
        n.bitpix = 64;
        err(n, {"bad.nii", "complex64", "not supported"});
        n.datatype = 128;
        n.bitpix = 24;
        err(n, {"bad.nii", "RGB24"});
        n.datatype = 2304;
        n.bitpix = 32;
        err(n, {"bad.nii", "RGBA32"});
        n.datatype = 3;
        err(n, {"bad.nii", "unknown datatype 3"});
        n.datatype = 16;
        n.bitpix = 8;
        err(n, {"bad.nii", "bitpix 8 disagrees with datatype 16 (float32, 32 bits)"});
    }
    {
        Nifti n;
        n.pixdim[2] = 0;
        err(n, {"bad.nii", "pixdim[2] = 0"});
        n.pixdim[2] = std::numeric_limits<float>::quiet_NaN();
        err(n, {"bad.nii", "pixdim[2] = nan"});
    }
    {
        Nifti n;
        n.sform = 1;
        n.srow[1][3] = std::numeric_limits<float>::infinity();
        err(n, {"bad.nii", "srow_y", "finite"});
    }
    {
        Nifti n;
        n.vox_offset = 100;
        err(n, {"bad.nii", "vox_offset 100", "at least 352"});
        n.vox_offset = std::numeric_limits<float>::quiet_NaN();
        err(n, {"bad.nii", "vox_offset nan"});
        n.vox_offset = -1;
        err(n, {"bad.nii", "vox_offset -1"});
        n.vox_offset = 3e38f;
        err(n, {"bad.nii", "vox_offset"});
        n.vox_offset = 1e9f;
        err(n, {"bad.nii", "header says 2x3x4 uint8 = 24 bytes but the file holds 0", "past its end"});
    }
    {
        Nifti n;
        err(n, {"bad.nii", "header says 2x3x4 uint8 = 24 bytes but the file holds 20"}, Bytes(20, 0));
        const Bytes garbage = random_volume(DType::UInt8, {400, 1, 1}).data;
        expect_error([&] { read_mem(read_nifti, garbage, "garbage.nii"); }, {"garbage.nii", "not a NIfTI-1 file"});
    }
}

TEST_CASE("NIfTI: broken .nii.gz", "[io][nifti][errors][gzip]") {
    Nifti n;
    const Bytes full = n.header() + Bytes(24, 7);
    auto err = [&](const Bytes& file, std::initializer_list<std::string> parts, ReadOptions opt = {}) {
        expect_error([&] { read_mem(read_nifti, file, "bad.nii.gz", opt); }, parts);
    };
    CHECK(read_mem(read_nifti, gzip(full), "ok.nii.gz").data == Bytes(24, 7));
    err(gzip(Bytes(full.begin(), full.begin() + 200)), {"bad.nii.gz", "truncated: 200 of 348 bytes"});
    err(gzip(Bytes(full.begin(), full.end() - 4)), {"bad.nii.gz", "truncated: 372 of 376 bytes"});
    err(gzip(full + Bytes(1 << 20, 0)), {"bad.nii.gz", "more data than the header declares"});
    Bytes cut = gzip(full);
    cut.resize(cut.size() - 10);
    err(cut, {"bad.nii.gz", "truncated"});
    Bytes corrupt = gzip(full);
    corrupt[corrupt.size() / 2] ^= 0xff;
    corrupt[corrupt.size() / 2 + 1] ^= 0xff;
    CHECK_THROWS_AS(read_mem(read_nifti, corrupt, "c.nii.gz"), FileFormatError);
    Nifti big;
    big.dim[1] = big.dim[2] = big.dim[3] = 32767;
    big.datatype = 64;
    big.bitpix = 64;
    ReadOptions unlimited;
    unlimited.max_bytes = std::uint64_t(1) << 62;
    err(gzip(big.header()), {"bad.nii.gz", "can inflate to at most"}, unlimited);
}

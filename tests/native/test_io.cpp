// Tests for volrig/io.hpp (NRRD, MetaImage, NIfTI-1, raw; atomic writes): round trips, hand-written headers for
// each feature, every kind of bad input. MetaImage: test_io_metaimage.cpp; NIfTI-1: test_io_nifti.cpp; the fuzz
// corpus and the real scans in ../shared/data when present: test_io_real.cpp.
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
// Round trips
// =================================================================================================================

TEST_CASE("NRRD round trip for every dtype, gzip and raw", "[io][nrrd]") {
    TempDir dir;
    for (DType t : kAllTypes) {
        for (bool gz : {true, false}) {
            INFO(dtype_name(t) << (gz ? " gzip" : " raw"));
            const Volume v = random_volume(t, {5, 4, 3}, static_cast<std::uint32_t>(t) + 1);
            const std::string path = dir / (std::string("rt_") + dtype_name(t) + (gz ? ".nrrd" : "_raw.nrrd"));
            write_nrrd(path, v.view(), gz);
            check_same(read_volume(path), v);
        }
    }
    // Only the written files remain (no temporary names).
    for (const auto& e : dir.entries()) CHECK(e.find(".tmp-") == std::string::npos);
}

TEST_CASE("MetaImage round trip for every dtype, compressed and not", "[io][metaimage]") {
    TempDir dir;
    for (DType t : kAllTypes) {
        for (bool z : {true, false}) {
            INFO(dtype_name(t) << (z ? " compressed" : " raw"));
            const Volume v = random_volume(t, {3, 5, 2}, static_cast<std::uint32_t>(t) + 11);
            const std::string path = dir / (std::string("rt_") + dtype_name(t) + (z ? ".mha" : "_raw.mha"));
            write_metaimage(path, v.view(), z);
            check_same(read_volume(path), v);
        }
    }
}

TEST_CASE("Writers keep awkward spacing and origin exactly", "[io]") {
    TempDir dir;
    Volume v = random_volume(DType::Float32, {2, 2, 2});
    v.grid.spacing = {0.1, 1.0 / 3.0, 1e-7};
    v.grid.origin = {-123.456789012345, 1e300, -0.0};
    write_nrrd(dir / "a.nrrd", v.view());
    write_metaimage(dir / "a.mha", v.view());
    check_same(read_volume(dir / "a.nrrd"), v);
    check_same(read_volume(dir / "a.mha"), v);
}

TEST_CASE("MetaImage writer fills in CompressedDataSize", "[io][metaimage]") {
    TempDir dir;
    const Volume v = random_volume(DType::Int16, {8, 8, 8});
    write_metaimage(dir / "c.mha", v.view(), true);
    const Bytes file = read_file(dir / "c.mha");
    const std::string text(file.begin(), file.end());
    const auto at = text.find("CompressedDataSize = ");
    REQUIRE(at != std::string::npos);
    const auto data_at = text.find("ElementDataFile = LOCAL\n") + std::strlen("ElementDataFile = LOCAL\n");
    CHECK(std::stoull(text.substr(at + 21)) == file.size() - data_at);
}

TEST_CASE("Writers refuse bad volumes", "[io]") {
    TempDir dir;
    Volume v = random_volume(DType::UInt8, {2, 2, 2});
    v.grid.spacing[1] = std::nan("");
    CHECK_THROWS_AS(write_nrrd(dir / "x.nrrd", v.view()), Error);
    v.grid.spacing[1] = 1;
    v.grid.dims[2] = 0;
    CHECK_THROWS_AS(write_metaimage(dir / "x.mha", v.view()), Error);
    CHECK(dir.entries().empty());
}

// =================================================================================================================
// Atomic writes
// =================================================================================================================

TEST_CASE("write_atomically renames into place and cleans up on failure", "[io][atomic]") {
    TempDir dir;
    const std::string target = dir / "out.bin";
    write_file(target, bytes("old"));
    std::string seen_tmp;
    CHECK_THROWS_AS(write_atomically(target,
                                     [&](const std::string& tmp) {
                                         seen_tmp = tmp;
                                         write_file(tmp, bytes("partial"));
                                         throw Error("boom");
                                     }),
                    Error);
    CHECK(fs::path(seen_tmp).parent_path() == fs::path(target).parent_path());
    CHECK(!fs::exists(seen_tmp));
    CHECK(read_file(target) == bytes("old"));
    CHECK(dir.entries() == std::vector<std::string>{"out.bin"});

    write_atomically(target, [&](const std::string& tmp) { write_file(tmp, bytes("new")); });
    CHECK(read_file(target) == bytes("new"));
    CHECK(dir.entries() == std::vector<std::string>{"out.bin"});
}

TEST_CASE("Writers into a missing or read-only folder fail and leave nothing", "[io][atomic]") {
    TempDir dir;
    const Volume v = random_volume(DType::UInt8, {4, 4, 4});
    expect_error<FileNotFound>([&] { write_nrrd(dir / "missing/x.nrrd", v.view()); }, {"missing/x.nrrd", "cannot create"});
    CHECK(dir.entries().empty());
    if (::geteuid() != 0) {  // root ignores permissions
        fs::create_directory(dir.path / "ro");
        fs::permissions(dir.path / "ro", fs::perms::owner_read | fs::perms::owner_exec);
        expect_error<Error>([&] { write_metaimage(dir / "ro/x.mha", v.view()); }, {"ro/x.mha", "cannot create"});
        fs::permissions(dir.path / "ro", fs::perms::owner_all);
        CHECK(fs::is_empty(dir.path / "ro"));
    }
    // Target is a directory: the rename fails, the temporary file is removed.
    fs::create_directory(dir.path / "isdir.nrrd");
    fs::create_directory(dir.path / "isdir.nrrd" / "keep");
    CHECK_THROWS_AS(write_nrrd(dir / "isdir.nrrd", v.view()), Error);
    for (const auto& e : dir.entries()) CHECK(e.find(".tmp-") == std::string::npos);
}

// =================================================================================================================
// Sources, dispatch, limits
// =================================================================================================================

TEST_CASE("open_file and read_volume report missing files and unknown formats", "[io]") {
    TempDir dir;
    expect_error<FileNotFound>([&] { open_file(dir / "nope.raw"); }, {"nope.raw", "no such file"});
    expect_error<FileNotFound>([&] { read_volume(dir / "nope.nrrd"); }, {"nope.nrrd"});
    expect_error<FileNotFound>([&] { read_volume(dir / "nope.nii.gz"); }, {"nope.nii.gz"});
    write_file(dir / "x.txt", bytes("hello"));
    expect_error<FileFormatError>([&] { read_volume(dir / "x.txt"); }, {"x.txt", "unknown volume format"});
    expect_error<FileNotFound>([&] { read_volume(dir.path.string() + "/.nrrd"); }, {".nrrd"});
    fs::create_directory(dir.path / "d.nrrd");
    expect_error<FileNotFound>([&] { read_volume(dir / "d.nrrd"); }, {"d.nrrd", "directory"});
}

TEST_CASE("ByteSource reads exactly or says what is missing", "[io]") {
    const Bytes b = bytes("0123456789");
    auto src = memory_source(b.data(), b.size(), "mem.bin");
    char buf[4];
    src->read(6, buf, 4);
    CHECK(std::string(buf, 4) == "6789");
    expect_error([&] { src->read(8, buf, 4); }, {"mem.bin", "4 bytes at offset 8"});
    expect_error([&] { src->read(std::numeric_limits<std::uint64_t>::max(), buf, 4); }, {"mem.bin"});
    expect_error([&] { src->open_sibling("x.raw"); },
                 {"mem.bin", "detached data files are not available for in-memory input"});
    TempDir dir;
    write_file(dir / "f.bin", b);
    auto f = open_file(dir / "f.bin");
    CHECK(f->size() == 10);
    CHECK(f->name() == dir / "f.bin");
    expect_error([&] { f->read(7, buf, 4); }, {"f.bin", "but the file holds 10 bytes"});
    expect_error<FileNotFound>([&] { f->open_sibling("other.raw"); }, {"f.bin", "other.raw"});
    auto sib = f->open_sibling("f.bin");
    CHECK(sib->size() == 10);
    auto abs = f->open_sibling(dir / "f.bin");
    CHECK(abs->size() == 10);
}

TEST_CASE("default_max_bytes honours VOLRIG_MAX_BYTES", "[io]") {
    const char* old = std::getenv("VOLRIG_MAX_BYTES");
    const std::string saved = old ? old : "";
    ::unsetenv("VOLRIG_MAX_BYTES");
    CHECK(default_max_bytes() == (std::uint64_t(16) << 30));
    ::setenv("VOLRIG_MAX_BYTES", "1000", 1);
    CHECK(default_max_bytes() == 1000);
    ::setenv("VOLRIG_MAX_BYTES", "2M", 1);
    CHECK(default_max_bytes() == (std::uint64_t(2) << 20));
    ::setenv("VOLRIG_MAX_BYTES", "3GiB", 1);
    CHECK(default_max_bytes() == (std::uint64_t(3) << 30));
    ::setenv("VOLRIG_MAX_BYTES", "lots", 1);
    CHECK(default_max_bytes() == (std::uint64_t(16) << 30));
    ::setenv("VOLRIG_MAX_BYTES", "64", 1);
    {
        ReadOptions opt;
        CHECK(opt.max_bytes == 64);
        const Bytes b = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 5\nencoding: raw\n\n" + Bytes(80, 1);
        expect_error([&] { read_mem(read_nrrd, b, "limit.nrrd", opt); }, {"limit.nrrd", "exceeds the limit of 64"});
    }
    if (old)
        ::setenv("VOLRIG_MAX_BYTES", saved.c_str(), 1);
    else
        ::unsetenv("VOLRIG_MAX_BYTES");
}

TEST_CASE("read_raw reads the layout it is given", "[io][raw]") {
    TempDir dir;
    const Bytes data = Bytes{9, 9, 9} + raw_of<std::int16_t>({1, -2, 300, -400, 5, 6}, true);
    write_file(dir / "v.raw", data);
    RawLayout layout;
    layout.dims = {3, 2, 1};
    layout.dtype = DType::Int16;
    layout.big_endian = true;
    layout.offset = 3;
    layout.spacing = {2, 2, 2};
    layout.origin = {1, 2, 3};
    auto src = open_file(dir / "v.raw");
    const Volume v = read_raw(*src, layout);
    CHECK(values<std::int16_t>(v) == std::vector<std::int16_t>{1, -2, 300, -400, 5, 6});
    CHECK(v.grid.spacing == std::array<double, 3>{2, 2, 2});
    CHECK(v.grid.origin == std::array<double, 3>{1, 2, 3});

    layout.dims = {3, 2, 2};
    expect_error([&] { read_raw(*src, layout); }, {"v.raw", "3x2x2 int16 = 24 bytes but the file holds 12"});
    layout.dims = {1 << 20, 1 << 20, 1};
    expect_error([&] { read_raw(*src, layout); }, {"v.raw", "exceeds the limit"});
    layout.dims = {3, -2, 1};
    expect_error([&] { read_raw(*src, layout); }, {"v.raw", "must all be positive"});
    layout.dims = {3, 2, 1};
    layout.offset = 1000;
    expect_error([&] { read_raw(*src, layout); }, {"v.raw", "past its end"});
    layout.offset = 0;
    layout.spacing = {1, std::nan(""), 1};
    expect_error([&] { read_raw(*src, layout); }, {"v.raw", "spacing"});
}

// =================================================================================================================
// NRRD features
// =================================================================================================================

TEST_CASE("NRRD: the tooth-like attached raw header", "[io][nrrd]") {
    const Bytes data = raw_of<std::uint8_t>({1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12});
    const Bytes b = "NRRD0004\n# Complete NRRD file format specification at:\n"
                    "# http://teem.sourceforge.net/nrrd/format.html\ntype: uint8_t\ndimension: 3\n"
                    "space: left-posterior-superior\nsizes: 3 2 2\nspace directions: (0.5,0,0) (0,-2,0) (0,0,3)\n"
                    "kinds: domain domain domain\nendian: little\nencoding: raw\nspace origin: (1.5,-2,100)\n\n" +
                    data;
    const Volume v = read_mem(read_nrrd, b, "tooth-like.nrrd");
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{3, 2, 2});
    CHECK(v.grid.spacing == std::array<double, 3>{0.5, 2, 3});
    CHECK(v.grid.origin == std::array<double, 3>{1.5, -2, 100});
    CHECK(v.data == data);
}

TEST_CASE("NRRD: every type alias", "[io][nrrd]") {
    const std::pair<const char*, DType> aliases[] = {
        {"uchar", DType::UInt8}, {"unsigned char", DType::UInt8}, {"uint8", DType::UInt8}, {"uint8_t", DType::UInt8},
        {"signed char", DType::Int8}, {"int8", DType::Int8}, {"int8_t", DType::Int8}, {"short", DType::Int16},
        {"short int", DType::Int16}, {"signed short", DType::Int16}, {"signed short int", DType::Int16},
        {"int16", DType::Int16}, {"int16_t", DType::Int16}, {"ushort", DType::UInt16},
        {"unsigned short", DType::UInt16}, {"unsigned short int", DType::UInt16}, {"uint16", DType::UInt16},
        {"uint16_t", DType::UInt16}, {"int", DType::Int32}, {"signed int", DType::Int32}, {"int32", DType::Int32},
        {"int32_t", DType::Int32}, {"uint", DType::UInt32}, {"unsigned int", DType::UInt32},
        {"uint32", DType::UInt32}, {"uint32_t", DType::UInt32}, {"longlong", DType::Int64},
        {"long long", DType::Int64}, {"long long int", DType::Int64}, {"signed long long", DType::Int64},
        {"signed long long int", DType::Int64}, {"int64", DType::Int64}, {"int64_t", DType::Int64},
        {"ulonglong", DType::UInt64}, {"unsigned long long", DType::UInt64},
        {"unsigned long long int", DType::UInt64}, {"uint64", DType::UInt64}, {"uint64_t", DType::UInt64},
        {"float", DType::Float32}, {"double", DType::Float64}, {"Unsigned  Short", DType::UInt16}};
    for (const auto& [name, t] : aliases) {
        INFO(name);
        const Bytes b = "NRRD0005\ntype: " + std::string(name) + "\ndimension: 3\nsizes: 2 1 1\nendian: little\n"
                        "encoding: raw\n\n" + Bytes(2 * dtype_size(t), 7);
        const Volume v = read_mem(read_nrrd, b, "alias.nrrd");
        CHECK(v.dtype == t);
        CHECK(v.data == Bytes(2 * dtype_size(t), 7));
    }
}

TEST_CASE("NRRD: detached header with line skip and byte skip", "[io][nrrd]") {
    TempDir dir;
    fs::create_directory(dir.path / "data");
    const Bytes payload = raw_of<std::uint16_t>({10, 20, 30, 40, 50, 60}, true);
    write_file(dir / "data/v.raw", bytes("junk line 1\njunk line 2\n") + Bytes{0xEE, 0xEE} + payload);
    write_file(dir / "v.nhdr", bytes("NRRD0004\ntype: ushort\ndimension: 2\nsizes: 3 2\nspacings: 0.25 4\n"
                                     "endian: big\nencoding: raw\nline skip: 2\nbyte skip: 2\n"
                                     "data file: data/v.raw\n"));
    const Volume v = read_volume(dir / "v.nhdr");
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{3, 2, 1});
    CHECK(v.grid.spacing == std::array<double, 3>{0.25, 4, 1});
    CHECK(values<std::uint16_t>(v) == std::vector<std::uint16_t>{10, 20, 30, 40, 50, 60});

    // "datafile" spelling, byte skip -1 (data at the end), an absolute path
    write_file(dir / "w.nhdr", bytes("NRRD0004\ntype: ushort\ndimension: 2\nsizes: 3 2\nendian: big\n"
                                     "encoding: raw\nbyte skip: -1\ndatafile: " + (dir / "data/v.raw") + "\n\n"));
    CHECK(values<std::uint16_t>(read_volume(dir / "w.nhdr")) == std::vector<std::uint16_t>{10, 20, 30, 40, 50, 60});

    // the data file is missing
    write_file(dir / "m.nhdr", bytes("NRRD0004\ntype: uchar\ndimension: 1\nsizes: 3\nencoding: raw\n"
                                     "data file: gone.raw\n"));
    expect_error<FileNotFound>([&] { read_volume(dir / "m.nhdr"); }, {"m.nhdr", "gone.raw"});
    // line skip past the end
    write_file(dir / "l.nhdr", bytes("NRRD0004\ntype: uchar\ndimension: 1\nsizes: 3\nencoding: raw\nline skip: 9\n"
                                     "data file: data/v.raw\n"));
    expect_error([&] { read_volume(dir / "l.nhdr"); }, {"l.nhdr", "line skip 9 runs past the end"});
    // in memory, a detached header cannot be followed
    const Bytes mem = read_file(dir / "v.nhdr");
    expect_error([&] { read_mem(read_nrrd, mem, "mem.nhdr"); }, {"mem.nhdr", "detached data files are not available"});
}

TEST_CASE("NRRD: gzip encoding, with byte skip, multi-member", "[io][nrrd]") {
    const Bytes data = raw_of<float>({1.5f, -2.f, 3.25f, 4.f, 5.f, 6.f, 7.f, 8.f});
    const std::string h = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\nencoding: gzip\n";
    CHECK(read_mem(read_nrrd, h + "\n" + gzip(data), "g.nrrd").data == data);
    CHECK(read_mem(read_nrrd, h + "byte skip: 3\n\n" + gzip(Bytes{1, 2, 3} + data), "g.nrrd").data == data);
    // concatenated gzip members (cat a.gz b.gz)
    const Bytes first(data.begin(), data.begin() + 13), second(data.begin() + 13, data.end());
    CHECK(read_mem(read_nrrd, h + "\n" + gzip(first) + gzip(second), "g.nrrd").data == data);
    // "gz" spelling and zlib (not gzip) streams are decoded too
    const std::string hz = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\nencoding: gz\n\n";
    CHECK(read_mem(read_nrrd, hz + zlib(data), "z.nrrd").data == data);
}

TEST_CASE("NRRD: big endian, ascii, CRLF, comments, key/values, 2-D, 4-D with a unit axis", "[io][nrrd]") {
    SECTION("big endian double") {
        const Bytes b = "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 1 1\nendian: big\nencoding: raw\n\n" +
                        raw_of<double>({1.25, -7e100}, true);
        CHECK(values<double>(read_mem(read_nrrd, b, "be.nrrd")) == std::vector<double>{1.25, -7e100});
    }
    SECTION("ascii") {
        const Bytes b = bytes("NRRD0004\ntype: float\ndimension: 2\nsizes: 3 2\nencoding: ascii\n\n"
                              "1.5 -2\n3e2,\t+4\n  nan\n-inf\n");
        const auto v = values<float>(read_mem(read_nrrd, b, "a.nrrd"));
        CHECK(v[0] == 1.5f);
        CHECK(v[1] == -2.f);
        CHECK(v[2] == 300.f);
        CHECK(v[3] == 4.f);
        CHECK(std::isnan(v[4]));
        CHECK(v[5] == -std::numeric_limits<float>::infinity());
        const Bytes ints = bytes("NRRD0004\ntype: short\ndimension: 1\nsizes: 4\nencoding: text\n\n-32768 32767 1e2 7.0");
        CHECK(values<std::int16_t>(read_mem(read_nrrd, ints, "i.nrrd")) == std::vector<std::int16_t>{-32768, 32767, 100, 7});
        expect_error([&] { read_mem(read_nrrd, bytes("NRRD0004\ntype: uchar\ndimension: 1\nsizes: 2\nencoding: txt\n\n1 256"), "o.nrrd"); },
                     {"o.nrrd", "text value #2 '256' is not a valid uint8"});
        expect_error([&] { read_mem(read_nrrd, bytes("NRRD0004\ntype: int\ndimension: 1\nsizes: 2\nencoding: ascii\n\n1 1.5"), "f.nrrd"); },
                     {"f.nrrd", "'1.5' is not a valid int32"});
        expect_error([&] { read_mem(read_nrrd, bytes("NRRD0004\ntype: int\ndimension: 1\nsizes: 3\nencoding: ascii\n\n1 2 x"), "x.nrrd"); },
                     {"x.nrrd", "'x'"});
        expect_error([&] { read_mem(read_nrrd, bytes("NRRD0004\ntype: int\ndimension: 1\nsizes: 3\nencoding: ascii\n\n1   2  "), "t.nrrd"); },
                     {"t.nrrd", "truncated: 2 of 3 values"});
        expect_error([&] { read_mem(read_nrrd, bytes("NRRD0004\ntype: int\ndimension: 1\nsizes: 30\nencoding: ascii\n\n1 2"), "r.nrrd"); },
                     {"r.nrrd", "30 values", "holds 3 bytes of text"});
    }
    SECTION("CRLF, comments, key/value pairs, unknown fields") {
        const Bytes b = "NRRD0004\r\n# a comment\r\ncreator:=someone: with colons\r\ntype: uchar\r\ncontent: x\r\n"
                        "dimension: 3\r\nsizes: 1 2 1\r\nencoding: raw\r\nthicknesses: 1 1 1\r\n\r\n" +
                        Bytes{4, 5};
        CHECK(read_mem(read_nrrd, b, "crlf.nrrd").data == Bytes{4, 5});
    }
    SECTION("4-D with a stub/scalar axis, and with a size-1 domain axis") {
        const Bytes b = "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 1 2 3 1\nkinds: scalar domain domain domain\n"
                        "space directions: none (2,0,0) (0,3,0) (0,0,4)\nencoding: raw\n\n" + Bytes(6, 1);
        const Volume v = read_mem(read_nrrd, b, "4d.nrrd");
        CHECK(v.grid.dims == std::array<std::int64_t, 3>{2, 3, 1});
        CHECK(v.grid.spacing == std::array<double, 3>{2, 3, 4});
        const Bytes c = "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 2 3 4 1\nencoding: raw\n\n" + Bytes(24, 1);
        CHECK(read_mem(read_nrrd, c, "4d.nrrd").grid.dims == std::array<std::int64_t, 3>{2, 3, 4});
    }
    SECTION("axis mins give the origin when there is no space origin") {
        const Bytes b = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\naxis mins: -1 2.5 nan\nspacings: 1 1 1\n"
                        "encoding: raw\n\n" + Bytes{1};
        CHECK(read_mem(read_nrrd, b, "mins.nrrd").grid.origin == std::array<double, 3>{-1, 2.5, 0});
    }
}

// =================================================================================================================
// NRRD bad input
// =================================================================================================================

TEST_CASE("NRRD: bad headers name the file and the problem", "[io][nrrd][errors]") {
    const std::string ok_tail = "encoding: raw\n\n";
    auto hdr = [](const std::string& fields) { return bytes("NRRD0004\n" + fields + "\n") + Bytes(64, 0); };
    auto err = [&](const Bytes& b, std::initializer_list<std::string> parts) {
        expect_error([&] { read_mem(read_nrrd, b, "bad.nrrd"); }, parts);
    };
    err(bytes("NRRX0004\n"), {"bad.nrrd", "not a NRRD file"});
    err(Bytes{}, {"bad.nrrd", "not a NRRD file"});
    err(bytes("NRRD000"), {"bad.nrrd", "not a NRRD file"});
    err(hdr("type: uchar\ndimension: 3\nencoding: raw\n"), {"bad.nrrd", "missing field 'sizes'"});
    err(hdr("dimension: 3\nsizes: 1 1 1\nencoding: raw\n"), {"bad.nrrd", "missing field 'type'"});
    err(hdr("type: uchar\nsizes: 1 1 1\nencoding: raw\n"), {"bad.nrrd", "missing field 'dimension'"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\n"), {"bad.nrrd", "missing field 'encoding'"});
    err(hdr("type: quaternion\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n"), {"bad.nrrd", "type 'quaternion'"});
    err(hdr("type: block\nblock size: 4\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n"), {"bad.nrrd", "type 'block'", "not supported"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: bzip2\n"), {"bad.nrrd", "bzip2", "not supported"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: hex\n"), {"bad.nrrd", "hex", "not supported"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: zip\n"), {"bad.nrrd", "'zip'"});
    err(hdr("type: short\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n"), {"bad.nrrd", "missing field 'endian'", "int16"});
    err(hdr("type: short\ndimension: 3\nsizes: 1 1 1\nendian: middle\nencoding: raw\n"), {"bad.nrrd", "endian 'middle'"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 3 -4 5\nencoding: raw\n"), {"bad.nrrd", "line 4", "sizes '3 -4 5'", "positive"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 3 0 5\nencoding: raw\n"), {"bad.nrrd", "positive"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 3 4\nencoding: raw\n"), {"bad.nrrd", "must list 3 sizes"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 99999999999999999999 1 1\nencoding: raw\n"), {"bad.nrrd", "positive integers"});
    err(hdr("type: uchar\ndimension: 0\nsizes: \nencoding: raw\n"), {"bad.nrrd", "dimension '0'"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1048576 1048576 1\nencoding: raw\n"), {"bad.nrrd", "exceeds the limit"});
    err(hdr("type: double\ndimension: 3\nsizes: 9223372036854775807 9223372036854775807 9223372036854775807\nendian: little\nencoding: raw\n"),
        {"bad.nrrd", "exceeds the limit"});
    err(hdr("type: uchar\ndimension: 4\nsizes: 2 2 2 2\nencoding: raw\n"), {"bad.nrrd", "4-D", "not supported"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 3 2 2\nkinds: RGB-color domain domain\nencoding: raw\n"),
        {"bad.nrrd", "'RGB-color' of size 3", "multi-component"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspacings: 1 nan 1\nencoding: raw\n"), {"bad.nrrd", "spacing along y", "nan"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspacings: 1 0 1\nencoding: raw\n"), {"bad.nrrd", "spacing along y"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspace directions: (1,0,0) (0,nan,0) (0,0,1)\nencoding: raw\n"),
        {"bad.nrrd", "spacing along y"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspace directions: (1,0,0) (0,1,0)\nencoding: raw\n"),
        {"bad.nrrd", "space directions", "one vector"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspace directions: (1,0,0) (0,1,0) (0,0,x)\nencoding: raw\n"),
        {"bad.nrrd", "space directions"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspace origin: (1,inf,0)\nencoding: raw\n"), {"bad.nrrd", "space origin", "finite"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspace origin: 1 2 3\nencoding: raw\n"), {"bad.nrrd", "space origin"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\ndata file: LIST\n"), {"bad.nrrd", "several files"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\ndata file: s%03d.raw 1 10 1 2\n"), {"bad.nrrd", "several files"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\nbyte skip: -2\n"), {"bad.nrrd", "byte skip '-2'"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: gzip\nbyte skip: -1\n"), {"bad.nrrd", "only valid with raw"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\nbyte skip: 1000\n"), {"bad.nrrd", "byte skip 1,000 runs past the end"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\nline skip: x\n"), {"bad.nrrd", "line skip 'x'"});
    err(hdr("type: uchar\ndimension: 3\nthis line has no separator\n"), {"bad.nrrd", "line 4", "expected 'field: value'"});
    err(bytes("NRRD0004\ntype: uchar\ndimension: 1\nsizes: 3\nencoding: raw\n"), {"bad.nrrd", "no data"});
    err(bytes("NRRD0004\n") + Bytes(2 << 20, 'a'), {"bad.nrrd", "longer than 1 MiB"});
}

TEST_CASE("NRRD: per-axis fields give one entry per axis", "[io][nrrd][errors]") {
    auto hdr = [](const std::string& fields) {
        return bytes("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 1 1\n" + fields + "encoding: raw\n\n") + Bytes{7, 9};
    };
    auto err = [&](const std::string& fields, std::initializer_list<std::string> parts) {
        expect_error([&] { read_mem(read_nrrd, hdr(fields), "axes.nrrd"); }, parts);
    };
    err("spacings: 1 1\n", {"axes.nrrd", "line 5", "spacings '1 1'", "one number per axis (3)"});
    err("spacings: 1 x 1\n", {"axes.nrrd", "spacings '1 x 1'", "must be numbers"});
    err("axis mins: 0 0\n", {"axes.nrrd", "axis mins '0 0'", "one number per axis (3)"});
    err("axis mins: 0 y 0\n", {"axes.nrrd", "axis mins '0 y 0'", "must be numbers"});
    err("kinds: domain domain\n", {"axes.nrrd", "kinds 'domain domain'", "one kind per axis (3)"});
    expect_error([&] {
        read_mem(read_nrrd, bytes("NRRD0004\ntype: uchar\ndimension: 2\nsizes: 1 1\nkinds: vector vector\n"
                                  "encoding: raw\n\n") + Bytes{1},
                 "axes.nrrd");
    }, {"axes.nrrd", "no spatial axes"});

    // Well-formed: the axis mins give the origin, a unit component axis is dropped, spacings keep their magnitude.
    const Volume v = read_mem(read_nrrd, hdr("axis mins: 5 6 7\nspacings: -0.5 2 3\n"), "axes.nrrd");
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{2, 1, 1});
    CHECK(v.grid.origin == std::array<double, 3>{5, 6, 7});
    CHECK(v.grid.spacing == std::array<double, 3>{0.5, 2, 3});
    CHECK(v.data == std::vector<std::uint8_t>{7, 9});
    const Bytes comp = bytes("NRRD0004\ntype: uchar\ndimension: 4\nsizes: 1 2 1 1\nkinds: vector domain domain domain\n"
                             "encoding: raw\n\n") + Bytes{4, 8};
    const Volume w = read_mem(read_nrrd, comp, "axes.nrrd");
    CHECK(w.grid.dims == std::array<std::int64_t, 3>{2, 1, 1});
    CHECK(w.data == std::vector<std::uint8_t>{4, 8});
}

TEST_CASE("NRRD and MetaImage: of several bad fields, the first in reading order is named", "[io][errors]") {
    // NRRD: type, then dimension and sizes, per-axis fields, grid, encoding, endian, data file, skips.
    auto nrrd = [](const std::string& fields) { return bytes("NRRD0004\n" + fields + "\n") + Bytes(8, 0); };
    expect_error([&] { read_mem(read_nrrd, nrrd("type: quux\ndimension: 0\nencoding: zip\n"), "o.nrrd"); },
                 {"o.nrrd", "type 'quux'"});
    expect_error([&] { read_mem(read_nrrd, nrrd("type: uchar\ndimension: 1\nsizes: 2\nspacings: 1 1\nencoding: zip\n"),
                                "o.nrrd"); },
                 {"o.nrrd", "spacings"});
    expect_error([&] { read_mem(read_nrrd, nrrd("type: short\ndimension: 1\nsizes: 2\nencoding: zip\n"), "o.nrrd"); },
                 {"o.nrrd", "encoding 'zip'"});
    expect_error([&] { read_mem(read_nrrd, nrrd("type: short\ndimension: 1\nsizes: 2\nencoding: raw\nbyte skip: -7\n"),
                                "o.nrrd"); },
                 {"o.nrrd", "missing field 'endian'"});
    // MetaImage: NDims, DimSize, ElementType, spacing and origin, encoding flags, data file.
    auto meta = [](const std::string& fields) { return bytes(fields + "ElementDataFile = LOCAL\n") + Bytes(8, 0); };
    expect_error([&] { read_mem(read_metaimage, meta("NDims = 3\nDimSize = 2 0 2\nElementType = MET_NONE\n"), "o.mha"); },
                 {"o.mha", "DimSize"});
    expect_error([&] { read_mem(read_metaimage, meta("NDims = 1\nDimSize = 2\nElementType = MET_NONE\nOffset = x\n"),
                                "o.mha"); },
                 {"o.mha", "ElementType = 'MET_NONE'"});
    expect_error([&] { read_mem(read_metaimage, meta("NDims = 1\nDimSize = 2\nElementType = MET_UCHAR\nOffset = inf\n"
                                                     "BinaryData = perhaps\n"), "o.mha"); },
                 {"o.mha", "line 4", "Offset = 'inf'", "must be finite"});
    expect_error([&] { read_mem(read_metaimage, meta("NDims = 1\nDimSize = 2\nElementType = MET_UCHAR\n"
                                                     "BinaryData = perhaps\nHeaderSize = -3\n"), "o.mha"); },
                 {"o.mha", "BinaryData = 'perhaps'", "True or False"});
}

TEST_CASE("NRRD: data shorter than the header says", "[io][nrrd][errors]") {
    const Bytes b = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 103 94 161\nencoding: raw\n\n" + Bytes(1000000, 3);
    expect_error([&] { read_mem(read_nrrd, b, "tooth.nrrd"); },
                 {"tooth.nrrd: header says 103x94x161 uint8 = 1,558,802 bytes but the file holds 1,000,000"});
    const Bytes be = "NRRD0004\ntype: int16\ndimension: 3\nsizes: 2 2 2\nendian: big\nencoding: raw\nbyte skip: -1\n\n" + Bytes(15, 3);
    expect_error([&] { read_mem(read_nrrd, be, "short.nrrd"); }, {"short.nrrd", "= 16 bytes but the file holds 15"});
}

TEST_CASE("NRRD: broken gzip data", "[io][nrrd][errors][gzip]") {
    const std::string h = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 10 10 10\nencoding: gzip\n\n";
    const Bytes zeros1000(1000, 0);
    auto err = [&](const Bytes& b, std::initializer_list<std::string> parts, ReadOptions opt = {}) {
        expect_error([&] { read_mem(read_nrrd, b, "z.nrrd", opt); }, parts);
    };
    SECTION("ok") { CHECK(read_mem(read_nrrd, h + gzip(zeros1000), "z.nrrd").data == zeros1000); }
    SECTION("stream shorter than declared") {
        err(h + gzip(Bytes(600, 0)), {"z.nrrd", "truncated: 600 of 1,000 bytes"});
    }
    SECTION("compressed bytes cut off") {
        Bytes z = gzip(random_volume(DType::UInt8, {10, 10, 10}).data);
        z.resize(z.size() / 2);
        err(h + z, {"z.nrrd", "truncated"});
        Bytes full = gzip(zeros1000);
        full.resize(full.size() - 4);  // all data there, the gzip trailer (length) is not
        err(h + full, {"z.nrrd", "truncated", "end marker"});
    }
    SECTION("wrong gzip length / checksum in the trailer") {
        Bytes z = gzip(zeros1000);
        z[z.size() - 1] ^= 0x55;  // ISIZE
        err(h + z, {"z.nrrd", "corrupt compressed data", "incorrect length check"});
        Bytes c = gzip(zeros1000);
        c[c.size() - 6] ^= 0x55;  // CRC32
        err(h + c, {"z.nrrd", "corrupt compressed data", "incorrect data check"});
    }
    SECTION("gzip bomb: many zeros, header declares fewer bytes") {
        const Bytes bomb = gzip(Bytes(10 << 20, 0));  // 10 MiB of zeros in ~10 KiB
        CHECK(bomb.size() < 20000);
        err(h + bomb, {"z.nrrd", "more data than the header declares"});
    }
    SECTION("header declares 100 GB with a tiny stream: refused before allocating") {
        const std::string big = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 100000 1000 1000\nencoding: gzip\n\n";
        ReadOptions unlimited;
        unlimited.max_bytes = std::uint64_t(1) << 62;
        err(big + gzip(zeros1000), {"z.nrrd", "header declares 100,000,000,000 bytes but", "compressed bytes can inflate to at most"},
            unlimited);
        err(big + gzip(zeros1000), {"z.nrrd", "exceeds the limit"});  // the default 16 GiB limit says no first
    }
    SECTION("garbage instead of a stream") {
        err(h + bytes("this is not compressed at all, not even a little"), {"z.nrrd", "corrupt compressed data"});
        err(bytes(h), {"z.nrrd", "truncated: 0 of 1,000"});
    }
}

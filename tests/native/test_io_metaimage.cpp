// Tests for volrig/io.hpp's MetaImage reader: hand-written headers for each feature and every kind of bad input.
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
// MetaImage
// =================================================================================================================

TEST_CASE("MetaImage: LOCAL raw, ElementSize, Position, ElementByteOrderMSB, MET_LONG", "[io][metaimage]") {
    const Bytes data = raw_of<std::int32_t>({-1, 2, -3, 4, 5, 6}, true);
    const Bytes b = "NDims = 3\nDimSize = 3 2 1\nElementSize = 2 3 -4\nPosition = 1 2 3\nElementByteOrderMSB = True\n"
                    "ElementType = MET_LONG\nElementDataFile = LOCAL\n" + data;
    const Volume v = read_mem(read_metaimage, b, "l.mha");
    CHECK(v.dtype == DType::Int32);  // MetaIO's MET_LONG is 4 bytes
    CHECK(values<std::int32_t>(v) == std::vector<std::int32_t>{-1, 2, -3, 4, 5, 6});
    CHECK(v.grid.spacing == std::array<double, 3>{2, 3, 4});
    CHECK(v.grid.origin == std::array<double, 3>{1, 2, 3});

    const Bytes ul = bytes("ObjectType = Image\nNDims = 2\nDimSize = 2 1\nElementType = MET_ULONG\n"
                           "BinaryDataByteOrderMSB = False\nElementDataFile = LOCAL\n") + raw_of<std::uint32_t>({7, 4000000000u});
    const Volume u = read_mem(read_metaimage, ul, "ul.mha");
    CHECK(u.dtype == DType::UInt32);
    CHECK(u.grid.dims == std::array<std::int64_t, 3>{2, 1, 1});
    CHECK(values<std::uint32_t>(u) == std::vector<std::uint32_t>{7, 4000000000u});
}

TEST_CASE("MetaImage: every element type", "[io][metaimage]") {
    const std::pair<const char*, DType> types[] = {
        {"MET_UCHAR", DType::UInt8},  {"MET_CHAR", DType::Int8},        {"MET_USHORT", DType::UInt16},
        {"MET_SHORT", DType::Int16},  {"MET_UINT", DType::UInt32},      {"MET_INT", DType::Int32},
        {"MET_ULONG", DType::UInt32}, {"MET_LONG", DType::Int32},       {"MET_ULONG_LONG", DType::UInt64},
        {"MET_LONG_LONG", DType::Int64}, {"MET_FLOAT", DType::Float32}, {"MET_DOUBLE", DType::Float64}};
    for (const auto& [name, t] : types) {
        INFO(name);
        const Bytes b = "NDims = 3\nDimSize = 2 1 1\nElementType = " + std::string(name) +
                        "\nElementDataFile = LOCAL\n" + Bytes(2 * dtype_size(t), 9);
        CHECK(read_mem(read_metaimage, b, "t.mha").dtype == t);
    }
}

TEST_CASE("MetaImage: detached data, HeaderSize, compression, text", "[io][metaimage]") {
    TempDir dir;
    const Bytes data = raw_of<std::int16_t>({1, -2, 3, -4, 5, -6, 7, -8});
    SECTION("HeaderSize -1: data at the end of the data file") {
        write_file(dir / "v.raw", Bytes(100, 0xAB) + data);
        write_file(dir / "v.mhd", bytes("ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nHeaderSize = -1\n"
                                        "ElementSpacing = 1 1 1.5\nOffset = -1 -2 -3\nElementType = MET_SHORT\n"
                                        "ElementDataFile = v.raw\n"));
        const Volume v = read_volume(dir / "v.mhd");
        CHECK(values<std::int16_t>(v) == std::vector<std::int16_t>{1, -2, 3, -4, 5, -6, 7, -8});
        CHECK(v.grid.spacing == std::array<double, 3>{1, 1, 1.5});
        CHECK(v.grid.origin == std::array<double, 3>{-1, -2, -3});
    }
    SECTION("HeaderSize N") {
        write_file(dir / "v.raw", Bytes(100, 0xAB) + data + Bytes(5, 0));
        write_file(dir / "v.mhd", bytes("NDims = 3\nDimSize = 2 2 2\nHeaderSize = 100\nElementType = MET_SHORT\n"
                                        "ElementDataFile = v.raw\n"));
        CHECK(values<std::int16_t>(read_volume(dir / "v.mhd")) == std::vector<std::int16_t>{1, -2, 3, -4, 5, -6, 7, -8});
    }
    SECTION("compressed .zraw with an understated CompressedDataSize (as VTK's frog)") {
        const Bytes z = zlib(data);
        write_file(dir / "v.zraw", z);
        write_file(dir / "v.mhd", bytes("NDims = 3\nDimSize = 2 2 2\nCompressedData = True\nCompressedDataSize = " +
                                        std::to_string(z.size() - 3) + "\nElementType = MET_SHORT\nElementDataFile = v.zraw\n"));
        CHECK(values<std::int16_t>(read_volume(dir / "v.mhd")) == std::vector<std::int16_t>{1, -2, 3, -4, 5, -6, 7, -8});
    }
    SECTION("compressed LOCAL without CompressedDataSize, big endian") {
        const Bytes b = "NDims = 3\nDimSize = 2 2 2\nCompressedData = True\nBinaryDataByteOrderMSB = True\n"
                        "ElementType = MET_SHORT\nElementDataFile = LOCAL\n" +
                        zlib(raw_of<std::int16_t>({1, -2, 3, -4, 5, -6, 7, -8}, true));
        CHECK(values<std::int16_t>(read_mem(read_metaimage, b, "c.mha")) == std::vector<std::int16_t>{1, -2, 3, -4, 5, -6, 7, -8});
    }
    SECTION("text data (BinaryData = False), CRLF") {
        const Bytes b = bytes("NDims = 2\r\nDimSize = 2 2\r\nBinaryData = False\r\nElementType = MET_FLOAT\r\n"
                              "ElementDataFile = LOCAL\r\n0.5 1.5\r\n-2 4e1\r\n");
        CHECK(values<float>(read_mem(read_metaimage, b, "t.mha")) == std::vector<float>{0.5f, 1.5f, -2.f, 40.f});
    }
    SECTION("missing data file") {
        write_file(dir / "m.mhd", bytes("NDims = 3\nDimSize = 2 2 2\nElementType = MET_SHORT\nElementDataFile = nothere.raw\n"));
        expect_error<FileNotFound>([&] { read_volume(dir / "m.mhd"); }, {"m.mhd", "nothere.raw"});
    }
}

TEST_CASE("MetaImage: bad headers name the file and the problem", "[io][metaimage][errors]") {
    auto err = [&](const std::string& header, std::initializer_list<std::string> parts, const Bytes& data = Bytes(64, 0)) {
        expect_error([&] { read_mem(read_metaimage, bytes(header) + data, "bad.mha"); }, parts);
    };
    const std::string tail = "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n";
    err("", {"bad.mha", "empty file"}, {});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n", {"bad.mha", "no ElementDataFile"}, {});
    err("\x89PNG\r\n", {"bad.mha", "expected 'Key = Value'"});
    err("DimSize = 2 2 2\n" + tail, {"bad.mha", "missing field 'NDims'"});
    err("NDims = 3\n" + tail, {"bad.mha", "missing field 'DimSize'"});
    err("NDims = 3\nDimSize = 2 2 2\nElementDataFile = LOCAL\n", {"bad.mha", "missing field 'ElementType'"});
    err("ObjectType = Mesh\nNDims = 3\nDimSize = 2 2 2\n" + tail, {"bad.mha", "ObjectType = 'Mesh'"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_FLOAT_ARRAY\nElementDataFile = LOCAL\n", {"bad.mha", "MET_FLOAT_ARRAY", "not supported"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_GIBBERISH\nElementDataFile = LOCAL\n", {"bad.mha", "MET_GIBBERISH"});
    err("NDims = 3\nDimSize = 2 2 2\nElementNumberOfChannels = 3\n" + tail, {"bad.mha", "ElementNumberOfChannels", "multi-channel"});
    err("NDims = 4\nDimSize = 2 2 2 5\n" + tail, {"bad.mha", "4-D image", "not supported"});
    err("NDims = 3\nDimSize = 2 -2 2\n" + tail, {"bad.mha", "DimSize = '2 -2 2'", "positive"});
    err("NDims = 3\nDimSize = 2 0 2\n" + tail, {"bad.mha", "positive"});
    err("NDims = 3\nDimSize = 2 2\n" + tail, {"bad.mha", "must give 3 sizes"});
    err("NDims = 3\nDimSize = 1048576 1048576 1\n" + tail, {"bad.mha", "exceeds the limit"});
    err("NDims = x\nDimSize = 2 2 2\n" + tail, {"bad.mha", "NDims = 'x'"});
    err("NDims = 3\nDimSize = 2 2 2\nElementSpacing = 1 nan 1\n" + tail, {"bad.mha", "ElementSpacing", "finite"});
    err("NDims = 3\nDimSize = 2 2 2\nElementSpacing = 1 0 1\n" + tail, {"bad.mha", "ElementSpacing", "non-zero"});
    err("NDims = 3\nDimSize = 2 2 2\nOffset = 1 2\n" + tail, {"bad.mha", "Offset", "3 numbers"});
    err("NDims = 3\nDimSize = 2 2 2\nCompressedData = Maybe\n" + tail, {"bad.mha", "CompressedData", "True or False"});
    err("NDims = 3\nDimSize = 2 2 2\nHeaderSize = -5\n" + tail, {"bad.mha", "HeaderSize"});
    err("NDims = 3\nDimSize = 2 2 2\nCompressedData = True\nHeaderSize = -1\n" + tail, {"bad.mha", "HeaderSize", "-1"});
    err("NDims = 3\nDimSize = 2 2 2\nHeaderSize = 1000\n" + tail, {"bad.mha", "HeaderSize 1,000 runs past the end"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = LIST\n", {"bad.mha", "several files"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = s%03d.raw 1 2 1\n", {"bad.mha", "several files"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = \n", {"bad.mha", "ElementDataFile", "empty"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = x.raw\n", {"bad.mha", "detached data files are not available"});
    err("NDims = 3\nDimSize = 10 10 10\n" + tail, {"bad.mha", "header says 10x10x10 uint8 = 1,000 bytes but the file holds 64"});
    err("NDims = 3\nDimSize = 10 10 10\nCompressedData = True\nCompressedDataSize = 5000\n" + tail,
        {"bad.mha", "CompressedDataSize 5,000 but the file holds 64"});
    err("NDims = 3\nDimSize = 10 10 10\nCompressedData = True\n" + tail, {"bad.mha", "truncated: 100 of 1,000 bytes"}, zlib(Bytes(100, 1)));
    err("NDims = 3\nDimSize = 10 10 10\nCompressedData = True\n" + tail, {"bad.mha", "more data than the header declares"},
        zlib(Bytes(1 << 20, 1)));
    err("NDims = 3\nDimSize = 100000 1000 1000\nCompressedData = True\n" + tail, {"bad.mha", "exceeds the limit"}, zlib(Bytes(100, 1)));
    {
        ReadOptions unlimited;
        unlimited.max_bytes = std::uint64_t(1) << 62;
        const Bytes b = "NDims = 3\nDimSize = 100000 1000 1000\nCompressedData = True\n" + tail + zlib(Bytes(100, 1));
        expect_error([&] { read_mem(read_metaimage, b, "bomb.mha", unlimited); }, {"bomb.mha", "can inflate to at most"});
    }
    err("NDims = 3\nDimSize = 2 2 2\nCompressedData = True\n" + tail, {"bad.mha", "corrupt compressed data"}, bytes("not zlib at all!"));
    err("NDims = 3\nDimSize = 2 1 1\nBinaryData = False\n" + tail, {"bad.mha", "'z' is not a valid uint8"}, bytes("1 z"));
}

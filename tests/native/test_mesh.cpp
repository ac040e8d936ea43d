// Tests for volrig/mesh.hpp: OBJ/PLY/OFF/STL/Medit/TGF readers (round trips of meshes written here in every
// encoding, every kind of malformed input), the fuzz corpus, and the arm and hand meshes and the arm's skeleton in
// ../shared/data when present. Voxelization: test_mesh_voxelize.cpp.
#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

#include "volrig/mesh.hpp"

#include "mesh_fixture.hpp"

using namespace volrig;
namespace fs = std::filesystem;

// =================================================================================================================
// OBJ
// =================================================================================================================

TEST_CASE("OBJ: vertices, every face entry form, relative indices, ignored statements", "[mesh][obj]") {
    const QuadBox b({-1.5, 0.25, 2}, {3.125, 1e-3, 7.5});
    std::string text = "# a box\r\nmtllib box.mtl\no box\ng side\ns off\nusemtl red\n";
    for (const auto& p : b.v) text += "v " + num(p[0]) + " " + num(p[1]) + " " + num(p[2]) + "\n";
    text += "vt 0 0\nvt 1 0 0\nvn 0 0 1\n";
    // one face in each entry form, one with relative indices, one continued over two lines, one with a comment
    auto corner = [&](int i, int k) {
        return static_cast<int>(b.quads[static_cast<std::size_t>(i)][static_cast<std::size_t>(k)]);
    };
    auto q = [&](int i, int k) { return std::to_string(corner(i, k) + 1); };
    text += "f " + q(0, 0) + " " + q(0, 1) + " " + q(0, 2) + " " + q(0, 3) + "\n";
    text += "f " + q(1, 0) + "/1 " + q(1, 1) + "/2 " + q(1, 2) + "/1 " + q(1, 3) + "/2\n";
    text += "f " + q(2, 0) + "//1 " + q(2, 1) + "//1 " + q(2, 2) + "//1 " + q(2, 3) + "//1\n";
    text += "f " + q(3, 0) + "/1/1 " + q(3, 1) + "/2/1 \\\n  " + q(3, 2) + "/1/1 " + q(3, 3) + "/2/1\n";
    auto rel = [&](int i, int k) { return std::to_string(corner(i, k) - 8); };
    text += "f " + rel(4, 0) + " " + rel(4, 1) + "/-1 " + rel(4, 2) + "//-1 " + rel(4, 3) + "\n";
    text += "l 1 2\np 3\n\t\n   f " + q(5, 0) + " " + q(5, 1) + " " + q(5, 2) + " " + q(5, 3) + "  # last face\n";
    const Mesh m = obj(text);
    const Mesh want = b.mesh();
    CHECK(m.vertices == want.vertices);
    CHECK(m.triangles == want.triangles);
}

TEST_CASE("OBJ: polygons fan-triangulated, vertex extras ignored, file without final newline", "[mesh][obj]") {
    const Mesh m = obj("v 0 0 0 1\nv 1 0 0 0.5 0.5 0.5\nv 1 1 0\nv 0 1 0\nv -1 0.5 0\nf 1 2 3 4 5");
    REQUIRE(m.vertices.size() == 5);
    CHECK(m.vertices[1] == Vec3{1, 0, 0});
    CHECK(m.triangles == std::vector<Tri>{{0, 1, 2}, {0, 2, 3}, {0, 3, 4}});
}

TEST_CASE("OBJ: bad input names the file, the line and the problem", "[mesh][obj][errors]") {
    const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    expect_error([&] { obj(tri + "f 1 2 9000\n", "arm.obj"); },
                 {"arm.obj: line 4: face index 9000 out of range (3 vertices)"});
    expect_error([&] { obj(tri + "f 1 2 3\n\nf 2 3 4\nf 1 2 3\n"); }, {"m.obj: line 6: face index 4 out of range (3"});
    expect_error([&] { obj(tri + "f 1 2 0\n"); }, {"line 4", "face index 0", "start at 1"});
    expect_error([&] { obj(tri + "f -1 -2 -4\n"); }, {"line 4", "-4", "before the first vertex", "3 vertices so far"});
    expect_error([&] { obj("v 0 0 0\nf -1 -1 -1\nv 1 0 0\nv 0 1 0\nf -1 -2 -3 -4\n"); }, {"line 5", "-4"});
    expect_error([&] { obj(tri + "f 1 2\n"); }, {"line 4", "2 vertices", "at least 3"});
    expect_error([&] { obj(tri + "f 1\n"); }, {"line 4", "1 vertex"});
    expect_error([&] { obj(tri + "f 1 2 x\n"); }, {"line 4", "'x'", "not an index"});
    expect_error([&] { obj(tri + "f 1 2 3/x\n"); }, {"line 4", "'3/x'"});
    expect_error([&] { obj(tri + "f 1 2 3//\n"); }, {"line 4", "'3//'"});
    expect_error([&] { obj(tri + "f 1 2 99999999999\n"); }, {"line 4", "99999999999", "out of range"});
    expect_error([&] { obj("v 0 0 0\nv 1 zero 0\n"); }, {"line 2", "y 'zero' is not a number"});
    expect_error([&] { obj("v 0 0 0\nv 1 0 0x10\n"); }, {"line 2", "z '0x10' is not a number"});
    expect_error([&] { obj("v 0 0 0\nv 1 0 1e999\n"); }, {"line 2", "'1e999' is not a number"});
    expect_error([&] { obj("v 0 0 0\nv 1 nan 0\n"); }, {"line 2", "y 'nan' is not finite"});
    expect_error([&] { obj("v 0 0 0\nv -inf 0 0\n"); }, {"line 2", "x '-inf' is not finite"});
    expect_error([&] { obj("v 0 0\n"); }, {"line 1", "vertex needs x y z"});
    expect_error([&] { obj(tri); }, {"m.obj: no faces"});
    expect_error([&] { obj("# nothing\n\n"); }, {"m.obj: no vertices"});
    expect_error([&] { obj(""); }, {"m.obj: no vertices"});
    expect_error([&] { obj(std::string("v 0 0 0\nv 1 0\0 0\n", 17)); }, {"line 2", "NUL"});
}

TEST_CASE("OBJ: the size limit stops a reader before it grows past it", "[mesh][obj][errors]") {
    std::string text;
    for (int i = 0; i < 100; ++i) text += "v " + std::to_string(i) + " 0 0\n";
    ReadOptions small;
    small.max_bytes = 24 * 50;
    expect_error([&] { read_mem(read_obj, bytes(text + "f 1 2 3\n"), "big.obj", small); },
                 {"big.obj: line 51", "51 vertices", "above the limit of 1,200 bytes"});
    small.max_bytes = 24 * 100 + 12 * 3;
    text += "f 1 2 3 4 5\n";  // 3 triangles: fits exactly
    CHECK(read_mem(read_obj, bytes(text), "ok.obj", small).triangles.size() == 3);
    expect_error([&] { read_mem(read_obj, bytes(text + "f 1 2 3\n"), "big.obj", small); }, {"line 102", "limit"});
}

// =================================================================================================================
// PLY
// =================================================================================================================

TEMPLATE_TEST_CASE("PLY: a box in ascii and both binary byte orders, xyz and index types, skipped extras",
                   "[mesh][ply]", float, double, std::int16_t) {
    const bool integral = std::is_integral_v<TestType>;
    const QuadBox b = integral ? QuadBox({-3, 0, 2}, {5, 1, 7}) : QuadBox({-1.5, 0.25, 2}, {3.125, 1e-3, 7.5});
    const char* xyz = std::is_same_v<TestType, float> ? "float" : std::is_same_v<TestType, double> ? "double" : "short";
    Mesh want = b.mesh();
    if (std::is_same_v<TestType, float>)
        for (auto& p : want.vertices)
            for (auto& c : p) c = static_cast<double>(static_cast<float>(c));
    for (PlyEnc enc : {PlyEnc::Ascii, PlyEnc::LE, PlyEnc::BE}) {
        INFO("encoding " << static_cast<int>(enc) << ", xyz " << xyz);
        const Mesh a = ply(box_ply<TestType, std::int32_t>(enc, xyz, "int", b));
        CHECK(a.vertices == want.vertices);
        CHECK(a.triangles == want.triangles);
        const Mesh u = ply(box_ply<TestType, std::uint16_t>(enc, xyz, "ushort", b));
        CHECK(u.triangles == want.triangles);
        const Mesh c = ply(box_ply<TestType, std::uint8_t>(enc, xyz, "uint8", b));
        CHECK(c.triangles == want.triangles);
    }
}

TEST_CASE("PLY: vertex_index, CRLF header, faces before vertices, zero-property elements", "[mesh][ply]") {
    const Bytes body = Bytes{3} + le<std::int32_t>({0, 1, 2}) + le<double>({0, 0, 0, 1, 0, 0, 0, 1, 0.5});
    std::string h = "ply\r\nformat binary_little_endian 1.0\r\nelement nothing 1000000000000\r\nelement face 1\r\n"
                    "property list uchar int vertex_index\r\nelement vertex 3\r\nproperty double x\r\n"
                    "property double y\r\nproperty double z\r\nend_header\r\n";
    const Mesh m = ply(bytes(h) + body);
    CHECK(m.triangles == std::vector<Tri>{{0, 1, 2}});
    CHECK(m.vertices[2] == Vec3{0, 1, 0.5});
    // the same with an index beyond the vertices read later
    const Bytes bad = Bytes{3} + le<std::int32_t>({0, 3, 2}) + le<double>({0, 0, 0, 1, 0, 0, 0, 1, 0.5});
    expect_error([&] { ply(bytes(h) + bad); }, {"face 0 of 1", "vertex index 3 out of range (3 vertices)"});
}

TEST_CASE("PLY: bad headers name the file, the line and the problem", "[mesh][ply][errors]") {
    const std::vector<std::string> xyz = {"element vertex 3", "property float x", "property float y",
                                          "property float z"};
    auto with = [&](std::vector<std::string> extra) {
        std::vector<std::string> l = xyz;
        l.insert(l.end(), extra.begin(), extra.end());
        return l;
    };
    const std::vector<std::string> face = {"element face 1", "property list uchar int vertex_indices"};
    expect_error([&] { ply(bytes("plyx\nformat ascii 1.0\nend_header\n")); }, {"m.ply: not a PLY file"});
    expect_error([&] { ply(bytes("")); }, {"m.ply: empty file"});
    expect_error([&] { ply(bytes("ply\nformat ascii 1.0\nelement vertex 3\n")); }, {"no end_header"});
    expect_error([&] { ply(bytes("ply\nelement vertex 0\nend_header\n")); }, {"no 'format' line"});
    expect_error([&] { ply(bytes("ply\nformat binary_middle_endian 1.0\nend_header\n")); },
                 {"line 2", "unknown format 'binary_middle_endian'"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, {"property float x"}, {})); },
                 {"line 4", "property before any element"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, with({"property flot w"}), {})); },
                 {"line 8", "unknown property type 'flot'"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, with({"element face 1", "property list float int vertex_indices"}),
                                    {})); },
                 {"line 9", "count type 'float' must be an integer type"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, with({"element face 1", "property list uchar float vertex_indices"}),
                                    {})); },
                 {"line 8", "vertex_indices", "integer type"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, with({"element face 1", "property int vertex_indices"}), {})); },
                 {"vertex_indices", "not a list"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, with({"element face 1", "property list uchar int corners"}), {})); },
                 {"line 8", "no 'vertex_indices' list"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, with({"element vertex 2"}), {})); }, {"line 8", "declared twice"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, with({"property float x"}), {})); }, {"line 8", "'x' declared twice"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, with({"element face -1"}), {})); }, {"line 8", "'-1'", "non-negative"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, with({"element face many"}), {})); }, {"line 8", "'many'"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, with({"what is this"}), {})); }, {"line 8", "unknown header line"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, {"element vertex 3", "property float x", "property float y"}, {})); },
                 {"line 4", "element vertex has no property 'z'"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, face, {})); }, {"no 'element vertex'"});
    expect_error([&] { ply(ply_with(PlyEnc::LE, xyz, le<float>({0, 0, 0, 1, 0, 0, 0, 1, 0}))); },
                 {"no 'element face'", "point cloud"});
}

TEST_CASE("PLY: counts the file cannot hold are refused before anything is allocated", "[mesh][ply][errors]") {
    const auto start = std::chrono::steady_clock::now();
    for (PlyEnc enc : {PlyEnc::Ascii, PlyEnc::LE, PlyEnc::BE}) {
        const Bytes huge = ply_with(enc,
                                    {"element vertex 1000000000000", "property float x", "property float y",
                                     "property float z", "element face 1", "property list uchar int vertex_indices"},
                                    Bytes(1000, '1'));
        expect_error([&] { ply(huge, "huge.ply"); },
                     {"huge.ply: line 4: header declares 1,000,000,000,000 vertex elements", "only 1,000 bytes"});
        const Bytes faces = ply_with(enc,
                                     {"element vertex 3", "property float x", "property float y", "property float z",
                                      "element face 4294967295", "property list uchar int vertex_indices"},
                                     Bytes(1000, '1'));
        expect_error([&] { ply(faces, "huge.ply"); }, {"line 8: header declares 4,294,967,295 face elements"});
    }
    CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(2));
    // a list claiming more items than the file holds
    expect_error([&] { ply(tiny_binary_ply(2, 0, 250)); }, {"face 0 of 1", "claims 250 items", "bytes remain"});
    // the size limit
    ReadOptions small;
    small.max_bytes = 3 * 24 + 12 - 1;
    expect_error([&] { read_mem(read_ply, tiny_binary_ply(), "t.ply", small); },
                 {"t.ply: header: 3 vertices and 1 triangles", "limit of 83 bytes"});
}

TEST_CASE("PLY: bad data names the element and where it is", "[mesh][ply][errors]") {
    CHECK(ply(tiny_binary_ply()).triangles.size() == 1);
    expect_error([&] { ply(tiny_binary_ply(3)); },
                 {"m.ply: face 0 of 1 (byte", "vertex index 3 out of range (3 vertices)"});
    expect_error([&] { ply(tiny_binary_ply(-1)); }, {"face 0 of 1", "vertex index -1 out of range"});
    expect_error([&] { ply(tiny_binary_ply(2, std::nanf(""))); }, {"vertex 0 of 3 (byte", "x is not finite"});
    expect_error([&] { ply(tiny_binary_ply(2, INFINITY)); }, {"vertex 0 of 3", "x is not finite (inf)"});
    expect_error([&] { ply(tiny_binary_ply(2, 0, 2)); }, {"face 0 of 1", "2 vertices", "at least 3"});
    // ascii: text in numbers, integers out of their type's range, NaN, files that end early
    const std::vector<std::string> h = {"element vertex 3",       "property float x", "property float y",
                                        "property float z",       "element face 1",
                                        "property list uchar int vertex_indices"};
    auto ascii = [&](const std::string& body) { return ply(ply_with(PlyEnc::Ascii, h, bytes(body)), "a.ply"); };
    CHECK(ascii("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").triangles == std::vector<Tri>{{0, 1, 2}});
    CHECK(ascii("0 0 0 1 0 0\n\n0 1 0 3\n0 1 2").triangles.size() == 1);  // a token stream
    expect_error([&] { ascii("0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n"); },
                 {"a.ply: line 12: vertex 1 of 3", "property 'y' 'zero' is not a valid float"});
    expect_error([&] { ascii("0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n"); }, {"line 12: vertex 1 of 3", "y is not finite"});
    expect_error([&] { ascii("0 0 0\n1 0 0\n0 1 0\n300 0 1 2\n"); },
                 {"line 14: face 0 of 1", "the count of list 'vertex_indices' '300' is not a valid uchar"});
    expect_error([&] { ascii("0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n"); }, {"line 14", "'2.5' is not a valid int"});
    // too short for the declared counts at two bytes per value: refused before reading
    expect_error([&] { ascii("0 0 0\n1 0 0\n0 1 0\n3 0 1\n"); }, {"line 8: header declares 1 face elements"});
    expect_error([&] { ascii("0.000 0 0\n1 0 0\n0 1 0\n3 0 1\n"); },
                 {"line 14: face 0 of 1", "ends before a vertex index"});
    expect_error([&] { ascii("0.0000000000 0 0\n1.00000000000 0 0\n"); },
                 {"vertex 2 of 3", "ends before property 'x'"});
}

TEST_CASE("PLY: every truncation of a binary file is refused, of an ascii file never crashes", "[mesh][ply][errors]") {
    const QuadBox b;
    for (PlyEnc enc : {PlyEnc::LE, PlyEnc::BE}) {
        const Bytes full = box_ply<float, std::int32_t>(enc, "float", "int", b);
        CHECK(ply(full).triangles.size() == 12);
        for (std::size_t n = 0; n < full.size(); ++n) {
            INFO("first " << n << " of " << full.size() << " bytes");
            const Bytes cut(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(n));
            CHECK_THROWS_AS(ply(cut), FileFormatError);
        }
    }
    const Bytes full = box_ply<float, std::int32_t>(PlyEnc::Ascii, "float", "int", b);
    for (std::size_t n = 0; n < full.size(); ++n) {
        const Bytes cut(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(n));
        try {
            ply(cut);
        } catch (const FileFormatError&) {
        }
    }
}

// =================================================================================================================
// TGF
// =================================================================================================================

TEST_CASE("TGF: joints, edges, extra columns, trailing section", "[mesh][tgf]") {
    const TgfSkeleton s = tgf("1 0 0 0 9 9 9\n2 1 0 0 3e300 nan\n\n3 1 1 0\n#\n1 2 1 0 0\n2   3\n#\nanything at all\n");
    CHECK(s.joints == std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}});
    CHECK(s.edges == std::vector<std::array<std::uint32_t, 2>>{{0, 1}, {1, 2}});
    CHECK(tgf("1 0.5 -2 3\n").edges.empty());  // joints only
}

TEST_CASE("TGF: bad input names the file, the line and the problem", "[mesh][tgf][errors]") {
    const std::string j = "1 0 0 0\n2 1 0 0\n3 2 0 0\n#\n";
    expect_error([&] { tgf(j + "1 2\n2 4\n", "arm.tgf"); }, {"arm.tgf: line 6: edge joint 4 out of range (3 joints"});
    expect_error([&] { tgf(j + "0 1\n"); }, {"line 5", "edge joint 0 out of range"});
    expect_error([&] { tgf(j + "2 2\n"); }, {"line 5", "joins joint 2 to itself"});
    expect_error([&] { tgf(j + "1 b\n"); }, {"line 5", "two integers"});
    expect_error([&] { tgf(j + "1\n"); }, {"line 5", "two joint numbers"});
    expect_error([&] { tgf("1 0 0 0\n2 1 y 0\n"); }, {"line 2", "joint y 'y' is not a number"});
    expect_error([&] { tgf("1 0 0 0\n2 1 inf 0\n"); }, {"line 2", "not finite"});
    expect_error([&] { tgf("1 0 0\n"); }, {"line 1", "index x y z"});
    expect_error([&] { tgf("one 0 0 0\n"); }, {"line 1", "joint index 'one'"});
    expect_error([&] { tgf("#\n1 2\n"); }, {"s.tgf: no joints"});
    expect_error([&] { tgf(""); }, {"no joints"});
}

// =================================================================================================================
// OFF, STL, Medit: helpers
// =================================================================================================================

namespace {

Mesh off(const std::string& text, const std::string& name = "m.off") { return read_mem(read_off, bytes(text), name); }
Mesh stl(const Bytes& b, const std::string& name = "m.stl") { return read_mem(read_stl, b, name); }
Mesh medit(const std::string& text, const std::string& name = "m.mesh") {
    return read_mem(read_medit, bytes(text), name);
}

/// Edges used by exactly one triangle (0 for a closed surface).
std::size_t open_edges(const Mesh& m) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> uses;
    for (const Tri& t : m.triangles)
        for (std::size_t k = 0; k < 3; ++k) ++uses[std::minmax(t[k], t[(k + 1) % 3])];
    return static_cast<std::size_t>(
        std::count_if(uses.begin(), uses.end(), [](const auto& e) { return e.second == 1; }));
}

/// The corners of every triangle, as coordinates (what survives welding and renumbering).
std::vector<std::array<Vec3, 3>> corners(const Mesh& m) {
    std::vector<std::array<Vec3, 3>> out;
    for (const Tri& t : m.triangles) out.push_back({m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]});
    return out;
}

std::string ascii_stl(const Mesh& m, const std::string& solid = "test") {
    std::string s = "solid " + solid + "\n";
    for (const auto& t : corners(m)) {
        s += "  facet normal 0 0 0\n    outer loop\n";
        for (const Vec3& p : t) s += "      vertex " + num(p[0]) + " " + num(p[1]) + " " + num(p[2]) + "\n";
        s += "    endloop\n  endfacet\n";
    }
    return s + "endsolid " + solid + "\n";
}

Bytes binary_stl(const Mesh& m, const std::string& header = "binary STL written by test_mesh.cpp") {
    Bytes b(80, 0);
    std::memcpy(b.data(), header.data(), std::min<std::size_t>(header.size(), 80));
    b = b + le<std::uint32_t>({static_cast<std::uint32_t>(m.triangles.size())});
    for (const auto& t : corners(m)) {
        b = b + le<float>({0.f, 0.f, 1.f});
        for (const Vec3& p : t)
            b = b + le<float>({static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])});
        b = b + Bytes{0, 0};
    }
    return b;
}

/// A Medit file: the vertices (reference 0), then `cells` (sections as text), then End.
std::string medit_text(const std::vector<Vec3>& v, const std::string& cells) {
    std::string s = "MeshVersionFormatted 2\nDimension 3\nVertices\n" + std::to_string(v.size()) + "\n";
    for (const Vec3& p : v) s += num(p[0]) + " " + num(p[1]) + " " + num(p[2]) + " 0\n";
    return s + cells + "End\n";
}

const std::string kTetVertices =
    "MeshVersionFormatted 1\nDimension 3\nVertices 4\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n";

}  // namespace

// =================================================================================================================
// OFF
// =================================================================================================================

TEST_CASE("OFF: keyword variants, counts, comments, colours, polygons", "[mesh][off]") {
    const QuadBox b({-1, 0.5, 2}, {3.25, 1.75, 2.125});
    std::string text = "COFF\n# a box with colours\n\n" + std::to_string(b.v.size()) + " 6 12\n";
    for (const Vec3& p : b.v) text += num(p[0]) + " " + num(p[1]) + " " + num(p[2]) + " 255 0 0 255\n";
    for (const auto& q : b.quads)
        text += "4  " + std::to_string(q[0]) + " " + std::to_string(q[1]) + " " + std::to_string(q[2]) + " " +
                std::to_string(q[3]) + "  0.5 0.5 0.5 # grey\n";
    const Mesh m = off(text);
    CHECK(m.vertices == b.v);
    CHECK(m.triangles == b.mesh().triangles);
    CHECK(off("NOFF 3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n").triangles == std::vector<Tri>{{0, 1, 2}});
    CHECK(off("3 1\r\n0 0 0\r\n1 0 0\r\n0 1 0\r\n3 2 1 0").triangles == std::vector<Tri>{{2, 1, 0}});
    CHECK(off("off\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").vertices.size() == 3);
    CHECK(off("STCNOFF\n3 1 0\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n").vertices[1] == Vec3{1, 0, 0});
    const Mesh pent = off("OFF\n5 1\n0 0 0\n1 0 0\n1.5 1 0\n0.5 1.5 0\n-0.5 1 0\n5 0 1 2 3 4\nignored trailing text\n");
    CHECK(pent.triangles == std::vector<Tri>{{0, 1, 2}, {0, 2, 3}, {0, 3, 4}});
}

TEST_CASE("OFF: bad input names the file, the line and the problem", "[mesh][off][errors]") {
    const std::string head = "OFF\n3 1 0\n0 0 0\n1 0 0\n";
    const std::string pad = "# padding so that the counts fit in the bytes that follow\n";
    expect_error([&] { off(head + "0 nan 0\n3 0 1 2\n" + pad, "c.off"); },
                 {"c.off: line 5: vertex y 'nan' is not finite"});
    expect_error([&] { off(head + "0 1 -inf\n3 0 1 2\n" + pad); }, {"line 5", "z '-inf' is not finite"});
    expect_error([&] { off(head + "0 1 zero\n3 0 1 2\n" + pad); }, {"line 5", "'zero' is not a number"});
    expect_error([&] { off(head + "0 1\n3 0 1 2\n" + pad); }, {"line 5", "vertex needs x y z, got 2"});
    expect_error([&] { off(head + "0 1 0\n3 0 1 3\n" + pad); }, {"line 6", "face index 3 out of range (3 vertices"});
    expect_error([&] { off(head + "0 1 0\n3 0 -1 2\n" + pad); }, {"line 6", "face index -1 out of range"});
    expect_error([&] { off(head + "0 1 0\n3 0 1 x\n" + pad); }, {"line 6", "face index 'x' is not an integer"});
    expect_error([&] { off(head + "0 1 0\n2 0 1\n" + pad); }, {"line 6", "2 vertices", "at least 3"});
    expect_error([&] { off(head + "0 1 0\n-3 0 1\n" + pad); }, {"line 6", "'-3' is not a non-negative integer"});
    expect_error([&] { off(head + "0 1 0\n4 0 1 2\n" + pad); }, {"line 6", "face of 4 vertices lists only 3 indices"});
    expect_error([&] { off(head + pad); }, {"the file ends after 2 of 3 vertices (truncated)"});
    expect_error([&] { off(head + "0 1 0\n" + pad); }, {"the file ends after 0 of 1 faces (truncated)"});
    expect_error([&] { off("OFF\n3 x 0\n" + pad); }, {"line 2", "expected the counts 'vertices faces [edges]'"});
    expect_error([&] { off("OFF\n3 -1 0\n" + pad); }, {"line 2", "expected the counts"});
    expect_error([&] { off("OFF\n3 1 0 7\n" + pad); }, {"line 2", "expected the counts"});
    expect_error([&] { off("OFF\n0 1 0\n" + pad); }, {"line 2", "no vertices"});
    expect_error([&] { off("OFF\n3 0 0\n" + pad); }, {"line 2", "no faces", "nothing to voxelize"});
    expect_error([&] { off("OFF\n# only a comment\n"); }, {"the file ends before the counts line"});
    expect_error([&] { off("4OFF\n3 1 0\n"); }, {"line 1", "'4OFF'", "4-D and n-dimensional"});
    expect_error([&] { off("nOFF\n3 3 1 0\n"); }, {"line 1", "not supported"});
    expect_error([&] { off("XOFF\n3 1 0\n"); }, {"line 1", "unknown OFF header keyword 'XOFF'"});
    expect_error([&] { off("OFF BINARY\n"); }, {"line 1", "binary OFF is not supported"});
    expect_error([&] { off("# hello\nhello world\n"); }, {"line 2", "not an OFF file", "'hello'"});
    expect_error([&] { off(""); }, {"m.off: empty file"});
    expect_error([&] { off(std::string("OFF\n3 1 0\n0 0\0 0\n", 18) + pad); }, {"line 3", "NUL"});
}

TEST_CASE("OFF: lying and absurd counts are refused before anything is allocated", "[mesh][off][errors]") {
    expect_error([&] { off("OFF\n4000000000 1 0\n0 0 0\n"); },
                 {"line 2", "4,000,000,000 vertices declared (at least 6 bytes each) but only 7 bytes follow"});
    expect_error([&] { off("OFF\n3 999999999999999 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"); },
                 {"line 2", "999,999,999,999,999 faces declared (at least 8 bytes each)"});
    expect_error([&] { off("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"); }, {"2 faces declared", "bytes follow"});
    std::string text = "OFF\n100 1 0\n";
    for (int i = 0; i < 100; ++i) text += std::to_string(i) + " 0 0\n";
    ReadOptions small;
    small.max_bytes = 24 * 100;
    expect_error([&] { read_mem(read_off, bytes(text + "3 0 1 2\n"), "big.off", small); },
                 {"big.off: line 2", "100 vertices and 1 triangles", "above the limit of 2,400 bytes"});
    small.max_bytes = 24 * 100 + 12 * 3;
    CHECK(read_mem(read_off, bytes(text + "5 0 1 2 3 4\n"), "ok.off", small).triangles.size() == 3);
    expect_error([&] { read_mem(read_off, bytes(text + "6 0 1 2 3 4 5\n"), "big.off", small); },
                 {"big.off: line 103", "4 triangles", "limit"});
}

// =================================================================================================================
// STL
// =================================================================================================================

TEST_CASE("STL: ASCII and binary files of a closed mesh read back as the same welded triangles", "[mesh][stl]") {
    Mesh sphere = icosphere(2, 1.5, {0.25, -2, 3});
    // Coordinates on a 2^-20 grid are exact in binary STL's float32 too. (Not by a double -> float -> double loop:
    // GCC 12.2 at -O3 leaves the last vertices of such a loop unconverted.)
    for (auto& p : sphere.vertices)
        for (double& c : p) c = std::ldexp(std::round(std::ldexp(c, 20)), -20);
    for (const auto& p : sphere.vertices)
        for (double c : p) REQUIRE(static_cast<double>(static_cast<float>(c)) == c);
    VoxelizeOptions opt;
    const Volume reference = voxelize(sphere, 0.1, opt);
    const std::pair<const char*, Bytes> files[] = {{"ascii", bytes(ascii_stl(sphere))},
                                                   {"binary", binary_stl(sphere)},
                                                   {"binary starting with solid", binary_stl(sphere, "solid ball")}};
    for (const auto& [what, file] : files) {
        INFO(what);
        const Mesh m = stl(file);
        CHECK(m.vertices.size() == sphere.vertices.size());  // every corner welded to its vertex
        CHECK(corners(m) == corners(sphere));
        CHECK(open_edges(m) == 0);
        CHECK(agreement(voxelize(m, 0.1, opt), reference).first == 1.0);
    }
    // -0 and 0 are one vertex; vertices come in order of first use; several solids; keywords in any case;
    // nan normals (written by some exporters for degenerate facets) are fine; loops of 4 are fan-split.
    const Mesh q = stl(bytes("solid a\nfacet normal nan nan nan\nouter loop\nvertex -0 0 0\nvertex 1 0 0\n"
                             "vertex 1 1 0\nendloop\nendfacet\nendsolid a\nSOLID b\nFACET NORMAL 0 0 1\nOUTER LOOP\n"
                             "VERTEX 0 0 0\nVERTEX 1 1 0\nVERTEX 0 1 0\nVERTEX 0 1 -0\nENDLOOP\nENDFACET\nENDSOLID"));
    CHECK(q.vertices == std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}});
    CHECK(q.triangles == std::vector<Tri>{{0, 1, 2}, {0, 2, 3}, {0, 3, 3}});
}

TEST_CASE("STL: bad input names the file, where, and the problem", "[mesh][stl][errors]") {
    const Mesh tet = medit(kTetVertices + "Tetrahedra 1 1 2 3 4 0\n");
    const Bytes bin = binary_stl(tet);
    REQUIRE(stl(bin).triangles.size() == 4);
    expect_error([&] { stl(Bytes(bin.begin(), bin.end() - 1), "cut.stl"); },
                 {"cut.stl: binary STL whose size does not match its triangle count: 84 + 50 x 4 = 284 bytes, but "
                  "the file holds 283"});
    expect_error([&] { stl(bin + Bytes{0}); }, {"284 bytes, but the file holds 285"});
    expect_error([&] { stl(Bytes(bin.begin(), bin.begin() + 84 - 4) + le<std::uint32_t>({0})); },
                 {"binary STL with 0 triangles"});
    expect_error([&] { stl(Bytes(20, 0)); }, {"20 bytes: too short for a binary STL"});
    Bytes nan = bin;
    const float bad = std::nanf("");
    std::memcpy(nan.data() + 84 + 2 * 50 + 12 + 12 + 4, &bad, 4);  // triangle 2, corner 1, y
    expect_error([&] { stl(nan); }, {"triangle 2 (byte 184): corner 1 has y = nan (not finite)"});
    const std::string facet =
        "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n";
    CHECK(stl(bytes("solid x\n" + facet + "endsolid x\n")).triangles.size() == 1);
    auto with = [&](const std::string& from, const std::string& to) {
        std::string f = "solid x\n" + facet + "endsolid x\n";
        f.replace(f.find(from), from.size(), to);
        return bytes(f);
    };
    expect_error([&] { stl(with("vertex 1 0 0", "vertex 1 nan 0")); }, {"line 5", "vertex y 'nan' is not finite"});
    expect_error([&] { stl(with("vertex 1 0 0", "vertex 1 0 1e999")); }, {"line 5", "'1e999' is not a number"});
    expect_error([&] { stl(with("vertex 0 1 0\n", "vertex 0 1\n")); }, {"line 7", "z 'endloop' is not a number"});
    expect_error([&] { stl(with("normal 0 0 1", "normal 0 zero 1")); }, {"line 2", "facet normal 'zero'"});
    expect_error([&] { stl(with("outer loop", "loop")); }, {"line 3", "expected 'outer', got 'loop'"});
    expect_error([&] { stl(with("endloop\n", "")); }, {"line 7", "expected 'vertex' or 'endloop', got 'endfacet'"});
    expect_error([&] { stl(with("vertex 0 1 0\n", "")); }, {"line 6", "facet has 2 vertices"});
    expect_error([&] { stl(with("endfacet", "end")); }, {"line 8", "expected 'endfacet', got 'end'"});
    expect_error([&] { stl(with("endsolid x\n", "")); }, {"the file ends before 'endsolid'", "truncated"});
    expect_error([&] { stl(with("facet normal", "facets normal")); }, {"line 2", "expected 'facet' or 'endsolid'"});
    expect_error([&] { stl(bytes("solid x\nendsolid x\n")); }, {"m.stl: no facets"});
    expect_error([&] { stl(bytes("hello\n")); }, {"line 1", "expected 'solid', got 'hello'"});
    expect_error([&] { stl(Bytes{}); }, {"m.stl: empty file"});
    ReadOptions small;
    small.max_bytes = 24 * 3 + 12 * 1;
    CHECK(read_mem(read_stl, bytes("solid x\n" + facet + "endsolid x\n"), "ok.stl", small).triangles.size() == 1);
    expect_error([&] { read_mem(read_stl, with("vertex 0 1 0\n", "vertex 0 1 0\nvertex 3 3 3\n"), "big.stl", small); },
                 {"big.stl: line 7", "4 vertices and 2 triangles", "above the limit"});
}

// =================================================================================================================
// Medit
// =================================================================================================================

TEST_CASE("Medit: triangles and quadrilaterals, skipped sections, any case, comments", "[mesh][medit]") {
    const QuadBox b({-1, 0.5, 2}, {3.25, 1.75, 2.125});
    std::string cells = "# sections this reader skips, before and after\nEdges\n2\n1 2 0\n2 3 0\nCorners 1 1\n"
                        "quadrilaterals\n6\n";
    for (const auto& q : b.quads)
        cells += std::to_string(q[0] + 1) + " " + std::to_string(q[1] + 1) + " " + std::to_string(q[2] + 1) + " " +
                 std::to_string(q[3] + 1) + " 7 # ref 7\n";
    cells += "Normals 1\n0 0 1\nNormalAtVertices 1 1 1\nRidges 1 1\n";
    const Mesh m = medit(medit_text(b.v, cells));
    CHECK(m.vertices == b.v);
    CHECK(m.triangles == b.mesh().triangles);
    // triangles and quadrilaterals together, keywords and counts anywhere on the lines, no End
    const Mesh t = medit("meshversionformatted 1 dimension 3 vertices 5 0 0 0 0 1 0 0 0 1 1 0 0 0 1 0 0 0 0 1 0 "
                         "triangles 1 1 2 5 0 QUADRILATERALS 1 1 2 3 4 0");
    CHECK(t.triangles == std::vector<Tri>{{0, 1, 4}, {0, 1, 2}, {0, 2, 3}});
    // triangles win over tetrahedra
    CHECK(medit(kTetVertices + "Tetrahedra 1 1 2 3 4 0\nTriangles 1 1 2 3 0\n").triangles ==
          std::vector<Tri>{{0, 1, 2}});
}

TEST_CASE("Medit: a tetrahedra-only file gives the boundary of its tetrahedra, facing out", "[mesh][medit]") {
    // The unit cube cut into six tetrahedra around its diagonal 0-7 (Kuhn), each positively oriented.
    std::vector<Vec3> v;
    for (int k = 0; k < 8; ++k) v.push_back({double(k & 1), double((k >> 1) & 1), double((k >> 2) & 1)});
    std::string cells = "Tetrahedra\n6\n";
    const int axes[6][3] = {{1, 2, 4}, {1, 4, 2}, {2, 1, 4}, {2, 4, 1}, {4, 1, 2}, {4, 2, 1}};
    for (const auto& a : axes) {
        std::array<int, 4> t = {0, a[0], a[0] + a[1], 7};
        const Vec3 &p = v[t[0]], &q = v[t[1]], &r = v[t[2]], &s = v[t[3]];
        const double det = (q[0] - p[0]) * ((r[1] - p[1]) * (s[2] - p[2]) - (r[2] - p[2]) * (s[1] - p[1])) -
                           (q[1] - p[1]) * ((r[0] - p[0]) * (s[2] - p[2]) - (r[2] - p[2]) * (s[0] - p[0])) +
                           (q[2] - p[2]) * ((r[0] - p[0]) * (s[1] - p[1]) - (r[1] - p[1]) * (s[0] - p[0]));
        if (det < 0) std::swap(t[1], t[2]);
        cells += std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " + std::to_string(t[2] + 1) + " " +
                 std::to_string(t[3] + 1) + " 1\n";
    }
    const Mesh m = medit(medit_text(v, cells));
    CHECK(m.vertices == v);
    CHECK(m.triangles.size() == 12);  // two per cube face; the 12 inner faces are shared and dropped
    CHECK(open_edges(m) == 0);
    CHECK(signed_volume6(m) == Approx(6.0));  // closed, facing out, volume 1
    const Volume vox = voxelize(m, 0.125);
    CHECK(count(vox) == 8 * 8 * 8);
    // one tetrahedron: its four faces
    CHECK(medit(kTetVertices + "Tetrahedra 1 1 2 3 4 0\n").triangles.size() == 4);
}

TEST_CASE("Medit: bad input names the file, the line and the problem", "[mesh][medit][errors]") {
    const std::string v4 = kTetVertices;
    const std::string pad = "# padding so that the counts fit in the bytes that follow\n";
    expect_error([&] { medit(v4 + "Triangles 1\n1 2 5 0\n", "h.mesh"); },
                 {"h.mesh: line 9: Triangles 1: vertex index 5 out of range (4 vertices, numbered from 1)"});
    expect_error([&] { medit(v4 + "Triangles 1\n0 2 3 0\n"); }, {"line 9", "vertex index 0 out of range"});
    expect_error([&] { medit(v4 + "Tetrahedra 1\n1 2 3 -4 0\n"); }, {"Tetrahedra 1: vertex index -4"});
    expect_error([&] { medit(v4 + "Triangles 1\n1 2 x 0\n"); }, {"a vertex index of Triangles 'x' is not an integer"});
    expect_error([&] { medit(v4 + "Triangles 1\n1 2 3 r\n"); }, {"the reference of one of the Triangles 'r'"});
    expect_error([&] { medit(v4 + "Triangles -1\n"); }, {"line 8", "Triangles count -1 is negative"});
    expect_error([&] { medit(v4 + "Triangles 2\n1 2 3 0\n" + pad); },
                 {"the file ends before a vertex index of Triangles (truncated)"});
    expect_error([&] { medit(v4 + "Triangles 99999999999\n1 2 3 0\n"); },
                 {"line 8", "99,999,999,999 Triangles declared (at least 8 bytes each) but only"});
    expect_error([&] { medit(v4 + "Triangles 1 1 2 3 0\n? 1\n"); }, {"line 9", "expected a keyword, got '?'"});
    expect_error([&] { medit(v4 + "Edges 1 1 2 ?\n"); }, {"line 8", "expected a number or a keyword, got '?'"});
    expect_error([&] { medit(v4 + "Vertices 1 0 0 0 0\n"); }, {"line 8", "a second Vertices section"});
    expect_error([&] { medit(v4 + "Edges 1 1 2 0\nEnd\n"); }, {"no Triangles, Quadrilaterals or Tetrahedra"});
    const std::string v0 = "MeshVersionFormatted 1\nDimension 3\n";
    expect_error([&] { medit(v0 + "Vertices 2\n0 0 0 0\n0 nan 0 0\n" + pad); },
                 {"line 5", "vertex y 'nan' is not finite"});
    expect_error([&] { medit(v0 + "Vertices 1\n0 0 inf 0\n" + pad); }, {"line 4", "z 'inf' is not finite"});
    expect_error([&] { medit(v0 + "Vertices 1\n0 0 0 0.5\n" + pad); }, {"a vertex reference '0.5' is not an integer"});
    expect_error([&] { medit(v0 + "Vertices 0\nTriangles 0\n"); }, {"line 3", "no vertices (Vertices 0)"});
    expect_error([&] { medit(v0 + "Triangles 1 1 2 3 0\n"); }, {"line 3", "Triangles before Vertices"});
    expect_error([&] { medit(v0 + "End\n"); }, {"no Vertices section"});
    expect_error([&] { medit("MeshVersionFormatted 1\nVertices 1 0 0 0 0\n"); },
                 {"line 2", "Vertices before 'Dimension 3'"});
    expect_error([&] { medit("MeshVersionFormatted 1\nDimension 2\n"); }, {"line 2", "Dimension 2: only 3-D"});
    expect_error([&] { medit("MeshVersionFormatted 5\n"); }, {"line 1", "MeshVersionFormatted 5 (known: 1 to 4)"});
    expect_error([&] { medit("MeshVersionFormatted one\n"); }, {"the version 'one' is not an integer"});
    expect_error([&] { medit("MeshVersionFormatted\n"); }, {"the file ends before the version (truncated)"});
    expect_error([&] { medit("# comment\nDimension 3\n"); }, {"line 2", "not a Medit .mesh file", "'Dimension'"});
    expect_error([&] { medit(""); }, {"m.mesh: empty file"});
    expect_error([&] { medit(std::string("MeshVersionFormatted 1\nDim\0nsion 3\n", 34)); }, {"line 2", "NUL"});
    ReadOptions small;
    small.max_bytes = 24 * 4 + 12 * 1;
    CHECK(read_mem(read_medit, bytes(v4 + "Triangles 1 1 2 3 0\n"), "ok.mesh", small).triangles.size() == 1);
    expect_error([&] { read_mem(read_medit, bytes(v4 + "Triangles 2 1 2 3 0 1 2 4 0\n"), "big.mesh", small); },
                 {"big.mesh: line 8", "4 vertices and 2 triangles", "above the limit"});
    expect_error([&] { read_mem(read_medit, bytes(v4 + "Tetrahedra 1 1 2 3 4 0\n"), "big.mesh", small); },
                 {"4 vertices and 8 triangles", "above the limit"});
}

// =================================================================================================================
// Dispatch, validation
// =================================================================================================================

TEST_CASE("read_mesh picks the reader by ending and reports missing files", "[mesh]") {
    const fs::path dir = fs::temp_directory_path() / ("volrig_mesh_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    {
        std::ofstream(dir / "t.OBJ") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        const Bytes p = tiny_binary_ply();
        std::ofstream(dir / "t.ply", std::ios::binary)
            .write(reinterpret_cast<const char*>(p.data()), static_cast<std::streamsize>(p.size()));
    }
    CHECK(read_mesh((dir / "t.OBJ").string()).triangles.size() == 1);
    CHECK(read_mesh((dir / "t.ply").string()).vertices.size() == 3);
    expect_error<FileNotFound>([&] { read_mesh((dir / "missing.obj").string()); }, {"missing.obj", "no such file"});
    {
        std::ofstream(dir / "t.off") << "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        std::ofstream(dir / "t.Mesh") << kTetVertices << "Triangles 1 1 2 3 0\n";
        const Bytes s = binary_stl(read_mesh((dir / "t.off").string()));
        std::ofstream(dir / "t.stl", std::ios::binary)
            .write(reinterpret_cast<const char*>(s.data()), static_cast<std::streamsize>(s.size()));
    }
    CHECK(read_mesh((dir / "t.off").string()).triangles.size() == 1);
    CHECK(read_mesh((dir / "t.stl").string()).vertices.size() == 3);
    CHECK(read_mesh((dir / "t.Mesh").string()).vertices.size() == 4);
    CHECK(mesh_extensions() == std::vector<std::string>{".obj", ".ply", ".off", ".stl", ".mesh"});
    expect_error([&] { read_mesh((dir / "t.3ds").string()); },
                 {"t.3ds: unknown mesh format (known endings: .obj .ply .off .stl .mesh)"});
    expect_error([&] { read_mesh((dir / "t.meshb").string()); }, {"t.meshb: binary Medit", "not supported"});
    fs::remove_all(dir);
}

TEST_CASE("make_mesh and check_mesh refuse bad arrays", "[mesh][errors]") {
    const double xyz[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const std::int64_t ok[] = {0, 1, 2}, bad[] = {0, 1, 3}, neg[] = {0, -1, 2};
    CHECK(make_mesh(xyz, 3, ok, 1).triangles == std::vector<Tri>{{0, 1, 2}});
    expect_error<Error>([&] { make_mesh(xyz, 3, bad, 1, "arrays"); },
                        {"arrays: triangle 0 uses vertex 3 out of range (3"});
    expect_error<Error>([&] { make_mesh(xyz, 3, neg, 1); }, {"vertex -1 out of range"});
    expect_error<Error>([&] { make_mesh(xyz, 0, ok, 1); }, {"no vertices"});
    expect_error<Error>([&] { make_mesh(xyz, 3, ok, 0); }, {"no triangles"});
    const double nan_xyz[] = {0, 0, 0, 1, std::nan(""), 0, 0, 1, 0};
    expect_error<Error>([&] { make_mesh(nan_xyz, 3, ok, 1); }, {"vertex 1", "non-finite", "y = nan"});
    Mesh m = make_mesh(xyz, 3, ok, 1);
    m.triangles[0][2] = 7;
    expect_error<Error>([&] { check_mesh(m, "m"); }, {"m: triangle 0 uses vertex 7"});
}


// =================================================================================================================
// Fuzz seed corpus: every seed must read or fail with a volrig error (regression for fuzzer findings)
// =================================================================================================================

TEST_CASE("Mesh fuzz corpus files never crash the readers", "[mesh][fuzz]") {
    const fs::path corpus = VOLRIG_FUZZ_CORPUS;
    if (!fs::is_directory(corpus)) {
        WARN("no fuzz corpus at " << corpus << ": skipped");
        return;
    }
    ReadOptions opt;
    opt.max_bytes = 64 << 20;
    int files = 0;
    const std::vector<Mesh (*)(const ByteSource&, const ReadOptions&)> readers = {read_obj, read_ply, read_off,
                                                                                 read_stl, read_medit};
    for (const char* sub : {"obj", "ply", "tgf", "off", "stl", "medit"}) {
        if (!fs::is_directory(corpus / sub)) continue;
        for (const auto& e : fs::directory_iterator(corpus / sub)) {
            const Bytes b = read_file(e.path());
            INFO(e.path());
            for (auto reader : readers) {
                try {
                    read_mem(reader, b, e.path().filename().string(), opt);
                } catch (const Error&) {
                }
            }
            try {
                read_mem(read_tgf, b, e.path().filename().string(), opt);
            } catch (const Error&) {
            }
            ++files;
        }
    }
    CHECK(files >= 60);
}

// =================================================================================================================
// Real data: libigl's arm
// =================================================================================================================

TEST_CASE("Real: arm.obj and arm.tgf read, voxelize, and the joints lie in the arm", "[mesh][real]") {
    if (skip_without_data()) return;
    const Mesh arm = read_mesh(shared_data() + "/meshes/arm.obj");
    CHECK(arm.vertices.size() == 8311);
    CHECK(arm.triangles.size() == 16618);
    auto src = open_file(shared_data() + "/meshes/arm.tgf");
    const TgfSkeleton s = read_tgf(*src);
    REQUIRE(s.joints.size() == 5);
    CHECK(s.edges == std::vector<std::array<std::uint32_t, 2>>{{0, 1}, {1, 2}, {2, 3}, {3, 4}});
    CHECK(s.joints[0][0] == Approx(-0.72962893));
    CHECK(s.joints[4][2] == Approx(0.090210152));

    const double h = 0.01;
    const Volume v = voxelize(arm, h);
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{187, 77, 47});
    const double exact = volume_of(arm) / (h * h * h);
    INFO("arm: " << count(v) << " voxels, polyhedron " << exact);
    CHECK(std::abs(static_cast<double>(count(v)) / exact - 1) < 0.01);
    VoxelizeOptions vdb;
    vdb.closing_radius = 0;
    CHECK(agreement(v, voxelize(arm, h, vdb)).first > 0.999);
    // every joint within 3 voxels of an inside voxel
    for (const Vec3& j : s.joints) {
        double best = 1e9;
        for (std::int64_t z = 0; z < v.grid.dims[2]; ++z)
            for (std::int64_t y = 0; y < v.grid.dims[1]; ++y)
                for (std::int64_t x = 0; x < v.grid.dims[0]; ++x)
                    if (v.data[static_cast<std::size_t>(v.grid.index(x, y, z))]) {
                        const Vec3 p = centre_of(v, x, y, z);
                        best = std::min(best, std::hypot(p[0] - j[0], p[1] - j[1], p[2] - j[2]));
                    }
        INFO("joint " << j[0] << " " << j[1] << " " << j[2]);
        CHECK(best <= 3 * h);
    }
}

TEST_CASE("Real: hand.mesh's triangles are the boundary of its tetrahedra", "[mesh][medit][real]") {
    if (skip_without_data()) return;
    const Bytes file = read_file(shared_data() + "/meshes/hand.mesh");
    const Mesh hand = read_mem(read_medit, file, "hand.mesh");
    CHECK(hand.vertices.size() == 7234);
    CHECK(hand.triangles.size() == 9556);
    CHECK(open_edges(hand) == 0);
    // The same file without its Triangles section: the surface comes from the tetrahedra.
    std::string text(file.begin(), file.end());
    const std::size_t from = text.find("\nTriangles\n"), to = text.find("\nTetrahedra\n");
    REQUIRE(from < to);
    text.erase(from, to - from);
    const Mesh tets = read_mem(read_medit, bytes(text), "hand-tets.mesh");
    auto sorted_faces = [](const Mesh& m) {
        std::vector<Tri> out;
        for (Tri t : m.triangles) {
            std::sort(t.begin(), t.end());
            out.push_back(t);
        }
        std::sort(out.begin(), out.end());
        return out;
    };
    CHECK(sorted_faces(tets) == sorted_faces(hand));
    // Both face the same way (a consistent orientation; sign of the enclosed volume equal).
    CHECK(signed_volume6(tets) == Approx(signed_volume6(hand)));
    INFO("hand volume " << signed_volume6(hand) / 6);
}

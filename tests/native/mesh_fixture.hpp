// mesh_fixture.hpp: what the mesh tests (test_mesh*.cpp) share: byte and file helpers, temporary folders, test
// meshes (boxes, spheres) and writers for the round trips.
#pragma once

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

using namespace volrig;
namespace fs = std::filesystem;

namespace {

using Bytes = std::vector<std::uint8_t>;
using Vec3 = std::array<double, 3>;
using Tri = std::array<std::uint32_t, 3>;

inline Bytes bytes(const std::string& s) { return Bytes(s.begin(), s.end()); }
inline Bytes operator+(Bytes a, const Bytes& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

inline Bytes read_file(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return Bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

template <class R>
auto read_mem(R reader, const Bytes& b, const std::string& name, ReadOptions opt = {}) {
    auto src = memory_source(b.data(), b.size(), name);
    return reader(*src, opt);
}
inline Mesh obj(const std::string& text, const std::string& name = "m.obj") {
    return read_mem(read_obj, bytes(text), name);
}
inline Mesh ply(const Bytes& b, const std::string& name = "m.ply") { return read_mem(read_ply, b, name); }
inline TgfSkeleton tgf(const std::string& text, const std::string& name = "s.tgf") {
    return read_mem(read_tgf, bytes(text), name);
}

/// Runs f and checks it throws E whose message contains every part.
template <class E = FileFormatError, class F>
void expect_error(F&& f, std::initializer_list<std::string> parts) {
    try {
        f();
    } catch (const E& e) {
        const std::string m = e.what();
        INFO("message: " << m);
        for (const auto& p : parts) CHECK(m.find(p) != std::string::npos);
        return;
    }
    std::string all;
    for (const auto& p : parts) all += "'" + p + "' ";
    FAIL("no exception; expected one mentioning " << all);
}

// ---- test meshes -----------------------------------------------------------------------------------------------

/// The box [lo, hi] as 8 vertices and 6 quads (outward, counter-clockwise), fan-split as the readers split them.
struct QuadBox {
    std::vector<Vec3> v;
    std::vector<std::array<std::uint32_t, 4>> quads = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                                       {2, 3, 7, 6}, {1, 2, 6, 5}, {0, 4, 7, 3}};
    explicit QuadBox(Vec3 lo = {0, 0, 0}, Vec3 hi = {1, 1, 1}) {
        for (int k = 0; k < 8; ++k)
            v.push_back({(k & 1) ^ ((k >> 1) & 1) ? hi[0] : lo[0], (k & 2) ? hi[1] : lo[1], (k & 4) ? hi[2] : lo[2]});
    }
    Mesh mesh() const {
        Mesh m;
        m.vertices = v;
        for (const auto& q : quads) {
            m.triangles.push_back({q[0], q[1], q[2]});
            m.triangles.push_back({q[0], q[2], q[3]});
        }
        return m;
    }
};

inline Mesh rotated(Mesh m, double ax, double ay, double az, Vec3 shift) {
    auto rot = [](Vec3 p, int a, double t) {
        const int i = (a + 1) % 3, j = (a + 2) % 3;
        const double c = std::cos(t), s = std::sin(t), pi = p[static_cast<std::size_t>(i)],
                     pj = p[static_cast<std::size_t>(j)];
        p[static_cast<std::size_t>(i)] = c * pi - s * pj;
        p[static_cast<std::size_t>(j)] = s * pi + c * pj;
        return p;
    };
    for (auto& p : m.vertices) {
        p = rot(rot(rot(p, 0, ax), 1, ay), 2, az);
        for (std::size_t a = 0; a < 3; ++a) p[a] += shift[a];
    }
    return m;
}

/// Icosahedron subdivided `levels` times onto the sphere of radius `r` centred at `c`.
inline Mesh icosphere(int levels, double r = 1.0, Vec3 c = {0, 0, 0}) {
    const double t = (1 + std::sqrt(5.0)) / 2;
    std::vector<Vec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                           {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    std::vector<Tri> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                          {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                          {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    auto unit = [](Vec3 p) {
        const double n = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        return Vec3{p[0] / n, p[1] / n, p[2] / n};
    };
    for (auto& p : v) p = unit(p);
    for (int l = 0; l < levels; ++l) {
        std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
        auto m = [&](std::uint32_t a, std::uint32_t b) {
            const auto key = std::minmax(a, b);
            auto it = mid.find(key);
            if (it != mid.end()) return it->second;
            v.push_back(unit({v[a][0] + v[b][0], v[a][1] + v[b][1], v[a][2] + v[b][2]}));
            return mid[key] = static_cast<std::uint32_t>(v.size() - 1);
        };
        std::vector<Tri> g;
        for (const auto& x : f) {
            const std::uint32_t ab = m(x[0], x[1]), bc = m(x[1], x[2]), ca = m(x[2], x[0]);
            g.push_back({x[0], ab, ca});
            g.push_back({x[1], bc, ab});
            g.push_back({x[2], ca, bc});
            g.push_back({ab, bc, ca});
        }
        f = std::move(g);
    }
    Mesh out;
    for (auto& p : v) out.vertices.push_back({c[0] + r * p[0], c[1] + r * p[1], c[2] + r * p[2]});
    out.triangles = f;
    return out;
}

/// Six times the signed volume of a closed mesh (positive when its triangles face outward).
inline double signed_volume6(const Mesh& m) {
    double s = 0;
    for (const Tri& t : m.triangles) {
        const Vec3 &a = m.vertices[t[0]], &b = m.vertices[t[1]], &c = m.vertices[t[2]];
        s += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
             a[2] * (b[0] * c[1] - b[1] * c[0]);
    }
    return s;
}

/// Exact volume of a closed, consistently oriented mesh (divergence theorem).
inline double volume_of(const Mesh& m) { return std::abs(signed_volume6(m)) / 6; }

inline std::int64_t count(const Volume& v) { return std::count(v.data.begin(), v.data.end(), std::uint8_t(1)); }

inline Vec3 centre_of(const Volume& v, std::int64_t x, std::int64_t y, std::int64_t z) {
    return {v.grid.origin[0] + v.grid.spacing[0] * static_cast<double>(x),
            v.grid.origin[1] + v.grid.spacing[1] * static_cast<double>(y),
            v.grid.origin[2] + v.grid.spacing[2] * static_cast<double>(z)};
}

/// Fraction of voxels on which two masks of one grid agree, and the overlap |a and b| / |a|.
inline std::pair<double, double> agreement(const Volume& a, const Volume& b) {
    REQUIRE(a.grid.dims == b.grid.dims);
    std::int64_t same = 0, both = 0, in_a = 0;
    for (std::size_t i = 0; i < a.data.size(); ++i) {
        same += a.data[i] == b.data[i];
        both += a.data[i] && b.data[i];
        in_a += a.data[i] != 0;
    }
    return {static_cast<double>(same) / static_cast<double>(a.data.size()),
            static_cast<double>(both) / static_cast<double>(std::max<std::int64_t>(in_a, 1))};
}

// ---- writers for the round trips -------------------------------------------------------------------------------

inline std::string num(double v) {
    std::ostringstream s;
    s.precision(17);
    s << v;
    return s.str();
}

enum class PlyEnc { Ascii, LE, BE };

struct PlyWriter {
    PlyEnc enc;
    std::string header = "ply\n";
    Bytes body;
    std::string line;  // ascii: the element instance being written

    explicit PlyWriter(PlyEnc e) : enc(e) {
        header += std::string("format ") +
                  (e == PlyEnc::Ascii ? "ascii" : e == PlyEnc::LE ? "binary_little_endian" : "binary_big_endian") +
                  " 1.0\ncomment written by test_mesh.cpp\n";
    }
    void h(const std::string& s) { header += s + "\n"; }
    template <class T>
    void put(T v) {
        if (enc == PlyEnc::Ascii) {
            if (!line.empty()) line += ' ';
            if constexpr (std::is_floating_point_v<T>)
                line += num(static_cast<double>(v));
            else
                line += std::to_string(static_cast<long long>(v));
            return;
        }
        std::uint8_t b[sizeof(T)];
        std::memcpy(b, &v, sizeof(T));
        if (enc == PlyEnc::BE) std::reverse(b, b + sizeof(T));
        body.insert(body.end(), b, b + sizeof(T));
    }
    void end_instance() {
        if (enc == PlyEnc::Ascii) {
            const Bytes l = bytes(line + "\n");
            body.insert(body.end(), l.begin(), l.end());
            line.clear();
        }
    }
    Bytes bytes_() const { return bytes(header + "end_header\n") + body; }
};

/// The QuadBox as PLY with extra properties and elements, x y z of type XYZ and indices of type I.
template <class XYZ, class I>
Bytes box_ply(PlyEnc enc, const char* xyz_type, const char* index_type, const QuadBox& b) {
    PlyWriter w(enc);
    w.h("obj_info extra elements before, between and after");
    w.h("element material 2");
    w.h("property uchar red");
    w.h("property list uchar float params");
    w.h("element vertex 8");
    w.h("property float nx");
    w.h(std::string("property ") + xyz_type + " x");
    w.h(std::string("property ") + xyz_type + " y");
    w.h("property list ushort int extra");
    w.h(std::string("property ") + xyz_type + " z");
    w.h("property uchar red");
    w.h("element face 6");
    w.h("property int flags");
    w.h(std::string("property list uchar ") + index_type + " vertex_indices");
    w.h("property double quality");
    w.h("element edge 1");
    w.h("property int vertex1");
    w.h("property int vertex2");
    for (int m = 0; m < 2; ++m) {
        w.put<std::uint8_t>(200);
        w.put<std::uint8_t>(static_cast<std::uint8_t>(m + 1));
        for (int k = 0; k <= m; ++k) w.put<float>(0.5f * static_cast<float>(k));
        w.end_instance();
    }
    for (const auto& p : b.v) {
        w.put<float>(-1.0f);
        w.put<XYZ>(static_cast<XYZ>(p[0]));
        w.put<XYZ>(static_cast<XYZ>(p[1]));
        w.put<std::uint16_t>(2);
        w.put<std::int32_t>(7);
        w.put<std::int32_t>(-7);
        w.put<XYZ>(static_cast<XYZ>(p[2]));
        w.put<std::uint8_t>(255);
        w.end_instance();
    }
    for (const auto& q : b.quads) {
        w.put<std::int32_t>(-3);
        w.put<std::uint8_t>(4);
        for (auto k : q) w.put<I>(static_cast<I>(k));
        w.put<double>(0.25);
        w.end_instance();
    }
    w.put<std::int32_t>(0);
    w.put<std::int32_t>(1);
    w.end_instance();
    return w.bytes_();
}

/// A minimal PLY: the header lines given, then the body.
inline Bytes ply_with(PlyEnc enc, const std::vector<std::string>& lines, const Bytes& body) {
    PlyWriter w(enc);
    for (const auto& l : lines) w.h(l);
    w.body = body;
    return w.bytes_();
}

template <class T>
Bytes le(std::initializer_list<T> vals) {
    Bytes out;
    for (T v : vals) {
        std::uint8_t b[sizeof(T)];
        std::memcpy(b, &v, sizeof(T));
        out.insert(out.end(), b, b + sizeof(T));
    }
    return out;
}

/// A binary little-endian triangle: 3 float vertices and one face of uchar count + int indices.
inline Bytes tiny_binary_ply(std::int32_t index2 = 2, float x0 = 0, std::uint8_t count = 3) {
    return ply_with(PlyEnc::LE,
                    {"element vertex 3", "property float x", "property float y", "property float z", "element face 1",
                     "property list uchar int vertex_indices"},
                    le<float>({x0, 0, 0, 1, 0, 0, 0, 1, 0}) + Bytes{count} + le<std::int32_t>({0, 1, index2}));
}

inline std::string shared_data() { return VOLRIG_SHARED_DATA; }
inline bool skip_without_data() {
    if (fs::is_directory(shared_data() + "/meshes")) return false;
    WARN("shared test data not found at " << shared_data() << "/meshes: real-mesh tests skipped");
    return true;
}

/// voxelize reports progress from 0 to 1 in order (at least `min_calls` calls), and a progress callback that
/// returns false once past each of `stops` cancels it: Cancelled, and no call after.
inline void check_voxelize_progress(const Mesh& mesh, double voxel, const VoxelizeOptions& opt, std::size_t min_calls,
                                    const std::vector<double>& stops) {
    std::vector<double> seen;
    voxelize(mesh, voxel, opt, [&](double f) {
        seen.push_back(f);
        return true;
    });
    REQUIRE(seen.size() >= min_calls);
    CHECK(seen.front() == 0.0);
    CHECK(seen.back() == 1.0);
    CHECK(std::is_sorted(seen.begin(), seen.end()));
    for (double stop_at : stops) {
        int calls_after = 0;
        bool stopped = false;
        CHECK_THROWS_AS(voxelize(mesh, voxel, opt,
                                 [&](double f) {
                                     if (stopped) ++calls_after;
                                     stopped = stopped || f > stop_at;
                                     return !stopped;
                                 }),
                        Cancelled);
        CHECK(calls_after == 0);
    }
}

}  // namespace

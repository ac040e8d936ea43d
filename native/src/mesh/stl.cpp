// mesh/stl.cpp: the STL reader of volrig/mesh.hpp, ASCII and binary, with exact vertex welding.
//
// Binary or ASCII is decided by the size equation (84 + 50 x count bytes), not by the first word: binary files
// often start with "solid" too. A binary file's size bounds everything it decodes to; an ASCII file is read line
// by line (1 MiB chunks) and stops once the decoded mesh would exceed ReadOptions::max_bytes.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <unordered_map>

#include "mesh/mesh_detail.hpp"

namespace volrig {

using mesh_detail::fail;
using mesh_detail::quoted;
using mesh_detail::with_commas;

namespace {

constexpr std::uint64_t kHeaderBytes = 84;      // 80-byte header + uint32 triangle count
constexpr std::uint64_t kRecordBytes = 50;      // normal, 3 corners (float32 x 12), uint16 attribute
constexpr std::uint64_t kBatch = 1 << 15;       // records read at a time
constexpr std::uint64_t kSniffBytes = 4096;     // bytes searched for a NUL to tell broken binary from text

using Vec3 = std::array<double, 3>;

/// Merges vertices with identical coordinates (-0 and +0 alike), appending new ones to the mesh.
class Welder {
public:
    explicit Welder(Mesh& m) : m_(m) {}

    std::uint32_t add(Vec3 p) {
        for (double& c : p) c += 0.0;  // -0 + 0 = +0
        const auto [it, fresh] = index_.try_emplace(p, static_cast<std::uint32_t>(m_.vertices.size()));
        if (fresh) m_.vertices.push_back(p);
        return it->second;
    }

private:
    struct Hash {
        std::size_t operator()(const Vec3& p) const {
            std::uint64_t h = 0x9e3779b97f4a7c15ULL, bits = 0;
            for (double c : p) {
                std::memcpy(&bits, &c, sizeof bits);
                h = (h ^ bits) * 0xff51afd7ed558ccdULL;
                h ^= h >> 32;
            }
            return static_cast<std::size_t>(h);
        }
    };
    Mesh& m_;
    std::unordered_map<Vec3, std::uint32_t, Hash> index_;
};

std::uint32_t read_u32_le(const std::uint8_t* b) {
    return std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 | std::uint32_t(b[2]) << 16 | std::uint32_t(b[3]) << 24;
}

float read_f32_le(const std::uint8_t* b) {
    const std::uint32_t u = read_u32_le(b);
    float f;
    std::memcpy(&f, &u, sizeof f);
    return f;
}

Mesh read_binary(const ByteSource& src, std::uint64_t count, const ReadOptions& opt) {
    const std::string& name = src.name();
    if (count == 0) fail(name, "binary STL with 0 triangles: nothing to voxelize");
    mesh_detail::check_mesh_size(name, [] { return std::string("header: "); }, 0, count, opt.max_bytes);
    Mesh m;
    m.triangles.reserve(static_cast<std::size_t>(count));
    Welder weld(m);
    std::vector<std::uint8_t> buf;
    for (std::uint64_t first = 0; first < count; first += kBatch) {
        const std::uint64_t k = std::min(kBatch, count - first);
        buf.resize(static_cast<std::size_t>(k * kRecordBytes));
        src.read(kHeaderBytes + first * kRecordBytes, buf.data(), buf.size());
        for (std::uint64_t j = 0; j < k; ++j) {
            const std::uint64_t t = first + j;
            auto where = [&] {
                return "triangle " + with_commas(t) + " (byte " + with_commas(kHeaderBytes + t * kRecordBytes) + "): ";
            };
            mesh_detail::check_mesh_size(name, where, m.vertices.size() + 3, count, opt.max_bytes);
            std::array<std::uint32_t, 3> tri{};
            for (std::size_t c = 0; c < 3; ++c) {
                Vec3 p{};
                for (std::size_t a = 0; a < 3; ++a) {
                    p[a] = static_cast<double>(read_f32_le(buf.data() + j * kRecordBytes + 12 * (c + 1) + 4 * a));
                    if (!std::isfinite(p[a]))
                        fail(name, where() + "corner " + std::to_string(c) + " has " + std::string(1, "xyz"[a]) +
                                       " = " + mesh_detail::format_double(p[a]) + " (not finite)");
                }
                tri[c] = weld.add(p);
            }
            m.triangles.push_back(tri);
        }
    }
    return m;
}

/// ASCII STL: solids of facets, read token by token.
class AsciiStl {
public:
    AsciiStl(const ByteSource& src, const ReadOptions& opt)
        : name_(src.name()), opt_(opt), lines_(src), tokens_(lines_, src.name(), "ASCII STL"), weld_(m_) {}

    Mesh read() {
        std::string_view tok;
        while (tokens_.next(tok)) {
            if (!mesh_detail::iequals(tok, "solid"))
                fail(name_, tokens_.here() + "expected 'solid', got " + quoted(tok));
            tokens_.skip_line();  // the solid's name
            read_solid();
        }
        if (m_.triangles.empty()) fail(name_, "no facets: nothing to voxelize");
        return std::move(m_);
    }

private:
    void read_solid() {
        for (;;) {
            const std::string_view tok = tokens_.need("'endsolid' (the solid is not closed)");
            if (mesh_detail::iequals(tok, "endsolid")) {
                tokens_.skip_line();  // the solid's name again
                return;
            }
            if (!mesh_detail::iequals(tok, "facet"))
                fail(name_, tokens_.here() + "expected 'facet' or 'endsolid', got " + quoted(tok));
            read_facet();
        }
    }

    void read_facet() {
        tokens_.expect("normal");
        for (int a = 0; a < 3; ++a) {  // the normal: numbers, but unused (writers put nan in degenerate facets)
            const std::string_view tok = tokens_.need("the facet normal");
            if (double ignored = 0; !mesh_detail::parse_double(tok, ignored))
                fail(name_, tokens_.here() + "facet normal " + quoted(tok) + " is not a number");
        }
        tokens_.expect("outer");
        tokens_.expect("loop");
        poly_.clear();
        for (;;) {
            const std::string_view tok = tokens_.need("'endloop'");
            if (mesh_detail::iequals(tok, "endloop")) break;
            if (!mesh_detail::iequals(tok, "vertex"))
                fail(name_, tokens_.here() + "expected 'vertex' or 'endloop', got " + quoted(tok));
            mesh_detail::check_mesh_size(name_, [&] { return tokens_.here(); }, m_.vertices.size() + 1,
                                    m_.triangles.size() + std::max<std::size_t>(poly_.size(), 1) - 1, opt_.max_bytes);
            poly_.push_back(weld_.add(vertex()));
        }
        if (poly_.size() < 3) fail(name_, tokens_.here() + "facet has " + std::to_string(poly_.size()) +
                                              " vertices (a facet needs at least 3)");
        tokens_.expect("endfacet");
        mesh_detail::fan(poly_, m_.triangles);
    }

    Vec3 vertex() {
        Vec3 p{};
        for (std::size_t a = 0; a < 3; ++a) {
            const std::string_view tok = tokens_.need("the vertex's coordinates");
            std::string why;
            if (!mesh_detail::parse_coordinate(tok, a, p[a], why)) fail(name_, tokens_.here() + "vertex " + why);
        }
        return p;
    }

    const std::string& name_;
    const ReadOptions& opt_;
    mesh_detail::LineReader lines_;
    mesh_detail::TokenReader tokens_;
    Mesh m_;
    Welder weld_;
    std::vector<std::uint32_t> poly_;
};

/// True when the first bytes hold a NUL (binary data, not text).
bool looks_binary(const ByteSource& src) {
    std::vector<std::uint8_t> head(static_cast<std::size_t>(std::min(src.size(), kSniffBytes)));
    src.read(0, head.data(), head.size());
    return std::find(head.begin(), head.end(), 0) != head.end();
}

}  // namespace

Mesh read_stl(const ByteSource& src, const ReadOptions& opt) {
    const std::string& name = src.name();
    const std::uint64_t size = src.size();
    std::uint64_t count = 0;
    if (size >= kHeaderBytes) {
        std::uint8_t b[4];
        src.read(80, b, 4);
        count = read_u32_le(b);
        if (size == kHeaderBytes + kRecordBytes * count) return read_binary(src, count, opt);
    }
    if (size == 0) fail(name, "empty file: not an STL file");
    if (looks_binary(src)) {
        if (size < kHeaderBytes)
            fail(name, "binary data in " + with_commas(size) + " bytes: too short for a binary STL (84-byte header)");
        fail(name, "binary STL whose size does not match its triangle count: 84 + 50 x " + with_commas(count) +
                       " = " + with_commas(kHeaderBytes + kRecordBytes * count) + " bytes, but the file holds " +
                       with_commas(size) + " (truncated or corrupt)");
    }
    return AsciiStl(src, opt).read();
}

}  // namespace volrig

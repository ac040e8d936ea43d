// mesh_io.cpp: the OBJ, PLY and TGF readers of volrig/mesh.hpp, and mesh validation.
//
// All three read through a ByteSource in 1 MiB chunks (never the whole file at once). Text formats report line
// numbers; binary PLY reports the element and its byte offset. Sizes: a PLY header's element counts are checked
// against the bytes that follow it before anything is allocated; every reader stops once the decoded mesh would
// exceed ReadOptions::max_bytes (24 bytes per vertex, 12 per triangle) or 2^32 - 1 vertices.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>

#include "io_detail.hpp"
#include "volrig/mesh.hpp"

namespace volrig {

namespace {

using detail::fail;
using detail::quoted;
using detail::with_commas;

using detail::at_line;
using detail::LineReader;
using detail::refuse_binary;

constexpr std::size_t kChunk = detail::kTextChunk;
constexpr std::size_t kMaxLine = detail::kMaxLine;
constexpr std::uint64_t kMaxVertices = std::numeric_limits<std::uint32_t>::max();
constexpr std::uint64_t kVertexBytes = sizeof(std::array<double, 3>);
constexpr std::uint64_t kTriangleBytes = sizeof(std::array<std::uint32_t, 3>);

/// Throws when a mesh of this many vertices and triangles would exceed the limits; `where()` gives the message's
/// location prefix (built only on failure).
template <class Where>
void check_mesh_size(const std::string& name, const Where& where, std::uint64_t vertices, std::uint64_t triangles,
                     std::uint64_t max_bytes) {
    const long double bytes = static_cast<long double>(vertices) * kVertexBytes +
                              static_cast<long double>(triangles) * kTriangleBytes;
    if (vertices <= kMaxVertices && bytes <= static_cast<long double>(max_bytes)) return;
    if (vertices > kMaxVertices)
        fail(name, where() + "more than " + with_commas(kMaxVertices) + " vertices (indices are 32-bit)");
    fail(name, where() + with_commas(vertices) + " vertices and " + with_commas(triangles) + " triangles take " +
                   with_commas(static_cast<std::uint64_t>(std::min<long double>(bytes, 1.8e19L))) +
                   " bytes, above the limit of " + with_commas(max_bytes) +
                   " bytes (raise max_bytes if this is intended)");
}

/// Parses three finite coordinates; the message names what is wrong.
bool parse_xyz(const std::vector<std::string_view>& w, std::size_t first, std::array<double, 3>& p, std::string& why) {
    for (int a = 0; a < 3; ++a) {
        const std::string_view tok = w[first + static_cast<std::size_t>(a)];
        if (!detail::parse_double(tok, p[static_cast<std::size_t>(a)])) {
            why = std::string(1, "xyz"[a]) + " " + quoted(tok) + " is not a number";
            return false;
        }
        if (!std::isfinite(p[static_cast<std::size_t>(a)])) {
            why = std::string(1, "xyz"[a]) + " " + quoted(tok) + " is not finite";
            return false;
        }
    }
    return true;
}

/// Appends the fan triangulation of polygon `poly` (v0 v1 v2, v0 v2 v3, ...).
void fan(const std::vector<std::uint32_t>& poly, std::vector<std::array<std::uint32_t, 3>>& out) {
    for (std::size_t i = 1; i + 1 < poly.size(); ++i) out.push_back({poly[0], poly[i], poly[i + 1]});
}

}  // namespace

// =================================================================================================================
// OBJ
// =================================================================================================================

namespace {

/// The vertex part of an OBJ face entry ("7", "7/2", "7//3", "7/2/3"); false when malformed.
bool obj_vertex_index(std::string_view tok, std::int64_t& index) {
    const std::size_t s1 = tok.find('/');
    if (!detail::parse_int(tok.substr(0, s1), index)) return false;
    if (s1 == std::string_view::npos) return true;
    std::string_view rest = tok.substr(s1 + 1);
    const std::size_t s2 = rest.find('/');
    std::int64_t ignored = 0;
    const std::string_view t = rest.substr(0, s2);
    if (!t.empty() && !detail::parse_int(t, ignored)) return false;
    if (s2 == std::string_view::npos) return true;
    const std::string_view n = rest.substr(s2 + 1);
    return !n.empty() && detail::parse_int(n, ignored);
}

}  // namespace

Mesh read_obj(const ByteSource& src, const ReadOptions& opt) {
    const std::string& name = src.name();
    LineReader lines(src);
    Mesh m;
    std::vector<std::uint32_t> poly;
    std::string joined;
    std::int64_t max_index = 0, max_index_line = 0;  // largest positive index: checked once all vertices are known
    std::string_view line;
    while (lines.next(line)) {
        const std::int64_t line_no = lines.line_number();
        refuse_binary(name, line_no, line, "OBJ");
        // A backslash at the end continues the statement on the next line.
        if (!detail::trim(line).empty() && detail::trim(line).back() == '\\') {
            joined.clear();
            std::string_view part = line;
            for (;;) {
                std::string_view t = detail::trim(part);
                if (t.empty() || t.back() != '\\') {
                    joined.append(part);
                    break;
                }
                t.remove_suffix(1);
                joined.append(t);
                joined += ' ';
                if (joined.size() > kMaxLine) fail(name, at_line(line_no) + "continued line is too long");
                if (!lines.next(part)) break;
                refuse_binary(name, lines.line_number(), part, "OBJ");
            }
            line = joined;
        }
        const std::size_t hash = line.find('#');
        if (hash != std::string_view::npos) line = line.substr(0, hash);
        const auto w = detail::split_words(line);
        if (w.empty()) continue;
        if (w[0] == "v") {
            if (w.size() < 4) fail(name, at_line(line_no) + "vertex needs x y z, got " + quoted(detail::trim(line)));
            std::array<double, 3> p{};
            std::string why;
            if (!parse_xyz(w, 1, p, why)) fail(name, at_line(line_no) + "vertex " + why);
            check_mesh_size(name, [&] { return at_line(line_no); }, m.vertices.size() + 1, m.triangles.size(),
                            opt.max_bytes);
            m.vertices.push_back(p);
        } else if (w[0] == "f") {
            if (w.size() < 4)
                fail(name, at_line(line_no) + "face has " + std::to_string(w.size() - 1) +
                               (w.size() == 2 ? " vertex" : " vertices") + " (a face needs at least 3)");
            poly.clear();
            const auto count = static_cast<std::int64_t>(m.vertices.size());
            for (std::size_t i = 1; i < w.size(); ++i) {
                std::int64_t k = 0;
                if (!obj_vertex_index(w[i], k))
                    fail(name, at_line(line_no) + "face entry " + quoted(w[i]) +
                                   " is not an index (expected i, i/t, i//n or i/t/n)");
                if (k == 0) fail(name, at_line(line_no) + "face index 0 is invalid (OBJ indices start at 1)");
                if (k < 0) {
                    if (-k > count)
                        fail(name, at_line(line_no) + "relative face index " + std::to_string(k) +
                                       " refers before the first vertex (" +
                                       with_commas(static_cast<std::uint64_t>(count)) + " vertices so far)");
                    k = count + k + 1;
                }
                if (static_cast<std::uint64_t>(k) > kMaxVertices)
                    fail(name, at_line(line_no) + "face index " + std::to_string(k) + " out of range (" +
                                   with_commas(m.vertices.size()) + " vertices)");
                if (k > max_index) {
                    max_index = k;
                    max_index_line = line_no;
                }
                poly.push_back(static_cast<std::uint32_t>(k - 1));
            }
            check_mesh_size(name, [&] { return at_line(line_no); }, m.vertices.size(),
                            m.triangles.size() + poly.size() - 2, opt.max_bytes);
            fan(poly, m.triangles);
        }
        // Everything else (vt vn vp g o s usemtl mtllib l p and unknown statements) is ignored.
    }
    if (m.vertices.empty()) fail(name, "no vertices ('v' lines): not an OBJ mesh");
    if (m.triangles.empty()) fail(name, "no faces ('f' lines): nothing to voxelize");
    if (static_cast<std::uint64_t>(max_index) > m.vertices.size())
        fail(name, at_line(max_index_line) + "face index " + std::to_string(max_index) + " out of range (" +
                       with_commas(m.vertices.size()) + " vertices)");
    return m;
}

// =================================================================================================================
// TGF
// =================================================================================================================

TgfSkeleton read_tgf(const ByteSource& src, const ReadOptions& opt) {
    const std::string& name = src.name();
    LineReader lines(src);
    TgfSkeleton s;
    struct PendingEdge {
        std::int64_t a, b, line;
    };
    std::vector<PendingEdge> edges;
    int section = 0;  // 0 joints, 1 edges, 2 ignored
    std::string_view line;
    while (section < 2 && lines.next(line)) {
        const std::int64_t line_no = lines.line_number();
        refuse_binary(name, line_no, line, "TGF");
        const auto w = detail::split_words(line);
        if (w.empty()) continue;
        if (w[0][0] == '#') {
            ++section;
            continue;
        }
        if (section == 0) {
            std::int64_t index = 0;
            if (w.size() < 4)
                fail(name, at_line(line_no) + "joint needs 'index x y z', got " + quoted(detail::trim(line)));
            if (!detail::parse_int(w[0], index))
                fail(name, at_line(line_no) + "joint index " + quoted(w[0]) + " is not an integer");
            std::array<double, 3> p{};
            std::string why;
            if (!parse_xyz(w, 1, p, why)) fail(name, at_line(line_no) + "joint " + why);
            check_mesh_size(name, [&] { return at_line(line_no); }, s.joints.size() + 1, edges.size(), opt.max_bytes);
            s.joints.push_back(p);
        } else {
            std::int64_t a = 0, b = 0;
            if (w.size() < 2)
                fail(name, at_line(line_no) + "edge needs two joint numbers, got " + quoted(detail::trim(line)));
            if (!detail::parse_int(w[0], a) || !detail::parse_int(w[1], b))
                fail(name, at_line(line_no) + "edge " + quoted(detail::trim(line)) +
                               " does not start with two integers");
            check_mesh_size(name, [&] { return at_line(line_no); }, s.joints.size(), edges.size() + 1, opt.max_bytes);
            edges.push_back({a, b, line_no});
        }
    }
    if (s.joints.empty()) fail(name, "no joints: not a TGF skeleton");
    const auto n = static_cast<std::int64_t>(s.joints.size());
    s.edges.reserve(edges.size());
    for (const PendingEdge& e : edges) {
        for (std::int64_t j : {e.a, e.b})
            if (j < 1 || j > n)
                fail(name, at_line(e.line) + "edge joint " + std::to_string(j) + " out of range (" +
                               with_commas(static_cast<std::uint64_t>(n)) + " joints, numbered from 1)");
        if (e.a == e.b) fail(name, at_line(e.line) + "edge joins joint " + std::to_string(e.a) + " to itself");
        s.edges.push_back({static_cast<std::uint32_t>(e.a - 1), static_cast<std::uint32_t>(e.b - 1)});
    }
    return s;
}

// =================================================================================================================
// PLY
// =================================================================================================================

namespace {

enum class PlyType : std::uint8_t { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

std::size_t ply_size(PlyType t) {
    switch (t) {
        case PlyType::Int8:
        case PlyType::UInt8: return 1;
        case PlyType::Int16:
        case PlyType::UInt16: return 2;
        case PlyType::Int32:
        case PlyType::UInt32:
        case PlyType::Float32: return 4;
        case PlyType::Float64: return 8;
    }
    return 1;
}

bool ply_integer(PlyType t) { return t != PlyType::Float32 && t != PlyType::Float64; }

bool ply_type(std::string_view s, PlyType& t) {
    static const std::pair<const char*, PlyType> names[] = {
        {"char", PlyType::Int8},     {"int8", PlyType::Int8},       {"uchar", PlyType::UInt8},
        {"uint8", PlyType::UInt8},   {"short", PlyType::Int16},     {"int16", PlyType::Int16},
        {"ushort", PlyType::UInt16}, {"uint16", PlyType::UInt16},   {"int", PlyType::Int32},
        {"int32", PlyType::Int32},   {"uint", PlyType::UInt32},     {"uint32", PlyType::UInt32},
        {"float", PlyType::Float32}, {"float32", PlyType::Float32}, {"double", PlyType::Float64},
        {"float64", PlyType::Float64}};
    for (const auto& [n, type] : names)
        if (s == n) {
            t = type;
            return true;
        }
    return false;
}

struct PlyProperty {
    std::string name;
    PlyType type = PlyType::UInt8;        // scalar type, or list item type
    bool list = false;
    PlyType count_type = PlyType::UInt8;  // list count type
};

struct PlyElement {
    std::string name;
    std::uint64_t count = 0;
    std::vector<PlyProperty> props;
    std::int64_t line = 0;
    /// Bytes of the fixed-size part of one instance in binary (scalars and list counts).
    std::uint64_t min_binary_bytes() const {
        std::uint64_t n = 0;
        for (const auto& p : props) n += ply_size(p.list ? p.count_type : p.type);
        return n;
    }
};

enum class PlyFormat { Ascii, BinaryLE, BinaryBE };

struct PlyHeader {
    PlyFormat format = PlyFormat::Ascii;
    std::vector<PlyElement> elements;
};

constexpr std::size_t kMaxPlyHeader = std::size_t(1) << 20;
constexpr std::size_t kMaxPlyNames = 10000;  // elements, and properties per element

PlyHeader read_ply_header(const ByteSource& src, LineReader& lines) {
    const std::string& name = src.name();
    PlyHeader h;
    bool have_format = false, ended = false;
    std::string_view line;
    while (!ended && lines.next(line)) {
        const std::int64_t line_no = lines.line_number();
        if (lines.offset() > kMaxPlyHeader)
            fail(name, "header is longer than " + with_commas(kMaxPlyHeader) + " bytes (no end_header)");
        if (line_no == 1) {
            if (detail::trim(line) != "ply") fail(name, "not a PLY file (it does not start with 'ply')");
            continue;
        }
        refuse_binary(name, line_no, line, "PLY header");
        const auto w = detail::split_words(line);
        if (w.empty()) continue;
        const std::string here = at_line(line_no);
        if (w[0] == "comment" || w[0] == "obj_info") continue;
        if (w[0] == "end_header") {
            ended = true;
        } else if (w[0] == "format") {
            if (have_format) fail(name, here + "a second 'format' line");
            if (w.size() != 3)
                fail(name, here + "expected 'format <ascii|binary_little_endian|binary_big_endian> 1.0'");
            if (w[1] == "ascii")
                h.format = PlyFormat::Ascii;
            else if (w[1] == "binary_little_endian")
                h.format = PlyFormat::BinaryLE;
            else if (w[1] == "binary_big_endian")
                h.format = PlyFormat::BinaryBE;
            else
                fail(name, here + "unknown format " + quoted(w[1]));
            have_format = true;
        } else if (w[0] == "element") {
            std::int64_t count = 0;
            if (w.size() != 3) fail(name, here + "expected 'element <name> <count>', got " + quoted(line));
            if (!detail::parse_int(w[2], count) || count < 0)
                fail(name, here + "element count " + quoted(w[2]) + " is not a non-negative integer");
            for (const auto& e : h.elements)
                if (e.name == w[1]) fail(name, here + "element '" + std::string(w[1]) + "' declared twice");
            if (h.elements.size() >= kMaxPlyNames) fail(name, here + "too many elements");
            PlyElement e;
            e.name = std::string(w[1]);
            e.count = static_cast<std::uint64_t>(count);
            e.line = line_no;
            h.elements.push_back(std::move(e));
        } else if (w[0] == "property") {
            if (h.elements.empty()) fail(name, here + "property before any element");
            PlyElement& e = h.elements.back();
            PlyProperty p;
            if (w.size() >= 2 && w[1] == "list") {
                if (w.size() != 5) fail(name, here + "expected 'property list <count type> <item type> <name>'");
                if (!ply_type(w[2], p.count_type)) fail(name, here + "unknown property type " + quoted(w[2]));
                if (!ply_type(w[3], p.type)) fail(name, here + "unknown property type " + quoted(w[3]));
                if (!ply_integer(p.count_type))
                    fail(name, here + "list count type " + quoted(w[2]) + " must be an integer type");
                p.list = true;
                p.name = std::string(w[4]);
            } else {
                if (w.size() != 3) fail(name, here + "expected 'property <type> <name>', got " + quoted(line));
                if (!ply_type(w[1], p.type)) fail(name, here + "unknown property type " + quoted(w[1]));
                p.name = std::string(w[2]);
            }
            for (const auto& q : e.props)
                if (q.name == p.name)
                    fail(name, here + "property '" + p.name + "' declared twice in element '" + e.name + "'");
            if (e.props.size() >= kMaxPlyNames) fail(name, here + "too many properties");
            e.props.push_back(std::move(p));
        } else {
            fail(name, here + "unknown header line " + quoted(line));
        }
    }
    if (lines.line_number() == 0) fail(name, "empty file: not a PLY file");
    if (!ended) fail(name, "the header has no end_header line (truncated?)");
    if (!have_format) fail(name, "the header has no 'format' line");
    return h;
}

/// Where the mesh's two elements and their key properties are.
struct PlyLayout {
    int vertex = -1, face = -1;            // element indices
    int xyz[3] = {-1, -1, -1};             // property indices in the vertex element
    int indices = -1;                      // the vertex_indices list in the face element
};

PlyLayout ply_layout(const std::string& name, const PlyHeader& h) {
    PlyLayout L;
    for (std::size_t i = 0; i < h.elements.size(); ++i) {
        if (h.elements[i].name == "vertex") L.vertex = static_cast<int>(i);
        if (h.elements[i].name == "face") L.face = static_cast<int>(i);
    }
    if (L.vertex < 0) fail(name, "no 'element vertex' in the header");
    const PlyElement& v = h.elements[static_cast<std::size_t>(L.vertex)];
    for (std::size_t i = 0; i < v.props.size(); ++i)
        for (int a = 0; a < 3; ++a)
            if (v.props[i].name == std::string(1, "xyz"[a])) {
                if (v.props[i].list)
                    fail(name, "line " + std::to_string(v.line) + ": vertex property '" + v.props[i].name +
                                   "' is a list, not a number");
                L.xyz[a] = static_cast<int>(i);
            }
    for (int a = 0; a < 3; ++a)
        if (L.xyz[a] < 0)
            fail(name, "line " + std::to_string(v.line) + ": element vertex has no property '" +
                           std::string(1, "xyz"[a]) + "'");
    if (L.face < 0) fail(name, "no 'element face' in the header (a point cloud has nothing to voxelize)");
    const PlyElement& f = h.elements[static_cast<std::size_t>(L.face)];
    for (std::size_t i = 0; i < f.props.size(); ++i)
        if (f.props[i].name == "vertex_indices" || f.props[i].name == "vertex_index") {
            if (!f.props[i].list)
                fail(name, "line " + std::to_string(f.line) + ": face property '" + f.props[i].name +
                               "' is not a list");
            if (!ply_integer(f.props[i].type))
                fail(name, "line " + std::to_string(f.line) + ": face property '" + f.props[i].name +
                               "' must hold an integer type");
            L.indices = static_cast<int>(i);
        }
    if (L.indices < 0)
        fail(name, "line " + std::to_string(f.line) + ": element face has no 'vertex_indices' list");
    return L;
}

/// Sequential binary input in chunks, with bounds checks that name the element being read.
class BinaryCursor {
public:
    BinaryCursor(const ByteSource& src, std::uint64_t offset, bool swap)
        : src_(src), size_(src.size()), pos_(offset), swap_(swap) {}

    std::uint64_t position() const { return pos_; }
    std::uint64_t remaining() const { return pos_ <= size_ ? size_ - pos_ : 0; }

    /// Reads n bytes; false (nothing read) when fewer remain.
    bool get(void* dst, std::size_t n) {
        if (n > remaining()) return false;
        auto* out = static_cast<std::uint8_t*>(dst);
        while (n > 0) {
            if (at_ == buf_.size()) refill();
            const std::size_t k = std::min(n, buf_.size() - at_);
            std::memcpy(out, buf_.data() + at_, k);
            at_ += k;
            pos_ += k;
            out += k;
            n -= k;
        }
        return true;
    }

    bool skip(std::uint64_t n) {
        if (n > remaining()) return false;
        const std::uint64_t in_buffer = buf_.size() - at_;
        if (n <= in_buffer) {
            at_ += static_cast<std::size_t>(n);
        } else {
            buf_.clear();
            at_ = 0;
        }
        pos_ += n;
        return true;
    }

    /// One scalar of type t, as a double (exact for every PLY integer type).
    bool number(PlyType t, double& out) {
        std::uint8_t b[8];
        const std::size_t n = ply_size(t);
        if (!get(b, n)) return false;
        if (swap_) detail::swap_bytes(b, 1, n);
        switch (t) {
            case PlyType::Int8: out = static_cast<std::int8_t>(b[0]); break;
            case PlyType::UInt8: out = b[0]; break;
            case PlyType::Int16: out = load<std::int16_t>(b); break;
            case PlyType::UInt16: out = load<std::uint16_t>(b); break;
            case PlyType::Int32: out = load<std::int32_t>(b); break;
            case PlyType::UInt32: out = load<std::uint32_t>(b); break;
            case PlyType::Float32: out = static_cast<double>(load<float>(b)); break;
            case PlyType::Float64: out = load<double>(b); break;
        }
        return true;
    }

private:
    template <class T>
    static T load(const std::uint8_t* b) {
        T v;
        std::memcpy(&v, b, sizeof v);
        return v;
    }
    void refill() {
        const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(kChunk, remaining()));
        buf_.resize(n);
        src_.read(pos_, buf_.data(), n);
        at_ = 0;
    }

    const ByteSource& src_;
    std::uint64_t size_;
    std::uint64_t pos_;
    bool swap_;
    std::vector<std::uint8_t> buf_;
    std::size_t at_ = 0;
};

/// Whitespace-separated ascii values after the header, with the line each came from.
class TokenReader {
public:
    explicit TokenReader(LineReader& lines) : lines_(lines) {}
    bool next(std::string_view& tok) {
        while (i_ == words_.size()) {
            std::string_view line;
            if (!lines_.next(line)) return false;
            words_ = detail::split_words(line);  // views into the line, valid until the next line is read
            i_ = 0;
        }
        tok = words_[i_++];
        return true;
    }
    std::int64_t line() const { return lines_.line_number(); }

private:
    LineReader& lines_;
    std::vector<std::string_view> words_;
    std::size_t i_ = 0;
};

bool ascii_number(std::string_view tok, PlyType t, double& out) {
    if (ply_integer(t)) {
        std::int64_t v = 0;
        if (!detail::parse_int(tok, v)) return false;
        std::int64_t lo = 0, hi = 0;
        switch (t) {
            case PlyType::Int8: lo = -128, hi = 127; break;
            case PlyType::UInt8: lo = 0, hi = 255; break;
            case PlyType::Int16: lo = -32768, hi = 32767; break;
            case PlyType::UInt16: lo = 0, hi = 65535; break;
            case PlyType::Int32:
                lo = std::numeric_limits<std::int32_t>::min(), hi = std::numeric_limits<std::int32_t>::max();
                break;
            default: lo = 0, hi = std::numeric_limits<std::uint32_t>::max(); break;
        }
        if (v < lo || v > hi) return false;
        out = static_cast<double>(v);
        return true;
    }
    return detail::parse_double(tok, out);
}

const char* ply_type_name(PlyType t) {
    switch (t) {
        case PlyType::Int8: return "char";
        case PlyType::UInt8: return "uchar";
        case PlyType::Int16: return "short";
        case PlyType::UInt16: return "ushort";
        case PlyType::Int32: return "int";
        case PlyType::UInt32: return "uint";
        case PlyType::Float32: return "float";
        case PlyType::Float64: return "double";
    }
    return "?";
}

/// Reads the element data of either encoding into a Mesh.
class PlyBody {
public:
    PlyBody(const ByteSource& src, const PlyHeader& h, const PlyLayout& L, LineReader& lines, const ReadOptions& opt)
        : name_(src.name()), h_(h), L_(L), opt_(opt), tokens_(lines),
          cursor_(src, lines.offset(), h.format == PlyFormat::BinaryBE ? !detail::host_is_big_endian()
                                                                       : detail::host_is_big_endian()) {}

    Mesh read() {
        check_counts();
        const PlyElement& ve = h_.elements[static_cast<std::size_t>(L_.vertex)];
        const PlyElement& fe = h_.elements[static_cast<std::size_t>(L_.face)];
        check_mesh_size(name_, [] { return std::string("header: "); }, ve.count, fe.count, opt_.max_bytes);
        m_.vertices.reserve(static_cast<std::size_t>(ve.count));
        m_.triangles.reserve(static_cast<std::size_t>(fe.count));
        for (std::size_t e = 0; e < h_.elements.size(); ++e) {
            element_ = &h_.elements[e];
            index_ = 0;
            if (element_->props.empty()) continue;  // nothing to read, however many
            if (static_cast<int>(e) == L_.vertex) {
                for (; index_ < element_->count; ++index_) read_vertex();
            } else if (static_cast<int>(e) == L_.face) {
                for (; index_ < element_->count; ++index_) read_face();
            } else if (!ascii() && fixed_size(*element_)) {  // skipped in one step
                if (!cursor_.skip(element_->count * element_->min_binary_bytes()))
                    fail(name_, where() + "the file ends inside this element (truncated)");
            } else {
                for (; index_ < element_->count; ++index_)
                    for (const auto& p : element_->props) skip_property(p);
            }
        }
        if (m_.vertices.empty()) fail(name_, "no vertices (element vertex has count 0)");
        if (m_.triangles.empty()) fail(name_, "no faces (element face has count 0): nothing to voxelize");
        if (!max_index_where_.empty() && max_index_ >= m_.vertices.size())
            fail(name_, max_index_where_ + "vertex index " + std::to_string(max_index_) + " out of range (" +
                            with_commas(m_.vertices.size()) + " vertices)");
        return std::move(m_);
    }

private:
    enum class Role { Scalar, Count, Item, Index };

    bool ascii() const { return h_.format == PlyFormat::Ascii; }
    static bool fixed_size(const PlyElement& e) {
        return std::none_of(e.props.begin(), e.props.end(), [](const PlyProperty& p) { return p.list; });
    }
    /// Bytes not yet read (binary), or all the bytes after the header (ascii: an upper bound for what is left).
    std::uint64_t remaining() const { return cursor_.remaining(); }

    /// "line 14: vertex 3 of 8: " or "face 2 of 6 (byte 1,234): " (0-based instance numbers).
    std::string where() const {
        std::string s = element_->name + " " + with_commas(index_) + " of " + with_commas(element_->count);
        if (ascii()) return at_line(std::max<std::int64_t>(tokens_.line(), 1)) + s + ": ";
        return s + " (byte " + with_commas(cursor_.position()) + "): ";
    }

    static std::string describe(const PlyProperty& p, Role r) {
        switch (r) {
            case Role::Scalar: return "property '" + p.name + "'";
            case Role::Count: return "the count of list '" + p.name + "'";
            case Role::Item: return "an item of list '" + p.name + "'";
            case Role::Index: return "a vertex index";
        }
        return p.name;
    }

    /// Refuses element counts the file cannot hold: each instance needs at least its fixed-size part in binary
    /// (plus three indices for a face), and two characters per value in ascii.
    void check_counts() const {
        const std::uint64_t have = cursor_.remaining();
        long double need = 0;
        for (std::size_t i = 0; i < h_.elements.size(); ++i) {
            const PlyElement& e = h_.elements[i];
            long double per = ascii() ? 2.0L * static_cast<long double>(e.props.size())
                                      : static_cast<long double>(e.min_binary_bytes());
            if (static_cast<int>(i) == L_.face) {
                const PlyType t = e.props[static_cast<std::size_t>(L_.indices)].type;
                per += 3.0L * (ascii() ? 2.0L : static_cast<long double>(ply_size(t)));
            }
            need += per * static_cast<long double>(e.count);
            if (need > static_cast<long double>(have) + (ascii() ? 1 : 0))
                fail(name_, "line " + std::to_string(e.line) + ": header declares " + with_commas(e.count) + " " +
                                e.name + " elements (at least " + with_commas(static_cast<std::uint64_t>(per)) +
                                " bytes each" + (ascii() ? " as text" : "") + ") but only " + with_commas(have) +
                                " bytes follow the header");
        }
    }

    double value(PlyType t, const PlyProperty& p, Role r) {
        double v = 0;
        if (ascii()) {
            std::string_view tok;
            if (!tokens_.next(tok)) fail(name_, where() + "the file ends before " + describe(p, r) + " (truncated)");
            if (!ascii_number(tok, t, v))
                fail(name_, where() + describe(p, r) + " " + quoted(tok) + " is not a valid " + ply_type_name(t));
        } else if (!cursor_.number(t, v)) {
            fail(name_, where() + "the file ends before " + describe(p, r) + " (truncated)");
        }
        return v;
    }

    std::uint64_t list_count(const PlyProperty& p) {
        const double c = value(p.count_type, p, Role::Count);
        if (c < 0)
            fail(name_, where() + "list '" + p.name + "' has a negative count (" + detail::format_double(c) + ")");
        const auto n = static_cast<std::uint64_t>(c);
        // Each item needs bytes of its own: refuse counts the rest of the file cannot hold before reading them.
        const std::uint64_t per = ascii() ? 2 : ply_size(p.type);
        const std::uint64_t have = remaining();
        if (n > have / per + 1)
            fail(name_, where() + "list '" + p.name + "' claims " + with_commas(n) + " items but only " +
                            with_commas(have) + " bytes remain");
        return n;
    }

    void skip_property(const PlyProperty& p) {
        if (!p.list) {
            value(p.type, p, Role::Scalar);
            return;
        }
        const std::uint64_t n = list_count(p);
        if (ascii()) {
            for (std::uint64_t k = 0; k < n; ++k) value(p.type, p, Role::Item);
        } else if (!cursor_.skip(n * ply_size(p.type))) {
            fail(name_, where() + "the file ends inside list '" + p.name + "' (truncated)");
        }
    }

    void read_vertex() {
        std::array<double, 3> xyz{};
        const auto& props = element_->props;
        for (std::size_t i = 0; i < props.size(); ++i) {
            const PlyProperty& p = props[i];
            int axis = -1;
            for (int a = 0; a < 3; ++a)
                if (L_.xyz[a] == static_cast<int>(i)) axis = a;
            if (axis < 0) {
                skip_property(p);
                continue;
            }
            const double v = value(p.type, p, Role::Scalar);
            if (!std::isfinite(v)) fail(name_, where() + p.name + " is not finite (" + detail::format_double(v) + ")");
            xyz[static_cast<std::size_t>(axis)] = v;
        }
        m_.vertices.push_back(xyz);
    }

    void read_face() {
        const auto& props = element_->props;
        const bool vertices_known = L_.vertex < L_.face;
        const std::uint64_t vertex_count = h_.elements[static_cast<std::size_t>(L_.vertex)].count;
        for (std::size_t i = 0; i < props.size(); ++i) {
            const PlyProperty& p = props[i];
            if (static_cast<int>(i) != L_.indices) {
                skip_property(p);
                continue;
            }
            const std::uint64_t n = list_count(p);
            if (n < 3)
                fail(name_, where() + "face has " + std::to_string(n) + (n == 1 ? " vertex" : " vertices") +
                                " (a face needs at least 3)");
            check_mesh_size(name_, [&] { return where(); }, vertices_known ? m_.vertices.size() : 0,
                            m_.triangles.size() + (n - 2), opt_.max_bytes);
            poly_.clear();
            for (std::uint64_t k = 0; k < n; ++k) {
                const double v = value(p.type, p, Role::Index);
                if (v < 0 || v >= static_cast<double>(kMaxVertices) ||
                    (vertices_known && v >= static_cast<double>(m_.vertices.size())))
                    fail(name_, where() + "vertex index " + detail::format_double(v) + " out of range (" +
                                    with_commas(vertices_known ? m_.vertices.size() : vertex_count) + " vertices)");
                const auto idx = static_cast<std::uint32_t>(v);
                if (!vertices_known && (max_index_where_.empty() || idx > max_index_)) {
                    max_index_ = idx;
                    max_index_where_ = where();
                }
                poly_.push_back(idx);
            }
            fan(poly_, m_.triangles);
        }
    }

    const std::string& name_;
    const PlyHeader& h_;
    const PlyLayout& L_;
    const ReadOptions& opt_;
    TokenReader tokens_;
    BinaryCursor cursor_;
    Mesh m_;
    const PlyElement* element_ = nullptr;
    std::uint64_t index_ = 0;
    std::vector<std::uint32_t> poly_;
    std::uint32_t max_index_ = 0;  // largest index of faces read before the vertices
    std::string max_index_where_;
};

}  // namespace

Mesh read_ply(const ByteSource& src, const ReadOptions& opt) {
    LineReader lines(src);
    const PlyHeader h = read_ply_header(src, lines);
    const PlyLayout L = ply_layout(src.name(), h);
    return PlyBody(src, h, L, lines, opt).read();
}

// =================================================================================================================
// Dispatch and validation
// =================================================================================================================

Mesh read_mesh(const std::string& path, const ReadOptions& opt) {
    const std::string low = detail::lower(path);
    auto ends = [&](const char* e) {
        const std::size_t n = std::strlen(e);
        return low.size() >= n && low.compare(low.size() - n, n, e) == 0;
    };
    if (!ends(".obj") && !ends(".ply"))
        throw FileFormatError(path + ": unknown mesh format (known endings: .obj .ply)");
    auto src = open_file(path);
    return ends(".obj") ? read_obj(*src, opt) : read_ply(*src, opt);
}

void check_mesh(const Mesh& mesh, const std::string& what) {
    if (mesh.vertices.empty()) throw Error(what + ": no vertices");
    if (mesh.triangles.empty()) throw Error(what + ": no triangles");
    if (mesh.vertices.size() > kMaxVertices)
        throw Error(what + ": more than " + with_commas(kMaxVertices) + " vertices (indices are 32-bit)");
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
        for (double c : mesh.vertices[i])
            if (!std::isfinite(c)) throw Error(what + ": vertex " + std::to_string(i) + " has a non-finite coordinate");
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i)
        for (std::uint32_t k : mesh.triangles[i])
            if (k >= mesh.vertices.size())
                throw Error(what + ": triangle " + std::to_string(i) + " uses vertex " + std::to_string(k) +
                            " out of range (" + with_commas(mesh.vertices.size()) + " vertices)");
}

Mesh make_mesh(const double* xyz, std::size_t vertex_count, const std::int64_t* triangles, std::size_t triangle_count,
               const std::string& what) {
    if (vertex_count == 0) throw Error(what + ": no vertices");
    if (triangle_count == 0) throw Error(what + ": no triangles");
    if (vertex_count > kMaxVertices)
        throw Error(what + ": more than " + with_commas(kMaxVertices) + " vertices (indices are 32-bit)");
    Mesh m;
    m.vertices.resize(vertex_count);
    for (std::size_t i = 0; i < vertex_count; ++i)
        for (std::size_t a = 0; a < 3; ++a) {
            const double c = xyz[3 * i + a];
            if (!std::isfinite(c))
                throw Error(what + ": vertex " + std::to_string(i) + " has a non-finite coordinate (" +
                            std::string(1, "xyz"[a]) + " = " + detail::format_double(c) + ")");
            m.vertices[i][a] = c;
        }
    m.triangles.resize(triangle_count);
    for (std::size_t i = 0; i < triangle_count; ++i)
        for (std::size_t a = 0; a < 3; ++a) {
            const std::int64_t k = triangles[3 * i + a];
            if (k < 0 || static_cast<std::uint64_t>(k) >= vertex_count)
                throw Error(what + ": triangle " + std::to_string(i) + " uses vertex " + std::to_string(k) +
                            " out of range (" + with_commas(vertex_count) + " vertices)");
            m.triangles[i][a] = static_cast<std::uint32_t>(k);
        }
    return m;
}

}  // namespace volrig

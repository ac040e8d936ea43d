// mesh/ply.cpp: the Stanford PLY reader of volrig/mesh.hpp (ascii, binary little- and big-endian).
//
// The header's element counts are checked against the bytes that follow it before anything is allocated; text
// data reports line numbers, binary data the element and its byte offset.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "mesh/mesh_detail.hpp"

namespace volrig {

using namespace mesh_detail;  // the reader helpers of io/io_detail.hpp and mesh_detail.hpp

namespace {

constexpr std::size_t kChunk = kTextChunk;

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
            if (mesh_detail::trim(line) != "ply") fail(name, "not a PLY file (it does not start with 'ply')");
            continue;
        }
        refuse_binary(name, line_no, line, "PLY header");
        const auto w = mesh_detail::split_words(line);
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
            if (!mesh_detail::parse_int(w[2], count) || count < 0)
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
        if (swap_) mesh_detail::swap_bytes(b, 1, n);
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

bool ascii_number(std::string_view tok, PlyType t, double& out) {
    if (ply_integer(t)) {
        std::int64_t v = 0;
        if (!mesh_detail::parse_int(tok, v)) return false;
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
    return mesh_detail::parse_double(tok, out);
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
          cursor_(src, lines.offset(), h.format == PlyFormat::BinaryBE ? !mesh_detail::host_is_big_endian()
                                                                       : mesh_detail::host_is_big_endian()) {}

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
            fail(name_, where() + "list '" + p.name + "' has a negative count (" + mesh_detail::format_double(c) + ")");
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
            if (!std::isfinite(v)) fail(name_, where() + p.name + " is not finite (" + mesh_detail::format_double(v) + ")");
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
            if (n < 3) fail(name_, where() + mesh_detail::too_few_corners(n));
            check_mesh_size(name_, [&] { return where(); }, vertices_known ? m_.vertices.size() : 0,
                            m_.triangles.size() + (n - 2), opt_.max_bytes);
            poly_.clear();
            for (std::uint64_t k = 0; k < n; ++k) {
                const double v = value(p.type, p, Role::Index);
                if (v < 0 || v >= static_cast<double>(kMaxVertices) ||
                    (vertices_known && v >= static_cast<double>(m_.vertices.size())))
                    fail(name_, where() + "vertex index " + mesh_detail::format_double(v) + " out of range (" +
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

}  // namespace volrig

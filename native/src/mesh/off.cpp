// mesh/off.cpp: the Geomview OFF reader of volrig/mesh.hpp. Read line by line through a ByteSource (1 MiB
// chunks); errors name the line. The counts line is checked against the bytes that follow it before anything is
// allocated (a vertex line takes at least 6 bytes, a face line 8).
#include <array>
#include <cstdint>
#include <string>

#include "mesh/mesh_detail.hpp"

namespace volrig {

using mesh_detail::at_line;
using mesh_detail::fail;
using mesh_detail::quoted;
using mesh_detail::with_commas;

namespace {

constexpr std::uint64_t kMinVertexLine = 6;  // "0 0 0\n"
constexpr std::uint64_t kMinFaceLine = 8;    // "3 0 1 2\n"

/// True when `w` is an OFF header keyword, [ST][C][N][4][n]OFF; fails for the variants this reader refuses.
bool off_keyword(const std::string& name, const std::string& where, std::string_view w) {
    if (w.size() < 3 || !mesh_detail::iequals(w.substr(w.size() - 3), "OFF")) return false;
    std::string_view prefix = w.substr(0, w.size() - 3);
    for (const char* part : {"ST", "C", "N", "4", "n"}) {
        const std::string_view p(part);
        if (prefix.substr(0, p.size()) != p) continue;
        if (p == "4" || p == "n")
            fail(name, where + quoted(w) + ": 4-D and n-dimensional OFF files are not supported");
        prefix.remove_prefix(p.size());
    }
    if (!prefix.empty()) fail(name, where + "unknown OFF header keyword " + quoted(w));
    return true;
}

class OffReader {
public:
    OffReader(const ByteSource& src, const ReadOptions& opt) : name_(src.name()), opt_(opt), lines_(src) {}

    Mesh read() {
        std::vector<std::string_view> w;
        if (!content_line(w)) fail(name_, "empty file: not an OFF file");
        std::size_t first = 0;  // the counts' first word in w
        if (off_keyword(name_, here(), w[0])) {
            first = 1;
            if (w.size() > 1 && mesh_detail::iequals(w[1], "BINARY"))
                fail(name_, here() + "binary OFF is not supported (save it as text OFF)");
            if (w.size() == 1) {
                if (!content_line(w)) fail(name_, "the file ends before the counts line (vertices faces edges)");
                first = 0;
            }
        } else if (std::int64_t ignored = 0; !mesh_detail::parse_int(w[0], ignored)) {
            fail(name_, at_line(lines_.line_number()) + "not an OFF file (it starts with " + quoted(w[0]) +
                            ", not OFF or the counts)");
        }
        counts(w, first);
        for (std::uint64_t i = 0; i < vertex_count_; ++i) read_vertex(i);
        for (std::uint64_t i = 0; i < face_count_; ++i) read_face(i);
        return std::move(m_);
    }

private:
    /// The words of the next line that has any (comments after '#' dropped); false at the end of the file.
    bool content_line(std::vector<std::string_view>& w) {
        std::string_view line;
        while (lines_.next(line)) {
            mesh_detail::refuse_binary(name_, lines_.line_number(), line, "OFF");
            w = mesh_detail::split_words(line.substr(0, line.find('#')));
            if (!w.empty()) return true;
        }
        return false;
    }

    /// The next content line of `what` number i of n; fails naming how far the file got.
    std::vector<std::string_view> record(const char* what, std::uint64_t i, std::uint64_t n) {
        std::vector<std::string_view> w;
        if (!content_line(w))
            fail(name_, "the file ends after " + with_commas(i) + " of " + with_commas(n) + " " + what +
                            " (truncated)");
        return w;
    }

    std::string here() const { return at_line(lines_.line_number()); }

    void counts(const std::vector<std::string_view>& w, std::size_t first) {
        const std::size_t n = w.size() - first;
        std::int64_t c[3] = {0, 0, 0};
        bool ok = n == 2 || n == 3;
        for (std::size_t k = 0; ok && k < n; ++k) ok = mesh_detail::parse_int(w[first + k], c[k]) && c[k] >= 0;
        if (!ok) fail(name_, here() + "expected the counts 'vertices faces [edges]' (non-negative integers)");
        vertex_count_ = static_cast<std::uint64_t>(c[0]);
        face_count_ = static_cast<std::uint64_t>(c[1]);
        if (vertex_count_ == 0) fail(name_, here() + "no vertices (the counts line says 0)");
        if (face_count_ == 0) fail(name_, here() + "no faces (the counts line says 0): nothing to voxelize");
        const std::uint64_t have = lines_.remaining() + 1;  // the last line may lack its newline
        mesh_detail::check_count_fits(name_, here(), vertex_count_, "vertices", kMinVertexLine, have);
        mesh_detail::check_count_fits(name_, here(), face_count_, "faces", kMinFaceLine,
                                 have - vertex_count_ * kMinVertexLine);
        mesh_detail::check_mesh_size(name_, [&] { return here(); }, vertex_count_, face_count_, opt_.max_bytes);
        m_.vertices.reserve(static_cast<std::size_t>(vertex_count_));
        m_.triangles.reserve(static_cast<std::size_t>(face_count_));
    }

    void read_vertex(std::uint64_t i) {
        const auto w = record("vertices", i, vertex_count_);
        if (w.size() < 3) fail(name_, here() + "vertex needs x y z, got " + std::to_string(w.size()) + " numbers");
        std::array<double, 3> p{};
        std::string why;
        if (!mesh_detail::parse_xyz(w, 0, p, why)) fail(name_, here() + "vertex " + why);
        m_.vertices.push_back(p);
    }

    void read_face(std::uint64_t i) {
        const auto w = record("faces", i, face_count_);
        std::int64_t n = 0;
        if (!mesh_detail::parse_int(w[0], n) || n < 0)
            fail(name_, here() + "face vertex count " + quoted(w[0]) + " is not a non-negative integer");
        if (n < 3) fail(name_, here() + mesh_detail::too_few_corners(static_cast<std::uint64_t>(n)));
        if (static_cast<std::uint64_t>(n) > w.size() - 1)
            fail(name_, here() + "face of " + std::to_string(n) + " vertices lists only " +
                            std::to_string(w.size() - 1) + " indices");
        mesh_detail::check_mesh_size(name_, [&] { return here(); }, m_.vertices.size(),
                                m_.triangles.size() + static_cast<std::uint64_t>(n) - 2, opt_.max_bytes);
        poly_.clear();
        for (std::size_t k = 1; k <= static_cast<std::size_t>(n); ++k) {
            std::int64_t v = 0;
            if (!mesh_detail::parse_int(w[k], v))
                fail(name_, here() + "face index " + quoted(w[k]) + " is not an integer");
            if (v < 0 || static_cast<std::uint64_t>(v) >= vertex_count_)
                fail(name_, here() + "face index " + std::to_string(v) + " out of range (" +
                                with_commas(vertex_count_) + " vertices, numbered from 0)");
            poly_.push_back(static_cast<std::uint32_t>(v));
        }
        mesh_detail::fan(poly_, m_.triangles);
    }

    const std::string& name_;
    const ReadOptions& opt_;
    mesh_detail::LineReader lines_;
    std::uint64_t vertex_count_ = 0, face_count_ = 0;
    std::vector<std::uint32_t> poly_;
    Mesh m_;
};

}  // namespace

Mesh read_off(const ByteSource& src, const ReadOptions& opt) { return OffReader(src, opt).read(); }

}  // namespace volrig

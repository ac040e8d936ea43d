// mesh/mesh_detail.hpp: what the mesh readers of volrig/mesh.hpp share (obj.cpp, ply.cpp, tgf.cpp, off.cpp,
// stl.cpp, medit.cpp): the size limits, coordinate parsing, fan triangulation and a whitespace tokenizer over
// LineReader. Not installed; not part of the public API.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "io/io_detail.hpp"
#include "volrig/mesh.hpp"

namespace volrig::mesh_detail {

// The mesh readers build on the I/O layer's byte and text helpers (io/io_detail.hpp).
using namespace io_detail;

constexpr std::uint64_t kMaxVertices = std::numeric_limits<std::uint32_t>::max();
constexpr std::uint64_t kVertexBytes = sizeof(std::array<double, 3>);
constexpr std::uint64_t kTriangleBytes = sizeof(std::array<std::uint32_t, 3>);

/// Fails naming `name` and `where`: the vertices exceed 2^32 - 1 or the mesh's bytes exceed `max_bytes`.
[[noreturn]] void fail_mesh_size(const std::string& name, const std::string& where, std::uint64_t vertices,
                                 std::uint64_t triangles, std::uint64_t max_bytes);

/// Fails when a mesh of this many vertices and triangles would exceed 2^32 - 1 vertices or `max_bytes` (24 bytes
/// per vertex, 12 per triangle); `where()` gives the message's location prefix, built only on failure.
template <class Where>
void check_mesh_size(const std::string& name, const Where& where, std::uint64_t vertices, std::uint64_t triangles,
                     std::uint64_t max_bytes) {
    const long double bytes = static_cast<long double>(vertices) * kVertexBytes +
                              static_cast<long double>(triangles) * kTriangleBytes;
    if (vertices <= kMaxVertices && bytes <= static_cast<long double>(max_bytes)) return;
    fail_mesh_size(name, where(), vertices, triangles, max_bytes);
}

/// Fails unless `count` records of at least `min_bytes` bytes each fit in the `have` bytes left in the file:
/// "<where><count> <what> declared (at least <min_bytes> bytes each) but only <have> bytes follow".
void check_count_fits(const std::string& name, const std::string& where, std::uint64_t count, const char* what,
                      std::uint64_t min_bytes, std::uint64_t have);

/// Parses one finite coordinate (axis 0, 1, 2 for x, y, z); false with `why` ("y '1e999' is not a number").
bool parse_coordinate(std::string_view tok, std::size_t axis, double& v, std::string& why);
/// Parses three finite coordinates from w[first..first+2]; false with `why` ("y '1e999' is not a number").
bool parse_xyz(const std::vector<std::string_view>& w, std::size_t first, std::array<double, 3>& p, std::string& why);

/// Appends the fan triangulation of polygon `poly` (v0 v1 v2, v0 v2 v3, ...).
void fan(const std::vector<std::uint32_t>& poly, std::vector<std::array<std::uint32_t, 3>>& out);

/// "face has 2 vertices (a face needs at least 3)".
std::string too_few_corners(std::uint64_t n);

/// Whitespace-separated tokens of a text file, read line by line, with the line each came from. Optionally cuts
/// each line at a comment character and refuses lines holding a NUL byte (naming `format`).
class TokenReader {
public:
    explicit TokenReader(LineReader& lines, std::string name = {}, const char* format = nullptr, char comment = 0)
        : lines_(lines), name_(std::move(name)), format_(format), comment_(comment) {}

    /// The next token; false at the end of the file. The view is valid until the next line is read.
    bool next(std::string_view& tok) {
        while (i_ == words_.size()) {
            std::string_view line;
            if (!lines_.next(line)) return false;
            if (format_) refuse_binary(name_, lines_.line_number(), line, format_);
            line_bytes_ = line.size();
            if (comment_) line = line.substr(0, line.find(comment_));
            words_ = split_words(line);  // views into the line, valid until the next line is read
            i_ = 0;
        }
        tok = words_[i_++];
        return true;
    }
    /// The next token; fails "line N: the file ends before <what> (truncated)" at the end of the file.
    std::string_view need(const std::string& what);
    /// Fails unless the next token is `keyword` (case-insensitive): "line N: expected 'loop', got 'lop'".
    void expect(const char* keyword);
    /// "line N: " for the token last returned.
    std::string here() const { return at_line(std::max<std::int64_t>(line(), 1)); }
    /// Drops the rest of the current line's tokens.
    void skip_line() { i_ = words_.size(); }
    /// Line of the token last returned (1-based; 0 before the first).
    std::int64_t line() const { return lines_.line_number(); }
    /// An upper bound on the bytes that hold the tokens not yet returned.
    std::uint64_t remaining() const { return lines_.remaining() + line_bytes_; }

private:
    LineReader& lines_;
    std::string name_;
    const char* format_;
    char comment_;
    std::vector<std::string_view> words_;
    std::size_t i_ = 0;
    std::uint64_t line_bytes_ = 0;
};

}  // namespace volrig::mesh_detail

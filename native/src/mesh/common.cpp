// mesh/common.cpp: the helpers of mesh_detail.hpp, read_mesh's dispatch by file ending, and mesh validation
// (make_mesh, check_mesh).
#include <cmath>
#include <cstring>
#include <utility>

#include "mesh/mesh_detail.hpp"

namespace volrig {

namespace mesh_detail {

void fail_mesh_size(const std::string& name, const std::string& where, std::uint64_t vertices,
                    std::uint64_t triangles, std::uint64_t max_bytes) {
    if (vertices > kMaxVertices)
        fail(name, where + "more than " + with_commas(kMaxVertices) + " vertices (indices are 32-bit)");
    const long double bytes = static_cast<long double>(vertices) * kVertexBytes +
                              static_cast<long double>(triangles) * kTriangleBytes;
    fail(name, where + with_commas(vertices) + " vertices and " + with_commas(triangles) + " triangles take " +
                   with_commas(static_cast<std::uint64_t>(std::min<long double>(bytes, 1.8e19L))) +
                   " bytes, above the limit of " + with_commas(max_bytes) +
                   " bytes (raise max_bytes if this is intended)");
}

void check_count_fits(const std::string& name, const std::string& where, std::uint64_t count, const char* what,
                      std::uint64_t min_bytes, std::uint64_t have) {
    if (count <= have / min_bytes) return;
    fail(name, where + with_commas(count) + " " + what + " declared (at least " + with_commas(min_bytes) +
                   " bytes each) but only " + with_commas(have) + " bytes follow");
}

bool parse_coordinate(std::string_view tok, std::size_t axis, double& v, std::string& why) {
    const char* problem = nullptr;
    if (!parse_double(tok, v))
        problem = " is not a number";
    else if (!std::isfinite(v))
        problem = " is not finite";
    if (problem) why = std::string(1, "xyz"[axis]) + " " + quoted(tok) + problem;
    return problem == nullptr;
}

bool parse_xyz(const std::vector<std::string_view>& w, std::size_t first, std::array<double, 3>& p, std::string& why) {
    for (std::size_t a = 0; a < 3; ++a)
        if (!parse_coordinate(w[first + a], a, p[a], why)) return false;
    return true;
}

void fan(const std::vector<std::uint32_t>& poly, std::vector<std::array<std::uint32_t, 3>>& out) {
    for (std::size_t i = 1; i + 1 < poly.size(); ++i) out.push_back({poly[0], poly[i], poly[i + 1]});
}

std::string too_few_corners(std::uint64_t n) {
    return "face has " + std::to_string(n) + (n == 1 ? " vertex" : " vertices") + " (a face needs at least 3)";
}

std::string_view TokenReader::need(const std::string& what) {
    std::string_view tok;
    if (!next(tok)) fail(name_, here() + "the file ends before " + what + " (truncated)");
    return tok;
}

void TokenReader::expect(const char* keyword) {
    const std::string_view tok = need(std::string("'") + keyword + "'");
    if (!iequals(tok, keyword)) fail(name_, here() + "expected '" + keyword + "', got " + quoted(tok));
}

}  // namespace mesh_detail

using mesh_detail::kMaxVertices;
using mesh_detail::with_commas;

// =================================================================================================================
// Dispatch
// =================================================================================================================

namespace {

using Reader = Mesh (*)(const ByteSource&, const ReadOptions&);

const std::pair<const char*, Reader> kReaders[] = {
    {".obj", read_obj}, {".ply", read_ply}, {".off", read_off}, {".stl", read_stl}, {".mesh", read_medit}};

bool ends_with(const std::string& s, const char* e) {
    const std::size_t n = std::strlen(e);
    return s.size() >= n && s.compare(s.size() - n, n, e) == 0;
}

}  // namespace

std::vector<std::string> mesh_extensions() {
    std::vector<std::string> out;
    for (const auto& r : kReaders) out.emplace_back(r.first);
    return out;
}

Mesh read_mesh(const std::string& path, const ReadOptions& opt) {
    const std::string low = mesh_detail::lower(path);
    if (ends_with(low, ".meshb"))
        throw FileFormatError(path + ": binary Medit meshes (.meshb) are not supported; save it as ASCII .mesh");
    for (const auto& [ending, reader] : kReaders)
        if (ends_with(low, ending)) return reader(*open_file(path), opt);
    std::string known;
    for (const auto& r : kReaders) known += std::string(known.empty() ? "" : " ") + r.first;
    throw FileFormatError(path + ": unknown mesh format (known endings: " + known + ")");
}

// =================================================================================================================
// Validation
// =================================================================================================================

namespace {

void check_counts(std::size_t vertex_count, std::size_t triangle_count, const std::string& what) {
    if (vertex_count == 0) throw Error(what + ": no vertices");
    if (triangle_count == 0) throw Error(what + ": no triangles");
    if (vertex_count > kMaxVertices)
        throw Error(what + ": more than " + with_commas(kMaxVertices) + " vertices (indices are 32-bit)");
}

[[noreturn]] void bad_index(std::size_t triangle, std::int64_t k, std::size_t vertex_count, const std::string& what) {
    throw Error(what + ": triangle " + std::to_string(triangle) + " uses vertex " + std::to_string(k) +
                " out of range (" + with_commas(vertex_count) + " vertices)");
}

}  // namespace

void check_mesh(const Mesh& mesh, const std::string& what) {
    check_counts(mesh.vertices.size(), mesh.triangles.size(), what);
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
        for (double c : mesh.vertices[i])
            if (!std::isfinite(c)) throw Error(what + ": vertex " + std::to_string(i) + " has a non-finite coordinate");
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i)
        for (std::uint32_t k : mesh.triangles[i])
            if (k >= mesh.vertices.size()) bad_index(i, k, mesh.vertices.size(), what);
}

Mesh make_mesh(const double* xyz, std::size_t vertex_count, const std::int64_t* triangles, std::size_t triangle_count,
               const std::string& what) {
    check_counts(vertex_count, triangle_count, what);
    Mesh m;
    m.vertices.resize(vertex_count);
    for (std::size_t i = 0; i < vertex_count; ++i)
        for (std::size_t a = 0; a < 3; ++a) {
            const double c = xyz[3 * i + a];
            if (!std::isfinite(c))
                throw Error(what + ": vertex " + std::to_string(i) + " has a non-finite coordinate (" +
                            std::string(1, "xyz"[a]) + " = " + mesh_detail::format_double(c) + ")");
            m.vertices[i][a] = c;
        }
    m.triangles.resize(triangle_count);
    for (std::size_t i = 0; i < triangle_count; ++i)
        for (std::size_t a = 0; a < 3; ++a) {
            const std::int64_t k = triangles[3 * i + a];
            if (k < 0 || static_cast<std::uint64_t>(k) >= vertex_count) bad_index(i, k, vertex_count, what);
            m.triangles[i][a] = static_cast<std::uint32_t>(k);
        }
    return m;
}

}  // namespace volrig

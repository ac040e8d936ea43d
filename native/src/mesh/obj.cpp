// mesh/obj.cpp: the Wavefront OBJ reader of volrig/mesh.hpp. Read line by line through a ByteSource (1 MiB
// chunks); errors name the line. Sizes: the reader stops once the decoded mesh would exceed ReadOptions::max_bytes.
#include <array>
#include <cstdint>
#include <string>

#include "mesh/mesh_detail.hpp"

namespace volrig {

using namespace mesh_detail;  // the reader helpers of io/io_detail.hpp and mesh_detail.hpp

namespace {

/// The vertex part of an OBJ face entry ("7", "7/2", "7//3", "7/2/3"); false when malformed.
bool obj_vertex_index(std::string_view tok, std::int64_t& index) {
    const std::size_t s1 = tok.find('/');
    if (!mesh_detail::parse_int(tok.substr(0, s1), index)) return false;
    if (s1 == std::string_view::npos) return true;
    std::string_view rest = tok.substr(s1 + 1);
    const std::size_t s2 = rest.find('/');
    std::int64_t ignored = 0;
    const std::string_view t = rest.substr(0, s2);
    if (!t.empty() && !mesh_detail::parse_int(t, ignored)) return false;
    if (s2 == std::string_view::npos) return true;
    const std::string_view n = rest.substr(s2 + 1);
    return !n.empty() && mesh_detail::parse_int(n, ignored);
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
        if (!mesh_detail::trim(line).empty() && mesh_detail::trim(line).back() == '\\') {
            joined.clear();
            std::string_view part = line;
            for (;;) {
                std::string_view t = mesh_detail::trim(part);
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
        const auto w = mesh_detail::split_words(line);
        if (w.empty()) continue;
        if (w[0] == "v") {
            if (w.size() < 4) fail(name, at_line(line_no) + "vertex needs x y z, got " + quoted(mesh_detail::trim(line)));
            std::array<double, 3> p{};
            std::string why;
            if (!parse_xyz(w, 1, p, why)) fail(name, at_line(line_no) + "vertex " + why);
            check_mesh_size(name, [&] { return at_line(line_no); }, m.vertices.size() + 1, m.triangles.size(),
                            opt.max_bytes);
            m.vertices.push_back(p);
        } else if (w[0] == "f") {
            if (w.size() < 4) fail(name, at_line(line_no) + mesh_detail::too_few_corners(w.size() - 1));
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


}  // namespace volrig

// mesh/tgf.cpp: the libigl TGF skeleton reader of volrig/mesh.hpp.
#include <array>
#include <cstdint>
#include <string>

#include "mesh/mesh_detail.hpp"

namespace volrig {

using namespace mesh_detail;  // the reader helpers of io/io_detail.hpp and mesh_detail.hpp

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
        const auto w = mesh_detail::split_words(line);
        if (w.empty()) continue;
        if (w[0][0] == '#') {
            ++section;
            continue;
        }
        if (section == 0) {
            std::int64_t index = 0;
            if (w.size() < 4)
                fail(name, at_line(line_no) + "joint needs 'index x y z', got " + quoted(mesh_detail::trim(line)));
            if (!mesh_detail::parse_int(w[0], index))
                fail(name, at_line(line_no) + "joint index " + quoted(w[0]) + " is not an integer");
            std::array<double, 3> p{};
            std::string why;
            if (!parse_xyz(w, 1, p, why)) fail(name, at_line(line_no) + "joint " + why);
            check_mesh_size(name, [&] { return at_line(line_no); }, s.joints.size() + 1, edges.size(), opt.max_bytes);
            s.joints.push_back(p);
        } else {
            std::int64_t a = 0, b = 0;
            if (w.size() < 2)
                fail(name, at_line(line_no) + "edge needs two joint numbers, got " + quoted(mesh_detail::trim(line)));
            if (!mesh_detail::parse_int(w[0], a) || !mesh_detail::parse_int(w[1], b))
                fail(name, at_line(line_no) + "edge " + quoted(mesh_detail::trim(line)) +
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

}  // namespace volrig

// mesh/medit.cpp: the Medit ASCII .mesh reader of volrig/mesh.hpp (INRIA's format, as libMeshb writes it).
//
// The file is a stream of whitespace-separated tokens: keywords, then a section's count and its records. Every
// count is checked against the bytes that follow it before anything is allocated (each number takes at least two
// bytes). Sections this reader does not use are skipped up to the next keyword.
#include <algorithm>
#include <array>
#include <cctype>
#include <cstdint>
#include <string>

#include "mesh/mesh_detail.hpp"

namespace volrig {

using mesh_detail::fail;
using mesh_detail::quoted;
using mesh_detail::with_commas;

namespace {

using Tri = std::array<std::uint32_t, 3>;

/// A section of cells: its keyword, its corners per cell, and how many triangles each cell may cost while read.
struct CellKind {
    const char* keyword;
    std::size_t corners;
    std::uint64_t triangle_cost;  // tetrahedra: 4 faces of a sort key and a triangle each while the boundary is found
};
constexpr CellKind kTriangles{"Triangles", 3, 1};
constexpr CellKind kQuadrilaterals{"Quadrilaterals", 4, 2};
constexpr CellKind kTetrahedra{"Tetrahedra", 4, 8};

/// The faces that belong to exactly one tetrahedron; each oriented as the outward face of a positively oriented
/// tetrahedron (a b c d): b c d, a d c, a b d, a c b.
std::vector<Tri> tet_boundary(const std::vector<std::uint32_t>& tets) {
    struct Face {
        Tri key, tri;
    };
    std::vector<Face> faces;
    faces.reserve(tets.size());
    for (std::size_t t = 0; t + 3 < tets.size(); t += 4) {
        const std::uint32_t a = tets[t], b = tets[t + 1], c = tets[t + 2], d = tets[t + 3];
        for (const Tri& f : {Tri{b, c, d}, Tri{a, d, c}, Tri{a, b, d}, Tri{a, c, b}}) {
            Tri key = f;
            std::sort(key.begin(), key.end());
            faces.push_back({key, f});
        }
    }
    std::sort(faces.begin(), faces.end(), [](const Face& x, const Face& y) { return x.key < y.key; });
    std::vector<Tri> out;
    for (std::size_t i = 0; i < faces.size();) {
        std::size_t j = i + 1;
        while (j < faces.size() && faces[j].key == faces[i].key) ++j;
        if (j == i + 1) out.push_back(faces[i].tri);
        i = j;
    }
    return out;
}

bool is_keyword(std::string_view tok) {
    return !tok.empty() && std::isalpha(static_cast<unsigned char>(tok[0])) &&
           std::all_of(tok.begin(), tok.end(),
                       [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
}

class MeditReader {
public:
    MeditReader(const ByteSource& src, const ReadOptions& opt)
        : name_(src.name()), opt_(opt), lines_(src), tokens_(lines_, src.name(), "Medit .mesh", '#') {}

    Mesh read() {
        std::string_view tok;
        if (!tokens_.next(tok)) fail(name_, "empty file: not a Medit .mesh file");
        if (!mesh_detail::iequals(tok, "MeshVersionFormatted"))
            fail(name_, tokens_.here() + "not a Medit .mesh file (it starts with " + quoted(tok) +
                            ", not MeshVersionFormatted)");
        if (const std::int64_t v = integer("the version"); v < 1 || v > 4)
            fail(name_, tokens_.here() + "MeshVersionFormatted " + std::to_string(v) + " (known: 1 to 4)");
        std::string keyword;
        while (next_keyword(keyword) && !mesh_detail::iequals(keyword, "End")) section(keyword);
        return finish();
    }

private:
    /// The next keyword (one a skipped section ran into, or the next token); false at the end of the file.
    bool next_keyword(std::string& keyword) {
        if (!pending_.empty()) {
            keyword.swap(pending_);
            pending_.clear();
            return true;
        }
        std::string_view tok;
        if (!tokens_.next(tok)) return false;
        if (!is_keyword(tok)) fail(name_, tokens_.here() + "expected a keyword, got " + quoted(tok));
        keyword = std::string(tok);
        return true;
    }

    std::int64_t integer(const std::string& what) {
        const std::string_view tok = tokens_.need(what);
        std::int64_t v = 0;
        if (!mesh_detail::parse_int(tok, v)) fail(name_, tokens_.here() + what + " " + quoted(tok) + " is not an integer");
        return v;
    }

    /// A section's count, checked against the bytes left for records of `numbers` numbers each.
    std::uint64_t count(const std::string& keyword, std::size_t numbers) {
        const std::int64_t n = integer("the number of " + keyword);
        if (n < 0) fail(name_, tokens_.here() + keyword + " count " + std::to_string(n) + " is negative");
        mesh_detail::check_count_fits(name_, tokens_.here(), static_cast<std::uint64_t>(n), keyword.c_str(), 2 * numbers,
                                 tokens_.remaining() + 1);
        return static_cast<std::uint64_t>(n);
    }

    void section(const std::string& keyword) {
        if (mesh_detail::iequals(keyword, "Dimension")) {
            if (const std::int64_t d = integer("the dimension"); d != 3)
                fail(name_, tokens_.here() + "Dimension " + std::to_string(d) + ": only 3-D meshes are read");
            have_dimension_ = true;
        } else if (mesh_detail::iequals(keyword, "Vertices")) {
            read_vertices();
        } else if (mesh_detail::iequals(keyword, kTriangles.keyword)) {
            read_cells(kTriangles, triangles_);
        } else if (mesh_detail::iequals(keyword, kQuadrilaterals.keyword)) {
            read_cells(kQuadrilaterals, quads_);
        } else if (mesh_detail::iequals(keyword, kTetrahedra.keyword)) {
            read_cells(kTetrahedra, tets_);
        } else {
            skip_section();
        }
    }

    void read_vertices() {
        if (!have_dimension_) fail(name_, tokens_.here() + "Vertices before 'Dimension 3'");
        if (!m_.vertices.empty()) fail(name_, tokens_.here() + "a second Vertices section");
        const std::uint64_t n = count("Vertices", 4);
        if (n == 0) fail(name_, tokens_.here() + "no vertices (Vertices 0)");
        mesh_detail::check_mesh_size(name_, [&] { return tokens_.here(); }, n, 0, opt_.max_bytes);
        m_.vertices.resize(static_cast<std::size_t>(n));
        for (auto& p : m_.vertices) {
            for (std::size_t a = 0; a < 3; ++a) {
                std::string why;
                if (!mesh_detail::parse_coordinate(tokens_.need("a vertex coordinate"), a, p[a], why))
                    fail(name_, tokens_.here() + "vertex " + why);
            }
            integer("a vertex reference");
        }
    }

    void read_cells(const CellKind& kind, std::vector<std::uint32_t>& cells) {
        if (m_.vertices.empty()) fail(name_, tokens_.here() + kind.keyword + " before Vertices");
        const std::string what = std::string("a vertex index of ") + kind.keyword;
        const std::uint64_t n = count(kind.keyword, kind.corners + 1);
        triangle_cost_ += n * kind.triangle_cost;
        mesh_detail::check_mesh_size(name_, [&] { return tokens_.here(); }, m_.vertices.size(), triangle_cost_,
                                opt_.max_bytes);
        cells.reserve(cells.size() + static_cast<std::size_t>(n * kind.corners));
        for (std::uint64_t i = 0; i < n; ++i) {
            for (std::size_t c = 0; c < kind.corners; ++c) {
                const std::int64_t k = integer(what);
                if (k < 1 || static_cast<std::uint64_t>(k) > m_.vertices.size())
                    fail(name_, tokens_.here() + kind.keyword + " " + with_commas(i + 1) + ": vertex index " +
                                    std::to_string(k) + " out of range (" + with_commas(m_.vertices.size()) +
                                    " vertices, numbered from 1)");
                cells.push_back(static_cast<std::uint32_t>(k - 1));
            }
            integer(std::string("the reference of one of the ") + kind.keyword);
        }
    }

    /// Skips a section this reader does not use: numbers up to the next keyword.
    void skip_section() {
        std::string_view tok;
        double ignored = 0;
        while (tokens_.next(tok))
            if (!mesh_detail::parse_double(tok, ignored)) {
                if (!is_keyword(tok))
                    fail(name_, tokens_.here() + "expected a number or a keyword, got " + quoted(tok));
                pending_ = std::string(tok);
                return;
            }
    }

    Mesh finish() {
        if (m_.vertices.empty()) fail(name_, "no Vertices section: not a mesh");
        if (triangles_.empty() && quads_.empty()) {
            if (tets_.empty()) fail(name_, "no Triangles, Quadrilaterals or Tetrahedra: nothing to voxelize");
            m_.triangles = tet_boundary(tets_);
            if (m_.triangles.empty()) fail(name_, "the Tetrahedra have no boundary face (each face is shared)");
            return std::move(m_);
        }
        m_.triangles.reserve(triangles_.size() / 3 + quads_.size() / 2);
        for (std::size_t i = 0; i + 2 < triangles_.size(); i += 3)
            m_.triangles.push_back({triangles_[i], triangles_[i + 1], triangles_[i + 2]});
        for (std::size_t i = 0; i + 3 < quads_.size(); i += 4) {
            m_.triangles.push_back({quads_[i], quads_[i + 1], quads_[i + 2]});
            m_.triangles.push_back({quads_[i], quads_[i + 2], quads_[i + 3]});
        }
        return std::move(m_);
    }

    const std::string& name_;
    const ReadOptions& opt_;
    mesh_detail::LineReader lines_;
    mesh_detail::TokenReader tokens_;
    std::string pending_;
    bool have_dimension_ = false;
    std::uint64_t triangle_cost_ = 0;
    std::vector<std::uint32_t> triangles_, quads_, tets_;  // 0-based corners, 3 or 4 per cell
    Mesh m_;
};

}  // namespace

Mesh read_medit(const ByteSource& src, const ReadOptions& opt) { return MeditReader(src, opt).read(); }

}  // namespace volrig

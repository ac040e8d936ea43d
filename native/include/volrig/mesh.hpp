// volrig/mesh.hpp: triangle meshes in: OBJ, PLY, OFF, STL and Medit readers, libigl TGF skeletons, and voxelization
// of a closed (or nearly closed) surface into a volume mask.
//
// Readers follow volrig/io.hpp's rules: counts are checked against the bytes present before anything is
// allocated, absurd sizes are refused (ReadOptions::max_bytes bounds the decoded mesh: 24 bytes per vertex, 12 per
// triangle), and every error is a FileFormatError (or FileNotFound) whose message starts with the file name and
// says what is wrong and where ("arm.obj: line 12: face index 9000 out of range (8311 vertices)").
// Coordinates must be finite; indices must be in range; a mesh without faces is refused.
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <cstdint>
#include <string>
#include <vector>

#include "volrig/io.hpp"
#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

/// A triangle mesh: polygons are fan-triangulated on reading (v0 v1 v2, v0 v2 v3, ...). Indices are 0-based.
struct Mesh {
    std::vector<std::array<double, 3>> vertices;
    std::vector<std::array<std::uint32_t, 3>> triangles;
};

/// A skeleton in libigl's Trivial Graph Format: joint positions and 0-based edges (bones) between them.
struct TgfSkeleton {
    std::vector<std::array<double, 3>> joints;
    std::vector<std::array<std::uint32_t, 2>> edges;
};

/// Wavefront OBJ: `v x y z [w | r g b]` and `f` lines whose entries are `i`, `i/t`, `i//n` or `i/t/n` (1-based,
/// or negative = relative to the vertices defined so far); faces of 3 or more vertices are fan-triangulated.
/// Texture coordinates, normals, groups, objects, smoothing, materials, lines, points and comments are ignored;
/// a trailing backslash continues a line.
Mesh read_obj(const ByteSource& src, const ReadOptions& opt = {});

/// Stanford PLY: ascii, binary_little_endian and binary_big_endian. `element vertex` needs scalar properties x, y,
/// z of any numeric type (other properties are skipped); `element face` needs `property list <count> <index>
/// vertex_indices` (or vertex_index) with integer types. Other elements and properties are skipped by their types.
Mesh read_ply(const ByteSource& src, const ReadOptions& opt = {});

/// libigl's TGF: joint lines `index x y z [ignored columns]`, a line `#`, edge lines `a b [ignored columns]`
/// (1-based joint numbers), optionally a second `#` after which everything is ignored.
TgfSkeleton read_tgf(const ByteSource& src, const ReadOptions& opt = {});

/// Geomview OFF: a header keyword `OFF` (optionally prefixed ST, C, N: `COFF`, `NOFF`, `CNOFF`, `STOFF` ...; the
/// keyword may be left out), a counts line `vertices faces [edges]` (edges ignored; the counts may also follow the
/// keyword on its line), one vertex per line (x y z, further columns such as colours or normals ignored), one face
/// per line (`n i1 .. in`, 0-based, optionally followed by a colour), `#` comments. Faces of 3 or more vertices
/// are fan-triangulated; anything after the declared faces is ignored. 4OFF/nOFF and `OFF BINARY` are refused.
Mesh read_off(const ByteSource& src, const ReadOptions& opt = {});

/// STL, ASCII or binary. Binary when the file size is 84 + 50 x (the uint32 triangle count at byte 80), whatever
/// its 80-byte header says (binary files may start with "solid" too); else ASCII, which must start with `solid`:
/// `facet normal nx ny nz / outer loop / vertex x y z` (3 or more; more are fan-triangulated) `/ endloop /
/// endfacet`, `endsolid`, keywords case-insensitive, several solids in one file allowed. Normals are ignored.
/// STL stores each triangle's corners separately: vertices with identical coordinates are welded (exactly; -0 and
/// 0 are the same), so a closed surface comes out closed, with vertices in order of first use.
Mesh read_stl(const ByteSource& src, const ReadOptions& opt = {});

/// Medit ASCII .mesh (INRIA, version 1 to 4): `MeshVersionFormatted v`, `Dimension 3`, `Vertices n` (x y z ref),
/// `Triangles n` (i j k ref), `Quadrilaterals n` (i j k l ref), `Tetrahedra n` (i j k l ref), `End`; 1-based
/// indices, keywords case-insensitive, `#` comments; other sections (Edges, Corners, Ridges, Normals, ...) are
/// skipped. The surface is the Triangles and Quadrilaterals (fan-split) when the file has any; otherwise the
/// boundary of the Tetrahedra (the faces that belong to exactly one tetrahedron, oriented as the tetrahedron's
/// outward face when it is positively oriented). All vertices are kept (interior ones too). Binary .meshb is not
/// read.
Mesh read_medit(const ByteSource& src, const ReadOptions& opt = {});

/// The file endings read_mesh knows, lower-case: .obj .ply .off .stl .mesh.
std::vector<std::string> mesh_extensions();

/// Picks the reader from the file name's ending (case-insensitive; see mesh_extensions). .meshb is refused with
/// a message saying binary Medit is not supported.
Mesh read_mesh(const std::string& path, const ReadOptions& opt = {});

/// Builds a Mesh from flat arrays (xyz per vertex; three 0-based indices per triangle), refusing non-finite
/// coordinates, indices outside [0, vertex_count), and empty input with an Error naming `what`.
Mesh make_mesh(const double* xyz, std::size_t vertex_count, const std::int64_t* triangles, std::size_t triangle_count,
               const std::string& what = "mesh");

/// Checks a mesh: at least one triangle, finite coordinates, indices in range. Throws Error naming `what`.
void check_mesh(const Mesh& mesh, const std::string& what = "mesh");

// ---- voxelization --------------------------------------------------------------------------------------------

/// How voxelize decides inside from outside.
enum class VoxelizeMethod {
    /// The exterior flood-filled from the grid border through voxels farther than closing_radius from the surface
    /// (or OpenVDB's sign when closing_radius is 0): exact for a closed surface, bridges holes narrower than about
    /// 2 closing_radius, loses the interior through wider ones.
    Flood,
    /// The generalized winding number (WindingNumber): inside when |w| >= 0.5 at the voxel centre. For surfaces
    /// that are not closed: separate open parts, missing caps, overlapping or inconsistently oriented pieces.
    /// closing_radius is not used.
    Winding,
    /// Flood when the mesh is closed (is_closed: every edge shared by exactly two triangles), so closed meshes
    /// give exactly Flood's mask; otherwise the union of Flood's and Winding's masks: the winding number restores
    /// the interiors the flood loses through wide holes, the flood keeps the parts its closing joins across gaps
    /// narrower than 2 closing_radius (which the winding number leaves apart). The winding number is evaluated
    /// only where the flood found no inside (the union is the same as the two masks made apart).
    Auto,
};

struct VoxelizeOptions {
    /// Inside/outside test (see VoxelizeMethod). Flood keeps the behaviour voxelize always had.
    VoxelizeMethod method = VoxelizeMethod::Flood;
    /// Whole empty voxels kept around the mesh's bounding box on each side (rounded up; 0 to 1000).
    double padding_voxels = 2;
    /// Hole closing radius in voxels (0 or 0.5 to 4). The exterior is the region reachable from the grid border
    /// through voxel centres farther than this from the surface, so holes (and gaps) narrower than about twice
    /// this radius do not let it in. 0 uses OpenVDB's own sign (watertight meshes only: its exterior flood fill
    /// leaks through any hole wider than about 1.5 voxels and the result is then empty or partly empty).
    double closing_radius = 1.5;
    /// Limit on the dense grid (bytes; voxelization holds two bytes per voxel).
    std::uint64_t max_bytes = default_max_bytes();
    /// When set, a point the output lattice passes through: voxel centres lie at anchor + voxel_size * k (the
    /// grid then starts up to one voxel lower and is one voxel longer), so that two voxelizations (a mesh and its
    /// posed copy) can be compared voxel for voxel.
    std::optional<std::array<double, 3>> anchor;
};

/// The generalized winding number of a triangle soup (Jacobson et al. 2013): w(q) = the sum of the signed solid
/// angles the triangles subtend at q over 4 pi. 1 inside and 0 outside a closed surface whose triangles face
/// outward (-1 inside when they face inward; k inside k nested or overlapping closed parts); for an open surface a
/// smooth function that goes from about 1 to about 0 across its holes. Evaluated fast after Barill et al. 2018: a
/// bounding-volume hierarchy whose clusters, seen from farther than `beta` times their radius, contribute a
/// second-order far-field expansion; nearer triangles are summed exactly (details in mesh/winding.cpp). The
/// object is immutable once built and can be evaluated from many threads at once.
class WindingNumber {
public:
    /// Refuses meshes without triangles, indices out of range and beta < 1 (2 is the usual accuracy; larger is
    /// more exact and slower).
    explicit WindingNumber(const Mesh& mesh, double beta = 2.0);
    ~WindingNumber();
    WindingNumber(WindingNumber&&) noexcept;
    WindingNumber& operator=(WindingNumber&&) noexcept;

    /// The winding number at q (fast).
    double operator()(const std::array<double, 3>& q) const;
    /// The winding number at q summed over every triangle exactly (brute force, for tests).
    double exact(const std::array<double, 3>& q) const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// True when every edge of the mesh is shared by exactly two triangles (no boundary edge, no non-manifold edge;
/// edges of degenerate triangles joining a vertex to itself are ignored).
bool is_closed(const Mesh& mesh);

/// Voxelizes the solid a triangle mesh encloses: a uint8 mask (1 inside) on a grid of spacing `voxel_size` in all
/// three axes whose origin is the mesh-space position of voxel (0, 0, 0)'s centre, so voxel (x, y, z) is centred at
/// origin + voxel_size * (x, y, z). The grid's cells cover the mesh's bounding box (its minimum corner lies on a
/// cell boundary) plus `padding_voxels` whole cells on every side. A voxel is inside when its centre is.
///
/// Method (closing_radius r > 0; details in mesh/voxelize.cpp): OpenVDB's meshToVolume gives the unsigned distance u to
/// the surface in a narrow band (made exact near the threshold with a bounding-volume hierarchy); the exterior E is
/// flood-filled from the grid border through voxels with u > r; a voxel is also outside when it lies strictly
/// inside a ball B(c, u(c)) around an exterior point c (such balls touch the surface but never cross it).
/// Everything else is inside. For a closed surface this is the solid it encloses, except that creases narrower
/// than 2r are filled and concave corners rounded (a morphological closing); holes narrower than about 2r are
/// bridged. Orientation and self-intersections do not matter; enclosed cavities are filled. Refuses non-positive or
/// non-finite voxel sizes, grids beyond max_bytes or 2^28 voxels along an axis, and meshes that enclose no voxel
/// centre at this voxel size.
///
/// With VoxelizeMethod::Winding a voxel is inside when the generalized winding number at its centre has
/// |w| >= 0.5 (closing_radius unused); it is evaluated on a lattice of every 8th voxel, and a block is split in
/// eight (recursively, down to single voxels) only when the surface comes within its circumradius (plus half a
/// voxel) or its corners disagree or lie within 0.1 of the threshold. Auto on a mesh that is not closed gives the
/// union of the Flood and Winding masks; on a closed mesh exactly Flood's.
Volume voxelize(const Mesh& mesh, double voxel_size, const VoxelizeOptions& opt, const Progress& progress = {});

/// Same with default options except the padding.
Volume voxelize(const Mesh& mesh, double voxel_size, double padding_voxels = 2, const Progress& progress = {});

}  // namespace volrig

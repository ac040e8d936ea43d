// Medial surfaces (medial_surface.hpp): simple points and the thinning against brute-force topology, the mesh of
// plates, shells and bent sheets of known area and thickness on anisotropic grids, a plate with a rod.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>

#include "volrig/distance.hpp"
#include "volrig/medial_surface.hpp"

using namespace volrig;

namespace {

constexpr double kPi = 3.14159265358979323846;

using Field = std::function<double(double, double, double)>;

/// The voxels whose centre (grid frame) lies closer than r to the set `dist` measures the distance to.
std::vector<std::uint8_t> shape(const Grid& g, const Field& dist, double r) {
    std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()));
    for (std::int64_t z = 0; z < g.dims[2]; ++z)
        for (std::int64_t y = 0; y < g.dims[1]; ++y)
            for (std::int64_t x = 0; x < g.dims[0]; ++x)
                m[static_cast<std::size_t>(g.index(x, y, z))] =
                    dist(double(x) * g.spacing[0], double(y) * g.spacing[1], double(z) * g.spacing[2]) < r;
    return m;
}

Grid grid(std::array<double, 3> extent, std::array<double, 3> spacing) {
    Grid g;
    g.spacing = spacing;
    for (int a = 0; a < 3; ++a) g.dims[static_cast<std::size_t>(a)] = static_cast<std::int64_t>(extent[static_cast<std::size_t>(a)] / spacing[static_cast<std::size_t>(a)]) + 1;
    return g;
}

// --- brute-force topology of a voxel set (26-connected object, 6-connected background, the outside background) --

bool inside(const Grid& g, std::int64_t x, std::int64_t y, std::int64_t z) {
    return x >= 0 && y >= 0 && z >= 0 && x < g.dims[0] && y < g.dims[1] && z < g.dims[2];
}

/// Components of the object (26) or of the background padded by one layer (6).
int components(const Grid& g, const std::vector<std::uint8_t>& m, bool object) {
    const std::int64_t px = g.dims[0] + 2, py = g.dims[1] + 2, pz = g.dims[2] + 2;
    auto in_set = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
        const bool o = inside(g, x, y, z) && m[static_cast<std::size_t>(g.index(x, y, z))];
        return o == object;
    };
    std::vector<std::uint8_t> seen(static_cast<std::size_t>(px * py * pz), 0);
    auto id = [&](std::int64_t x, std::int64_t y, std::int64_t z) { return static_cast<std::size_t>(((z + 1) * py + y + 1) * px + x + 1); };
    int count = 0;
    std::vector<std::array<std::int64_t, 3>> stack;
    for (std::int64_t z = -1; z <= g.dims[2]; ++z)
        for (std::int64_t y = -1; y <= g.dims[1]; ++y)
            for (std::int64_t x = -1; x <= g.dims[0]; ++x) {
                if (!in_set(x, y, z) || seen[id(x, y, z)]) continue;
                ++count;
                seen[id(x, y, z)] = 1;
                stack.push_back({x, y, z});
                while (!stack.empty()) {
                    const auto p = stack.back();
                    stack.pop_back();
                    for (std::int64_t dz = -1; dz <= 1; ++dz)
                        for (std::int64_t dy = -1; dy <= 1; ++dy)
                            for (std::int64_t dx = -1; dx <= 1; ++dx) {
                                const std::int64_t l1 = std::abs(dx) + std::abs(dy) + std::abs(dz);
                                if (l1 == 0 || (!object && l1 > 1)) continue;
                                const std::int64_t X = p[0] + dx, Y = p[1] + dy, Z = p[2] + dz;
                                if (X < -1 || Y < -1 || Z < -1 || X > g.dims[0] || Y > g.dims[1] || Z > g.dims[2]) continue;
                                if (!in_set(X, Y, Z) || seen[id(X, Y, Z)]) continue;
                                seen[id(X, Y, Z)] = 1;
                                stack.push_back({X, Y, Z});
                            }
                }
            }
    return count;
}

/// Euler characteristic of the union of the object's closed unit cubes (V - E + F - C of the cubical complex),
/// the 26-connected object's.
std::int64_t euler(const Grid& g, const std::vector<std::uint8_t>& m) {
    auto obj = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
        return inside(g, x, y, z) && m[static_cast<std::size_t>(g.index(x, y, z))];
    };
    std::int64_t chi = 0;
    // A cell of the complex at lattice position (cell corner c, dimension mask k): present when one of the voxels
    // whose closed cube contains it is object. Cells are named by voxel-corner coordinates: vertex (x, y, z) is the
    // corner shared by voxels x-1..x, etc.
    for (std::int64_t z = 0; z <= g.dims[2]; ++z)
        for (std::int64_t y = 0; y <= g.dims[1]; ++y)
            for (std::int64_t x = 0; x <= g.dims[0]; ++x)
                for (int k = 0; k < 8; ++k) {
                    const int ex = k & 1, ey = (k >> 1) & 1, ez = (k >> 2) & 1;  // extends along these axes
                    bool present = false;
                    for (int dz = ez ? 0 : -1; dz <= 0 && !present; ++dz)
                        for (int dy = ey ? 0 : -1; dy <= 0 && !present; ++dy)
                            for (int dx = ex ? 0 : -1; dx <= 0 && !present; ++dx) present = obj(x + dx, y + dy, z + dz);
                    if (present) chi += ((ex + ey + ez) % 2 == 0) ? 1 : -1;
                }
    return chi;
}

struct Topology {
    int objects, backgrounds;
    std::int64_t chi;
    bool operator==(const Topology& o) const { return objects == o.objects && backgrounds == o.backgrounds && chi == o.chi; }
};

Topology topology(const Grid& g, const std::vector<std::uint8_t>& m) {
    return {components(g, m, true), components(g, m, false), euler(g, m)};
}

std::vector<std::uint8_t> skeleton_voxels(const std::vector<std::uint8_t>& cls) {
    std::vector<std::uint8_t> s(cls.size());
    for (std::size_t i = 0; i < cls.size(); ++i) s[i] = cls[i] != 0;
    return s;
}

double area(const MedialSurface& s) {
    double a = 0;
    for (const auto& f : s.faces) {
        const auto& p = s.vertices[static_cast<std::size_t>(f[0])];
        const auto& q = s.vertices[static_cast<std::size_t>(f[1])];
        const auto& r = s.vertices[static_cast<std::size_t>(f[2])];
        const double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]}, v[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
        const double c[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        a += 0.5 * std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    }
    return a;
}

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
}

/// Checks the mesh of a plate: area, thickness, manifold with the expected Euler characteristic.
void check_plate(const MedialSurface& s, double expected_area, double thickness, std::int64_t chi, double voxel) {
    const MeshTopology top = mesh_topology(s.vertices.size(), s.faces);
    CAPTURE(s.vertices.size(), s.faces.size(), top.euler, top.components, top.nonmanifold_edges, top.nonmanifold_vertices);
    CHECK(top.manifold());
    CHECK(top.consistent);
    CHECK_FALSE(top.duplicate_faces);
    CHECK_FALSE(top.degenerate_faces);
    CHECK(top.components == 1);
    CHECK(top.euler == chi);
    const double a = area(s);
    CAPTURE(a, expected_area);
    WARN("area " << a << " / analytic " << expected_area << " = " << a / expected_area << ", median thickness "
                 << median(s.thickness) << " / " << thickness);
    CHECK(std::abs(a / expected_area - 1.0) < 0.05);
    const double med = median(s.thickness);
    CAPTURE(med, thickness, voxel);
    CHECK(std::abs(med - thickness) <= voxel);
    // Within one voxel away from the rim (where the rounded rim really is thinner).
    std::size_t good = 0;
    for (double t : s.thickness) good += std::abs(t - thickness) <= voxel;
    CHECK(double(good) >= 0.8 * double(s.thickness.size()));
}

}  // namespace

TEST_CASE("simple points: the characterisation on known neighbourhoods", "[medial_surface]") {
    auto bit = [](int dx, int dy, int dz) { return 1u << ((dz + 1) * 9 + (dy + 1) * 3 + (dx + 1)); };
    CHECK_FALSE(is_simple27(0));                                     // isolated
    CHECK(is_simple27(bit(1, 0, 0)));                                // a curve end
    CHECK_FALSE(is_simple27(bit(1, 0, 0) | bit(-1, 0, 0)));          // inside a curve
    CHECK_FALSE(is_simple27((1u << 27) - 1));                        // interior
    std::uint32_t half = 0;                                          // on a flat face of a block
    for (int dz = -1; dz <= 0; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) half |= bit(dx, dy, dz);
    CHECK(is_simple27(half));
    std::uint32_t sheet = 0;                                         // inside a one-voxel sheet: a hole
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) sheet |= bit(dx, dy, 0);
    CHECK_FALSE(is_simple27(sheet));
    CHECK_FALSE(is_simple27(bit(1, 1, 1) | bit(-1, -1, -1)));        // joins two parts
}

TEST_CASE("deleting a simple point keeps the brute-force topology; a non-simple one changes it", "[medial_surface]") {
    std::mt19937 rng(22);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    Grid g;
    g.dims = {3, 3, 3};
    int simple = 0, not_simple = 0;
    for (int trial = 0; trial < 3000; ++trial) {
        std::vector<std::uint8_t> m(27);
        const double density = u(rng);
        for (auto& v : m) v = u(rng) < density;
        m[13] = 1;
        const Topology before = topology(g, m);
        m[13] = 0;
        const Topology after = topology(g, m);
        m[13] = 1;
        const bool s = is_simple(g, m.data(), 1, 1, 1);
        (s ? simple : not_simple)++;
        // Within a 3x3x3 array whose outside is background, simple deletions keep the topology exactly (the
        // neighbourhood is all there is); non-simple ones change it.
        CHECK((before == after) == s);
    }
    CHECK(simple > 100);
    CHECK(not_simple > 100);
}

TEST_CASE("the skeleton keeps the object's topology on random blobs, and is thin", "[medial_surface]") {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int trial = 0; trial < 20; ++trial) {
        Grid g;
        g.dims = {14, 12, 10};
        g.spacing = {1.0, 0.8 + 0.4 * u(rng), 1.0 + u(rng)};
        // A union of random balls with random holes: several components, tunnels and cavities.
        std::vector<std::uint8_t> m(static_cast<std::size_t>(g.voxel_count()), 0);
        for (int b = 0; b < 6; ++b) {
            const double cx = 13 * u(rng), cy = 11 * u(rng), cz = 9 * u(rng), r = 1.5 + 3 * u(rng);
            const bool hole = b >= 4;
            for (std::int64_t z = 0; z < g.dims[2]; ++z)
                for (std::int64_t y = 0; y < g.dims[1]; ++y)
                    for (std::int64_t x = 0; x < g.dims[0]; ++x)
                        if (std::hypot(double(x) - cx, double(y) - cy, double(z) - cz) < r)
                            m[static_cast<std::size_t>(g.index(x, y, z))] = hole ? 0 : 1;
        }
        const auto cls = medial_skeleton(g, m.data(), 5.0);
        const auto skel = skeleton_voxels(cls);
        CHECK(topology(g, skel) == topology(g, m));
        // medial_surface's skeleton, its spurs pruned, too.
        CHECK(topology(g, skeleton_voxels(medial_surface(g, m.data(), 2.0).skeleton)) == topology(g, m));
        for (std::size_t i = 0; i < m.size(); ++i) CHECK((!skel[i] || m[i]));
        // Thin: every remaining voxel that is not an anchor (surface) is not simple, or a curve end.
        std::int64_t deletable = 0;
        for (std::int64_t z = 0; z < g.dims[2]; ++z)
            for (std::int64_t y = 0; y < g.dims[1]; ++y)
                for (std::int64_t x = 0; x < g.dims[0]; ++x) {
                    const auto i = static_cast<std::size_t>(g.index(x, y, z));
                    if (cls[i] == std::uint8_t(SkeletonClass::Curve) && is_simple(g, skel.data(), x, y, z)) {
                        int n = 0;
                        for (int dz = -1; dz <= 1; ++dz)
                            for (int dy = -1; dy <= 1; ++dy)
                                for (int dx = -1; dx <= 1; ++dx)
                                    n += (dx || dy || dz) && inside(g, x + dx, y + dy, z + dz) && skel[static_cast<std::size_t>(g.index(x + dx, y + dy, z + dz))];
                        deletable += n != 1;
                    }
                }
        CHECK(deletable == 0);
    }
}

TEST_CASE("medial surface of a disc plate on an anisotropic grid", "[medial_surface]") {
    const double R = 30.0, r = 3.0;
    const Grid g = grid({2 * R + 12, 2 * R + 12, 2 * r + 12}, {1.0, 0.9, 1.5});
    const double cx = R + 6.13, cy = R + 6.21, cz = r + 6.07;
    const auto m = shape(g, [&](double x, double y, double z) {
        const double rho = std::hypot(x - cx, y - cy), dz = z - cz;
        return rho <= R ? std::abs(dz) : std::hypot(rho - R, dz);
    }, r);
    const MedialSurface s = medial_surface(g, m.data(), 5.0);
    check_plate(s, kPi * R * R, 2 * r, 1, 1.5);
    // The vertices lie on the mid-plane.
    double worst = 0;
    for (const auto& v : s.vertices) worst = std::max(worst, std::abs(v[2] - cz));
    CHECK(worst < 0.75);
    // The skeleton: a surface, homotopic (one component, no tunnel), no rods.
    const auto skel = skeleton_voxels(s.skeleton);
    CHECK(topology(g, skel) == topology(g, m));
    CHECK(s.rods.empty());
    CHECK(std::count(s.skeleton.begin(), s.skeleton.end(), std::uint8_t(SkeletonClass::Surface)) > 2000);
}

TEST_CASE("medial surface of a spherical shell is a closed sphere", "[medial_surface]") {
    const double R = 20.0, r = 2.5;
    const Grid g = grid({2 * (R + r) + 8, 2 * (R + r) + 8, 2 * (R + r) + 8}, {1.0, 1.2, 1.4});
    const double c[3] = {R + r + 4.1, R + r + 4.2, R + r + 4.05};
    const auto m = shape(g, [&](double x, double y, double z) {
        return std::abs(std::hypot(x - c[0], y - c[1], z - c[2]) - R);
    }, r);
    const MedialSurface s = medial_surface(g, m.data(), 5.0);
    check_plate(s, 4 * kPi * R * R, 2 * r, 2, 1.4);
    double worst = 0;
    for (const auto& v : s.vertices) worst = std::max(worst, std::abs(std::hypot(v[0] - c[0], v[1] - c[1], v[2] - c[2]) - R));
    CHECK(worst < 0.75);
    CHECK(topology(g, skeleton_voxels(s.skeleton)) == topology(g, m));
}

TEST_CASE("medial surface of a bent sheet (a cylinder patch)", "[medial_surface]") {
    const double R = 24.0, angle = 2.0, H = 40.0, r = 3.0;
    const Grid g = grid({2 * R + 2 * r + 8, H + 2 * r + 8, R + 2 * r + 8}, {1.0, 1.3, 0.9});
    const double cx = R + r + 4.1, y0 = r + 4.0, cz = -R * std::cos(angle / 2) + r + 4.1;
    const auto m = shape(g, [&](double x, double y, double z) {
        const double X = x - cx, Z = z - cz;
        const double phi = std::clamp(std::atan2(X, Z), -angle / 2, angle / 2);
        const double yc = std::clamp(y - y0, 0.0, H);
        return std::hypot(X - R * std::sin(phi), Z - R * std::cos(phi), y - y0 - yc);
    }, r);
    const MedialSurface s = medial_surface(g, m.data(), 5.0);
    check_plate(s, R * angle * H, 2 * r, 1, 1.3);
    CHECK(topology(g, skeleton_voxels(s.skeleton)) == topology(g, m));
}

TEST_CASE("a plate with a rod attached is classified as both surface and rod", "[medial_surface]") {
    const double R = 16.0, r = 2.5, rod = 2.0, len = 14.0;
    const Grid g = grid({2 * R + 12, 2 * R + 12, 2 * r + len + 12}, {1.0, 1.0, 1.4});
    const double cx = R + 6.13, cy = R + 6.21, cz = r + 4.0;
    const auto m = shape(g, [&](double x, double y, double z) {
        const double rho = std::hypot(x - cx, y - cy), dz = z - cz;
        const double plate = rho <= R ? std::abs(dz) - r : std::hypot(rho - R, dz) - r;
        const bool in_rod = std::hypot(x - cx - 5, y - cy) < rod && z > cz && z < cz + r + len;
        return in_rod ? -1.0 : plate;
    }, 0.0);
    const MedialSurface s = medial_surface(g, m.data(), 5.0);
    const auto count = [&](SkeletonClass c) { return std::count(s.skeleton.begin(), s.skeleton.end(), std::uint8_t(c)); };
    CHECK(count(SkeletonClass::Surface) > 300);
    CHECK(count(SkeletonClass::Curve) >= 5);
    CHECK(count(SkeletonClass::Junction) >= 1);
    REQUIRE(s.rods.size() == 1);
    const auto& line = s.rods[0];
    CHECK(line.size() >= 6);
    // The rod runs up the cylinder's axis from the plate to about a radius short of its top.
    for (const auto& p : line) {
        CHECK(std::hypot(p[0] - cx - 5, p[1] - cy) < 1.5);
        CHECK(p[2] > cz);
    }
    const double top = std::max(line.front()[2], line.back()[2]), bottom = std::min(line.front()[2], line.back()[2]);
    CHECK(top > cz + r + len - 2 * rod - 1.4);
    CHECK(bottom < cz + r + 2 * 1.4 + 1e-9);  // within two voxels of the plate's face
    for (double radius : s.rod_radii[0]) CHECK(std::abs(radius - rod) <= 1.0);
    const MeshTopology top_mesh = mesh_topology(s.vertices.size(), s.faces);
    CHECK(top_mesh.manifold());
    CHECK(top_mesh.euler == 1);
    CHECK(topology(g, skeleton_voxels(s.skeleton)) == topology(g, m));
}

TEST_CASE("medial surface of an empty mask and of a ball", "[medial_surface]") {
    Grid g;
    g.dims = {9, 9, 9};
    std::vector<std::uint8_t> m(729, 0);
    MedialSurface s = medial_surface(g, m.data(), 5.0);
    CHECK(s.vertices.empty());
    CHECK(s.faces.empty());
    CHECK(s.rods.empty());
    m = shape(g, [](double x, double y, double z) { return std::hypot(x - 4, y - 4, z - 4); }, 3.5);
    s = medial_surface(g, m.data(), 5.0);
    CHECK(topology(g, skeleton_voxels(s.skeleton)) == topology(g, m));
    CHECK_THROWS_AS(medial_surface(g, m.data(), -1.0), Error);
    CHECK_THROWS_AS(medial_surface(g, m.data(), 5.0, [](double) { return false; }), Cancelled);
    std::vector<double> seen;
    medial_surface(g, m.data(), 5.0, [&](double f) {
        seen.push_back(f);
        return true;
    });
    CHECK(std::is_sorted(seen.begin(), seen.end()));
    CHECK(seen.back() == 1.0);
}

TEST_CASE("mesh topology of small hand-made meshes", "[medial_surface]") {
    // A tetrahedron's surface: closed, oriented, Euler characteristic 2.
    std::vector<std::array<std::int64_t, 3>> tet = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {2, 0, 3}};
    MeshTopology m = mesh_topology(4, tet);
    CHECK(m.manifold());
    CHECK(m.consistent);
    CHECK(m.euler == 2);
    CHECK(m.boundary_edges == 0);
    CHECK(m.components == 1);
    std::swap(tet[0][1], tet[0][2]);  // one face flipped
    CHECK_FALSE(mesh_topology(4, tet).consistent);
    // Two triangles touching at a vertex (a bow tie): a non-manifold vertex, two components.
    m = mesh_topology(5, {{0, 1, 2}, {0, 3, 4}});
    CHECK(m.nonmanifold_vertices == 1);
    CHECK(m.components == 2);
    CHECK(m.euler == 1);  // 5 - 6 + 2: the shared vertex counted once
    // Three triangles on one edge: a non-manifold edge; a repeated face; a degenerate one.
    m = mesh_topology(5, {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}});
    CHECK(m.nonmanifold_edges == 1);
    CHECK(mesh_topology(3, {{0, 1, 2}, {2, 1, 0}}).duplicate_faces);
    CHECK(mesh_topology(3, {{0, 1, 1}}).degenerate_faces);
    CHECK_THROWS_AS(mesh_topology(2, {{0, 1, 2}}), Error);
}

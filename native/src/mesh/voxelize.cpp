// mesh/voxelize.cpp: the solid a triangle mesh encloses, as a dense mask (volrig/mesh.hpp).
//
// Why not OpenVDB's signed distance alone: meshToVolume decides inside/outside by flood-filling the exterior sign
// through narrow-band voxels farther than 0.75 voxel from the surface, then propagating signs into the tiles. A hole
// wider than about 1.5 voxels lets that fill into the interior, which then comes out empty or partly empty (the
// tests show a sphere with a few deleted triangles losing its whole interior). It is kept as closing_radius = 0.
//
// What is done instead (closing_radius r > 0), on a working grid with a margin of ceil(r) + 3 voxels:
//   1. OpenVDB's meshToVolume in UNSIGNED_DISTANCE_FIELD mode gives u, the distance (in voxels) from each voxel
//      centre within r + 2.5 voxels of the surface to a triangle. Its band expansion propagates candidate triangles,
//      so u is an upper bound, not always the nearest (about 3% of the arm's band voxels are up to 0.43 voxel too
//      far); the voxels with r < u <= r + 2 get the exact distance from a bounding-volume hierarchy of the
//      triangles (TriangleTree).
//   2. Voxels with u <= r are walls. The exterior E is flood-filled (6-connected, scanline fill) from the grid
//      border through the other voxels, so it cannot pass any hole or gap narrower than about 2r.
//   3. A ball B(e, u(e)) around an exterior voxel touches the surface but never crosses it, so every voxel strictly
//      inside such a ball is outside too (the exterior voxels with u <= r + 2 are the centres; their balls reach
//      every wall voxel outside the surface). A voxel inside a closed surface is never covered: any segment from it
//      to an exterior voxel crosses the surface.
//   3b. Ball centres on the lattice miss some voxels within a few hundredths of a voxel of the surface. Each wall
//      voxel v within half a voxel of it gets a second test with a centre off the lattice: q = s + (r + 1) n, where
//      s is v's nearest surface point and n the unit vector from s to v. If no triangle comes nearer to q than v
//      and q's nearest voxel (which must be exterior or covered), v is in q's empty ball, connected to the
//      exterior, and outside. This is sound for the same reason as 3.
//   4. Inside = neither exterior nor covered. The result is close to the morphological closing of the solid with a
//      ball of radius r: creases narrower than 2r are filled, concave corners are rounded (the voxel row along a
//      concave edge stays inside, as it does with OpenVDB's sign), holes narrower than about 2r are bridged by a
//      cap that dips at most r - sqrt(r² - h²) voxels (hole radius h < r), enclosed cavities are filled.
//      Measured on the closed arm mesh at voxel size 0.01: 58,778 voxels against the exact volume's 58,619 (+0.27%);
//      OpenVDB's sign gives 58,630. They differ on 184 voxels, all within 1.3 voxels of the surface; a winding-number
//      test sides with the closing on 76 of them (OpenVDB's sign is not exact either) and with OpenVDB on 108.
#include <openvdb/openvdb.h>
#include <openvdb/math/Proximity.h>
#include <openvdb/tools/MeshToVolume.h>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <limits>
#include <sstream>
#include <thread>

#include "volrig/mesh.hpp"

namespace volrig {

namespace {

/// OpenVDB reads the mesh through this: vertex positions in the working grid's index space.
struct IndexSpaceMesh {
    const std::vector<openvdb::Vec3d>& points;
    const std::vector<std::array<std::uint32_t, 3>>& triangles;

    std::size_t polygonCount() const { return triangles.size(); }
    std::size_t pointCount() const { return points.size(); }
    std::size_t vertexCount(std::size_t) const { return 3; }
    void getIndexSpacePoint(std::size_t n, std::size_t v, openvdb::Vec3d& pos) const { pos = points[triangles[n][v]]; }
};

/// Exact distance from a point to the nearest triangle: a bounding-volume hierarchy (median splits, up to four
/// triangles per leaf) searched nearest-first with the best distance so far as the bound.
class TriangleTree {
public:
    TriangleTree(const std::vector<openvdb::Vec3d>& points, const std::vector<std::array<std::uint32_t, 3>>& triangles)
        : points_(points), triangles_(triangles), order_(triangles.size()) {
        std::vector<openvdb::Vec3d> centroid(triangles.size());
        for (std::size_t i = 0; i < triangles.size(); ++i) {
            order_[i] = static_cast<std::uint32_t>(i);
            const auto& t = triangles[i];
            centroid[i] = (points[t[0]] + points[t[1]] + points[t[2]]) / 3.0;
        }
        nodes_.reserve(2 * triangles.size() / kLeafSize + 2);
        build(0, triangles.size(), centroid);
    }

    /// Distance from p to the nearest triangle, or `bound` when none is nearer than `bound`; `closest` (when given
    /// and a triangle is nearer than `bound`) receives the nearest surface point.
    double nearest(const openvdb::Vec3d& p, double bound, openvdb::Vec3d* closest = nullptr) const {
        double best2 = bound * bound;
        search(p, [&](const openvdb::Vec3d& q) {
            const double d2 = (q - p).lengthSqr();
            if (d2 < best2) {
                best2 = d2;
                if (closest) *closest = q;
            }
            return best2;
        }, best2);
        return std::sqrt(best2);
    }

    /// True when some triangle comes nearer to p than `distance`.
    bool any_within(const openvdb::Vec3d& p, double distance) const {
        const double limit = distance * distance;
        bool found = false;
        search(p, [&](const openvdb::Vec3d& q) {
            found = found || (q - p).lengthSqr() < limit;
            return found ? -1.0 : limit;
        }, limit);
        return found;
    }

private:
    /// Visits the closest point of every triangle in the boxes nearer than the bound that `visit` returns
    /// (nearest boxes first); a negative bound stops the search.
    template <class Visit>
    void search(const openvdb::Vec3d& p, const Visit& visit, double bound2) const {
        std::uint32_t stack[128];
        int top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const Node& n = nodes_[stack[--top]];
            if (box_distance2(n, p) >= bound2) continue;
            if (n.count > 0) {
                for (std::uint32_t k = n.first; k < n.first + n.count; ++k) {
                    const auto& t = triangles_[order_[k]];
                    openvdb::Vec3d uvw;
                    bound2 = visit(openvdb::math::closestPointOnTriangleToPoint(points_[t[0]], points_[t[1]],
                                                                                 points_[t[2]], p, uvw));
                    if (bound2 < 0) return;
                }
                continue;
            }
            // Nearer child last, so it is searched first.
            const std::uint32_t a = node_index(&n) + 1, b = n.first;
            const bool a_first = box_distance2(nodes_[a], p) <= box_distance2(nodes_[b], p);
            stack[top++] = a_first ? b : a;
            stack[top++] = a_first ? a : b;
        }
    }

    static constexpr std::size_t kLeafSize = 4;
    struct Node {
        openvdb::Vec3d lo, hi;
        std::uint32_t first = 0;  // leaf: first entry of order_; inner node: index of the right child
        std::uint32_t count = 0;  // leaf: number of triangles; 0 for inner nodes (left child follows the node)
    };

    std::uint32_t node_index(const Node* n) const { return static_cast<std::uint32_t>(n - nodes_.data()); }

    static double box_distance2(const Node& n, const openvdb::Vec3d& p) {
        double d2 = 0;
        for (int a = 0; a < 3; ++a) {
            const double d = std::max({n.lo[a] - p[a], 0.0, p[a] - n.hi[a]});
            d2 += d * d;
        }
        return d2;
    }

    std::uint32_t build(std::size_t begin, std::size_t end, const std::vector<openvdb::Vec3d>& centroid) {
        const auto index = static_cast<std::uint32_t>(nodes_.size());
        nodes_.emplace_back();
        Node box;
        box.lo = openvdb::Vec3d(std::numeric_limits<double>::infinity());
        box.hi = openvdb::Vec3d(-std::numeric_limits<double>::infinity());
        for (std::size_t k = begin; k < end; ++k)
            for (std::uint32_t v : triangles_[order_[k]]) {
                box.lo = openvdb::math::minComponent(box.lo, points_[v]);
                box.hi = openvdb::math::maxComponent(box.hi, points_[v]);
            }
        if (end - begin <= kLeafSize) {
            box.first = static_cast<std::uint32_t>(begin);
            box.count = static_cast<std::uint32_t>(end - begin);
            nodes_[index] = box;
            return index;
        }
        const openvdb::Vec3d ext = box.hi - box.lo;
        const int axis = ext[0] >= ext[1] && ext[0] >= ext[2] ? 0 : (ext[1] >= ext[2] ? 1 : 2);
        const std::size_t mid = begin + (end - begin) / 2;
        std::nth_element(order_.begin() + static_cast<std::ptrdiff_t>(begin),
                         order_.begin() + static_cast<std::ptrdiff_t>(mid),
                         order_.begin() + static_cast<std::ptrdiff_t>(end),
                         [&](std::uint32_t x, std::uint32_t y) { return centroid[x][axis] < centroid[y][axis]; });
        build(begin, mid, centroid);  // the left child is index + 1
        box.first = build(mid, end, centroid);
        nodes_[index] = box;
        return index;
    }

    const std::vector<openvdb::Vec3d>& points_;
    const std::vector<std::array<std::uint32_t, 3>>& triangles_;
    std::vector<std::uint32_t> order_;
    std::vector<Node> nodes_;
};

/// Progress and cancel for OpenVDB: its stage boundaries (percent >= 0, called from the thread that started the
/// conversion) are reported as fractions in [lo, hi]; worker threads only see the stop flag. An exception from the
/// callback (Cancelled or anything else) stops the conversion and is rethrown afterwards.
class Interrupter final : public openvdb::util::NullInterrupter {
public:
    Interrupter(const Progress& progress, double lo, double hi)
        : progress_(progress), lo_(lo), hi_(hi), owner_(std::this_thread::get_id()) {}

    bool wasInterrupted(int percent = -1) override {
        if (stop_.load(std::memory_order_relaxed)) return true;
        if (percent < 0 || !progress_ || std::this_thread::get_id() != owner_) return false;
        try {
            report(progress_, lo_ + (hi_ - lo_) * std::clamp(percent, 0, 100) / 100.0);
        } catch (...) {
            error_ = std::current_exception();
            stop_.store(true);
            return true;
        }
        return false;
    }
    void rethrow() const {
        if (error_) std::rethrow_exception(error_);
    }

private:
    const Progress& progress_;
    double lo_, hi_;
    std::thread::id owner_;
    std::atomic<bool> stop_{false};
    std::exception_ptr error_;
};

// Working states of a voxel in the closing method.
constexpr std::uint8_t kOpen = 0;      // farther than r from the surface, not (yet) reached from the border
constexpr std::uint8_t kWall = 1;      // within r of the surface
constexpr std::uint8_t kExterior = 2;  // reached from the border through open voxels
constexpr std::uint8_t kCovered = 3;   // inside the ball of an exterior voxel: outside the surface

// Walls at most this far (voxels) from the surface get the second, per-voxel test (step 3b).
constexpr float kSurfaceLayer = 0.5f;

std::string number(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

/// Marks every open voxel 6-connected to voxel 0 (through open voxels) as exterior: a scanline fill, each voxel
/// visited a bounded number of times.
void fill_exterior(const Grid& g, std::uint8_t* state, const Progress& progress, double lo, double hi) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2], slice = nx * ny;
    const double total = static_cast<double>(g.voxel_count());
    std::vector<std::int64_t> stack{0};
    std::int64_t filled = 0, next_report = std::int64_t(1) << 22;
    while (!stack.empty()) {
        const std::int64_t i = stack.back();
        stack.pop_back();
        if (state[i] != kOpen) continue;
        const std::int64_t x = i % nx, row = i - x, y = (i / nx) % ny, z = i / slice;
        std::int64_t a = x, b = x;
        while (a > 0 && state[row + a - 1] == kOpen) --a;
        while (b + 1 < nx && state[row + b + 1] == kOpen) ++b;
        std::fill(state + row + a, state + row + b + 1, kExterior);
        filled += b - a + 1;
        const std::int64_t rows[4] = {y > 0 ? row - nx : -1, y + 1 < ny ? row + nx : -1, z > 0 ? row - slice : -1,
                                      z + 1 < nz ? row + slice : -1};
        for (std::int64_t r : rows) {
            if (r < 0) continue;
            for (std::int64_t k = a; k <= b; ++k)
                if (state[r + k] == kOpen && (k == a || state[r + k - 1] != kOpen)) stack.push_back(r + k);
        }
        if (filled >= next_report) {
            next_report += std::int64_t(1) << 22;
            report(progress, lo + (hi - lo) * std::min(1.0, static_cast<double>(filled) / total));
        }
    }
}

struct BallCentre {
    std::int32_t x, y, z;
    float radius;  // u at the centre, voxels
};

/// Marks the non-exterior voxels strictly inside the balls as covered. Centres are processed in z-slabs at least
/// twice the largest radius thick, even slabs in parallel and then odd ones, so no two threads write one voxel.
void cover_balls(const Grid& g, std::uint8_t* state, std::vector<BallCentre>& centres, double max_radius) {
    const int R = static_cast<int>(std::ceil(max_radius));
    struct Off {
        int dx, dy, dz, d2;
    };
    std::vector<Off> offs;
    for (int dz = -R; dz <= R; ++dz)
        for (int dy = -R; dy <= R; ++dy)
            for (int dx = -R; dx <= R; ++dx) {
                const int d2 = dx * dx + dy * dy + dz * dz;
                if (d2 < max_radius * max_radius) offs.push_back({dx, dy, dz, d2});
            }
    std::sort(offs.begin(), offs.end(), [](const Off& a, const Off& b) { return a.d2 < b.d2; });

    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    const std::int64_t slab = 2 * R + 1;
    const std::int64_t slabs = (nz + slab - 1) / slab;
    std::sort(centres.begin(), centres.end(), [](const BallCentre& a, const BallCentre& b) { return a.z < b.z; });
    std::vector<std::size_t> first(static_cast<std::size_t>(slabs) + 1, centres.size());
    for (std::size_t i = centres.size(); i-- > 0;) first[static_cast<std::size_t>(centres[i].z / slab)] = i;
    for (std::int64_t s = slabs; s-- > 0;)
        first[static_cast<std::size_t>(s)] =
            std::min(first[static_cast<std::size_t>(s)], first[static_cast<std::size_t>(s) + 1]);

    auto do_slab = [&](std::int64_t s) {
        for (std::size_t c = first[static_cast<std::size_t>(s)]; c < first[static_cast<std::size_t>(s) + 1]; ++c) {
            const BallCentre& e = centres[c];
            const float r2 = e.radius * e.radius;
            for (const Off& o : offs) {
                if (static_cast<float>(o.d2) >= r2) break;
                const std::int64_t x = e.x + o.dx, y = e.y + o.dy, z = e.z + o.dz;
                if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
                std::uint8_t& v = state[(z * ny + y) * nx + x];
                if (v == kOpen || v == kWall) v = kCovered;
            }
        }
    };
    for (std::int64_t parity = 0; parity < 2; ++parity) {
        const std::int64_t count = (slabs - parity + 1) / 2;
        tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, count), [&](const tbb::blocked_range<std::int64_t>& r) {
            for (std::int64_t k = r.begin(); k != r.end(); ++k) do_slab(2 * k + parity);
        });
    }
}

using Range = tbb::blocked_range<std::size_t>;
using FloatTree = openvdb::FloatGrid::TreeType;
using FloatLeaf = FloatTree::LeafNodeType;

std::vector<const FloatLeaf*> leaves_of(const FloatTree& tree) {
    std::vector<const FloatLeaf*> leaves;
    leaves.reserve(tree.leafCount());
    tree.getNodes(leaves);
    return leaves;
}

/// Writes out[x, y, z] = inside(work[x + k, y + k, z + k]) in parallel; returns the number of inside voxels.
template <class Inside>
std::int64_t write_mask(const Grid& out, std::uint8_t* dst, std::int64_t k, const Inside& inside) {
    const std::int64_t nx = out.dims[0], ny = out.dims[1], nz = out.dims[2];
    return tbb::parallel_reduce(
        tbb::blocked_range<std::int64_t>(0, nz), std::int64_t(0),
        [&](const tbb::blocked_range<std::int64_t>& r, std::int64_t count) {
            for (std::int64_t z = r.begin(); z != r.end(); ++z)
                for (std::int64_t y = 0; y < ny; ++y) {
                    std::uint8_t* row = dst + (z * ny + y) * nx;
                    for (std::int64_t x = 0; x < nx; ++x) {
                        const std::uint8_t in = inside(x + k, y + k, z + k) ? 1 : 0;
                        row[x] = in;
                        count += in;
                    }
                }
            return count;
        },
        [](std::int64_t a, std::int64_t b) { return a + b; });
}

void check_options(double h, const VoxelizeOptions& opt) {
    if (!std::isfinite(h) || h <= 0) throw Error("voxelize: voxel size must be finite and positive, got " + number(h));
    if (!std::isfinite(opt.padding_voxels) || opt.padding_voxels < 0 || opt.padding_voxels > 1000)
        throw Error("voxelize: padding must be between 0 and 1000 voxels, got " + number(opt.padding_voxels));
    if (opt.method != VoxelizeMethod::Flood && opt.method != VoxelizeMethod::Winding &&
        opt.method != VoxelizeMethod::Auto)
        throw Error("voxelize: unknown method");
    const double r = opt.closing_radius;
    if (!(r == 0 || (r >= 0.5 && r <= 4)))
        throw Error("voxelize: closing radius must be 0 or between 0.5 and 4 voxels, got " + number(r));
}

/// The output grid and the working grid around it, `extra` voxels wider on each side.
struct Grids {
    Grid out, work;
    std::int64_t extra = 0;
};

/// The output grid's cells cover the bounding box of the vertices the triangles use (its minimum on a cell
/// boundary) plus `pad` cells each side. The working grid adds a margin so that the border lies outside every wall
/// and every ball centre that matters.
Grids voxelize_grids(const Mesh& mesh, double h, const VoxelizeOptions& opt) {
    std::array<double, 3> lo{}, hi{};
    lo.fill(std::numeric_limits<double>::infinity());
    hi.fill(-std::numeric_limits<double>::infinity());
    for (const auto& t : mesh.triangles)
        for (std::uint32_t k : t)
            for (std::size_t a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], mesh.vertices[k][a]);
                hi[a] = std::max(hi[a], mesh.vertices[k][a]);
            }
    const double r = opt.closing_radius;
    const auto pad = static_cast<std::int64_t>(std::ceil(opt.padding_voxels));
    const std::int64_t margin = r > 0 ? static_cast<std::int64_t>(std::ceil(r)) + 3 : 1;
    Grids g;
    g.extra = std::max<std::int64_t>(0, margin - pad);
    constexpr double kMaxDim = double(1 << 28);
    for (std::size_t a = 0; a < 3; ++a) {
        const double cells = (hi[a] - lo[a]) / h;
        if (!(cells < kMaxDim))
            throw Error("voxelize: voxel size " + number(h) + " gives " + number(std::ceil(cells)) + " voxels along " +
                        std::string(1, "xyz"[a]) + " for a mesh " + number(hi[a] - lo[a]) +
                        " units wide (the limit is 2^28); use a larger voxel size");
        // An extent that is a whole number of voxels up to rounding (0.2 / 0.1 = 2.0000000000000018) is taken as one.
        const double whole = std::ceil(cells - 1e-9 * std::max(1.0, cells));
        g.out.dims[a] = std::max<std::int64_t>(1, static_cast<std::int64_t>(whole)) + 2 * pad;
        g.out.spacing[a] = h;
        g.out.origin[a] = lo[a] - (static_cast<double>(pad) - 0.5) * h;
        if (opt.anchor) {  // down onto the anchor's lattice, one voxel longer to keep the box covered
            const double at = (*opt.anchor)[a];
            if (!std::isfinite(at)) throw Error("voxelize: the anchor must be finite");
            g.out.origin[a] = at + h * std::floor((g.out.origin[a] - at) / h);
            g.out.dims[a] += 1;
        }
        g.work.dims[a] = g.out.dims[a] + 2 * g.extra;
        g.work.spacing[a] = h;
        g.work.origin[a] = g.out.origin[a] - static_cast<double>(g.extra) * h;
    }
    check_grid(g.out, 2, opt.max_bytes, "voxelize: the grid at voxel size " + number(h));
    check_grid(g.work, 2, opt.max_bytes, "voxelize: the working grid at voxel size " + number(h));
    return g;
}

/// The mesh as OpenVDB reads it: its vertices in the working grid's index space.
struct IndexMesh {
    std::vector<openvdb::Vec3d> points;
    const Mesh& mesh;
    IndexSpaceMesh adapter() const { return IndexSpaceMesh{points, mesh.triangles}; }
};

IndexMesh index_mesh(const Mesh& mesh, const Grid& work) {
    IndexMesh m{std::vector<openvdb::Vec3d>(mesh.vertices.size()), mesh};
    for (std::size_t i = 0; i < m.points.size(); ++i)
        for (std::size_t a = 0; a < 3; ++a)
            m.points[i][static_cast<int>(a)] = (mesh.vertices[i][a] - work.origin[a]) / work.spacing[a];
    return m;
}

/// closing_radius = 0: OpenVDB's signed distance, in narrow bands; its signed flood fill gives the tiles and
/// inactive voxels the interior sign, so the sign of every value says inside or outside. Fills v; returns the
/// number of inside voxels.
std::int64_t signed_distance_mask(const IndexMesh& m, const Grids& g, Volume& v, const Progress& progress) {
    const auto xform = openvdb::math::Transform::createLinearTransform(1.0);
    Interrupter interrupter(progress, 0.0, 0.8);
    const openvdb::FloatGrid::Ptr sdf =
        openvdb::tools::meshToVolume<openvdb::FloatGrid>(interrupter, m.adapter(), *xform, 2.0f, 2.0f);
    interrupter.rethrow();
    report(progress, 0.8);
    v.data.resize(static_cast<std::size_t>(g.out.voxel_count()));
    tbb::enumerable_thread_specific<openvdb::FloatGrid::ConstAccessor> accessors(
        [&] { return sdf->getConstAccessor(); });
    return write_mask(g.out, v.data.data(), g.extra, [&](std::int64_t x, std::int64_t y, std::int64_t z) {
        return accessors.local().getValue(
                   openvdb::Coord(static_cast<int>(x), static_cast<int>(y), static_cast<int>(z))) <= 0.0f;
    });
}

/// The voxel states of the closing method over the working grid, indexed by OpenVDB coordinates.
struct States {
    std::vector<std::uint8_t> state;
    std::int64_t wx, wy, wz;

    explicit States(const Grid& work)
        : state(static_cast<std::size_t>(work.voxel_count()), kOpen),
          wx(work.dims[0]),
          wy(work.dims[1]),
          wz(work.dims[2]) {}
    bool contains(const openvdb::Coord& c) const {
        return c.x() >= 0 && c.y() >= 0 && c.z() >= 0 && c.x() < wx && c.y() < wy && c.z() < wz;
    }
    std::uint8_t& operator[](const openvdb::Coord& c) {
        return state[static_cast<std::size_t>((static_cast<std::int64_t>(c.z()) * wy + c.y()) * wx + c.x())];
    }
};

/// The band voxels of the unsigned distance u, sorted out by step 1.
struct Band {
    std::vector<BallCentre> near;       // candidate ball centres: r < u <= r + 2
    std::vector<openvdb::Coord> close;  // walls within kSurfaceLayer of the surface
};

/// Step 1: marks the voxels with u <= r as walls; collects the candidate centres and the walls hugging the surface.
Band sort_band(const openvdb::FloatGrid& udf, States& st, float rf, float reach) {
    const std::vector<const FloatLeaf*> leaves = leaves_of(udf.tree());
    tbb::enumerable_thread_specific<Band> found;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves.size()), [&](const Range& br) {
        auto& mine = found.local();
        for (std::size_t i = br.begin(); i != br.end(); ++i)
            for (auto it = leaves[i]->cbeginValueOn(); it; ++it) {
                const openvdb::Coord c = it.getCoord();
                if (!st.contains(c)) continue;
                if (*it <= rf) {
                    st[c] = kWall;
                    if (*it <= kSurfaceLayer) mine.close.push_back(c);
                } else if (*it <= reach) {
                    mine.near.push_back({c.x(), c.y(), c.z(), *it});
                }
            }
    });
    Band band;
    for (auto& f : found) {
        band.near.insert(band.near.end(), f.near.begin(), f.near.end());
        band.close.insert(band.close.end(), f.close.begin(), f.close.end());
    }
    return band;
}

/// Step 2, first half: exact distances for the candidate centres (never larger than the true distance); those
/// at most r become walls.
void exact_distances(const TriangleTree& tree, std::vector<BallCentre>& near, States& st, float rf) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, near.size()), [&](const Range& br) {
        for (std::size_t i = br.begin(); i != br.end(); ++i) {
            BallCentre& e = near[i];
            const double d = tree.nearest(openvdb::Vec3d(e.x, e.y, e.z), e.radius + 1e-3);
            e.radius = static_cast<float>(d);
            if (static_cast<double>(e.radius) > d) e.radius = std::nextafter(e.radius, 0.0f);  // never larger
            if (e.radius <= rf) st[openvdb::Coord(e.x, e.y, e.z)] = kWall;
        }
    });
}

/// Step 3b: walls hugging the surface that no lattice ball reached. Steps from the nearest surface point s through
/// the voxel v to q = s + (r + 1)(v - s)/|v - s|. When no triangle comes nearer to q than v and q's nearest voxel
/// (which is exterior or covered), v is in q's empty ball and so outside as well. A voxel inside the surface never
/// passes: the segment from it to an outside q crosses the surface.
void cover_surface_walls(const TriangleTree& tree, const std::vector<openvdb::Coord>& close, States& st, double r) {
    std::vector<std::uint8_t> outside(close.size(), 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, close.size()), [&](const Range& br) {
        for (std::size_t i = br.begin(); i != br.end(); ++i) {
            if (st[close[i]] != kWall) continue;
            const openvdb::Vec3d p = close[i].asVec3d();
            openvdb::Vec3d s;
            const double d = tree.nearest(p, kSurfaceLayer + 1e-3, &s);
            if (!(d > 0) || d > kSurfaceLayer) continue;
            const openvdb::Vec3d q = s + (p - s) * ((r + 1) / d);
            const openvdb::Coord cq = openvdb::Coord::round(q);
            if (!st.contains(cq)) continue;
            const std::uint8_t sq = st[cq];
            if (sq != kExterior && sq != kCovered) continue;
            const double reach_q = std::max((p - q).length(), (cq.asVec3d() - q).length());
            outside[i] = !tree.any_within(q, reach_q);
        }
    });
    for (std::size_t i = 0; i < close.size(); ++i)
        if (outside[i]) st[close[i]] = kCovered;
}

/// closing_radius r > 0: steps 1-4 of the opening comment. Fills v; returns the number of inside voxels.
std::int64_t closing_mask(const IndexMesh& m, const Grids& g, double r, Volume& v, const Progress& progress) {
    // 1. Unsigned distance in a band of r + 2.5 voxels. OpenVDB's values are distances to some triangle, not
    //    always the nearest (its band expansion propagates candidate triangles; about 3% of band voxels come
    //    out up to ~0.4 voxel too far on the arm mesh), so they are upper bounds: those at most r are walls,
    //    and those up to r + 2 are recomputed exactly below.
    const auto xform = openvdb::math::Transform::createLinearTransform(1.0);
    const float band_width = static_cast<float>(r) + 2.5f;
    Interrupter interrupter(progress, 0.0, 0.45);
    const openvdb::FloatGrid::Ptr udf = openvdb::tools::meshToVolume<openvdb::FloatGrid>(
        interrupter, m.adapter(), *xform, band_width, 0.0f, openvdb::tools::UNSIGNED_DISTANCE_FIELD);
    interrupter.rethrow();
    report(progress, 0.45);
    States st(g.work);
    const float rf = static_cast<float>(r), reach = rf + 2.0f;
    Band band = sort_band(*udf, st, rf, reach);
    report(progress, 0.5);

    // 2. Exact distances for the voxels between r and r + 2; walls, then the exterior.
    const TriangleTree tree(m.points, m.mesh.triangles);
    exact_distances(tree, band.near, st, rf);
    report(progress, 0.6);
    fill_exterior(g.work, st.state.data(), progress, 0.6, 0.75);
    report(progress, 0.75);

    // 3. Balls around the exterior voxels near the surface.
    std::vector<BallCentre>& near = band.near;
    near.erase(std::remove_if(near.begin(), near.end(),
                              [&](const BallCentre& e) { return st[openvdb::Coord(e.x, e.y, e.z)] != kExterior; }),
               near.end());
    cover_balls(g.work, st.state.data(), near, reach);
    report(progress, 0.85);
    cover_surface_walls(tree, band.close, st, r);  // 3b
    report(progress, 0.9);

    // 4. Inside = neither exterior nor covered.
    v.data.resize(static_cast<std::size_t>(g.out.voxel_count()));
    const std::int64_t wx = st.wx, wy = st.wy;
    return write_mask(g.out, v.data.data(), g.extra, [&](std::int64_t x, std::int64_t y, std::int64_t z) {
        const std::uint8_t s = st.state[static_cast<std::size_t>((z * wy + y) * wx + x)];
        return s == kOpen || s == kWall;
    });
}

/// The recursive fill of VoxelizeMethod::Winding (winding_mask). `known` (optional, on the output grid): voxels
/// already known to be inside (Auto's flood mask, which the winding mask is united with). They are set inside
/// without their |w|, and a block wholly known is filled without evaluating anything in it; every other voxel is
/// decided exactly as without `known` (the same lattice values, the same block tests), so the union is unchanged.
class WindingFill {
public:
    WindingFill(const WindingNumber& wn, const TriangleTree& tree, const Grid& out, std::uint8_t* dst,
                const std::uint8_t* known = nullptr)
        : wn_(wn), tree_(tree), nx_(out.dims[0]), ny_(out.dims[1]), nz_(out.dims[2]), dst_(dst), known_(known) {}

    /// True when every voxel of the block [x0, x0 + s)^3 (clipped to the grid) is known to be inside.
    bool all_known(std::int64_t x0, std::int64_t y0, std::int64_t z0, std::int64_t s) const {
        if (!known_) return false;
        const std::int64_t x1 = std::min(nx_, x0 + s), y1 = std::min(ny_, y0 + s), z1 = std::min(nz_, z0 + s);
        for (std::int64_t z = z0; z < z1; ++z)
            for (std::int64_t y = y0; y < y1; ++y) {
                const std::uint8_t* row = known_ + (z * ny_ + y) * nx_;
                if (std::find(row + x0, row + x1, std::uint8_t(0)) != row + x1) return false;
            }
        return true;
    }

    /// Whether lattice point (i, j, k) of a split block (0..2 each) is a corner of a child k (bit 0: +x, bit 1: +y,
    /// bit 2: +z) with need[k].
    static bool needed(int i, int j, int k, const bool need[8]) {
        for (int d = std::max(0, k - 1); d <= std::min(1, k); ++d)
            for (int b = std::max(0, j - 1); b <= std::min(1, j); ++b)
                for (int a = std::max(0, i - 1); a <= std::min(1, i); ++a)
                    if (need[a | b << 1 | d << 2]) return true;
        return false;
    }

    bool known(std::int64_t x, std::int64_t y, std::int64_t z) const {
        return known_ && known_[(z * ny_ + y) * nx_ + x] != 0;
    }

    float at(std::int64_t x, std::int64_t y, std::int64_t z) const {
        return static_cast<float>(
            std::abs(wn_({static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)})));
    }

    /// Fills the voxels of the block [x0, x0 + s)^3 (clipped to the grid) whose corners (x0 + s * (k & 1),
    /// y0 + s * (k >> 1 & 1), z0 + s * (k >> 2)) have |w| = c[k]; returns the number of inside voxels.
    std::int64_t fill(std::int64_t x0, std::int64_t y0, std::int64_t z0, std::int64_t s, const float c[8]) const {
        if (x0 >= nx_ || y0 >= ny_ || z0 >= nz_) return 0;
        if (all_known(x0, y0, z0, s)) return fill_block(x0, y0, z0, s, true);
        if (s == 1) {
            const bool in = c[0] >= 0.5f;
            dst_[(z0 * ny_ + y0) * nx_ + x0] = in ? 1 : 0;
            return in;
        }
        bool any_in = false, any_out = false, close = false;
        for (int k = 0; k < 8; ++k) {
            (c[k] >= 0.5f ? any_in : any_out) = true;
            close = close || std::abs(c[k] - 0.5f) < kWindingMargin;
        }
        const double half = 0.5 * static_cast<double>(s);
        if (!(any_in && any_out) && !close &&
            !tree_.any_within(openvdb::Vec3d(static_cast<double>(x0) + half, static_cast<double>(y0) + half,
                                             static_cast<double>(z0) + half),
                              std::sqrt(3.0) * half + 0.5)) {
            return fill_block(x0, y0, z0, s, any_in);
        }
        if (s == 2) {  // the block's eight voxels: (x0, y0, z0) known, the other seven evaluated
            const std::int64_t x1 = std::min(nx_, x0 + 2), y1 = std::min(ny_, y0 + 2), z1 = std::min(nz_, z0 + 2);
            std::int64_t count = 0;
            for (std::int64_t z = z0; z < z1; ++z)
                for (std::int64_t y = y0; y < y1; ++y)
                    for (std::int64_t x = x0; x < x1; ++x) {
                        const bool in = known(x, y, z) || (x == x0 && y == y0 && z == z0 ? c[0] : at(x, y, z)) >= 0.5f;
                        dst_[(z * ny_ + y) * nx_ + x] = in ? 1 : 0;
                        count += in;
                    }
            return count;
        }
        // |w| on the 3 x 3 x 3 lattice of step s / 2: the eight corners known, the rest evaluated where a child
        // needs them (not for children wholly outside the grid or wholly known to be inside: never read).
        const std::int64_t h = s / 2;
        bool need[8];
        for (int k = 0; k < 8; ++k) {
            const std::int64_t cx = x0 + (k & 1) * h, cy = y0 + ((k >> 1) & 1) * h, cz = z0 + (k >> 2) * h;
            need[k] = cx < nx_ && cy < ny_ && cz < nz_ && !all_known(cx, cy, cz, h);
        }
        float w[27];
        for (int k = 0; k < 3; ++k)
            for (int j = 0; j < 3; ++j)
                for (int i = 0; i < 3; ++i) {
                    float& wv = w[9 * k + 3 * j + i];
                    if (i != 1 && j != 1 && k != 1) {
                        wv = c[(i >> 1) | (j & 2) | ((k >> 1) << 2)];
                    } else {
                        wv = needed(i, j, k, need) ? at(x0 + i * h, y0 + j * h, z0 + k * h) : 0.0f;
                    }
                }
        std::int64_t count = 0;
        for (int k = 0; k < 8; ++k) {
            const int a = k & 1, b = (k >> 1) & 1, d = k >> 2;
            float cc[8];
            for (int m = 0; m < 8; ++m) cc[m] = w[9 * (d + (m >> 2)) + 3 * (b + ((m >> 1) & 1)) + a + (m & 1)];
            count += fill(x0 + a * h, y0 + b * h, z0 + d * h, h, cc);
        }
        return count;
    }

    static constexpr float kWindingMargin = 0.1f;

private:
    /// Sets the block [x0, x0 + s)^3 (clipped to the grid) to `in`; returns its inside voxels.
    std::int64_t fill_block(std::int64_t x0, std::int64_t y0, std::int64_t z0, std::int64_t s, bool in) const {
        const std::int64_t x1 = std::min(nx_, x0 + s), y1 = std::min(ny_, y0 + s), z1 = std::min(nz_, z0 + s);
        for (std::int64_t z = z0; z < z1; ++z)
            for (std::int64_t y = y0; y < y1; ++y)
                std::fill(dst_ + (z * ny_ + y) * nx_ + x0, dst_ + (z * ny_ + y) * nx_ + x1, in ? 1 : 0);
        return in ? (x1 - x0) * (y1 - y0) * (z1 - z0) : 0;
    }

    const WindingNumber& wn_;
    const TriangleTree& tree_;
    std::int64_t nx_, ny_, nz_;
    std::uint8_t* dst_;
    const std::uint8_t* known_;
};

/// The blocks of side kStride that winding_mask fills, and the lattice of their corners.
struct WindingBlocks {
    static constexpr std::int64_t kStride = 8;
    std::int64_t bx, by, bz, cx, cy, cz;

    explicit WindingBlocks(const Grid& out)
        : bx((out.dims[0] + kStride - 1) / kStride),
          by((out.dims[1] + kStride - 1) / kStride),
          bz((out.dims[2] + kStride - 1) / kStride),
          cx(bx + 1),
          cy(by + 1),
          cz(bz + 1) {}
    std::int64_t blocks() const { return bx * by * bz; }
    std::int64_t corners() const { return cx * cy * cz; }
    /// Corner k (bit 0: +x, bit 1: +y, bit 2: +z) of block b.
    std::size_t corner(std::int64_t b, int k) const {
        const std::int64_t jx = b % bx, jy = (b / bx) % by, jz = b / (bx * by);
        return static_cast<std::size_t>(((jz + (k >> 2)) * cy + jy + ((k >> 1) & 1)) * cx + jx + (k & 1));
    }
};

/// |w| at the block corners that some block not wholly known to be inside needs (the others are left at 0 and
/// never read).
std::vector<float> winding_corners(const WindingFill& filler, const WindingBlocks& B) {
    constexpr std::int64_t S = WindingBlocks::kStride;
    std::vector<std::uint8_t> open_block(static_cast<std::size_t>(B.blocks()));  // not wholly known inside
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, B.blocks()), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t b = r.begin(); b != r.end(); ++b)
            open_block[static_cast<std::size_t>(b)] =
                !filler.all_known(b % B.bx * S, (b / B.bx) % B.by * S, b / (B.bx * B.by) * S, S);
    });
    // Corner (x, y, z) belongs to the blocks (x - a, y - b, z - d), a, b, d in {0, 1}, that exist.
    auto needed = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
        for (std::int64_t d = std::max<std::int64_t>(0, z - 1); d <= std::min(z, B.bz - 1); ++d)
            for (std::int64_t b = std::max<std::int64_t>(0, y - 1); b <= std::min(y, B.by - 1); ++b)
                for (std::int64_t a = std::max<std::int64_t>(0, x - 1); a <= std::min(x, B.bx - 1); ++a)
                    if (open_block[static_cast<std::size_t>((d * B.by + b) * B.bx + a)]) return true;
        return false;
    };
    std::vector<float> corner(static_cast<std::size_t>(B.corners()), 0.0f);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, B.cz * B.cy), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t zy = r.begin(); zy != r.end(); ++zy)
            for (std::int64_t x = 0; x < B.cx; ++x)
                if (needed(x, zy % B.cy, zy / B.cy))
                    corner[static_cast<std::size_t>(zy * B.cx + x)] =
                        filler.at(x * S, (zy % B.cy) * S, (zy / B.cy) * S);
    });
    return corner;
}

/// VoxelizeMethod::Winding: inside when |w| >= 0.5 at the voxel centre (w the generalized winding number). |w| is
/// evaluated on the lattice of every 8th voxel (block corners, some just past the grid's far end). A block whose
/// eight corners agree, none within 0.1 of the threshold, and whose circumscribed ball (plus half a voxel) no
/// triangle enters takes their answer: w is harmonic off the surface, so it cannot swing across 0.5 and back
/// inside such a block. Any other block is split in eight (|w| evaluated at the 19 new lattice points) and its
/// children tested the same way, down to single voxels. Fills v; returns the number of inside voxels.
/// `known` (Auto: the flood's mask, on `out`): voxels taken as inside without their |w| (WindingFill).
std::int64_t winding_mask(const Mesh& mesh, const Grid& out, Volume& v, const Progress& progress,
                          const std::uint8_t* known = nullptr) {
    // The mesh in the output grid's index space: voxel centres at whole coordinates.
    Mesh local;
    local.triangles = mesh.triangles;
    local.vertices.resize(mesh.vertices.size());
    std::vector<openvdb::Vec3d> points(mesh.vertices.size());
    for (std::size_t i = 0; i < points.size(); ++i)
        for (std::size_t a = 0; a < 3; ++a) {
            local.vertices[i][a] = (mesh.vertices[i][a] - out.origin[a]) / out.spacing[a];
            points[i][static_cast<int>(a)] = local.vertices[i][a];
        }
    const WindingNumber wn(local);
    const TriangleTree tree(points, local.triangles);
    report(progress, 0.05);
    v.data.assign(static_cast<std::size_t>(out.voxel_count()), 0);
    const WindingFill filler(wn, tree, out, v.data.data(), known);
    const WindingBlocks B(out);
    const std::vector<float> corner = winding_corners(filler, B);
    report(progress, 0.15);

    // Blocks in about ten slabs of block rows, so that progress is reported (and a cancel seen) between them
    // from the calling thread.
    constexpr std::int64_t S = WindingBlocks::kStride;
    const std::int64_t blocks = B.blocks(), chunk = std::max<std::int64_t>(B.bx * B.by, blocks / 10);
    std::int64_t inside = 0;
    for (std::int64_t first = 0; first < blocks; first += chunk) {
        inside += tbb::parallel_reduce(
            tbb::blocked_range<std::int64_t>(first, std::min(blocks, first + chunk), 1), std::int64_t(0),
            [&](const tbb::blocked_range<std::int64_t>& r, std::int64_t count) {
                for (std::int64_t b = r.begin(); b != r.end(); ++b) {
                    float c[8];
                    for (int k = 0; k < 8; ++k) c[k] = corner[B.corner(b, k)];
                    count += filler.fill(b % B.bx * S, (b / B.bx) % B.by * S, b / (B.bx * B.by) * S, S, c);
                }
                return count;
            },
            [](std::int64_t a, std::int64_t b) { return a + b; });
        report(progress, 0.15 + 0.8 * static_cast<double>(std::min(blocks, first + chunk)) / static_cast<double>(blocks));
    }
    return inside;
}

}  // namespace

Volume voxelize(const Mesh& mesh, double voxel_size, const VoxelizeOptions& opt, const Progress& progress) {
    check_mesh(mesh, "voxelize");
    const double h = voxel_size;
    check_options(h, opt);
    const Grids g = voxelize_grids(mesh, h, opt);
    Volume v;
    v.grid = g.out;
    v.dtype = DType::UInt8;
    report(progress, 0.0);
    // Auto on a mesh that is not closed: the union of both masks (the flood's losses are interiors the exterior
    // leaked into, the winding number's are connections the closing makes across narrow gaps; neither adds much).
    const bool open = opt.method == VoxelizeMethod::Auto && !is_closed(mesh);
    const bool flood = opt.method == VoxelizeMethod::Flood || opt.method == VoxelizeMethod::Auto;
    const bool winding = opt.method == VoxelizeMethod::Winding || open;
    const double split = flood && winding ? 0.5 : 1.0;
    std::int64_t inside = 0;
    if (flood) {
        const Progress part = !progress || split == 1.0 ? progress : Progress([&](double x) { return progress(split * x); });
        const IndexMesh m = index_mesh(mesh, g.work);
        inside = opt.closing_radius == 0 ? signed_distance_mask(m, g, v, part)
                                         : closing_mask(m, g, opt.closing_radius, v, part);
    }
    if (winding) {
        const Progress part = !progress || split == 1.0
                                  ? progress
                                  : Progress([&](double x) { return progress(split + (1 - split) * x); });
        if (!flood) {
            inside = winding_mask(mesh, g.out, v, part);
        } else {
            Volume w;  // the flood's inside voxels are known: only the others need |w|
            winding_mask(mesh, g.out, w, part, v.data.data());
            inside = 0;
            for (std::size_t i = 0; i < v.data.size(); ++i) {
                v.data[i] |= w.data[i];
                inside += v.data[i];
            }
        }
    }
    if (inside == 0)
        throw Error("voxelize: the mesh encloses no voxel centre at voxel size " + number(h) +
                    " (an open surface, or a voxel size too large for the mesh)");
    report(progress, 1.0);
    return v;
}

Volume voxelize(const Mesh& mesh, double voxel_size, double padding_voxels, const Progress& progress) {
    VoxelizeOptions opt;
    opt.padding_voxels = padding_voxels;
    return voxelize(mesh, voxel_size, opt, progress);
}

}  // namespace volrig

// mesh/triangle_tree.hpp: exact distances from points to a triangle mesh, for voxelize's closing method
// (mesh/voxelize.cpp) and the winding-number fill's test for a block near the surface (mesh/winding_mask.cpp).
// Internal to the core; not installed.
#pragma once

#include <openvdb/openvdb.h>
#include <openvdb/math/Proximity.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace volrig::mesh_detail {

/// Exact distance from a point to the nearest triangle: a bounding-volume hierarchy (median splits, up to four
/// triangles per leaf) searched nearest-first with the best distance so far as the bound; a leaf's triangle whose
/// plane lies beyond the bound is passed over without its closest point (a quarter less time in voxelize's exact
/// distances, the same answers).
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
        planes_.resize(triangles.size());
        for (std::size_t k = 0; k < triangles.size(); ++k) {
            const auto& t = triangles[order_[k]];
            const openvdb::Vec3d normal = (points[t[1]] - points[t[0]]).cross(points[t[2]] - points[t[0]]);
            const double length = normal.length();
            if (length > 0 && std::isfinite(length))
                planes_[k] = {normal / length, (normal / length).dot(points[t[0]])};
        }
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
                    if (beyond(planes_[k], p, bound2)) continue;
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

    /// A triangle's plane (unit normal n, n . x = d; n = 0 for a triangle without area: never beyond).
    struct Plane {
        openvdb::Vec3d n{0, 0, 0};
        double d = 0;
    };

    /// True when the triangle's plane, and so the triangle, is farther from p than sqrt(bound2) by more than
    /// kPlaneSlack: its closest point could not come nearer than the bound (nor equal it), so skipping it changes
    /// no answer. The slack (a millionth of a voxel, the coordinates being grid indices) is far above the rounding
    /// of the two distances (about 1e-16 of the coordinates).
    static bool beyond(const Plane& plane, const openvdb::Vec3d& p, double bound2) {
        const double h = std::abs(plane.n.dot(p) - plane.d) - kPlaneSlack;
        return h > 0 && h * h > bound2;
    }

    static constexpr double kPlaneSlack = 1e-6;
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
    std::vector<Plane> planes_;  // in order_'s order
};

}  // namespace volrig::mesh_detail

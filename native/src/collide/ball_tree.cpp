#include "collide/ball_tree.hpp"

#include <algorithm>
#include <cmath>

namespace volrig::collide_detail {

namespace {

double distance(const Vec3& a, const Vec3& b) {
    return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/// The node over order[begin, end): centred on the middle of the centres' box; returns the widest axis.
int fill_node(BallNode& n, const std::vector<Vec3>& centre, const std::vector<double>& radius,
              const std::vector<std::uint32_t>& order, std::uint32_t begin, std::uint32_t end) {
    Vec3 lo = centre[order[begin]], hi = lo;
    for (std::uint32_t k = begin; k < end; ++k)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], centre[order[k]][a]);
            hi[a] = std::max(hi[a], centre[order[k]][a]);
        }
    for (int a = 0; a < 3; ++a) n.centre[a] = 0.5 * (lo[a] + hi[a]);
    n.begin = begin;
    n.end = end;
    for (std::uint32_t k = begin; k < end; ++k) {
        const double d = distance(n.centre, centre[order[k]]);
        n.reach = std::max(n.reach, d);
        n.bound = std::max(n.bound, d + radius[order[k]]);
        n.rmax = std::max(n.rmax, radius[order[k]]);
    }
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (hi[a] - lo[a] > hi[axis] - lo[axis]) axis = a;
    return axis;
}

std::int32_t build(BallTree& t, const std::vector<Vec3>& centre, const std::vector<double>& radius,
                   std::uint32_t begin, std::uint32_t end) {
    const auto id = static_cast<std::int32_t>(t.nodes.size());
    t.nodes.emplace_back();
    const int axis = fill_node(t.nodes.back(), centre, radius, t.order, begin, end);
    if (end - begin <= kLeafSize) return id;
    const std::uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(t.order.begin() + begin, t.order.begin() + mid, t.order.begin() + end,
                     [&](std::uint32_t a, std::uint32_t b) {
                         return centre[a][axis] < centre[b][axis] || (centre[a][axis] == centre[b][axis] && a < b);
                     });
    const std::int32_t left = build(t, centre, radius, begin, mid);
    const std::int32_t right = build(t, centre, radius, mid, end);
    t.nodes[static_cast<std::size_t>(id)].child[0] = left;
    t.nodes[static_cast<std::size_t>(id)].child[1] = right;
    return id;
}

}  // namespace

BallTree build_ball_tree(const std::vector<Vec3>& centre, const std::vector<double>& radius,
                         std::vector<std::uint32_t> members) {
    BallTree t;
    members.erase(std::remove_if(members.begin(), members.end(), [&](std::uint32_t i) { return !(radius[i] > 0); }),
                  members.end());
    if (members.empty()) return t;
    t.order = std::move(members);
    t.nodes.reserve(2 * t.order.size() / kLeafSize + 2);
    build(t, centre, radius, 0, static_cast<std::uint32_t>(t.order.size()));
    return t;
}

}  // namespace volrig::collide_detail

// collide/ball_tree.hpp: a binary tree of bounding spheres over one field's reconstruction balls, in rest world
// coordinates (docs/ALGORITHMS.md §8). A field moves rigidly, so the tree bounds its balls in every pose.
#pragma once

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

namespace volrig::collide_detail {

using Vec3 = std::array<double, 3>;

struct BallNode {
    Vec3 centre{0, 0, 0};
    double reach = 0;   ///< largest distance from `centre` to a member ball's centre
    double bound = 0;   ///< largest distance from `centre` to a member ball's surface (unscaled radii)
    double rmax = 0;    ///< largest member radius (unscaled)
    std::int32_t child[2] = {-1, -1};  ///< -1: a leaf
    std::uint32_t begin = 0, end = 0;  ///< members: BallTree::order[begin, end)

    bool leaf() const { return child[0] < 0; }
    /// Bounding radius with every radius scaled by at most `scale` (1: the unscaled bound).
    double radius(double scale) const { return scale == 1.0 ? bound : reach + rmax * scale; }
};

struct BallTree {
    std::vector<BallNode> nodes;       ///< nodes[0] is the root (absent when the field has no ball)
    std::vector<std::uint32_t> order;  ///< sphere indices, each leaf's members contiguous

    bool empty() const { return nodes.empty(); }
    std::size_t memory_bytes() const {
        return nodes.capacity() * sizeof(BallNode) + order.capacity() * sizeof(std::uint32_t);
    }
};

/// A dual descent's step for a node pair that may touch: opens the node with the larger bound (a leaf never) and
/// pushes its children paired with the other node.
inline void open_larger(std::vector<std::pair<std::int32_t, std::int32_t>>& stack, const BallNode& na, std::int32_t ia,
                        double ra, const BallNode& nb, std::int32_t ib, double rb) {
    if (nb.leaf() || (!na.leaf() && ra >= rb)) {
        stack.emplace_back(na.child[0], ib);
        stack.emplace_back(na.child[1], ib);
    } else {
        stack.emplace_back(ia, nb.child[0]);
        stack.emplace_back(ia, nb.child[1]);
    }
}

/// Builds the tree over `members` (sphere indices into `centre` and `radius`): median splits along the widest axis
/// of the centres, leaves of at most kLeafSize balls. Balls of radius 0 hold no lattice point and are left out.
BallTree build_ball_tree(const std::vector<Vec3>& centre, const std::vector<double>& radius,
                         std::vector<std::uint32_t> members);

constexpr std::uint32_t kLeafSize = 4;

}  // namespace volrig::collide_detail

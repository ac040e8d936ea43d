// rig/autorig/node_tree.hpp: the level-set tree's nodes as a rooted tree: spur pruning, extremities by significance,
// paths between nodes (internal to the core; tested alone in tests/native/test_rig_autorig.cpp).
#pragma once

#include <utility>
#include <vector>

#include "rig/autorig/shape_tree.hpp"

namespace volrig::rig_detail {

class NodeTree {
public:
    /// Nodes at `pos` with radii `rad`, joined by the (tree) `edges`; every node kept, rooted at the largest.
    NodeTree(std::vector<Vec> pos, std::vector<double> rad, const std::vector<std::array<std::uint32_t, 2>>& edges);

    std::size_t size() const { return pos_.size(); }
    const Vec& at(std::uint32_t v) const { return pos_[v]; }
    double radius(std::uint32_t v) const { return rad_[v]; }
    /// How flat the object is across node v (RigContext::cross_section_ratio: 1 round, more for a sheet; 1 when
    /// not given).
    double sheet(std::uint32_t v) const { return sheet_.empty() ? 1.0 : sheet_[v]; }
    void set_sheet(std::vector<double> sheet) { sheet_ = std::move(sheet); }
    std::uint32_t root() const { return root_; }
    std::uint32_t parent(std::uint32_t v) const { return parent_[v]; }
    std::uint32_t depth(std::uint32_t v) const { return depth_[v]; }
    const std::vector<std::uint32_t>& children(std::uint32_t v) const { return children_[v]; }
    /// Kept nodes in BFS order from the root.
    const std::vector<std::uint32_t>& order() const { return order_; }
    const std::vector<std::uint8_t>& kept() const { return kept_; }

    /// Roots the kept nodes at `root`: parent pointers, BFS order, depth.
    void reroot(std::uint32_t root);
    /// Kept leaves (the root excluded).
    std::vector<std::uint32_t> leaves() const;
    /// Spur pruning: a leaf branch (leaf up to its first junction) goes when the leaf's ball lies inside the ball,
    /// scaled by `scale`, of the junction or of any node between it and the root; repeated until stable. Of the
    /// branches of one junction, the one whose tip reaches farthest always stays.
    void prune(double scale);
    /// When the root (the thickest node) is an end of the tree whose centre lies outside the ball of the first
    /// junction below it (a part on a neck, or a big head on the shoulders whose ball reaches into theirs), reroots
    /// at that junction, so that end is a leaf and counts as an extremity: a head thicker than the trunk (a
    /// mouse's, a child's, a cartoon's) is the end of a branch like any other. Nothing changes on a path (no
    /// junction), an inner root, or a thick end that is the body itself (the junction's ball holds its centre).
    /// Balls apart was asked before 2026-12-08: a crouching boy's big head, its ball reaching into the
    /// shoulders', stayed the root and no extremity, and his right hand was read as the head.
    void root_off_an_end();
    /// When the kept nodes form a path, reroots it at its thicker end (its bones then run outward from there).
    void root_path_at_thicker_end();
    /// Leaves by descending significance: each leaf's branch in the longest-path decomposition of the rooted tree
    /// attaches at a node; the significance is how far the leaf lies outside the balls of that node and of every
    /// node between it and the root (the body it sticks out of, however thin the node it hangs from).
    std::vector<std::pair<double, std::uint32_t>> extremities() const;

    std::uint32_t lca(std::uint32_t a, std::uint32_t b) const;
    /// The node on all three paths between a, b and c.
    std::uint32_t median(std::uint32_t a, std::uint32_t b, std::uint32_t c) const;
    /// Nodes of the path from a to b, both included.
    std::vector<std::uint32_t> path(std::uint32_t a, std::uint32_t b) const;
    /// Size (hi - lo per axis) of the bounding box of the given nodes' positions; zero for none.
    Vec box_size(const std::vector<std::uint32_t>& nodes) const;
    /// Diagonal of that box.
    double extent(const std::vector<std::uint32_t>& nodes) const;
    double mean_radius(const std::vector<std::uint32_t>& nodes) const;
    /// Length of the polyline through the given nodes' positions.
    double length(const std::vector<std::uint32_t>& nodes) const;
    /// The point `share` (0..1) of the way along that polyline.
    Vec point_along(const std::vector<std::uint32_t>& nodes, double share) const;
    /// A path from its first node out to its node farthest (straight line) from there, two nodes at least: the
    /// level-set tree of a sheet (a wing, a tail's fin) runs around its border, so the leaf a path ends at may lie
    /// back near where it started, past the part's tip.
    std::vector<std::uint32_t> out_to_farthest(std::vector<std::uint32_t> path) const;
    /// A leg's path from the trunk without the nodes before it reaches its own side of the body: `across` (unit)
    /// points to the leg's side, `mid` is the body's mid-plane offset along it. When the path's root lies on the
    /// other side and the path crosses the mid-plane within the first half of its length (through the trunk's
    /// medial sheet, or around a ring: a stick figure's pelvis), the nodes between the root and the first node
    /// from which on the path stays on its own side go: they are trunk, and their arc would lengthen the leg's
    /// first bones and put its hip on the other side. Not the arms: on the shared characters it changed the
    /// five-marker rigs alone (3.13 -> 3.08) and the bat (6.73 -> 6.69), and on the Visible Human's 8 mm slices,
    /// arms raised, one slice phase lost a wrist the bones had found (11 -> 10 of 12 within 30 mm).
    std::vector<std::uint32_t> from_own_side(std::vector<std::uint32_t> path, const Vec& across, double mid) const;
    /// Mean radius of the few nodes nearest an end of a path (its thickness there).
    double end_radius(std::uint32_t end) const;
    /// The median of sheet() over path[lo, hi) (the upper one of an even count; 1, round, for none).
    double median_sheet(const std::vector<std::uint32_t>& path, std::size_t lo, std::size_t hi) const;

private:
    std::vector<Vec> pos_;
    std::vector<double> rad_;
    std::vector<double> sheet_;
    std::vector<std::vector<std::uint32_t>> adj_;
    std::vector<std::uint8_t> kept_;
    std::uint32_t root_ = 0;
    std::vector<std::uint32_t> parent_, order_, depth_;
    std::vector<std::vector<std::uint32_t>> children_;
};

}  // namespace volrig::rig_detail

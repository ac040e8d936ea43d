// rig/autorig/rig_builder.hpp: what the templates share: the context they read (object, points, node tree) and the
// builder that turns chains of nodes cut at joints into named bones (internal to the core).
#pragma once

#include <string>
#include <unordered_map>
#include <vector>

#include "rig/autorig/chain_fit.hpp"
#include "rig/autorig/node_tree.hpp"
#include "volrig/rig.hpp"

namespace volrig::rig_detail {

struct RigContext {
    const Grid& grid;
    const std::uint8_t* mask;
    const PointSet& pts;
    const NodeTree& tree;
    const std::vector<std::uint32_t>& rep;  ///< per node: the skeleton point a joint on it sits on

    /// The nodes' 4-D samples (position, radius).
    Chain4 samples(const std::vector<std::uint32_t>& nodes) const;
    /// How far from `from` along the unit vector `dir` the object reaches without a gap, from `start` up to
    /// `limit` (world units), in steps of half the finest spacing; `start` itself when the next step leaves it.
    double reach_inside(const Vec& from, const Vec& dir, double start, double limit) const;
    /// How flat the object's cross-section through `at` across the unit vector `dir` is: the ratio of its long to
    /// its short standard deviation (1 for a round limb, the width over the thickness for a sheet), over the piece
    /// connected to `at` within `reach` of it (a disc: a limb lying against the trunk leaks into it no farther). 1
    /// when `at` lies outside the object.
    double cross_section_ratio(const Vec& at, const Vec& dir, double reach) const;
};

/// The index of the bone named `name` in `rig`, or -1.
std::int32_t bone_index(const Rig& rig, const std::string& name);
/// Joint `end` (0: head, 1: tail) of bone b as a vector.
Vec bone_end(const Rig& rig, std::size_t b, int end);
/// Moves joint j to q; it is a free joint then (joint_points -1).
void move_joint(Rig& rig, std::int32_t j, const Vec& q);
/// Moves the head of bone b out along the bone's line (away from its tail), as far as the object reaches, so that
/// the bone is `want` long; nothing when it is that long already.
void lengthen_proximal(const RigContext& c, Rig& rig, std::size_t b, double want);

class RigBuilder {
public:
    explicit RigBuilder(const RigContext& c) : c_(c) {}
    /// Adds the bones of a chain of nodes cut at `cuts` (indices into `nodes`), named names[0..]; the first bone's
    /// parent is `parent` when given, else the bone ending (else the first bone starting) at the chain's first joint.
    void chain(const std::vector<std::uint32_t>& nodes, const std::vector<std::size_t>& cuts,
               const std::vector<std::string>& names, std::int32_t parent = -1);
    /// The bone whose span of its chain holds `node`, or -1.
    std::int32_t bone_of(std::uint32_t node) const;
    /// The bone a part hanging from `node` moves with: bone_of(node), or the next bone when the node lies within
    /// `reach` of that bone's tail and exactly one bone starts there (a part at an elbow goes with the forearm
    /// wherever the cut fell among the nodes around it), or -1.
    std::int32_t attach_bone(std::uint32_t node, double reach) const;
    const Rig& rig() const { return rig_; }
    /// The rig of the given kind, its end joints (tails no bone starts from) moved outward along their bone to the
    /// object's surface, up to twice the end point's radius.
    Rig finish(const std::string& kind);

private:
    std::int32_t joint(std::uint32_t node);

    const RigContext& c_;
    Rig rig_;
    std::unordered_map<std::uint32_t, std::int32_t> joint_of_node_;
    std::unordered_map<std::int32_t, std::int32_t> bone_ending_at_;    // joint -> bone whose tail it is
    std::unordered_map<std::int32_t, std::int32_t> bone_starting_at_;  // joint -> first bone with that head
    std::unordered_map<std::uint32_t, std::int32_t> bone_of_node_;
};

/// Bone names of a chain: base, base.001, base.002, ... (Blender's numbering).
std::vector<std::string> numbered_names(const std::string& base, std::size_t count);

}  // namespace volrig::rig_detail

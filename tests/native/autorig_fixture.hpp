// autorig_fixture.hpp: what the autorig stage tests (test_rig_autorig*.cpp) share: small masks, skeleton points and
// their trees, as a RigContext.
#pragma once

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>

#include "rig/autorig/chain_fit.hpp"
#include "rig/autorig/coarse.hpp"
#include "rig/autorig/node_tree.hpp"
#include "rig/autorig/shape_tree.hpp"
#include "rig/autorig/templates.hpp"

using namespace volrig;
using namespace volrig::rig_detail;

namespace {

/// A tree of nodes drawn as polylines: each limb starts at an existing node and runs to a point in steps of
/// about 1, with radii interpolated from r0 to r1.
struct Figure {
    std::vector<Vec> pos;
    std::vector<double> rad;
    std::vector<std::array<std::uint32_t, 2>> edges;

    explicit Figure(const Vec& root, double r) : pos{root}, rad{r} {}
    /// Returns the last node of the limb.
    std::uint32_t limb(std::uint32_t from, const Vec& to, double r0, double r1) {
        const Vec a = pos[from];
        const int steps = std::max(1, static_cast<int>(std::lround((to - a).norm())));
        std::uint32_t prev = from;
        for (int s = 1; s <= steps; ++s) {
            const double t = static_cast<double>(s) / steps;
            pos.push_back(a + t * (to - a));
            rad.push_back(r0 + t * (r1 - r0));
            const auto cur = static_cast<std::uint32_t>(pos.size() - 1);
            edges.push_back({prev, cur});
            prev = cur;
        }
        return prev;
    }
    NodeTree tree() const { return NodeTree(pos, rad, edges); }
};

/// A stick figure standing along +z: pelvis at the origin, chest at z = 30, head to z = 45, arms from the chest
/// out along +-x and down, legs from the pelvis down to z = -45 (thicker than the arms). The head's tip node is
/// returned in `head`.
inline Figure stick_figure(std::uint32_t& head) {
    Figure f(Vec(0, 0, 0), 8.0);
    const std::uint32_t chest = f.limb(0, Vec(0, 0, 30), 8, 7);
    head = f.limb(f.limb(chest, Vec(0, 0, 36), 4, 4), Vec(0, 0, 45), 5, 4);
    for (double s : {-1.0, 1.0}) {
        const std::uint32_t elbow = f.limb(f.limb(chest, Vec(s * 10, 0, 30), 3, 3), Vec(s * 18, 0, 12), 2.5, 2.5);
        f.limb(elbow, Vec(s * 20, 0, -5), 2, 1.5);
        f.limb(f.limb(0, Vec(s * 6, 0, -22), 4.5, 4), Vec(s * 6, 0, -45), 4, 3);
    }
    return f;
}

/// A figure's nodes as skeleton points at their rounded positions, in a solid grid of the given size.
struct Solid {
    Grid g;
    std::vector<std::uint8_t> mask;
    std::vector<std::int32_t> ijk;
    std::vector<float> r;
    std::vector<std::uint32_t> rep;
    NodeTree tree;
    PointSet pts;

    Solid(const Figure& f, const std::array<std::int64_t, 3>& dims) : tree(f.tree()) {
        g.dims = dims;
        mask.assign(static_cast<std::size_t>(g.voxel_count()), 1);
        for (std::size_t k = 0; k < f.pos.size(); ++k) {
            for (int a = 2; a >= 0; --a) ijk.push_back(static_cast<std::int32_t>(std::lround(f.pos[k][a])));
            r.push_back(static_cast<float>(f.rad[k]));
            rep.push_back(static_cast<std::uint32_t>(k));
        }
        pts = PointSet{ijk.data(), r.data(), r.size()};
    }
    RigContext context() const { return RigContext{g, mask.data(), pts, tree, rep}; }
};

/// A solid block of voxels as the object, with a one-node tree: the context for stages that only walk inside the
/// object.
struct Block {
    Grid g;
    std::vector<std::uint8_t> mask;
    NodeTree tree{{Vec(0, 0, 0)}, {1.0}, {}};
    std::vector<std::int32_t> ijk{0, 0, 0};
    std::vector<float> r{1.0f};
    PointSet pts{ijk.data(), r.data(), 1};
    std::vector<std::uint32_t> rep{0};

    explicit Block(const std::array<std::int64_t, 3>& dims) {
        g.dims = dims;
        mask.assign(static_cast<std::size_t>(g.voxel_count()), 1);
    }
    Block(const Block&) = delete;
    RigContext context() const { return RigContext{g, mask.data(), pts, tree, rep}; }
};

}  // namespace

namespace {

/// A quadruped standing along +z: hips at `o` (radius `hips`), spine along +x to the chest 40 ahead, neck and
/// head tip forward and up (relative to the hips), legs down 35 (front feet `stride` apart along x: walking; front
/// legs of radius `front`, hind legs 4), a tail along the polyline `tail` (relative to the hips; none when empty).
struct Quadruped {
    Vec neck = Vec(52, 0, 10), head = Vec(60, 0, 14);
    double stride = 0, front = 4, hips = 8;
    std::vector<Vec> tail;

    /// The figure; its head's tip node in `head_tip`.
    Figure figure(const Vec& o, std::uint32_t& head_tip) const {
        Figure f(o, hips);
        const std::uint32_t chest = f.limb(0, o + Vec(40, 0, 0), 8, 8);
        head_tip = f.limb(f.limb(chest, o + neck, 4, 4), o + head, 5, 4);
        for (double s : {-1.0, 1.0}) {
            f.limb(f.limb(0, o + Vec(0, s * 8, -15), 4, 4), o + Vec(0, s * 8, -35), 4, 3);
            const double x = 40 + 0.5 * s * stride;
            f.limb(f.limb(chest, o + Vec(x, s * 8, -15), front, front), o + Vec(x, s * 8, -35), front, front - 1);
        }
        std::uint32_t at = 0;
        for (std::size_t k = 0; k < tail.size(); ++k)
            at = f.limb(at, o + tail[k], k == 0 ? 3 : 2.5, k == 0 ? 2.5 : 1.5);
        return f;
    }
};

/// The quadruped body plan built on a figure in a solid 120 x 60 x 80 grid, told that up is +z.
inline Candidate quadruped_rig(const Figure& f) {
    const Solid solid(f, {120, 60, 80});
    const PlanSearch s = search_plans(solid.tree, {Vec(0, 0, 1), fitted_plan_weights(), {}});
    REQUIRE(s.quadruped.score < plan_limit());
    return build_plan(solid.context(), s.quadruped, PlanKind::Quadruped, 0.35);
}

/// How far the bones named tail* reach behind `o` along -x, and below it along -z.
inline std::pair<double, double> tail_reach(const Rig& rig, const Vec& o) {
    double back = 0, down = 0;
    for (std::size_t k = 0; k < rig.names.size(); ++k)
        if (rig.names[k].rfind("tail", 0) == 0) {
            const auto& tip = rig.joints[rig.bones[k][1]];
            back = std::max(back, o.x() - tip[0]);
            down = std::max(down, o.z() - tip[2]);
        }
    return {back, down};
}

}  // namespace

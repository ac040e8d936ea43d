// autorig's stages alone (native/src/autorig/): scale axis, level-set tree, node tree, chain cutting, body-plan
// search, on small inputs whose answer is known. Also run under ASan/UBSan by scripts/test.
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
Figure stick_figure(std::uint32_t& head) {
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

TEST_CASE("scale_axis drops small balls inside a larger ball and keeps the rest", "[autorig]") {
    Grid g;
    g.dims = {40, 40, 40};
    // [z, y, x]: a big ball at x = 10; a small one 3 voxels from it (inside 1.25 x 10); a small one far away; a
    // ball more than half as large beside the big one.
    const std::vector<std::int32_t> ijk{20, 20, 10, 20, 20, 13, 20, 20, 35, 20, 23, 10};
    const std::vector<float> r{10.f, 2.f, 2.f, 6.f};
    const std::vector<std::uint8_t> keep = scale_axis(g, PointSet{ijk.data(), r.data(), r.size()});
    CHECK(keep == std::vector<std::uint8_t>{1, 0, 1, 1});
}

TEST_CASE("level_set_tree cuts a loop at a weak contact, even when the contact is the shortest link", "[autorig]") {
    // Two limbs of radius 4 hang from a bridge at y = 60 (x = 10 and x = 12, y 0..59). A thin near-surface point
    // (radius 1) beside the right limb at (13, 11) touches the left limb at (10, 10): a short edge between pieces
    // of two levels, weak (1 against the pieces' 4). By centroid distance alone it would stay and a link within
    // a limb would go.
    Grid g;
    g.dims = {20, 70, 3};
    std::vector<std::int32_t> ijk;
    std::vector<float> r;
    std::vector<std::array<std::uint32_t, 2>> edges;
    auto add = [&](int x, int y, float radius) {
        for (const std::int32_t v : {1, y, x}) ijk.push_back(v);
        r.push_back(radius);
        return static_cast<std::uint32_t>(r.size() - 1);
    };
    // Levels are measured from the bridge's thickest point, above the left limb.
    const std::uint32_t left_top = add(10, 60, 4.6f), mid = add(11, 60, 4.5f), right_top = add(12, 60, 4.5f);
    edges.push_back({left_top, mid});
    edges.push_back({mid, right_top});
    std::uint32_t left_contact = 0, right_axis = 0;
    for (int x : {10, 12}) {
        std::uint32_t prev = x == 10 ? left_top : right_top;
        for (int y = 59; y >= 0; --y) {
            const std::uint32_t p = add(x, y, 4.f);
            edges.push_back({prev, p});
            prev = p;
            if (x == 10 && y == 10) left_contact = p;
            if (x == 12 && y == 11) right_axis = p;
        }
    }
    const std::uint32_t crease = add(13, 11, 1.f);
    edges.push_back({right_axis, crease});
    edges.push_back({left_contact, crease});
    const PointSet pts{ijk.data(), r.data(), r.size()};
    const SkeletonGraph graph = graph_of_edges(g, pts, edges);
    const LevelSetTree t = level_set_tree(g, pts, graph, std::vector<std::uint8_t>(pts.n, 1), 3.0);
    REQUIRE(t.edges.size() == t.centroid.size() - 1);
    const std::uint32_t a = t.node_of_point[left_contact], b = t.node_of_point[crease];
    REQUIRE(a != b);
    const bool contact_kept = std::any_of(t.edges.begin(), t.edges.end(), [&](const auto& e) {
        return (e[0] == a && e[1] == b) || (e[0] == b && e[1] == a);
    });
    CHECK_FALSE(contact_kept);
}

TEST_CASE("level_set_tree follows a Y with nodes a band apart, whatever the point density", "[autorig]") {
    Grid g;
    g.dims = {80, 80, 4};
    for (int step : {1, 2}) {
        // Points along three arms of a Y meeting at (40, 40): down to (40, 4), up-left and up-right.
        std::vector<std::int32_t> ijk;
        std::vector<float> r;
        auto add = [&](int x, int y) {
            for (const std::int32_t v : {1, y, x}) ijk.push_back(v);
            r.push_back(3.f);
        };
        add(40, 40);
        for (int k = step; k <= 36; k += step) {
            add(40, 40 - k);
            add(40 - k * 7 / 10, 40 + k * 7 / 10);
            add(40 + k * 7 / 10, 40 + k * 7 / 10);
        }
        const PointSet pts{ijk.data(), r.data(), r.size()};
        std::vector<std::array<std::uint32_t, 2>> edges;
        for (std::uint32_t i = 0; i < pts.n; ++i)
            for (std::uint32_t j = i + 1; j < pts.n; ++j) {
                const double dx = ijk[3 * i + 2] - ijk[3 * j + 2], dy = ijk[3 * i + 1] - ijk[3 * j + 1];
                if (std::hypot(dx, dy) <= 2.0 * step) edges.push_back({i, j});
            }
        const SkeletonGraph graph = graph_of_edges(g, pts, edges);
        const LevelSetTree t = level_set_tree(g, pts, graph, std::vector<std::uint8_t>(pts.n, 1), 4.0);
        INFO("step " << step);
        // Three arms of about 36 / 4 levels each, plus the centre.
        CHECK(t.centroid.size() >= 25);
        CHECK(t.centroid.size() <= 31);
        REQUIRE(t.edges.size() == t.centroid.size() - 1);
        std::vector<int> degree(t.centroid.size(), 0);
        for (const auto& e : t.edges) {
            ++degree[e[0]];
            ++degree[e[1]];
        }
        CHECK(std::count(degree.begin(), degree.end(), 1) == 3);
        CHECK(std::count_if(degree.begin(), degree.end(), [](int d) { return d >= 3; }) == 1);
        for (std::size_t i = 0; i < pts.n; ++i) CHECK(t.node_of_point[i] != kNone);
    }
}

TEST_CASE("NodeTree prunes spurs inside a ball and ranks extremities by how far they stick out", "[autorig]") {
    Figure f(Vec(0, 0, 0), 10.0);
    const std::uint32_t long_tip = f.limb(0, Vec(40, 0, 0), 4, 3);
    const std::uint32_t mid_tip = f.limb(0, Vec(0, 25, 0), 4, 3);
    const std::uint32_t spur = f.limb(0, Vec(0, 0, 8), 2, 1);  // inside the root's 1.5x ball
    NodeTree t = f.tree();
    CHECK(t.root() == 0);
    CHECK(t.leaves().size() == 3);
    t.prune(1.5);
    CHECK(t.leaves().size() == 2);
    CHECK_FALSE(t.kept()[spur]);
    const auto ext = t.extremities();
    REQUIRE(ext.size() == 2);
    CHECK(ext[0].second == long_tip);
    CHECK(ext[1].second == mid_tip);
    CHECK(ext[0].first == Approx(40 - 10));
    CHECK(t.median(long_tip, mid_tip, 0) == 0);
    const auto p = t.path(long_tip, mid_tip);
    CHECK(p.front() == long_tip);
    CHECK(p.back() == mid_tip);
    CHECK(p.size() == 40 + 25 + 1);
}

TEST_CASE("a path is rooted at its thicker end", "[autorig]") {
    Figure f(Vec(0, 0, 0), 3.0);
    f.limb(0, Vec(30, 0, 0), 3, 1);
    f.limb(0, Vec(-20, 0, 0), 3, 6);  // the thick end
    NodeTree t = f.tree();
    t.root_path_at_thicker_end();
    CHECK(t.at(t.root()).x() == Approx(-20));
}

TEST_CASE("fit_chain cuts an L at its corner; limb_fit puts an elbow at the bend", "[autorig]") {
    Chain4 l;
    for (int k = 0; k <= 20; ++k) l.emplace_back(k, 0, 0, 1);
    for (int k = 1; k <= 20; ++k) l.emplace_back(20, k, 0, 1);
    const Fit two = fit_chain(l, 2);
    REQUIRE(two.cuts.size() == 3);
    CHECK(two.cuts[1] == 20);
    CHECK(two.worst == Approx(0).margin(1e-9));
    CHECK(fit_chain(l, 1).worst > 5);
    // An arm: a shoulder girdle out along x, then the upper arm down, a gentle bend at the elbow (30 degrees
    // forward), forearm and hand.
    Chain4 arm;
    for (int k = 0; k <= 15; ++k) arm.emplace_back(k, 0, 0, 3);
    for (int k = 1; k <= 20; ++k) arm.emplace_back(15, 0, -k, 3);
    for (int k = 1; k <= 25; ++k) arm.emplace_back(15, 0.5 * k, -20 - 0.866 * k, 2.5);
    const Fit f = limb_fit(arm, true);
    REQUIRE(f.cuts.size() == 5);
    // the girdle's corner, pulled a little toward the elbow by the forearm's bend
    CHECK(f.cuts[1] >= 15);
    CHECK(f.cuts[1] <= 18);
    CHECK(std::abs(static_cast<int>(f.cuts[2]) - 35) <= 1);  // the elbow at the bend
    CHECK(f.cuts[3] > f.cuts[2]);
    CHECK(f.cuts[4] == arm.size() - 1);
    CHECK(arc_of(arm).back() == Approx(60).epsilon(1e-3));
}

TEST_CASE("proportional_fit cuts a straight chain at its proportions and a bent one at its bend", "[autorig]") {
    // A straight leg 0..100 along -z, radius 5: nothing but the proportions decides.
    Chain4 straight;
    for (int k = 0; k <= 100; ++k) straight.emplace_back(0, 0, -k, 5);
    const Fit even = proportional_fit(straight, {1, 2, 1}, 0.0);
    REQUIRE(even.cuts.size() == 4);
    const std::vector<double> arc = arc_of(straight);
    CHECK(arc[even.cuts[1]] == Approx(25).margin(2));
    CHECK(arc[even.cuts[2]] == Approx(75).margin(2));
    CHECK(even.cuts.back() == 100);
    // `extra` lengthens the last bone: with 20 beyond the tip, 1 : 1 puts the cut at 60.
    CHECK(arc[proportional_fit(straight, {1, 1}, 20.0).cuts[1]] == Approx(60).margin(2));
    // A right-angle bend at 20 of 50 wins over a 1 : 1 proportion (at most 64 samples: every one is used).
    Chain4 bent;
    for (int k = 0; k <= 20; ++k) bent.emplace_back(0, 0, -k, 5);
    for (int k = 1; k <= 30; ++k) bent.emplace_back(k, 0, -20, 5);
    const Fit corner = proportional_fit(bent, {1, 1}, 0.0);
    REQUIRE(corner.cuts.size() == 3);
    CHECK(corner.cuts[1] == 20);
    CHECK(corner.worst == Approx(0).margin(1e-9));
    // Too few samples for the bones asked: no fit.
    CHECK(proportional_fit(Chain4(3, Eigen::Vector4d(0, 0, 0, 1)), {1, 1, 1}, 0.0).cuts.empty());
}

TEST_CASE("limb_fit finds a standing leg's hip, ankle and a knee halfway between", "[autorig]") {
    // Pelvis centre out 10 to the hip, down 90 to the ankle (no bend at the knee), forward 20 along the foot.
    Chain4 leg;
    for (int k = 0; k <= 10; ++k) leg.emplace_back(k, 0, 0, 8);
    for (int k = 1; k <= 90; ++k) leg.emplace_back(10, 0, -k, 8 - 4.0 * k / 90);
    for (int k = 1; k <= 20; ++k) leg.emplace_back(10, -k, -90, 3);
    const Fit f = limb_fit(leg, false);
    REQUIRE(f.cuts.size() == 5);
    CHECK(std::abs(static_cast<int>(f.cuts[1]) - 10) <= 1);   // the hip at the corner
    CHECK(std::abs(static_cast<int>(f.cuts[2]) - 55) <= 3);   // the knee halfway down the straight leg
    CHECK(std::abs(static_cast<int>(f.cuts[3]) - 100) <= 1);  // the ankle at the corner
}

TEST_CASE("limbs_carry: a body's limbs carry its head; an arm's fingers do not carry the rest of it", "[autorig]") {
    std::uint32_t head = 0;
    const Figure stick = stick_figure(head);
    const NodeTree t = stick.tree();
    // The stick figure: pelvis node 0, chest at z = 30; its limb tips are the leaves other than the head.
    std::vector<std::uint32_t> tips;
    for (std::uint32_t l : t.leaves())
        if (l != head) tips.push_back(l);
    REQUIRE(tips.size() == 4);
    std::uint32_t chest = 0;
    for (std::uint32_t v = 0; v < stick.pos.size(); ++v)
        if ((stick.pos[v] - Vec(0, 0, 30)).norm() < 0.5) chest = v;
    const std::uint32_t legs[2] = {tips[0], tips[1]}, arms[2] = {tips[2], tips[3]};
    CHECK(limbs_carry(t, 0, chest, head, legs, arms));
    // An arm: the "head" is the shoulder end 100 away from a palm whose "limbs" are fingers 8 long.
    Figure arm(Vec(0, 0, 0), 3.0);
    const std::uint32_t shoulder_end = arm.limb(0, Vec(-100, 0, 0), 3, 4);
    std::uint32_t fingers[4];
    for (int k = 0; k < 4; ++k) fingers[k] = arm.limb(0, Vec(8, 2.0 * k - 3, 0), 1, 0.8);
    const NodeTree a = arm.tree();
    CHECK_FALSE(limbs_carry(a, 0, 0, shoulder_end, {fingers[0], fingers[1]}, {fingers[2], fingers[3]}));
}

TEST_CASE("restore_proximal moves a hidden shoulder out to its proportion, inside the object", "[autorig]") {
    Block block({10, 10, 80});
    Grid& g = block.g;
    std::vector<std::uint8_t>& mask = block.mask;
    const RigContext c = block.context();
    // shoulder 0 -> 1, upper_arm 1 -> 2 (10 long), forearm 2 -> 3 (20 long) along z.
    auto arm = [] {
        Rig rig;
        rig.joints = {{5, 5, 40}, {5, 5, 30}, {5, 5, 20}, {5, 5, 0}};
        rig.joint_points = {0, 0, 0, 0};
        rig.bones = {{0, 1}, {1, 2}, {2, 3}};
        rig.names = {"shoulder", "upper_arm", "forearm"};
        rig.parents = {-1, 0, 1};
        return rig;
    };
    Rig rig = arm();
    restore_proximal(c, rig, "upper_arm", "forearm", 1.5);  // wants 30: the shoulder moves from z 30 to 50
    CHECK(rig.joints[1][2] == Approx(50).margin(0.5));
    CHECK(rig.joints[1][0] == Approx(5));
    CHECK(rig.joint_points[1] == -1);
    // The object ends at z 45: the shoulder stops inside it.
    for (std::int64_t z = 46; z < 80; ++z)
        for (std::int64_t y = 0; y < 10; ++y)
            for (std::int64_t x = 0; x < 10; ++x) mask[static_cast<std::size_t>(g.index(x, y, z))] = 0;
    rig = arm();
    restore_proximal(c, rig, "upper_arm", "forearm", 1.5);
    CHECK(rig.joints[1][2] == Approx(45).margin(0.6));
    // Long enough (10 >= 0.8 x 0.5 x 20): unchanged; a missing bone: unchanged.
    rig = arm();
    restore_proximal(c, rig, "upper_arm", "forearm", 0.5);
    CHECK(rig.joints[1][2] == 30);
    restore_proximal(c, rig, "upper_arm", "hand", 1.5);
    CHECK(rig.joints[1][2] == 30);
}

TEST_CASE("search_plans finds a stick figure's head, and a given up direction rules out its upside-down reading",
          "[autorig]") {
    std::uint32_t head = 0;
    const NodeTree t = stick_figure(head).tree();
    const PlanSearch free = search_plans(t, std::nullopt);
    REQUIRE(free.humanoid.score < kPlanLimit);
    CHECK(free.humanoid.head == head);
    CHECK(free.humanoid.score < free.quadruped.score);
    const PlanSearch up = search_plans(t, Vec(0, 0, 1));
    CHECK(up.humanoid.head == head);
    // Told that up is -z, no humanoid reading of the figure has its spine pointing up.
    const PlanSearch down = search_plans(t, Vec(0, 0, -1));
    CHECK_FALSE(down.humanoid.score < kPlanLimit);
}

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
Candidate quadruped_rig(const Figure& f) {
    const Solid solid(f, {120, 60, 80});
    const PlanSearch s = search_plans(solid.tree, Vec(0, 0, 1));
    REQUIRE(s.quadruped.score < kPlanLimit);
    return build_plan(solid.context(), s.quadruped, false, 0.35);
}

/// How far the bones named tail* reach behind `o` along -x, and below it along -z.
std::pair<double, double> tail_reach(const Rig& rig, const Vec& o) {
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

TEST_CASE("search_plans reads four legs under a horizontal spine as a quadruped", "[autorig]") {
    std::uint32_t head = 0;
    const NodeTree t = Quadruped().figure(Vec(0, 0, 0), head).tree();
    for (const auto& up : {std::optional<Vec>{}, std::optional<Vec>{Vec(0, 0, 1)}}) {
        const PlanSearch s = search_plans(t, up);
        REQUIRE(s.quadruped.score < kPlanLimit);
        CHECK(s.quadruped.head == head);
        CHECK(s.quadruped.score < s.humanoid.score);
    }
    // Upside down (told up is -z) the legs point up: no quadruped.
    CHECK_FALSE(search_plans(t, Vec(0, 0, -1)).quadruped.score < kPlanLimit);
}

TEST_CASE("coarse: the object's box, factors to its own scale, and a majority downsampling", "[autorig]") {
    Grid g;
    g.dims = {40, 12, 10};
    g.spacing = {0.5, 0.5, 1.0};
    g.origin = {10, 20, 30};
    std::vector<std::uint8_t> mask(static_cast<std::size_t>(g.voxel_count()), 0);
    // A bar x 4..35, y 2..9, z 3..6 (exclusive ends), and one stray voxel beside it.
    for (int z = 3; z < 7; ++z)
        for (int y = 2; y < 10; ++y)
            for (int x = 4; x < 36; ++x) mask[static_cast<std::size_t>(g.index(x, y, z))] = 1;
    const auto box = object_box(g, mask.data());
    CHECK(box == std::array<std::int64_t, 6>{4, 2, 3, 36, 10, 7});
    // Longest extent 32 x 0.5 = 16: 8 cells of 2 world units, i.e. 4, 4 and 2 voxels.
    const auto f = coarse_factor(g, box, 8);
    CHECK(f == std::array<std::int64_t, 3>{4, 4, 2});
    CHECK(coarse_factor(g, box, 1000) == std::array<std::int64_t, 3>{1, 1, 1});  // never finer than the volume
    mask[static_cast<std::size_t>(g.index(20, 10, 7))] = 1;  // a stray voxel: a minority of its block
    const CoarseShape c = downsample(g, mask.data(), object_box(g, mask.data()), f);
    CHECK(c.grid.dims == std::array<std::int64_t, 3>{10, 5, 5});
    std::size_t object = 0;
    for (std::int64_t z = 0; z < c.grid.dims[2]; ++z)
        for (std::int64_t y = 0; y < c.grid.dims[1]; ++y)
            for (std::int64_t x = 0; x < c.grid.dims[0]; ++x) {
                const bool in = c.mask[static_cast<std::size_t>(c.grid.index(x, y, z))];
                object += in;
                // The bar covers coarse x 1..8, y 1..2, z 1..2 whole; the stray voxel's block stays empty.
                CHECK(in == (x >= 1 && x <= 8 && y >= 1 && y <= 2 && z >= 1 && z <= 2));
            }
    CHECK(object == 8 * 2 * 2);
    // Coarse voxel (1, 1, 1) is the mean of fine voxels x 4..7, y 2..5, z 3..4 (the grid's origin is 0, the world
    // is `offset` away).
    CHECK(c.grid.origin == std::array<double, 3>{0, 0, 0});
    CHECK(c.offset[0] + c.grid.spacing[0] == Approx(10 + 5.5 * 0.5));
    CHECK(c.offset[1] + c.grid.spacing[1] == Approx(20 + 3.5 * 0.5));
    CHECK(c.offset[2] + c.grid.spacing[2] == Approx(30 + 3.5 * 1.0));
}

TEST_CASE("build_plan keeps a quadruped's tail as a chain parented to its hips; the thicker end is the head",
          "[autorig]") {
    const Vec o(40, 30, 50);
    Quadruped q;
    q.tail = {Vec(-15, 0, 8), Vec(-30, 0, 4)};
    std::uint32_t head = 0;
    const Candidate c = quadruped_rig(q.figure(o, head));
    REQUIRE(c.rig.bones.size() > 21);
    const auto& names = c.rig.names;
    const auto tail = std::find(names.begin(), names.end(), "tail");
    REQUIRE(tail != names.end());
    const auto b = static_cast<std::size_t>(tail - names.begin());
    CHECK(names[static_cast<std::size_t>(c.rig.parents[b])] == "hips");
    // the tail's chain ends at the tail's tip (extended to the grid's edge along its last bone at most 2 radii)
    const double far = tail_reach(c.rig, o).first;
    CHECK(far >= 29);
    CHECK(far <= 30 + 2 * 1.5 + 1);
    CHECK(std::count(names.begin(), names.end(), "head") == 1);
    CHECK(c.up.z() > 0.9);
}

namespace {

/// A hand in a grid, fingers along +y: a wrist stub from y = 10 up to the palm centre at y = 50 (thickest), the
/// thumb leaving the palm at y = 30 out along -x and up (its tip raised along +z), four fingers from the palm
/// centre to knuckles at y = 60 and up to their tips (the middle one longest). The tips in `tips`: thumb, index,
/// middle, ring, pinky. The palm centre's radius is `palm_radius` (a hand's: 9, twice the fingers').
Figure hand_figure(std::array<std::uint32_t, 5>& tips, double palm_radius = 9) {
    const Vec o(60, 10, 30);
    Figure f(o, 7.0);
    const std::uint32_t thumb_base = f.limb(0, o + Vec(0, 20, 0), 8, 9);
    const std::uint32_t palm = f.limb(thumb_base, o + Vec(0, 40, 0), 9, palm_radius);
    tips[0] = f.limb(f.limb(thumb_base, o + Vec(-22, 32, 3), 5, 4.5), o + Vec(-36, 50, 8), 4.5, 3.5);
    const double x[4] = {-15, -5, 5, 15}, len[4] = {38, 42, 38, 30};
    for (int k = 0; k < 4; ++k)
        tips[static_cast<std::size_t>(k) + 1] =
            f.limb(f.limb(palm, o + Vec(x[k], 50, 0), 5, 4), o + Vec(1.2 * x[k], 50 + len[k], 0), 4, 3);
    return f;
}

}  // namespace

TEST_CASE("search_hand finds the thumb and orders the fingers; hand_rig names 16 bones", "[autorig]") {
    std::array<std::uint32_t, 5> tips{};
    const Figure f = hand_figure(tips);
    const Solid solid(f, {120, 120, 60});
    const HandPlan p = search_hand(solid.tree);
    REQUIRE(p.score < kPlanLimit);
    CHECK(p.fingers == tips);
    CHECK(solid.tree.at(p.wrist).y() == Approx(10));
    const Candidate c = hand_rig(solid.context(), p);
    REQUIRE(c.rig.bones.size() == 16);
    CHECK(c.rig.kind == "hand");
    CHECK(c.fit > 0.5);
    const auto& names = c.rig.names;
    CHECK(names[0].rfind("palm", 0) == 0);
    const std::string side = names[0].substr(4);
    CHECK(side == ".L");  // the thumb raised on +z: the palm faces +z, the thumb on the viewer's left
    for (const char* bone : {"thumb.01", "thumb.03", "f_index.01", "f_middle.02", "f_ring.03", "f_pinky.01"})
        CHECK(std::count(names.begin(), names.end(), bone + side) == 1);
    for (std::size_t b = 1; b < names.size(); ++b) CHECK(c.rig.parents[b] == static_cast<std::int32_t>(b % 3 == 1 ? 0 : b - 1));
    // Not a body plan: five fingers are no head, arms and legs.
    const PlanSearch plans = search_plans(solid.tree, std::nullopt);
    CHECK(plans.humanoid.score > p.score);
    CHECK(plans.quadruped.score > p.score);
}

TEST_CASE("search_hand: a palm five times thicker than its fingers is a body, no palm", "[autorig]") {
    // A camel read as a hand: its hump the wrist, its body the palm, its legs the fingers, its neck the thumb.
    std::array<std::uint32_t, 5> tips{};
    const HandPlan thin = search_hand(hand_figure(tips).tree()), thick = search_hand(hand_figure(tips, 22).tree());
    REQUIRE(thin.score < kPlanLimit);
    CHECK(thick.score >= thin.score + 2.0);
    CHECK_FALSE(thick.score < kPlanLimit);
}

TEST_CASE("a stick figure is no hand", "[autorig]") {
    std::uint32_t head = 0;
    Figure f = stick_figure(head);
    CHECK_FALSE(search_hand(f.tree()).score < kPlanLimit);
    f.limb(0, Vec(0, -15, -5), 3, 2);  // a sixth extremity: a tail
    CHECK_FALSE(search_hand(f.tree()).score < kPlanLimit);
}

TEST_CASE("build_plan keeps a tail hanging down along a thick rump", "[autorig]") {
    // The tail's tip lies within two radii of the thick hips it hangs from, yet it sticks out of the body by
    // several of its own radii: a part, not a bump.
    const Vec o(40, 30, 50);
    Quadruped q;
    q.hips = 16;
    q.tail = {Vec(-14, 0, 2), Vec(-17, 0, -22)};
    std::uint32_t head = 0;
    const Candidate c = quadruped_rig(q.figure(o, head));
    CHECK(std::count(c.rig.names.begin(), c.rig.names.end(), "tail") == 1);
    CHECK(tail_reach(c.rig, o).second >= 20);
}

TEST_CASE("a branch looping back into the body from a thin attachment is no extremity", "[autorig]") {
    // A body (thick, along x) with a leg down; from the leg's middle a thick branch runs back up into the body (a
    // thigh whose knee touches the other leg: the level-set tree hangs it from the knee). Measured from the thin
    // node it hangs from it sticks out 18; it lies inside the body's balls.
    Figure f(Vec(0, 0, 0), 10.0);
    f.limb(0, Vec(30, 0, 0), 10, 9);
    const std::uint32_t knee = f.limb(0, Vec(0, 0, -20), 4, 2);
    const std::uint32_t foot = f.limb(knee, Vec(0, 0, -40), 2, 1.5);
    const std::uint32_t loop = f.limb(knee, Vec(3, 4, -3), 3, 5);
    const auto ext = f.tree().extremities();
    REQUIRE(ext.size() == 3);
    CHECK(ext[0].second == foot);
    for (const auto& [significance, leaf] : ext)
        if (leaf == loop) CHECK(significance < 0);
}

TEST_CASE("search_plans: a figure whose hands reach its feet is a poor humanoid", "[autorig]") {
    std::uint32_t head = 0;
    const PlanSearch standing = search_plans(stick_figure(head).tree(), Vec(0, 0, 1));
    // The same figure with arms down to the ground (a quadruped's four feet read as legs and arms).
    Figure f(Vec(0, 0, 0), 8.0);
    const std::uint32_t chest = f.limb(0, Vec(0, 0, 30), 8, 7);
    f.limb(f.limb(chest, Vec(0, 0, 36), 4, 4), Vec(0, 0, 45), 5, 4);
    for (double s : {-1.0, 1.0}) {
        const std::uint32_t elbow = f.limb(f.limb(chest, Vec(s * 10, 0, 30), 3, 3), Vec(s * 18, 0, 0), 2.5, 2.5);
        f.limb(elbow, Vec(s * 20, 0, -45), 2, 1.5);
        f.limb(f.limb(0, Vec(s * 6, 0, -22), 4.5, 4), Vec(s * 6, 0, -45), 4, 3);
    }
    const PlanSearch low = search_plans(f.tree(), Vec(0, 0, 1));
    REQUIRE(standing.humanoid.score < kPlanLimit);
    CHECK(low.humanoid.score >= standing.humanoid.score + 0.8 * kHandsAboveFeet);
}


TEST_CASE("search_plans: a walking quadruped looking aside keeps its head, not a front foot", "[autorig]") {
    // One front foot forward, the head turned aside level with it: foot and head mirror each other about the
    // spine's line as well as the two front feet do. But the two pairs must mirror across one midplane and the
    // neck runs on beyond the chest: a foot taken for the head (and the head for an arm) breaks both.
    Quadruped q;
    q.neck = Vec(46, 15, 5);
    q.head = Vec(48, 35, 0);
    q.stride = 16;
    std::uint32_t head = 0;
    const NodeTree t = q.figure(Vec(0, 0, 0), head).tree();
    for (const auto& up : {std::optional<Vec>{}, std::optional<Vec>{Vec(0, 0, 1)}}) {
        const PlanSearch s = search_plans(t, up);
        REQUIRE(s.quadruped.score < kPlanLimit);
        CHECK(s.quadruped.head == head);
    }
}

TEST_CASE("search_plans: a quadruped with thick front legs keeps its head at the front", "[autorig]") {
    // Legs thicker than arms is a humanoid's rule: a bull's front legs may be its thickest; read backwards, its
    // tail would be taken for the head.
    Quadruped q;
    q.front = 6;
    q.tail = {Vec(-13, 0, 8), Vec(-26, 0, 4)};
    std::uint32_t head = 0;
    const NodeTree t = q.figure(Vec(0, 0, 0), head).tree();
    const PlanSearch s = search_plans(t, Vec(0, 0, 1));
    REQUIRE(s.quadruped.score < kPlanLimit);
    CHECK(s.quadruped.head == head);
}

TEST_CASE("own_start finds where an arm leaves the trunk's sheet, not where its hand thickens", "[autorig]") {
    Chain4 chain;
    auto add = [&](double z, double r) { chain.emplace_back(0.0, 0.0, z, r); };
    for (double z : {100.0, 95.0, 90.0}) add(z, 20.0);  // trunk
    for (int k = 0; k < 20; ++k) add(85.0 - 3 * k, 8.0 - 0.2 * k);  // arm, tapering
    add(20.0, 1.0);  // a finger tip: its neighbour is more than 1.5x as thick, but it is the far end
    CHECK(own_start(chain) == 3);
    // Only the root is trunk: the arm starts at 1. No trunk at all: 0.
    chain.erase(chain.begin(), chain.begin() + 2);
    CHECK(own_start(chain) == 1);
    chain.front()[3] = 8.0;
    CHECK(own_start(chain) == 0);
}

TEST_CASE("fused_arm: an arm against the trunk gets its shoulder up its line, a radius under the surface",
          "[autorig]") {
    // A solid column x 0..35, y 0..19, z 0..99; the arm's visible axis runs down x = 30 (5 inside the outer
    // side) from z = 70 to 40, then the forearm forward-down. Its shoulder: up x = 30 to the top (z 99), 5 back
    // in, midway front to back.
    const Block block({36, 20, 100});
    const RigContext c = block.context();
    Chain4 chain;
    chain.emplace_back(10, 10, 80, 12);  // chest
    chain.emplace_back(20, 10, 76, 11);  // the trunk's sheet
    for (int z = 70; z >= 40; z -= 2) chain.emplace_back(30, 10, z, 5);                 // upper arm
    for (int k = 1; k <= 12; ++k) chain.emplace_back(30, 10 - 0.6 * k, 40 - 2.0 * k, 4);  // forearm
    for (int k = 1; k <= 6; ++k) chain.emplace_back(30, 2.8 - 0.3 * k, 16 - 1.5 * k, 3);  // hand
    const auto f = fused_arm(c, chain, Vec(0, 0, 1), Vec::Zero());
    REQUIRE(f);
    CHECK(f->own == 2);
    CHECK(f->shoulder.x() == Approx(30).margin(1.0));  // half-voxel steps
    CHECK(f->shoulder.z() == Approx(94.5).margin(1.0));
    CHECK(f->shoulder.y() == Approx(9.5).margin(0.6));
    REQUIRE(f->cuts.size() == 5);
    CHECK(f->cuts[0] == 0);
    CHECK(f->cuts[1] == 2);
    CHECK(chain[f->cuts[2]].z() == Approx(40).margin(4.1));  // the elbow at the bend
    CHECK(f->cuts[4] == chain.size() - 1);
    // An arm whose top runs across the body (a shoulder girdle) is not fused.
    Chain4 across{chain[0], Eigen::Vector4d(14, 10, 80, 11)};
    for (int x = 20; x <= 30; ++x) across.emplace_back(x, 10, 78, 5);
    across.insert(across.end(), chain.begin() + 2, chain.end());
    CHECK_FALSE(fused_arm(c, across, Vec(0, 0, 1), Vec::Zero()));
}

TEST_CASE("fused_arm: in a shoulder deeper than the arm is thick, the joint sits a radius behind the front",
          "[autorig]") {
    // The column of the test above, 40 deep (y 0..39) with the front at -y: the shoulder blade's depth lies
    // behind the joint, which goes a radius (5) behind the front face (y -0.5), not midway.
    const Block block({36, 40, 100});
    Chain4 chain;
    chain.emplace_back(10, 10, 80, 12);
    chain.emplace_back(20, 10, 76, 11);
    for (int z = 70; z >= 40; z -= 2) chain.emplace_back(30, 10, z, 5);
    for (int k = 1; k <= 12; ++k) chain.emplace_back(30, 10 - 0.6 * k, 40 - 2.0 * k, 4);
    const auto f = fused_arm(block.context(), chain, Vec(0, 0, 1), Vec(0, -1, 0));
    REQUIRE(f);
    CHECK(f->shoulder.y() == Approx(4.5).margin(0.6));
    CHECK(f->shoulder.x() == Approx(30).margin(1.0));
    CHECK(f->shoulder.z() == Approx(94.5).margin(1.0));
}

namespace {

/// A leg of nodes from (0, 0, 100) to (0, 0, 0) with the axis bent `bend` at z = 40 (pushed along y), and a rig
/// of hips (its head at z `fork`), thigh 100 -> 40 and shin 40 -> 0 over it.
struct Leg {
    Figure f{Vec(0, 0, 100), 10.0};
    Rig rig;
    std::vector<std::uint32_t> nodes;
    Leg(double bend, double fork) {
        f.limb(f.limb(0, Vec(0, bend, 40), 10, 9), Vec(0, 0, 0), 9, 6);
        for (std::uint32_t k = 0; k < f.pos.size(); ++k) nodes.push_back(k);
        rig.joints = {{0, 0, fork}, {0, 0, 100}, {0, bend, 40}, {0, 0, 0}};
        rig.joint_points = {0, 0, 0, 0};
        rig.bones = {{0, 1}, {1, 2}, {2, 3}};
        rig.names = {"hips", "thigh.L", "shin.L"};
        rig.parents = {-1, 0, 1};
    }
};

}  // namespace

TEST_CASE("straight_knee: a straight leg's knee at the thigh's share, a bent one's left at its bend", "[autorig]") {
    Leg straight(2.0, 100.0);  // 2 off the line: straight (radius about 9)
    Solid s(straight.f, {10, 10, 110});
    straight_knee(s.context(), straight.rig, straight.nodes, ".L");
    const double share = kLegProportions[1] / (kLegProportions[1] + kLegProportions[2]);
    CHECK(straight.rig.joints[2][2] == Approx(100 * (1 - share)).margin(1.5));
    CHECK(straight.rig.joint_points[2] == -1);
    Leg bent(30.0, 100.0);  // a bent knee: its bend stays
    Solid sb(bent.f, {10, 40, 110});
    straight_knee(sb.context(), bent.rig, bent.nodes, ".L");
    CHECK(bent.rig.joints[2][2] == 40);
    CHECK(bent.rig.joints[2][1] == 30);
}

TEST_CASE("hip_on_thigh_line moves a hip below the legs' fork up the thigh's line, never down", "[autorig]") {
    Leg leg(0.0, 120.0);  // the fork 20 above the thigh's head
    hip_on_thigh_line(leg.rig, "thigh.L");
    CHECK(leg.rig.joints[1][2] == Approx(120));
    CHECK(leg.rig.joints[1][1] == Approx(0));
    Leg low(0.0, 90.0);
    hip_on_thigh_line(low.rig, "thigh.L");
    CHECK(low.rig.joints[1][2] == 100);
}

TEST_CASE("straight_knee: a straight leg narrowing between thigh and calf has its knee at the neck", "[autorig]") {
    Leg leg(0.0, 100.0);
    leg.f = Figure(Vec(0, 0, 100), 10.0);
    // The thigh narrowing to the knee (9 at z 60, 6.5 at 45) and the calf 8.5: a neck well beyond the distance
    // transform's steps (kNeckNoise).
    const std::uint32_t above = leg.f.limb(0, Vec(0, 0, 60), 10, 9);
    leg.f.limb(leg.f.limb(leg.f.limb(above, Vec(0, 0, 45), 9, 6.5), Vec(0, 0, 30), 6.5, 8.5), Vec(0, 0, 0), 8.5, 6);
    leg.nodes.clear();
    for (std::uint32_t k = 0; k < leg.f.pos.size(); ++k) leg.nodes.push_back(k);
    Solid s(leg.f, {10, 10, 110});
    straight_knee(s.context(), leg.rig, leg.nodes, ".L");
    CHECK(leg.rig.joints[2][2] == Approx(45).margin(0.5));  // not the proportional 50
    CHECK(leg.rig.joints[1][2] == 100);  // the thigh (55) is longer than its share of the knee height (51): kept
    // A hip left low (at a fork 20 below): with the knee at its neck, the thigh grows
    leg.rig.joints[1] = {0, 0, 80};
    leg.rig.joints[2] = {0, 0, 40};
    straight_knee(s.context(), leg.rig, leg.nodes, ".L");
    CHECK(leg.rig.joints[2][2] == Approx(45).margin(0.5));
    // to its share of the knee's height above the sole (the axis' last sample, z 0, radius 6).
    CHECK(leg.rig.joints[1][2] == Approx(45 + kThighToKneeHeight * (45 + 6)).margin(0.5));
}

namespace {

/// A lower leg from the knee (0, 0, 100) down to a heel at z = 20 and a foot forward to (0, 40, 10), the rig's
/// ankle at the heel (where such an axis turns); `neck` the radius at z = 40 (the heel's is 8).
struct LowerLeg {
    Figure f{Vec(0, 0, 100), 9.0};
    Rig rig;
    std::vector<std::uint32_t> nodes;
    explicit LowerLeg(double neck) {
        f.limb(f.limb(f.limb(0, Vec(0, 0, 40), 9, neck), Vec(0, 0, 20), neck, 8), Vec(0, 40, 10), 8, 3);
        for (std::uint32_t k = 0; k < f.pos.size(); ++k) nodes.push_back(k);
        rig.joints = {{0, 0, 100}, {0, 0, 20}, {0, 40, 10}};
        rig.joint_points = {0, 0, 0};
        rig.bones = {{0, 1}, {1, 2}};
        rig.names = {"shin.L", "foot.L"};
        rig.parents = {-1, 0};
    }
};

}  // namespace

TEST_CASE("heel_ankle: an ankle at the heel's centre goes up midway to the leg's neck; a plain taper keeps it",
          "[autorig]") {
    LowerLeg leg(5.0);
    Solid s(leg.f, {10, 50, 110});
    heel_ankle(s.context(), leg.rig, leg.nodes, ".L");
    CHECK(leg.rig.joints[1][2] == Approx(30).margin(1.0));  // midway between the neck (z 40) and the heel (z 20)
    CHECK(leg.rig.joints[1][1] == Approx(0).margin(1e-9));
    CHECK(leg.rig.joints[2][2] == 10);  // the toe stays
    LowerLeg taper(8.0);  // no neck: 9 at the knee down to 8 at the heel
    Solid st(taper.f, {10, 50, 110});
    heel_ankle(st.context(), taper.rig, taper.nodes, ".L");
    CHECK(taper.rig.joints[1][2] == 20);
}

TEST_CASE("wrist_at_neck: a hand resting on something widens past the wrist; a free hand keeps the wrist",
          "[autorig]") {
    // The arm's axis from the elbow (0, 0, 100) down: the forearm narrows from 9 to 5 at z = 60, a hand lying on
    // something widens to 7 at z = 45 and ends at z = 20; the rig's wrist (by proportion) at z = 35.
    auto arm = [](double palm) {
        Figure f(Vec(0, 0, 100), 9.0);
        f.limb(f.limb(f.limb(0, Vec(0, 0, 60), 9, 5), Vec(0, 0, 45), 5, palm), Vec(0, 0, 20), palm, 2);
        return f;
    };
    auto rig_of = [] {
        Rig rig;
        rig.joints = {{0, 0, 130}, {0, 0, 100}, {0, 0, 35}, {0, 0, 20}};
        rig.joint_points = {0, 0, 0, 0};
        rig.bones = {{0, 1}, {1, 2}, {2, 3}};
        rig.names = {"upper_arm.L", "forearm.L", "hand.L"};
        rig.parents = {-1, 0, 1};
        return rig;
    };
    const Figure resting = arm(7.0);
    std::vector<std::uint32_t> nodes;
    for (std::uint32_t k = 0; k < resting.pos.size(); ++k) nodes.push_back(k);
    Solid s(resting, {10, 10, 110});
    Rig rig = rig_of();
    wrist_at_neck(s.context(), rig, nodes, ".L");
    CHECK(rig.joints[2][2] == Approx(60).margin(1.0));
    CHECK(rig.joints[3][2] == 20);  // the hand's tip stays
    const Figure free = arm(4.0);  // the hand thinner than the wrist: no neck
    Solid sf(free, {10, 10, 110});
    Rig kept = rig_of();
    wrist_at_neck(sf.context(), kept, nodes, ".L");
    CHECK(kept.joints[2][2] == 35);
}

TEST_CASE("centre_chest puts the chest joint between the shoulders and the hips' head between the hips",
          "[autorig]") {
    Rig rig;
    rig.joints = {{0, 0, 0}, {5, 1, 10}, {12, 0, 12}, {-8, 0, 12}, {14, 0, 0}, {-10, 0, 0},
                  {1, 2, -3}, {6, 0, -6}, {-4, 0, -6}, {6, 0, -30}, {-4, 0, -30}};
    rig.joint_points.assign(rig.joints.size(), 0);
    rig.bones = {{0, 1}, {1, 2}, {1, 3}, {2, 4}, {3, 5}, {6, 0}, {6, 7}, {6, 8}, {7, 9}, {8, 10}};
    rig.names = {"chest", "shoulder.L", "shoulder.R", "upper_arm.L", "upper_arm.R", "hips", "pelvis.L", "pelvis.R",
                 "thigh.L", "thigh.R"};
    rig.parents = {5, 0, 0, 1, 2, -1, 5, 5, 6, 7};
    centre_chest(rig, Vec(0, 0, 1));
    CHECK(rig.joints[1][0] == Approx(2));   // midway between x 12 and -8
    CHECK(rig.joints[1][1] == Approx(1));   // depth kept
    CHECK(rig.joints[1][2] == Approx(12));  // at the shoulders' height
    CHECK(rig.joint_points[1] == -1);
    CHECK(rig.joints[6][0] == Approx(1));   // midway between the hips
    CHECK(rig.joints[6][1] == Approx(2));
    CHECK(rig.joints[6][2] == Approx(-6));
}

TEST_CASE("level_hips puts both hip joints at the mean of their heights", "[autorig]") {
    Rig rig;
    rig.joints = {{4, 0, 10}, {-4, 1, 6}, {4, 0, 0}, {-4, 0, 0}};
    rig.joint_points = {0, 0, 0, 0};
    rig.bones = {{0, 2}, {1, 3}};
    rig.names = {"thigh.L", "thigh.R"};
    rig.parents = {-1, -1};
    level_hips(rig, Vec(0, 0, 1));
    CHECK(rig.joints[0][2] == Approx(8));
    CHECK(rig.joints[1][2] == Approx(8));
    CHECK(rig.joints[1][1] == 1);  // across and front to back kept
    CHECK(rig.joints[0][0] == 4);
}

TEST_CASE("place_head puts the head joint 0.6 of the way down from the top and its tail straight up",
          "[autorig]") {
    // A neck from z 20 up to 30, the head's axis running forward to the face (y 2); the head's top at z 39.
    const Block block({20, 20, 40});
    Rig rig;
    rig.joints = {{10, 10, 20}, {10, 10, 30}, {10, 2, 30}};
    rig.joint_points = {0, 0, 0};
    rig.bones = {{0, 1}, {1, 2}};
    rig.names = {"neck", "head"};
    rig.parents = {-1, 0};
    Chain4 head;
    for (int z = 20; z <= 30; ++z) head.emplace_back(10, 10, z, 4);
    for (int y = 9; y >= 2; --y) head.emplace_back(10, y, 30, 3);
    place_head(block.context(), rig, head, Vec(0, 0, 1));
    const double top = 39.5, want = top - kHeadShare * (top - 20);  // the reach ends half a voxel out
    CHECK(rig.joints[1][2] == Approx(want).margin(0.6));
    CHECK(rig.joints[1][0] == Approx(9.5).margin(0.6));  // centred in the head's section
    CHECK(rig.joints[1][1] == Approx(9.5).margin(0.6));
    CHECK(rig.joints[2][0] == Approx(rig.joints[1][0]));  // straight up
    CHECK(rig.joints[2][1] == Approx(rig.joints[1][1]));
    CHECK(rig.joints[2][2] == Approx(top).margin(0.6));
}

TEST_CASE("deepest_dip finds a knee between thigh and calf, not the narrowing towards the ankle", "[autorig]") {
    Chain4 leg;
    for (double r : {10.0, 9.0, 8.0, 7.0, 7.5, 8.0, 7.0, 6.0, 5.0}) leg.emplace_back(0, 0, 0, r);
    CHECK(deepest_dip(leg, 0, leg.size() - 1, 1.0) == std::optional<std::size_t>(3));
    CHECK_FALSE(deepest_dip(leg, 4, leg.size() - 1, 1.0));  // from the calf down: a plain taper
    // A cylinder 6 voxels thick whose radii step by the distance transform's fractions of a voxel: no knee at 1
    // voxel, though 5.7 dips 5.3% below 6.0 (the same profile 100 times thicker in voxels has one).
    Chain4 tube;
    for (double r : {7.0, 6.6, 6.0, 6.0, 5.7, 6.0, 6.0, 5.9, 5.8}) tube.emplace_back(0, 0, 0, r);
    CHECK_FALSE(deepest_dip(tube, 2, tube.size() - 1, 1.0));
    CHECK(deepest_dip(tube, 2, tube.size() - 1, 0.01) == std::optional<std::size_t>(4));
    // The knee's dip (7.0 under 7.5 and 8.0) stands out of that noise.
    CHECK(deepest_dip(leg, 0, leg.size() - 1, 1.0) == std::optional<std::size_t>(3));
}

TEST_CASE("trunk_fit cuts a wiggling spine at thirds of its chord", "[autorig]") {
    Chain4 spine;
    for (int z = 0; z <= 30; ++z) spine.emplace_back(z % 2 == 0 ? 0.0 : 3.0, 0, z, 5);  // wiggles along x
    const Fit fit = trunk_fit(spine);
    REQUIRE(fit.cuts.size() == 4);
    CHECK(fit.cuts == std::vector<std::size_t>{0, 10, 20, 30});
    // Cut again between a hips' head moved up to z 6 and a chest's tail moved up to z 36: at z 16 and 26.
    Rig rig;
    rig.joints = {{0, 0, 6}, {0, 0, 10}, {0, 0, 20}, {0, 0, 36}};
    rig.joint_points = {0, 0, 0, 0};
    rig.bones = {{0, 1}, {1, 2}, {2, 3}};
    rig.names = {"hips", "spine", "chest"};
    rig.parents = {-1, 0, 1};
    recut_spine(rig, spine);
    CHECK(rig.joints[1][2] == 16);
    CHECK(rig.joints[2][2] == 26);
    CHECK(rig.joints[0][2] == 6);
    CHECK(rig.joints[3][2] == 36);
}

TEST_CASE("bend_corner moves a bent elbow from the rounded axis to the corner of the bones' lines; a straight "
          "limb keeps it", "[autorig]") {
    // An arm down x = 5, y = 40 from z 60 to 36, rounded over a quarter circle of radius 6 into a forearm along -y
    // at z 30: the lines meet at (5, 40, 30).
    const double pi = 3.14159265358979;
    Figure f(Vec(5, 40, 60), 5.0);
    std::uint32_t at = f.limb(0, Vec(5, 40, 36), 5, 5), elbow = 0;
    for (int k = 1; k <= 6; ++k) {
        const double a = k * pi / 12;
        at = f.limb(at, Vec(5, 34 + 6 * std::cos(a), 36 - 6 * std::sin(a)), 5, 5);
        if (k == 3) elbow = at;
    }
    f.limb(at, Vec(5, 10, 30), 5, 5);
    const Solid s(f, {10, 50, 70});
    std::vector<std::uint32_t> nodes(f.pos.size());
    for (std::uint32_t k = 0; k < nodes.size(); ++k) nodes[k] = k;
    Rig rig;
    const Vec e = f.pos[elbow];
    rig.joints = {{5, 40, 60}, {e.x(), e.y(), e.z()}, {5, 10, 30}};
    rig.joint_points = {0, 0, 0};
    rig.bones = {{0, 1}, {1, 2}};
    rig.names = {"upper_arm.L", "forearm.L"};
    rig.parents = {-1, 0};
    bend_corner(s.context(), rig, nodes, "upper_arm.L", "forearm.L");
    CHECK(rig.joints[1][0] == Approx(5).margin(0.3));
    CHECK(rig.joints[1][1] == Approx(40).margin(0.3));
    CHECK(rig.joints[1][2] == Approx(30).margin(0.3));
    // Straight: unchanged.
    Figure g(Vec(5, 40, 60), 5.0);
    g.limb(0, Vec(5, 40, 5), 5, 5);
    const Solid sg(g, {10, 50, 70});
    std::vector<std::uint32_t> straight(g.pos.size());
    for (std::uint32_t k = 0; k < straight.size(); ++k) straight[k] = k;
    rig.joints = {{5, 40, 60}, {5, 40, 30}, {5, 40, 5}};
    bend_corner(sg.context(), rig, straight, "upper_arm.L", "forearm.L");
    CHECK(rig.joints[1][2] == 30);
}

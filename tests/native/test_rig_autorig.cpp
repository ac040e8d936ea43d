// autorig's stages alone (native/src/rig/autorig/): scale axis, level-set tree, node tree, chain cutting, body-plan
// search, on small inputs whose answer is known (hands, hard body plans and the joints the medial axis does not show:
// test_rig_autorig_joints.cpp). Also run under ASan/UBSan by scripts/test.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>

#include "rig/autorig/chain_fit.hpp"
#include "rig/autorig/coarse.hpp"
#include "rig/autorig/node_tree.hpp"
#include "rig/autorig/shape_tree.hpp"
#include "rig/autorig/templates.hpp"

#include "autorig_fixture.hpp"

using namespace volrig;
using namespace volrig::rig_detail;

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

TEST_CASE("from_own_side drops a limb path's nodes before it reaches its side of the body", "[autorig]") {
    // A ring pelvis (a stick figure's): the path to the left leg (-x) starts on the ring's right side (x = 6),
    // runs round the ring's front to x = -6, then down the leg.
    Figure f(Vec(6, 0, 0), 2.0);
    const std::uint32_t front = f.limb(0, Vec(0, 6, 0), 2, 2);
    const std::uint32_t left = f.limb(front, Vec(-6, 0, 0), 2, 2);
    const std::uint32_t foot = f.limb(left, Vec(-6, 0, -40), 2, 2);
    const NodeTree t = f.tree();
    const std::vector<std::uint32_t> path = t.path(0, foot);
    const std::vector<std::uint32_t> own = t.from_own_side(path, Vec(-1, 0, 0), 0.0);
    REQUIRE(own.size() < path.size());
    CHECK(own.front() == 0);                     // still hangs from the root
    CHECK(t.at(own[1]).x() < 0);                 // then at once on the left
    for (std::size_t k = 1; k < own.size(); ++k) CHECK(t.at(own[k]).x() <= 0);
    CHECK(own.back() == foot);
    CHECK(t.from_own_side(path, Vec(1, 0, 0), 0.0) == path);  // a root on the limb's own side: kept
    // A path that reaches its side only after half its length (an arm folded across the body) keeps its nodes.
    Figure g(Vec(6, 0, 0), 2.0);
    const std::uint32_t stub = g.limb(g.limb(g.limb(0, Vec(6, 20, 0), 2, 2), Vec(-6, 20, 0), 2, 2), Vec(-6, 20, -4), 2, 2);
    const NodeTree u = g.tree();
    const std::vector<std::uint32_t> late = u.path(0, stub);
    CHECK(u.from_own_side(late, Vec(-1, 0, 0), 0.0) == late);
}

TEST_CASE("a path is rooted at its thicker end", "[autorig]") {
    Figure f(Vec(0, 0, 0), 3.0);
    f.limb(0, Vec(30, 0, 0), 3, 1);
    f.limb(0, Vec(-20, 0, 0), 3, 6);  // the thick end
    NodeTree t = f.tree();
    t.root_path_at_thicker_end();
    CHECK(t.at(t.root()).x() == Approx(-20));
}

TEST_CASE("a thick end on a neck or the shoulders becomes a leaf; a thick end that is the body stays the root", "[autorig]") {
    // A big head (radius 12) on a thin neck down to a trunk junction with two legs: the head is the thickest node.
    Figure mouse(Vec(0, 0, 40), 12.0);
    const std::uint32_t junction = mouse.limb(0, Vec(0, 0, 10), 3, 5);
    const std::uint32_t leg_a = mouse.limb(junction, Vec(15, 0, -20), 4, 3);
    mouse.limb(junction, Vec(-15, 0, -20), 4, 3);
    NodeTree t = mouse.tree();
    REQUIRE(t.root() == 0);
    t.root_off_an_end();
    CHECK(t.root() == junction);
    const auto leaves = t.leaves();
    CHECK(std::count(leaves.begin(), leaves.end(), 0u) == 1);  // the head is an extremity
    CHECK(std::count(leaves.begin(), leaves.end(), leg_a) == 1);
    // A big head right on the shoulders (its ball reaching into the junction's, its centre outside it): a leaf too.
    Figure child(Vec(0, 0, 24), 12.0);
    const std::uint32_t shoulders = child.limb(0, Vec(0, 0, 10), 4, 6);
    child.limb(shoulders, Vec(15, 0, -20), 4, 3);
    child.limb(shoulders, Vec(-15, 0, -20), 4, 3);
    NodeTree c = child.tree();
    REQUIRE(c.root() == 0);
    c.root_off_an_end();
    CHECK(c.root() == shoulders);
    // The same head with the junction's ball holding its centre (the thick end is the body): nothing moves.
    Figure blob(Vec(0, 0, 14), 12.0);
    const std::uint32_t j = blob.limb(0, Vec(0, 0, 10), 6, 6);
    blob.limb(j, Vec(15, 0, -20), 4, 3);
    blob.limb(j, Vec(-15, 0, -20), 4, 3);
    NodeTree u = blob.tree();
    u.root_off_an_end();
    CHECK(u.root() == 0);
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

TEST_CASE("limbs_short: a body's limbs carry its head; an arm's fingers do not carry the rest of it", "[autorig]") {
    // Every reading of the stick figure that has its head as head has limbs reaching as far as the head.
    std::uint32_t head = 0;
    const NodeTree t = stick_figure(head).tree();
    std::vector<PlanReading> all;
    search_plans(t, {std::nullopt, fitted_plan_weights(), {}}, &all);
    REQUIRE_FALSE(all.empty());
    for (const PlanReading& r : all)
        if (r.leaves[0] == head) CHECK(r.features[kLimbsShort] == 0.0);
    // An arm: the "head" is the shoulder end 100 away from a palm whose "limbs" are fingers 8 long.
    Figure arm(Vec(0, 0, 0), 3.0);
    const std::uint32_t shoulder_end = arm.limb(0, Vec(-100, 0, 0), 3, 4);
    for (int k = 0; k < 5; ++k) arm.limb(0, Vec(8, 2.0 * k - 4, 0), 1, 0.8);
    all.clear();
    search_plans(arm.tree(), {std::nullopt, fitted_plan_weights(), {}}, &all);
    CHECK(std::none_of(all.begin(), all.end(), [&](const PlanReading& r) {
        return r.leaves[0] == shoulder_end && r.features[kLimbsShort] < 0.8;
    }));
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
    const PlanSearch free = search_plans(t, {std::nullopt, fitted_plan_weights(), {}});
    REQUIRE(free.humanoid.score < plan_limit());
    CHECK(free.humanoid.head == head);
    CHECK(free.humanoid.score < free.quadruped.score);
    const PlanSearch up = search_plans(t, {Vec(0, 0, 1), fitted_plan_weights(), {}});
    CHECK(up.humanoid.head == head);
    // Told that up is -z, the figure's upright reading (its head as head) is no humanoid any more.
    const PlanSearch down = search_plans(t, {Vec(0, 0, -1), fitted_plan_weights(), {}});
    CHECK((down.humanoid.head != head || !(down.humanoid.score < plan_limit())));
}


TEST_CASE("search_plans reads four legs under a horizontal spine as a quadruped", "[autorig]") {
    std::uint32_t head = 0;
    const NodeTree t = Quadruped().figure(Vec(0, 0, 0), head).tree();
    for (const auto& up : {std::optional<Vec>{}, std::optional<Vec>{Vec(0, 0, 1)}}) {
        const PlanSearch s = search_plans(t, {up, fitted_plan_weights(), {}});
        REQUIRE(s.quadruped.score < plan_limit());
        CHECK(s.quadruped.head == head);
        CHECK(s.quadruped.score < s.humanoid.score);
    }
    // Upside down (told up is -z) the legs point up: no quadruped.
    CHECK_FALSE(search_plans(t, {Vec(0, 0, -1), fitted_plan_weights(), {}}).quadruped.score < plan_limit());
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

TEST_CASE("cross_section_ratio is 1 across a round limb and the width over the thickness across a sheet",
          "[autorig]") {
    // A rod of radius 4 along x, a plate 2 thick and 16 wide along x beside it (apart), a rod touching a trunk.
    Block block({60, 60, 60});
    Grid& g = block.g;
    std::vector<std::uint8_t>& mask = block.mask;
    std::fill(mask.begin(), mask.end(), 0);
    auto set = [&](std::int64_t x, std::int64_t y, std::int64_t z) { mask[static_cast<std::size_t>(g.index(x, y, z))] = 1; };
    for (std::int64_t x = 0; x < 60; ++x)
        for (std::int64_t y = 0; y < 60; ++y)
            for (std::int64_t z = 0; z < 60; ++z) {
                if ((y - 10) * (y - 10) + (z - 10) * (z - 10) <= 16) set(x, y, z);   // rod
                if (y >= 32 && y < 48 && z >= 10 && z < 12) set(x, y, z);           // plate
            }
    const RigContext c = block.context();
    const Vec along(1, 0, 0);
    CHECK(c.cross_section_ratio(Vec(30, 10, 10), along, 12) == Approx(1.0).margin(0.05));
    // The plate within reach 12 of its middle: 16 wide (all of it), 2 thick: std ratio 16 / 2.
    CHECK(c.cross_section_ratio(Vec(30, 40, 10.5), along, 12) == Approx(8.0).margin(0.6));
    // Within reach 4: the disc cuts it 8 wide.
    CHECK(c.cross_section_ratio(Vec(30, 40, 10.5), along, 4) == Approx(4.0).margin(0.8));
    // Across the rod (along y): its section is the rod's length within reach (a sheet-like section) ...
    CHECK(c.cross_section_ratio(Vec(30, 10, 10), Vec(0, 1, 0), 12) > 2.5);
    // Outside the object: 1.
    CHECK(c.cross_section_ratio(Vec(30, 25, 30), along, 12) == 1.0);
}

TEST_CASE("build_plan makes a chain of a part sticking out by a quarter of the body, not of a smaller one",
          "[autorig]") {
    // The stick figure (90 tall) with a part forward off its chest: 12 long (6 of its radii, an eighth of the body:
    // a fold, a bun) or 40 (a long tail or trunk).
    auto chains_of = [](double length) {
        std::uint32_t head = 0;
        Figure f = stick_figure(head);
        f.limb(20, Vec(0, -length, 20), 2, 2);  // node 20: the spine at z 20
        const Solid solid(f, {1, 1, 1});
        const PlanSearch s = search_plans(solid.tree, {Vec(0, 0, 1), fitted_plan_weights(), {}});
        REQUIRE(s.humanoid.score < plan_limit());
        REQUIRE(s.humanoid.head == head);
        const Candidate c = build_plan(solid.context(), s.humanoid, PlanKind::Humanoid, 0.35);
        return std::count_if(c.rig.names.begin(), c.rig.names.end(),
                             [](const std::string& n) { return n.rfind("chain.", 0) == 0; });
    };
    CHECK(chains_of(12.0) == 0);
    CHECK(chains_of(40.0) >= 1);
}

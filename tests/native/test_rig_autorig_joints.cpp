// autorig's stages alone (native/src/rig/autorig/), continued: hands, tails, hard body plans, and the joints the
// medial axis does not show (fused arms, knees, heels, wrists, chest, hips, head, trunk, elbows), on small inputs whose
// answer is known. Also run under ASan/UBSan by scripts/test.
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
    REQUIRE(hand_plan_score(p, fitted_plan_weights()) < plan_limit());
    CHECK(p.fingers == tips);
    CHECK(solid.tree.at(p.wrist).y() == Approx(10));
    const Candidate c = hand_rig(solid.context(), p);
    REQUIRE(c.rig.bones.size() == 16);
    CHECK(c.rig.kind == "hand");
    const auto& names = c.rig.names;
    CHECK(names[0].rfind("palm", 0) == 0);
    const std::string side = names[0].substr(4);
    CHECK(side == ".L");  // the thumb raised on +z: the palm faces +z, the thumb on the viewer's left
    for (const char* bone : {"thumb.01", "thumb.03", "f_index.01", "f_middle.02", "f_ring.03", "f_pinky.01"})
        CHECK(std::count(names.begin(), names.end(), bone + side) == 1);
    for (std::size_t b = 1; b < names.size(); ++b) CHECK(c.rig.parents[b] == static_cast<std::int32_t>(b % 3 == 1 ? 0 : b - 1));
    // Not a body plan: five fingers are no head, arms and legs.
    const PlanSearch plans = search_plans(solid.tree, {std::nullopt, fitted_plan_weights(), {}});
    CHECK(plans.humanoid.score > hand_plan_score(p, fitted_plan_weights()));
    CHECK(plans.quadruped.score > hand_plan_score(p, fitted_plan_weights()));
}

TEST_CASE("search_hand: a palm five times thicker than its fingers is a body, no palm", "[autorig]") {
    // A camel read as a hand: its hump the wrist, its body the palm, its legs the fingers, its neck the thumb.
    std::array<std::uint32_t, 5> tips{};
    const HandPlan thin = search_hand(hand_figure(tips).tree()), thick = search_hand(hand_figure(tips, 22).tree());
    const std::vector<double>& w = fitted_plan_weights();
    REQUIRE(hand_plan_score(thin, w) < plan_limit());
    CHECK(thick.score >= thin.score + 2.0);
    CHECK_FALSE(hand_plan_score(thick, w) < plan_limit());
}

TEST_CASE("a stick figure is no hand", "[autorig]") {
    std::uint32_t head = 0;
    Figure f = stick_figure(head);
    const std::vector<double>& w = fitted_plan_weights();
    CHECK_FALSE(hand_plan_score(search_hand(f.tree()), w) < plan_limit());
    f.limb(0, Vec(0, -15, -5), 3, 2);  // a sixth extremity: a tail
    CHECK_FALSE(hand_plan_score(search_hand(f.tree()), w) < plan_limit());
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

/// The humanoid reading of a figure with this head (the first leaf of a reading), the lowest scored.
PlanReading humanoid_reading(const NodeTree& t, std::uint32_t head) {
    std::vector<PlanReading> all;
    search_plans(t, {Vec(0, 0, 1), fitted_plan_weights(), {}}, &all);
    PlanReading best;
    double best_score = std::numeric_limits<double>::infinity();
    for (const PlanReading& r : all)
        if (r.kind == "humanoid" && r.leaves[0] == head && plan_score(r.features, fitted_plan_weights()) < best_score) {
            best = r;
            best_score = plan_score(r.features, fitted_plan_weights());
        }
    return best;
}

TEST_CASE("search_plans: a figure whose hands reach its feet shows it in h_hands_low", "[autorig]") {
    std::uint32_t head = 0;
    const NodeTree stick = stick_figure(head).tree();
    const PlanReading standing = humanoid_reading(stick, head);
    // The same figure with arms down to the ground (a quadruped's four feet read as legs and arms).
    Figure f(Vec(0, 0, 0), 8.0);
    const std::uint32_t chest = f.limb(0, Vec(0, 0, 30), 8, 7);
    f.limb(f.limb(chest, Vec(0, 0, 36), 4, 4), Vec(0, 0, 45), 5, 4);
    for (double s : {-1.0, 1.0}) {
        const std::uint32_t elbow = f.limb(f.limb(chest, Vec(s * 10, 0, 30), 3, 3), Vec(s * 18, 0, 0), 2.5, 2.5);
        f.limb(elbow, Vec(s * 20, 0, -45), 2, 1.5);
        f.limb(f.limb(0, Vec(s * 6, 0, -22), 4.5, 4), Vec(s * 6, 0, -45), 4, 3);
    }
    const NodeTree t = f.tree();
    std::uint32_t low_head = 0;
    for (std::uint32_t v : t.leaves())
        if (t.at(v).z() > 40) low_head = v;
    const PlanReading low = humanoid_reading(t, low_head);
    REQUIRE(standing.kind == "humanoid");
    REQUIRE(low.kind == "humanoid");
    CHECK(standing.features[kHHandsLow] == 0.0);
    CHECK(low.features[kHHandsLow] >= 0.8 * kHandsAboveFeet);
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
        const PlanSearch s = search_plans(t, {up, fitted_plan_weights(), {}});
        REQUIRE(s.quadruped.score < plan_limit());
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
    const PlanSearch s = search_plans(t, {Vec(0, 0, 1), fitted_plan_weights(), {}});
    REQUIRE(s.quadruped.score < plan_limit());
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
    Leg bowed(12.0, 100.0);  // 12 off the line: more than its radius, but a bend of 0.12 of its length (27 degrees)
    Solid sw(bowed.f, {10, 25, 110});
    straight_knee(sw.context(), bowed.rig, bowed.nodes, ".L");
    CHECK(bowed.rig.joints[2][2] == Approx(100 * (1 - share)).margin(1.5));
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

TEST_CASE("place_head puts the head joint 0.6 of the way down from the top and its tail straight up, half-way",
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
    CHECK(rig.joints[2][2] == Approx(rig.joints[1][2] + kHeadTail * (top - rig.joints[1][2])).margin(0.6));
}

TEST_CASE("end_hands_and_feet ends hands at the knuckles and feet at the ball, a hand holding fingers kept", "[autorig]") {
    Rig rig;
    rig.joints = {{0, 0, 0}, {10, 0, 0}, {0, 0, 0}, {-10, 0, 0}, {-12, 0, 0}, {0, 0, -50}, {0, -9, -50}};
    rig.joint_points = {0, 0, 0, 0, 0, 0, 0};
    rig.bones = {{0, 1}, {2, 3}, {3, 4}, {5, 6}};
    rig.names = {"hand.L", "hand.R", "finger.R", "foot.L"};
    rig.parents = {-1, -1, 1, -1};
    end_hands_and_feet(rig);
    CHECK(rig.joints[1][0] == Approx(10 * kHandToKnuckles));
    CHECK(rig.joint_points[1] == -1);
    CHECK(rig.joints[3][0] == -10);  // the finger's root stays
    CHECK(rig.joints[6][1] == Approx(-9 * kFootToBall));
    CHECK(rig.joints[6][2] == -50);
    CHECK(rig.joints[0][0] == 0);  // heads stay
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

TEST_CASE("match_limb_fits gives a leg whose knee fell on its ankle the other leg's proportions", "[autorig]") {
    // Two straight legs from a pelvis at z 110: 8 across, 100 down, a foot 15 forward; nodes 1 apart.
    Figure f(Vec(20, 20, 110), 8.0);
    std::vector<std::uint32_t> leg[2];
    for (int s = 0; s < 2; ++s) {
        const double x = 20 + (s ? 8.0 : -8.0);
        const auto first = static_cast<std::uint32_t>(f.pos.size());
        f.limb(f.limb(f.limb(0, Vec(x, 20, 110), 8, 6), Vec(x, 20, 10), 6, 4), Vec(x, 5, 10), 3, 2);
        leg[s].push_back(0);
        for (auto k = first; k < f.pos.size(); ++k) leg[s].push_back(k);
    }
    REQUIRE(leg[0].size() == 124);
    const Solid solid(f, {40, 40, 120});
    // Indices into each leg: its pelvis bone ends at 8, the knee at 58 (z 60), the ankle at 108, the toe at 123.
    Fit fit[2] = {Fit{{0, 8, 58, 108, 123}, 0.0}, Fit{{0, 8, 106, 113, 123}, 0.0}};  // leg 1: knee on the ankle
    match_limb_fits(solid.context(), leg, fit, kLegProportions);
    CHECK(fit[0].cuts == std::vector<std::size_t>{0, 8, 58, 108, 123});
    REQUIRE(fit[1].cuts.size() == 5);
    CHECK(fit[1].cuts[1] == 8);  // the pelvis bone keeps its cut
    CHECK(std::abs(static_cast<double>(fit[1].cuts[2]) - 58) <= 2);
    CHECK(std::abs(static_cast<double>(fit[1].cuts[3]) - 108) <= 2);
    // Shares within kLimbMismatch: both fits stay.
    Fit close[2] = {Fit{{0, 8, 58, 108, 123}, 0.0}, Fit{{0, 8, 62, 108, 123}, 0.0}};
    match_limb_fits(solid.context(), leg, close, kLegProportions);
    CHECK(close[1].cuts == std::vector<std::size_t>{0, 8, 62, 108, 123});
}

TEST_CASE("raise_low_hips: legs forking far below the neck get their hips at the least hip height", "[autorig]") {
    // Legs from a fork at z 30 down to soles at z 0 (end radius 1); the neck's base at z 100.
    auto body = [](double fork) {
        Figure f(Vec(20, 20, fork), 6.0);
        std::vector<std::uint32_t> leg[2];
        for (int s = 0; s < 2; ++s) {
            const double x = 20 + (s ? 8.0 : -8.0);
            const auto first = static_cast<std::uint32_t>(f.pos.size());
            f.limb(f.limb(0, Vec(x, 20, fork), 4, 4), Vec(x, 20, 1), 4, 1);
            for (auto k = first; k < f.pos.size(); ++k) leg[s].push_back(k);
        }
        Rig rig;
        rig.joints = {{20, 20, fork}, {20, 20, 100}, {20, 20, 110}, {12, 20, fork}, {12, 20, 8}, {12, 20, 1},
                      {28, 20, fork}, {28, 20, 8}, {28, 20, 1}};
        rig.joint_points.assign(rig.joints.size(), 0);
        rig.bones = {{0, 1}, {1, 2}, {3, 4}, {4, 5}, {6, 7}, {7, 8}};
        rig.names = {"hips", "neck", "thigh.L", "shin.L", "thigh.R", "shin.R"};
        rig.parents = {-1, 0, 0, 2, 0, 4};
        return std::make_tuple(f, std::vector<std::uint32_t>(leg[0]), std::vector<std::uint32_t>(leg[1]), rig);
    };
    const std::string sfx[2] = {".L", ".R"};
    auto [f, l0, l1, rig] = body(30.0);
    const std::vector<std::uint32_t> leg[2] = {l0, l1};
    const Solid solid(f, {40, 40, 120});
    raise_low_hips(solid.context(), rig, leg, sfx, Vec(0, 0, 1));
    const double least = kLeastHipHeight * 100.0;  // the sole at z 0: the last node (z 1) less its radius 1
    const double share = kLegProportions[1] / (kLegProportions[1] + kLegProportions[2]);
    for (std::size_t hip : {3u, 6u}) {
        CHECK(rig.joints[hip][2] == Approx(least).margin(0.01));
        CHECK(rig.joints[hip + 1][2] == Approx(least + share * (1 - least)).margin(1.0));  // the knee, on the axis
        CHECK(rig.joints[hip + 1][0] == Approx(rig.joints[hip][0]));
    }
    // Hips above it stay.
    auto [g, m0, m1, high] = body(70.0);
    const std::vector<std::uint32_t> legs_high[2] = {m0, m1};
    const Solid solid_high(g, {40, 40, 120});
    raise_low_hips(solid_high.context(), high, legs_high, sfx, Vec(0, 0, 1));
    CHECK(high.joints[3][2] == 70);
    CHECK(high.joints[4][2] == 8);
}

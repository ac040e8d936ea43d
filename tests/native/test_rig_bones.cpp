// Rigs from a scan's bones (volrig/rig.hpp bone_segments, rig_to_bones) on a synthetic "femur / tibia" phantom:
// two cylinders along z with a gap between them (the knee at the gap's centre), or joined by a thin neck (split at
// the narrowest section). The Visible Human's joints: tests/python/test_bones.py.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>

#include "rig/bones/bones.hpp"
#include "volrig/components.hpp"
#include "volrig/error.hpp"
#include "volrig/rig.hpp"

using namespace volrig;

namespace {

constexpr double kRadius = 8.0;

struct Phantom {
    Grid grid;
    std::vector<std::uint8_t> bone;
};

/// Bone on a grid of `dims` 1 mm voxels wherever inside(x, y, z, r) holds (r: the distance from the axis x = y = 20).
template <class F>
Phantom phantom_of(const std::array<std::int64_t, 3>& dims, F&& inside) {
    Phantom p;
    p.grid.dims = dims;
    p.bone.assign(static_cast<std::size_t>(p.grid.voxel_count()), 0);
    for (std::int64_t z = 0; z < dims[2]; ++z)
        for (std::int64_t y = 0; y < dims[1]; ++y)
            for (std::int64_t x = 0; x < dims[0]; ++x)
                p.bone[static_cast<std::size_t>(p.grid.index(x, y, z))] = inside(x, y, z, std::hypot(x - 20.0, y - 20.0));
    return p;
}

/// A femur (z 62..106) above a tibia (z 12..56), radius 8 about x = y = 20 (1 mm voxels); `neck` > 0 joins them
/// through the gap z 57..61 with a cylinder of that radius.
Phantom femur_tibia(double neck) {
    return phantom_of({40, 40, 120}, [neck](std::int64_t, std::int64_t, std::int64_t z, double r) {
        const bool shaft = (z >= 62 && z <= 106) || (z >= 12 && z <= 56);
        return (shaft && r <= kRadius) || (z > 56 && z < 62 && r <= neck);
    });
}

/// A leg rig: thigh.L from (20, 20, 112) to a knee guessed at (23, 18, 66), shin.L down to (20, 20, 6).
Rig leg_rig() {
    Rig r;
    r.joints = {{20, 20, 112}, {23, 18, 66}, {20, 20, 6}};
    r.bones = {{0, 1}, {1, 2}};
    r.names = {"thigh.L", "shin.L"};
    r.parents = {-1, 0};
    r.kind = "humanoid";
    return r;
}

const BoneJoint& joint_named(const BoneRig& b, const std::string& name) {
    for (const BoneJoint& j : b.joints)
        if (j.name == name) return j;
    FAIL("no joint " << name);
    return b.joints.front();
}

}  // namespace

TEST_CASE("bone segments: an opening parts bones, every bone voxel in one segment", "[rig][bones]") {
    const Phantom p = femur_tibia(0);
    const BoneSegments s = bone_segments(p.grid, p.bone.data());
    REQUIRE(s.sizes.size() == 2);
    const std::int32_t femur = s.labels[static_cast<std::size_t>(p.grid.index(20, 20, 80))];
    const std::int32_t tibia = s.labels[static_cast<std::size_t>(p.grid.index(20, 20, 30))];
    CHECK(femur != tibia);
    std::int64_t total = 0;
    for (std::size_t i = 0; i < p.bone.size(); ++i) {
        CHECK((p.bone[i] != 0) == (s.labels[i] != 0));
        total += p.bone[i];
    }
    CHECK(s.sizes[0] + s.sizes[1] == total);
}

TEST_CASE("bone rig: the knee goes to the centre of the gap between femur and tibia", "[rig][bones]") {
    const Phantom p = femur_tibia(0);
    const BoneRig b = rig_to_bones(p.grid, p.bone.data(), leg_rig());
    const BoneJoint& knee = joint_named(b, "knee.L");
    CHECK(knee.how == "contact");
    CHECK(knee.parent_segment != knee.child_segment);
    CHECK(knee.joint == 1);
    CHECK(std::abs(knee.to[0] - 20.0) <= 1.0);  // the gap's centre: (20, 20, 59), exact within a voxel
    CHECK(std::abs(knee.to[1] - 20.0) <= 1.0);
    CHECK(std::abs(knee.to[2] - 59.0) <= 1.0);
    CHECK(b.rig.joints[1] == knee.to);
    CHECK(b.rig.names == leg_rig().names);  // topology and names unchanged
    CHECK(b.rig.bones == leg_rig().bones);
    CHECK(b.bone_segment[0] == knee.parent_segment);
    CHECK(b.bone_segment[1] == knee.child_segment);
}

TEST_CASE("bone rig: touching bones split at the narrowest section", "[rig][bones]") {
    const Phantom p = femur_tibia(3.0);
    BoneRigOptions opt;
    opt.opening = 1.0;  // one voxel: the neck (radius 3) survives it, femur and tibia stay one segment
    REQUIRE(bone_segments(p.grid, p.bone.data(), opt).sizes.size() == 1);
    const BoneRig b = rig_to_bones(p.grid, p.bone.data(), leg_rig(), opt);
    const BoneJoint& knee = joint_named(b, "knee.L");
    CHECK(knee.how == "section");
    CHECK(std::abs(knee.to[0] - 20.0) <= 1.0);
    CHECK(std::abs(knee.to[1] - 20.0) <= 1.0);
    CHECK(std::abs(knee.to[2] - 59.0) <= 1.0);
    // the split: the tibia is a segment of its own, the femur keeps the other
    const std::int32_t femur = b.segments.labels[static_cast<std::size_t>(p.grid.index(20, 20, 80))];
    const std::int32_t tibia = b.segments.labels[static_cast<std::size_t>(p.grid.index(20, 20, 30))];
    CHECK(femur != tibia);
    CHECK(tibia == knee.child_segment);
    for (std::int64_t z = 12; z <= 56; ++z)
        CHECK(b.segments.labels[static_cast<std::size_t>(p.grid.index(20 + 7, 20, z))] == tibia);
    for (std::int64_t z = 62; z <= 106; ++z)
        CHECK(b.segments.labels[static_cast<std::size_t>(p.grid.index(20, 20 - 7, z))] == femur);
}

/// A hip: the femur and tibia of femur_tibia (1 mm voxels, the femur z 62..100 here) with a femoral head (radius 10
/// about (20, 20, 108)) under an acetabulum (a plate z 121..132 over x 5..55), on a grid 70 wide.
Phantom hip_joint() {
    return phantom_of({70, 40, 140}, [](std::int64_t x, std::int64_t y, std::int64_t z, double r) {
        const bool shaft = (z >= 62 && z <= 100) || (z >= 12 && z <= 56);
        const bool head = std::hypot(r, z - 108.0) <= 10.0;
        const bool socket = z >= 121 && z <= 132 && x >= 5 && x <= 55 && y >= 5 && y <= 35;
        return (shaft && r <= kRadius) || head || socket;
    });
}

TEST_CASE("bone rig: a hip the outer shape put off its femur is found up the femur's shaft", "[rig][bones]") {
    const Phantom p = hip_joint();
    Rig r = leg_rig();
    r.joints = {{58, 20, 108}, {20, 20, 59}, {20, 20, 10}};  // the hip 38 mm out to the side: no femur near it
    const BoneRig b = rig_to_bones(p.grid, p.bone.data(), r);
    const BoneJoint& hip = joint_named(b, "hip.L");
    CHECK(joint_named(b, "knee.L").how == "contact");
    CHECK(hip.how == "ball");  // the head's sphere, facing its socket
    CHECK(std::abs(hip.to[0] - 20.0) <= 1.5);
    CHECK(std::abs(hip.to[1] - 20.0) <= 1.5);
    CHECK(std::abs(hip.to[2] - 108.0) <= 1.5);
    CHECK(hip.child_segment == joint_named(b, "knee.L").parent_segment);  // the femur the knee found
    // Near its femur, the same guess is left to the sphere fit from where it is (no shaft seed needed)
    r.joints[0] = {24, 20, 112};
    CHECK(std::abs(joint_named(rig_to_bones(p.grid, p.bone.data(), r), "hip.L").to[2] - 108.0) <= 1.5);
}

TEST_CASE("bone rig: bad input is refused clearly; rigs without limbs are kept", "[rig][bones]") {
    const Phantom p = femur_tibia(0);
    const std::vector<std::uint8_t> empty(p.bone.size(), 0);
    CHECK_THROWS_WITH(bone_segments(p.grid, empty.data()), Catch::Contains("bone mask is empty"));
    CHECK_THROWS_AS(rig_to_bones(p.grid, empty.data(), leg_rig()), Error);
    BoneRigOptions bad;
    bad.opening = -1;
    CHECK_THROWS_AS(bone_segments(p.grid, p.bone.data(), bad), Error);
    Rig chains = leg_rig();
    chains.names = {"chain.001", "chain.002"};
    const BoneRig b = rig_to_bones(p.grid, p.bone.data(), chains);
    CHECK(b.joints.empty());
    CHECK(b.rig.joints == chains.joints);
}

// ---- when the flesh is missing (bare_bone_share, bone_body) --------------------------------------------------------

namespace {

/// The phantom's bones inside a body: a cylinder of `skin` mm about them (0: the bone alone is the body).
std::vector<std::uint8_t> body_around(const Phantom& p, double skin) {
    std::vector<std::uint8_t> body = p.bone;
    for (std::int64_t z = 4; z < 116; ++z)
        for (std::int64_t y = 0; y < 40; ++y)
            for (std::int64_t x = 0; x < 40; ++x)
                if (skin > 0 && std::hypot(x - 20.0, y - 20.0) <= kRadius + skin)
                    body[static_cast<std::size_t>(p.grid.index(x, y, z))] = 1;
    return body;
}

}  // namespace

TEST_CASE("bare bone share: about 0 under skin, about 1 for the bone alone", "[rig][bones]") {
    const Phantom p = femur_tibia(0);
    const auto skinned = body_around(p, 6.0);
    CHECK(bare_bone_share(p.grid, skinned.data(), p.bone.data()) == 0.0);
    CHECK(bare_bone_share(p.grid, p.bone.data(), p.bone.data()) == 1.0);
    // Bones poking out of a body (a fleshless leg beside a skinned one): the share is the bare bone's part of the
    // surface, between the two.
    auto half = skinned;
    for (std::int64_t z = 4; z < 60; ++z)
        for (std::int64_t y = 0; y < 40; ++y)
            for (std::int64_t x = 0; x < 40; ++x) {
                const auto i = static_cast<std::size_t>(p.grid.index(x, y, z));
                half[i] = p.bone[i];
            }
    const double share = bare_bone_share(p.grid, half.data(), p.bone.data());
    CHECK(share > kBareBoneShare);
    CHECK(share < 0.9);
    // An empty body has no surface.
    const std::vector<std::uint8_t> none(p.bone.size(), 0);
    CHECK(bare_bone_share(p.grid, none.data(), p.bone.data()) == 0.0);
}

TEST_CASE("bone body: grown until the bones are one body, the gap bridged", "[rig][bones]") {
    const Phantom p = femur_tibia(0);  // two bones 5 mm apart (z 57..61 empty)
    const BoneBody b = bone_body(p.grid, p.bone.data());
    // The median depth of a radius-8 cylinder's voxels is a few mm: the first radius already bridges 5 mm.
    CHECK(b.joined == 1.0);
    CHECK(b.radius >= 2.5);
    CHECK(b.radius < 2 * kRadius);
    std::int64_t grown = 0;
    for (std::size_t i = 0; i < p.bone.size(); ++i) {
        if (p.bone[i]) REQUIRE(b.mask[i] == 1);  // every bone voxel in the body
        grown += b.mask[i];
    }
    // The body is the bones thickened by the radius, bounded: no more than the cylinder of radius 8 + radius.
    const double cap = M_PI * std::pow(kRadius + b.radius + 1, 2) * (106 - 12 + 2 * b.radius + 2);
    CHECK(static_cast<double>(grown) < cap);
    CHECK(b.mask[static_cast<std::size_t>(p.grid.index(20, 20, 59))] == 1);  // the gap's centre
    // Far from the bone (the grid's corner, where an unpadded transform would see the grid's face as bone): out.
    CHECK(b.mask[static_cast<std::size_t>(p.grid.index(0, 0, 0))] == 0);
    CHECK(b.mask[static_cast<std::size_t>(p.grid.index(39, 39, 119))] == 0);
}

TEST_CASE("bone body: bones far apart stay apart after the last growth; an empty bone is refused", "[rig][bones]") {
    Phantom p;
    p.grid.dims = {200, 8, 8};
    p.bone.assign(static_cast<std::size_t>(p.grid.voxel_count()), 0);
    for (std::int64_t x : {2, 3, 196, 197})  // two thin plates 193 voxels apart
        for (std::int64_t y = 2; y < 6; ++y)
            for (std::int64_t z = 2; z < 6; ++z) p.bone[static_cast<std::size_t>(p.grid.index(x, y, z))] = 1;
    const BoneBody b = bone_body(p.grid, p.bone.data());
    CHECK(b.joined == 0.5);
    // Plates two voxels thick: depth 1, so the first radius is 2, grown kBoneBodySteps - 1 times.
    CHECK(b.radius == Approx(2.0 * std::pow(kBoneBodyGrowth, kBoneBodySteps - 1)));
    const std::vector<std::uint8_t> none(p.bone.size(), 0);
    CHECK_THROWS_AS(bone_body(p.grid, none.data()), Error);
}

namespace {

/// Random bone: balls of radius 1.5-4 voxels scattered over a small grid (some cut by its border), the sparse
/// passes' test subject.
Phantom random_bone(unsigned seed, const std::array<std::int64_t, 3>& dims) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<std::array<double, 4>> balls(12);
    for (auto& b : balls)
        b = {u(rng) * static_cast<double>(dims[0]), u(rng) * static_cast<double>(dims[1]),
             u(rng) * static_cast<double>(dims[2]), 1.5 + 2.5 * u(rng)};
    Phantom p = phantom_of(dims, [&](std::int64_t x, std::int64_t y, std::int64_t z, double) {
        return std::any_of(balls.begin(), balls.end(), [&](const auto& b) {
            return std::hypot(x - b[0], y - b[1], z - b[2]) <= b[3];
        });
    });
    p.grid.spacing = {1.0, 1.0, 2.0};  // (an opening of 2 mm: 2 steps; the slices one)
    return p;
}

/// bone_segments by its definition on the dense grid: `steps` 6-neighbour erosions (the border erodes), the
/// 26-connected components of at least `min_voxels`, every other bone voxel taking the core it reaches first.
std::vector<std::int32_t> dense_segments(const Phantom& p, int steps, std::int64_t min_voxels) {
    const Grid& g = p.grid;
    std::vector<std::uint8_t> a(p.bone), b(a.size());
    for (int s = 0; s < steps; ++s) {
        for (std::int64_t z = 0; z < g.dims[2]; ++z)
            for (std::int64_t y = 0; y < g.dims[1]; ++y)
                for (std::int64_t x = 0; x < g.dims[0]; ++x) {
                    const auto at = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
                        return i >= 0 && j >= 0 && k >= 0 && i < g.dims[0] && j < g.dims[1] && k < g.dims[2] &&
                               a[static_cast<std::size_t>(g.index(i, j, k))];
                    };
                    b[static_cast<std::size_t>(g.index(x, y, z))] = at(x, y, z) && at(x - 1, y, z) && at(x + 1, y, z) &&
                                                                   at(x, y - 1, z) && at(x, y + 1, z) &&
                                                                   at(x, y, z - 1) && at(x, y, z + 1);
                }
        a.swap(b);
    }
    Components c = label_components(g, a.data());
    for (auto& l : c.labels)
        if (l > 0 && c.sizes[static_cast<std::size_t>(l - 1)] < min_voxels) l = 0;
    std::vector<std::uint8_t> code(a.size());
    for (std::size_t i = 0; i < code.size(); ++i) code[i] = c.labels[i] ? 1 : (p.bone[i] ? 2 : 0);
    const std::vector<std::int64_t> pairs = nearest_seed_fill(g, code.data());
    for (std::size_t k = 0; k + 1 < pairs.size(); k += 2)
        c.labels[static_cast<std::size_t>(pairs[k])] = c.labels[static_cast<std::size_t>(pairs[k + 1])];
    return c.labels;
}

}  // namespace

TEST_CASE("bone segments: the sparse passes equal the dense definition on random bone", "[rig][bones]") {
    for (unsigned seed = 1; seed <= 12; ++seed) {
        const Phantom p = random_bone(seed, {23, 19, 14});
        BoneRigOptions opt;
        opt.opening = 2.0;     // two erosion steps at 1 mm
        opt.min_volume = 8.0;  // 4 voxels of 2 mm^3: the floor of 8 voxels
        std::vector<std::int32_t> want;
        try {
            want = dense_segments(p, 2, 8);
        } catch (const Error&) {
            continue;
        }
        if (std::none_of(want.begin(), want.end(), [](std::int32_t l) { return l > 0; })) {
            CHECK_THROWS_AS(bone_segments(p.grid, p.bone.data(), opt), Error);
            continue;
        }
        const BoneSegments s = bone_segments(p.grid, p.bone.data(), opt);
        CHECK(s.labels == want);
    }
}

TEST_CASE("bone contact: the bucketed search equals the brute-force one", "[rig][bones]") {
    using rig_detail::P3;
    for (unsigned seed = 1; seed <= 6; ++seed) {
        const Phantom a = random_bone(seed, {30, 26, 18}), b = random_bone(seed + 100, {30, 26, 18});
        std::vector<std::int32_t> labels(a.bone.size());
        for (std::size_t i = 0; i < labels.size(); ++i) labels[i] = a.bone[i] ? 1 : (b.bone[i] ? 2 : 0);
        const P3 centre{15, 13, 18};
        const rig_detail::Patch pa = rig_detail::patch_of(a.grid, labels, 1, centre, 14);
        const rig_detail::Patch pb = rig_detail::patch_of(a.grid, labels, 2, centre, 14);
        for (const double reach : {3.0, 40.0}) {
            const rig_detail::Contact got = rig_detail::contact_of(a.grid, pa, pb, reach, 1.5);
            // brute force: every surface voxel against every other's
            const auto nearest = [](const rig_detail::Patch& p, const rig_detail::Patch& q, std::size_t k) {
                double best = std::numeric_limits<double>::infinity();
                for (std::size_t m = 0; m < q.pos.size(); ++m)
                    if (q.surface[m]) best = std::min(best, rig_detail::dist2(p.pos[k], q.pos[m]));
                return std::sqrt(best);
            };
            double gap = std::numeric_limits<double>::infinity();
            for (std::size_t k = 0; k < pa.pos.size(); ++k)
                if (pa.surface[k]) gap = std::min(gap, nearest(pa, pb, k));
            REQUIRE(got.found == (gap <= reach));
            if (!got.found) continue;
            CHECK(got.gap == gap);
            std::size_t na = 0, nb = 0;
            for (std::size_t k = 0; k < pa.pos.size(); ++k) na += pa.surface[k] && nearest(pa, pb, k) <= gap + 1.5;
            for (std::size_t k = 0; k < pb.pos.size(); ++k) nb += pb.surface[k] && nearest(pb, pa, k) <= gap + 1.5;
            CHECK(got.a.size() == na);
            CHECK(got.b.size() == nb);
        }
    }
}

TEST_CASE("bone segments: the defaults scale with the skeleton (a femur and tibia a tenth the size)", "[rig][bones]") {
    Phantom p = femur_tibia(0);
    p.grid.spacing = {0.1, 0.1, 0.1};  // 4.5 mm long bones: an adult's 4 mm opening would erode them away
    const BoneSegments s = bone_segments(p.grid, p.bone.data());
    REQUIRE(s.sizes.size() == 2);
    CHECK(s.labels[static_cast<std::size_t>(p.grid.index(20, 20, 80))] !=
          s.labels[static_cast<std::size_t>(p.grid.index(20, 20, 30))]);
    BoneRigOptions adult;
    adult.opening = 4.0;
    CHECK_THROWS_AS(bone_segments(p.grid, p.bone.data(), adult), Error);
    Rig r = leg_rig();
    for (auto& j : r.joints)
        for (double& c : j) c *= 0.1;
    const BoneRig fit = rig_to_bones(p.grid, p.bone.data(), r);
    const BoneJoint& knee = joint_named(fit, "knee.L");
    CHECK(knee.how == "contact");
    CHECK(std::abs(knee.to[2] - 5.9) <= 0.15);  // the gap z 57..61 (voxels): its centre at 5.9 mm
}

TEST_CASE("bone rig: a bone fused on to a segment's end is found behind the contact by its valley", "[rig][bones]") {
    // a "tibia" (z 40..110, radius 8) and a "talus" (z 14..33, radius 8) fused through a neck (z 34..39) of radius
    // `neck`; the contact found at the talus' far end (z 16), the parent bone pointing down
    const auto fused = [](double neck) {
        const Phantom p = phantom_of({40, 40, 120}, [neck](std::int64_t, std::int64_t, std::int64_t z, double r) {
            return ((z >= 40 && z <= 110) || (z >= 14 && z <= 33)) ? r <= kRadius : (z > 33 && z < 40 && r <= neck);
        });
        std::vector<std::int32_t> labels(p.bone.begin(), p.bone.end());
        const rig_detail::P3 at{20, 20, 16}, down{0, 0, -1};
        const rig_detail::Patch patch = rig_detail::patch_of(p.grid, labels, 1, at, 45);
        return rig_detail::fused_end(patch, at, down, 15, 30, 10, 1.0, 0.1);
    };
    const rig_detail::Section s = fused(6.0);  // the neck holds 56% of a full section's bone
    REQUIRE(s.found);
    CHECK(std::abs(s.centre[2] - 36.5) <= 2.0);
    CHECK(std::hypot(s.centre[0] - 20, s.centre[1] - 20) <= 1.0);
    CHECK_FALSE(fused(kRadius).found);  // one even bone: no valley
    CHECK_FALSE(fused(7.8).found);      // a valley under a tenth of its wall: not a joint
}

namespace {

/// A phantom with every `step`-th slice along z kept from slice `phase` (slices `step` mm apart, origin moved up).
Phantom every_slice(const Phantom& p, int step, int phase) {
    Phantom out;
    out.grid = p.grid;
    out.grid.dims[2] = (p.grid.dims[2] - phase + step - 1) / step;
    out.grid.spacing[2] = p.grid.spacing[2] * step;
    out.grid.origin[2] = p.grid.origin[2] + phase * p.grid.spacing[2];
    const std::int64_t slice = p.grid.dims[0] * p.grid.dims[1];
    for (std::int64_t z = 0; z < out.grid.dims[2]; ++z) {
        const auto from = p.bone.begin() + (z * step + phase) * slice;
        out.bone.insert(out.bone.end(), from, from + slice);
    }
    return out;
}

}  // namespace

TEST_CASE("bone slices: a tilted rod on slices 4 mm apart interpolated back up to its outline", "[rig][bones]") {
    // a rod of radius 6 tilted 30 degrees from z: its cross-sections move 2.3 mm a slice, so the slices alone
    // overlap less than the rod does; shape-based interpolation puts the rod back between them
    const double t = std::tan(30.0 * 3.14159265358979 / 180.0);
    const Phantom full = phantom_of({60, 40, 60}, [t](std::int64_t x, std::int64_t y, std::int64_t z, double) {
        return std::hypot(static_cast<double>(x) - 18.0 - t * static_cast<double>(z), static_cast<double>(y) - 20.0) <= 6.0 &&
               z >= 4 && z <= 52;
    });
    for (int phase = 0; phase < 4; ++phase) {
        const Phantom thin = every_slice(full, 4, phase);
        const auto fine = rig_detail::refine_slices(thin.grid, thin.bone.data());
        REQUIRE(fine);
        CHECK(fine->axis == 2);
        CHECK(fine->factor == 4);
        CHECK(fine->grid.spacing[2] == Approx(1.0));
        std::int64_t differ = 0, inside = 0;
        for (std::int64_t z = 0; z < fine->grid.dims[2]; ++z)
            for (std::int64_t y = 0; y < fine->grid.dims[1]; ++y)
                for (std::int64_t x = 0; x < fine->grid.dims[0]; ++x) {
                    const std::int64_t fz = static_cast<std::int64_t>(std::lround(fine->grid.origin[2])) + z,
                                       fy = fine->lo[1] + y, fx = fine->lo[0] + x;
                    if (fz < 0 || fz >= full.grid.dims[2]) continue;
                    const bool want = full.bone[static_cast<std::size_t>(full.grid.index(fx, fy, fz))] != 0;
                    const bool got = fine->bone[static_cast<std::size_t>(fine->grid.index(x, y, z))] != 0;
                    inside += want;
                    // a voxel may differ only on the rod's outline: within a voxel and a half of its surface (each
                    // slice's outline is jagged by a voxel, and the blend of two such outlines by up to half more)
                    const double r = std::hypot(static_cast<double>(fx) - 18.0 - t * static_cast<double>(fz),
                                                static_cast<double>(fy) - 20.0);
                    if (want != got && std::abs(r - 6.0) > 1.5 && fz > 8 && fz < 48) ++differ;
                }
        CHECK(differ == 0);
        CHECK(inside > 0);
        // the slices themselves are kept as they were
        for (std::int64_t z = 0; z < thin.grid.dims[2]; ++z)
            for (std::int64_t y = 0; y < thin.grid.dims[1]; ++y)
                for (std::int64_t x = 0; x < thin.grid.dims[0]; ++x) {
                    const std::array<std::int64_t, 3> f{x - fine->lo[0], y - fine->lo[1], (z - fine->lo[2]) * 4};
                    const bool in_box = f[0] >= 0 && f[1] >= 0 && f[2] >= 0 && f[0] < fine->grid.dims[0] &&
                                        f[1] < fine->grid.dims[1] && f[2] < fine->grid.dims[2];
                    const bool got = in_box && fine->bone[static_cast<std::size_t>(fine->grid.index(f[0], f[1], f[2]))];
                    REQUIRE(got == (thin.bone[static_cast<std::size_t>(thin.grid.index(x, y, z))] != 0));
                }
    }
    // slices less than twice as far apart as the in-plane spacing are not interpolated; 5 mm over 2 mm: 2.5 mm
    Phantom iso = full;
    CHECK_FALSE(rig_detail::refine_slices(iso.grid, iso.bone.data()));
    iso.grid.spacing[2] = 1.9;
    CHECK_FALSE(rig_detail::refine_slices(iso.grid, iso.bone.data()));
    iso.grid.spacing = {2.0, 2.0, 5.0};
    const auto coarse = rig_detail::refine_slices(iso.grid, iso.bone.data());
    REQUIRE(coarse);
    CHECK(coarse->factor == 2);
    CHECK(coarse->grid.spacing[2] == Approx(2.5));
}

TEST_CASE("bone rig: the knee found on slices 4 mm apart at every phase, segments on the scan's own slices", "[rig][bones]") {
    const Phantom full = femur_tibia(0);
    for (int phase = 0; phase < 4; ++phase) {
        const Phantom thin = every_slice(full, 4, phase);
        const BoneRig r = rig_to_bones(thin.grid, thin.bone.data(), leg_rig());
        const BoneJoint& knee = joint_named(r, "knee.L");
        CHECK(knee.how == "contact");
        CHECK(std::abs(knee.to[2] - 59.0) <= 4.0);  // the gap z 57..61, its slices 4 mm apart
        CHECK(std::hypot(knee.to[0] - 20.0, knee.to[1] - 20.0) <= 1.5);
        REQUIRE(r.segments.labels.size() == thin.bone.size());
        std::int64_t total = 0;
        for (std::size_t i = 0; i < thin.bone.size(); ++i) CHECK((r.segments.labels[i] > 0) == (thin.bone[i] != 0));
        for (const std::int64_t s : r.segments.sizes) total += s;
        CHECK(total == std::count(thin.bone.begin(), thin.bone.end(), std::uint8_t{1}));
    }
}

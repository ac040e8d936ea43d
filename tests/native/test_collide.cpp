// Collision detection (docs/ALGORITHMS.md §8): the fast path against brute force (every lattice point against every
// moved ball) and against two deformed frames intersected voxel by voxel, on random poses of small limbs, in every
// mode, on anisotropic and mismatched grids; self-contact; bad input. Also run under ASan/UBSan.
#include <catch2/catch.hpp>

#include <random>

#include "limb_fixture.hpp"
#include "volrig/collide.hpp"

using namespace volrig;

namespace {

void require_same(const Collision& fast, const Collision& ref) {
    REQUIRE(fast.hit == ref.hit);
    REQUIRE(fast.voxels == ref.voxels);
    REQUIRE(fast.bone_pairs == ref.bone_pairs);
    REQUIRE(fast.bones_a == ref.bones_a);
    REQUIRE(fast.bones_b == ref.bones_b);
    for (int k = 0; k < 6; ++k) REQUIRE(fast.box[k] == Approx(ref.box[k]));
    REQUIRE(fast.points.empty());
}

/// The same with the contact voxels listed: the very voxels of the reference.
void require_same_points(const Collision& fast, const Collision& ref) {
    REQUIRE(fast.voxels == static_cast<std::int64_t>(fast.points.size()));
    REQUIRE(fast.points == ref.points);
}

/// Lattice points covered in both frames (A's frame and B's, deformed on the same lattice).
std::int64_t frames_intersected(const Limb& L, const std::vector<double>& ma, const std::vector<double>& mb,
                                const DeformOptions& o) {
    const DeformedVolume fa = deform_reference(L.view(), L.spheres(true), ma.data(), o);
    const std::array<std::int64_t, 6> box{fa.offset[0], fa.offset[1], fa.offset[2],
                                          fa.grid.dims[0], fa.grid.dims[1], fa.grid.dims[2]};
    const DeformedVolume fb = deform_reference(L.view(), L.spheres(true), mb.data(), o, {}, &box);
    std::int64_t n = 0;
    for (std::size_t k = 0; k < fa.bone.size(); ++k) n += fa.bone[k] && fb.bone[k];
    return n;
}

}  // namespace

TEST_CASE("collide equals brute force and the intersection of the two deformed frames", "[collide]") {
    std::mt19937 rng(11);
    for (auto spacing : {std::array<double, 3>{1.0, 1.0, 1.0}, std::array<double, 3>{0.9, 1.2, 1.5}}) {
        const Limb L = make_limb(spacing);
        const Collider c(L.grid, L.spheres(true), {-1, 0});
        int hits = 0;
        for (int trial = 0; trial < 6; ++trial) {
            const auto ma = random_pose(rng, L, 60, 2), mb = random_pose(rng, L, 60, 12);
            for (DeformMode mode : {DeformMode::Rigid, DeformMode::Linear, DeformMode::DualQuaternion}) {
                INFO("spacing " << spacing[2] << " trial " << trial << " mode " << int(mode));
                CollideOptions o;
                o.mode = mode;
                const Collision fast = collide(c, ma.data(), o, c, mb.data(), o);
                const Collision ref = collide_reference(c, ma.data(), o, c, mb.data(), o);
                require_same(fast, ref);
                require_same_points(collide(c, ma.data(), o, c, mb.data(), o, true), ref);
                DeformOptions d;
                d.mode = mode;
                d.values = false;
                REQUIRE(fast.voxels == frames_intersected(L, ma, mb, d));
                hits += fast.hit;
                if (fast.hit) {
                    REQUIRE(fast.stats.sphere_pairs > 0);
                    REQUIRE(fast.stats.lattice_tests > 0);
                }
            }
        }
        REQUIRE(hits >= 6);  // the poses overlap often enough for the test to mean something
    }
}

TEST_CASE("collide between different grids and with radius scales equals brute force", "[collide]") {
    std::mt19937 rng(5);
    const Limb A = make_limb({1.0, 1.0, 1.0});
    Limb B = make_limb({0.8, 1.1, 0.7});
    B.grid.origin = {1.3, -0.4, 2.2};
    const Collider ca(A.grid, A.spheres(true)), cb(B.grid, B.spheres(false));
    std::uniform_real_distribution<double> U(0.5, 1.5);
    int hits = 0;
    for (int trial = 0; trial < 6; ++trial) {
        const auto ma = random_pose(rng, A, 90, 3), mb = random_pose(rng, B, 90, 6);
        CollideOptions oa, ob;
        oa.mode = trial % 2 ? DeformMode::DualQuaternion : DeformMode::Rigid;
        if (trial >= 3)
            for (std::size_t i = 0; i < B.radius.size(); ++i) ob.radius_scale.push_back(static_cast<float>(U(rng)));
        INFO("trial " << trial);
        const Collision fast = collide(ca, ma.data(), oa, cb, mb.data(), ob);
        require_same(fast, collide_reference(ca, ma.data(), oa, cb, mb.data(), ob));
        hits += fast.hit;
    }
    REQUIRE(hits >= 3);
}

TEST_CASE("bodies far apart: no contact, and no ball pair is looked at", "[collide]") {
    const Limb L = make_limb({1.0, 1.0, 1.0});
    const Collider c(L.grid, L.spheres(true));
    const auto id = motion({0, 0, 1}, 0, {0, 0, 0}, {0, 0, 0});
    const auto far = motion({0, 0, 1}, 30, {0, 0, 0}, {200, 0, 0});
    std::vector<double> ma(id.begin(), id.end()), mb(far.begin(), far.end());
    ma.insert(ma.end(), id.begin(), id.end());
    mb.insert(mb.end(), far.begin(), far.end());
    const Collision none = collide(c, ma.data(), {}, c, mb.data(), {});
    REQUIRE_FALSE(none.hit);
    REQUIRE(none.voxels == 0);
    REQUIRE(none.stats.sphere_pairs == 0);
    REQUIRE(none.bones_a.empty());
    // the same body at the same place touches itself everywhere: every voxel of its reconstruction
    const Collision all = collide(c, ma.data(), {}, c, ma.data(), {});
    DeformOptions d;
    d.values = false;
    REQUIRE(all.voxels == deform_reference(L.view(), L.spheres(true), ma.data(), d).stats.covered);
    REQUIRE(all.bone_pairs == std::vector<std::pair<std::int32_t, std::int32_t>>{{0, 0}, {0, 1}, {1, 0}, {1, 1}});
}

/// The limb with a third bone, bones by place: 0 the upright capsule (x < 15, z >= 10), 2 the far end of the
/// other (x >= 25), a child of 1 (the rest), weighted to it alone. Bones 0 and 2 do not touch at rest; folding
/// bones 1 and 2 up about the joint brings 2 against 0.
struct Limb3 {
    Limb L;
    std::vector<std::int32_t> bone, wbones;
    std::vector<std::int64_t> offsets{0};
    std::vector<float> weights;
    explicit Limb3(std::array<double, 3> spacing) : L(make_limb(spacing)), bone(L.bone) {
        for (std::size_t i = 0; i < L.radius.size(); ++i) {
            const std::int32_t x = L.ijk[3 * i + 2], z = L.ijk[3 * i];
            bone[i] = x >= 25 ? 2 : (x < 15 && z >= 10 ? 0 : 1);
            if (bone[i] == 2) {
                wbones.push_back(2);
                weights.push_back(1.0f);
            } else
                for (std::int64_t k = L.offsets[i]; k < L.offsets[i + 1]; ++k) {
                    wbones.push_back(L.wbones[static_cast<std::size_t>(k)]);
                    weights.push_back(L.weights[static_cast<std::size_t>(k)]);
                }
            offsets.push_back(static_cast<std::int64_t>(wbones.size()));
        }
    }
    BoundSpheres spheres() const {
        BoundSpheres s = L.spheres(true);
        s.bone = bone.data();
        s.bone_count = 3;
        s.weight_offsets = offsets.data();
        s.weight_bones = wbones.data();
        s.weights = weights.data();
        return s;
    }
};

TEST_CASE("self-contact: a limb folded onto itself, and none at rest", "[collide]") {
    for (auto spacing : {std::array<double, 3>{1.0, 1.0, 1.0}, std::array<double, 3>{1.1, 0.9, 1.3}}) {
        const Limb3 L3(spacing);
        const Collider c(L3.L.grid, L3.spheres(), {-1, 0, 1});
        const auto joint = world(L3.L.grid, L3.L.joint);
        const auto id = motion({0, 0, 1}, 0, joint, {0, 0, 0});
        for (double fold : {0.0, 60.0, 100.0}) {
            // bones 1 and 2 run from the joint along +x; folding them about y brings them up against bone 0 (+z)
            const auto m1 = motion({0, 1, 0}, -fold, joint, {0, 0, 0});
            std::vector<double> m(id.begin(), id.end());
            for (int b = 0; b < 2; ++b) m.insert(m.end(), m1.begin(), m1.end());
            for (DeformMode mode : {DeformMode::Rigid, DeformMode::Linear}) {
                INFO("fold " << fold << " mode " << int(mode));
                CollideOptions o;
                o.mode = mode;
                const Collision fast = self_collide(c, m.data(), o);
                const Collision ref = self_collide_reference(c, m.data(), o);
                require_same(fast, ref);
                require_same_points(self_collide(c, m.data(), o, 2, true, true), ref);
                if (fold == 0.0) REQUIRE_FALSE(fast.hit);
                if (fold == 100.0) {
                    REQUIRE(fast.hit);
                    REQUIRE(fast.bone_pairs == std::vector<std::pair<std::int32_t, std::int32_t>>{{0, 2}});
                    REQUIRE(fast.bones_a == std::vector<std::int32_t>{0, 2});
                }
                // bones 0 and 1 are joined at rest: they never count unless rest contact is counted too, and then
                // their overlap at the joint counts even at rest
                require_same(self_collide(c, m.data(), o, 1, true), self_collide_reference(c, m.data(), o, 1, true));
                const Collision all = self_collide(c, m.data(), o, 1, false);
                require_same(all, self_collide_reference(c, m.data(), o, 1, false));
                REQUIRE(all.hit);
                REQUIRE(all.voxels > fast.voxels);
                REQUIRE(std::find(all.bone_pairs.begin(), all.bone_pairs.end(), std::make_pair(0, 1)) != all.bone_pairs.end());
            }
        }
    }
}

TEST_CASE("collide refuses bad rigs, matrices and options", "[collide]") {
    const Limb L = make_limb({1.0, 1.0, 1.0});
    REQUIRE_THROWS_WITH(Collider(L.grid, L.spheres(true), {-1, 0, 1}), Catch::Contains("3 parents for a rig of 2"));
    REQUIRE_THROWS_WITH(Collider(L.grid, L.spheres(true), {1, 0}), Catch::Contains("do not form a tree"));
    REQUIRE_THROWS_WITH(Collider(L.grid, L.spheres(true), {-1, 5}), Catch::Contains("outside the rig"));
    const Collider c(L.grid, L.spheres(true));
    const auto id = motion({0, 0, 1}, 0, {0, 0, 0}, {0, 0, 0});
    std::vector<double> m(id.begin(), id.end());
    m.insert(m.end(), id.begin(), id.end());
    REQUIRE_THROWS_WITH(self_collide(c, m.data(), {}), Catch::Contains("without the rig's bone parents"));
    const Collider cp(L.grid, L.spheres(true), {-1, 0});
    REQUIRE_THROWS_WITH(self_collide(cp, m.data(), {}, 0), Catch::Contains("at least 1"));
    CollideOptions bad;
    bad.radius_scale = {1.0f};
    REQUIRE_THROWS_WITH(collide(c, m.data(), bad, c, m.data(), {}), Catch::Contains("radius_scale"));
    m[0] = 2.0;  // a scale
    REQUIRE_THROWS_WITH(collide(c, m.data(), {}, c, m.data(), {}), Catch::Contains("not a rotation"));
    REQUIRE(bone_distances({-1, 0, 1, 0}) ==
            std::vector<std::int32_t>{0, 1, 2, 1, 1, 0, 1, 2, 2, 1, 0, 3, 1, 2, 3, 0});
}

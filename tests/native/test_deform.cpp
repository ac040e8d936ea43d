// Per-frame sampled reconstruction (docs/ALGORITHMS.md §7): the Deformer against the thesis' brute-force scatter on
// small random rigs, the identity pose against reconstruct(), and bad input. Also run under ASan/UBSan.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "volrig/deform.hpp"
#include "volrig/distance.hpp"
#include "volrig/reconstruct.hpp"
#include "limb_fixture.hpp"

using namespace volrig;

TEST_CASE("the identity pose reproduces reconstruct() and the source", "[deform]") {
    const Limb L = make_limb({1.0, 1.0, 1.0});
    Deformer d(L.view(), L.spheres(false));
    std::vector<double> id(32, 0.0);
    for (int b = 0; b < 2; ++b)
        for (int k = 0; k < 4; ++k) id[16 * b + 5 * k] = 1.0;
    for (Proximity prox : {Proximity::Power, Proximity::Nearest}) {
        DeformOptions o;
        o.proximity = prox;
        const DeformedVolume f = d.frame(id.data(), o);
        const std::vector<std::uint8_t> rec = reconstruct(L.grid, Metric::Euclidean, L.ijk.data(), L.radius.data(), L.radius.size());
        std::int64_t covered = 0;
        for (std::int64_t z = 0; z < f.grid.dims[2]; ++z)
            for (std::int64_t y = 0; y < f.grid.dims[1]; ++y)
                for (std::int64_t x = 0; x < f.grid.dims[0]; ++x) {
                    const auto i = static_cast<std::size_t>(f.grid.index(x, y, z));
                    const std::int64_t sx = x + f.offset[0], sy = y + f.offset[1], sz = z + f.offset[2];
                    const bool in = sx >= 0 && sy >= 0 && sz >= 0 && sx < L.dims[0] && sy < L.dims[1] && sz < L.dims[2];
                    const auto si = in ? static_cast<std::size_t>(L.grid.index(sx, sy, sz)) : 0;
                    const bool want = in && rec[si];
                    REQUIRE((f.bone[i] > 0) == want);
                    if (want) {
                        REQUIRE(f.values[i] == float(L.samples[si]));
                        ++covered;
                    }
                }
        REQUIRE(covered == f.stats.covered);
        REQUIRE(covered > 2000);
    }
}

/// Whether every face of the frame's box holds a covered voxel (the box is the covered voxels' bounding box).
bool tight(const DeformedVolume& f) {
    const std::int64_t n[3] = {f.grid.dims[0], f.grid.dims[1], f.grid.dims[2]};
    bool face[6] = {false, false, false, false, false, false};
    for (std::int64_t z = 0; z < n[2]; ++z)
        for (std::int64_t y = 0; y < n[1]; ++y)
            for (std::int64_t x = 0; x < n[0]; ++x) {
                if (!f.bone[static_cast<std::size_t>((z * n[1] + y) * n[0] + x)]) continue;
                const std::int64_t v[3] = {x, y, z};
                for (int a = 0; a < 3; ++a) {
                    face[a] = face[a] || v[a] == 0;
                    face[3 + a] = face[3 + a] || v[a] == n[a] - 1;
                }
            }
    return std::all_of(face, face + 6, [](bool b) { return b; });
}

/// The brute-force scatter on the fast frame's box equals it voxel for voxel, and that box is tight.
void require_brute_force(const Limb& L, bool with_weights, const std::vector<double>& mats, const DeformOptions& o,
                         const DeformedVolume& fast) {
    const std::array<std::int64_t, 6> box{fast.offset[0], fast.offset[1], fast.offset[2],
                                          fast.grid.dims[0], fast.grid.dims[1], fast.grid.dims[2]};
    const DeformedVolume ref = deform_reference(L.view(), L.spheres(with_weights), mats.data(), o, {}, &box);
    REQUIRE(fast.stats.covered == ref.stats.covered);
    REQUIRE(fast.bone == ref.bone);
    REQUIRE(fast.values == ref.values);
    REQUIRE(tight(fast));
}

TEST_CASE("the Deformer equals the brute-force scatter on random poses", "[deform]") {
    std::mt19937 rng(7);
    std::int64_t contact = 0;  // voxels given up at contact planes (the weights blend along z on both sides of the
                               // joint: to the bend model the limb is straight there)
    for (auto spacing : {std::array<double, 3>{1.0, 1.0, 1.0}, std::array<double, 3>{0.9, 1.2, 1.5}}) {
        const Limb L = make_limb(spacing);
        Deformer d(L.view(), L.spheres(true));
        for (int trial = 0; trial < 4; ++trial) {
            const std::vector<double> mats = random_pose(rng, L, 50, 3);
            for (DeformMode mode : {DeformMode::Rigid, DeformMode::Linear, DeformMode::DualQuaternion})
                for (Proximity prox : {Proximity::Power, Proximity::Nearest}) {
                    DeformOptions o;
                    o.mode = mode;
                    o.proximity = prox;
                    o.sampling = trial % 2 ? Sampling::Nearest : Sampling::Trilinear;
                    INFO("spacing " << spacing[2] << " trial " << trial << " mode " << int(mode) << " prox " << int(prox));
                    const DeformedVolume fast = d.frame(mats.data(), o);
                    require_brute_force(L, true, mats, o, fast);
                    if (mode != DeformMode::Rigid) REQUIRE(fast.stats.blended_spheres > 0);
                    contact += fast.stats.contact;
                    if (trial == 0) {  // the reference on its own box (every posed ball), cropped: the same frame
                        DeformedVolume wide = deform_reference(L.view(), L.spheres(true), mats.data(), o);
                        REQUIRE(wide.bone.size() > fast.bone.size());
                        crop_to_covered(wide);
                        REQUIRE(wide.offset == fast.offset);
                        REQUIRE(wide.grid.dims == fast.grid.dims);
                        for (int a = 0; a < 3; ++a) REQUIRE(wide.grid.origin[a] == Approx(fast.grid.origin[a]));
                        REQUIRE(wide.bone == fast.bone);
                        REQUIRE(wide.values == fast.values);
                    }
                }
        }
    }
    REQUIRE(contact > 0);
}

TEST_CASE("every decision tier of the Deformer is used, and it still equals the brute-force scatter", "[deform]") {
    // A limb three times as thick (radius 15): whole output blocks inside one bone, cubes inside two bones at the
    // joint, cubes the power ranges cannot settle, and voxels only the full search settles.
    const Limb L = make_limb({1.0, 1.0, 1.0}, 3);
    Deformer d(L.view(), L.spheres(false));
    d.set_lattice_after(0);  // the tiers of the bones' lattice tables from the first frame
    const auto joint = world(L.grid, L.joint);
    std::int64_t tiers[4] = {0, 0, 0, 0};
    for (double deg : {0.0, 35.0, 80.0}) {
        std::vector<double> mats;
        const auto m0 = motion({0, 0, 1}, 0, joint, {0, 0, 0});
        const auto m1 = motion({0.3, 1, 0.2}, deg, joint, {0, 0, 0});
        mats.insert(mats.end(), m0.begin(), m0.end());
        mats.insert(mats.end(), m1.begin(), m1.end());
        DeformOptions o;
        INFO("bend " << deg);
        const DeformedVolume fast = d.frame(mats.data(), o);
        require_brute_force(L, false, mats, o, fast);
        REQUIRE(fast.stats.by_block + fast.stats.by_cube + fast.stats.by_sphere + fast.stats.by_search ==
                fast.stats.covered);
        tiers[0] += fast.stats.by_block;
        tiers[1] += fast.stats.by_cube;
        tiers[2] += fast.stats.by_sphere;
        tiers[3] += fast.stats.by_search;
    }
    INFO("block " << tiers[0] << " cube " << tiers[1] << " sphere " << tiers[2] << " search " << tiers[3]);
    for (std::int64_t t : tiers) REQUIRE(t > 0);
}

TEST_CASE("the bones' lattice tables come after lattice_after frames, and frames are the same with or without them",
          "[deform]") {
    std::mt19937 rng(11);
    const Limb L = make_limb({0.9, 1.2, 1.5});
    Deformer tables(L.view(), L.spheres(true)), balls(L.view(), L.spheres(true)), later(L.view(), L.spheres(true));
    REQUIRE(later.lattice_after() == Deformer::kLatticeAfter);
    tables.set_lattice_after(0);
    balls.set_lattice_after(-1);
    later.set_lattice_after(2);
    REQUIRE_THROWS_AS(later.set_lattice_after(-2), Error);
    REQUIRE(!tables.lattice_tables());  // (nothing built before the first frame)
    for (int trial = 0; trial < 5; ++trial) {
        const std::vector<double> mats = random_pose(rng, L, 60, 3);
        DeformOptions o;
        o.mode = trial % 2 ? DeformMode::Linear : DeformMode::Rigid;
        INFO("trial " << trial);
        const DeformedVolume a = tables.frame(mats.data(), o), b = balls.frame(mats.data(), o),
                             c = later.frame(mats.data(), o);
        require_brute_force(L, true, mats, o, a);
        REQUIRE(b.offset == a.offset);
        REQUIRE(b.bone == a.bone);
        REQUIRE(b.values == a.values);
        REQUIRE(c.bone == a.bone);
        REQUIRE(c.values == a.values);
        REQUIRE(tables.lattice_tables());
        REQUIRE(!balls.lattice_tables());
        // every trial changes the mode family, which rebuilds the fields: `later` never reaches its two frames
        REQUIRE(later.lattice_tables() == false);
        REQUIRE(balls.memory_bytes() < tables.memory_bytes());
    }
    DeformOptions o;
    const std::vector<double> mats = random_pose(rng, L, 60, 3);
    later.frame(mats.data(), o);  // (the last trial drew the first rigid frame: this is the second)
    REQUIRE(!later.lattice_tables());
    // cancelled after the first bone's tables (of two): the Deformer stays whole and builds the rest next frame
    const std::size_t before = later.memory_bytes();
    REQUIRE_THROWS_AS(later.frame(mats.data(), o, [](double) { return false; }), Cancelled);
    REQUIRE(!later.lattice_tables());
    REQUIRE(later.memory_bytes() > before);
    const DeformedVolume next = later.frame(mats.data(), o);
    REQUIRE(later.lattice_tables());
    const DeformedVolume ref = tables.frame(mats.data(), o);
    REQUIRE(next.bone == ref.bone);
    REQUIRE(next.values == ref.values);
}

TEST_CASE("sub-blocks whose powers come from one sphere (smooth blend groups) still equal the brute-force scatter",
          "[deform]") {
    // The thick limb with its blend across the joint: many (field, sub-block) pairs lie in one sphere's power
    // cell, where the gather takes that sphere's power itself instead of the per-cube tables.
    const Limb L = make_limb({1.0, 1.0, 1.0}, 3);
    Deformer d(L.view(), L.spheres(true));
    const auto joint = world(L.grid, L.joint);
    for (DeformMode mode : {DeformMode::Rigid, DeformMode::Linear, DeformMode::DualQuaternion})
        for (double deg : {20.0, 70.0}) {
            std::vector<double> mats;
            const auto m0 = motion({0, 0, 1}, 5, joint, {0.5, 0, 0});
            const auto m1 = motion({0.3, 1, 0.2}, deg, joint, {0, 0.25, 0});
            mats.insert(mats.end(), m0.begin(), m0.end());
            mats.insert(mats.end(), m1.begin(), m1.end());
            for (Proximity prox : {Proximity::Power, Proximity::Nearest}) {
                DeformOptions o;
                o.mode = mode;
                o.proximity = prox;
                INFO("mode " << int(mode) << " bend " << deg << " prox " << int(prox));
                const DeformedVolume fast = d.frame(mats.data(), o);
                REQUIRE(fast.stats.exact_sub_blocks > 0);
                require_brute_force(L, true, mats, o, fast);
            }
        }
}

TEST_CASE("blocks and sub-blocks whose blended balls are one field's are decided whole, as the voxel-by-voxel scatter",
          "[deform]") {
    // A bake's frames: no lattice tables, every sphere a posed ball of the blend candidate. Inside the thick limb,
    // far from the joint, the balls that may give the least power over a block or 4³ sub-block are one bone's:
    // it is filled with that field at once (by_block) instead of per voxel; at the joint the voxels still go one by
    // one (by_cube). Random poses, every mode, with and without sliding contact: the brute-force scatter's voxels.
    std::mt19937 rng(56);
    std::int64_t whole = 0, per_voxel = 0, contact = 0;
    for (auto spacing : {std::array<double, 3>{1.0, 1.0, 1.0}, std::array<double, 3>{0.9, 1.2, 1.1}}) {
        const Limb L = make_limb(spacing, 3);
        Deformer d(L.view(), L.spheres(true));
        d.set_lattice_after(-1);
        for (int trial = 0; trial < 3; ++trial) {
            const std::vector<double> mats = random_pose(rng, L, 70, 2);
            for (DeformMode mode : {DeformMode::Rigid, DeformMode::Linear, DeformMode::DualQuaternion})
                for (bool keep : {true, false}) {
                    DeformOptions o;
                    o.mode = mode;
                    o.keep_volume = keep;
                    o.sampling = trial % 2 ? Sampling::Nearest : Sampling::Trilinear;
                    INFO("spacing " << spacing[2] << " trial " << trial << " mode " << int(mode) << " keep " << keep);
                    const DeformedVolume fast = d.frame(mats.data(), o);
                    require_brute_force(L, true, mats, o, fast);
                    REQUIRE(fast.stats.by_block + fast.stats.by_cube + fast.stats.by_sphere + fast.stats.by_search ==
                            fast.stats.covered);
                    whole += fast.stats.by_block;
                    per_voxel += fast.stats.by_cube + fast.stats.by_sphere + fast.stats.by_search;
                    contact += fast.stats.contact;
                }
        }
    }
    INFO("whole " << whole << " per voxel " << per_voxel << " contact " << contact);
    REQUIRE(whole > 0);
    REQUIRE(per_voxel > 0);
    REQUIRE(contact > 0);  // voxels given up at contact planes: the groups sought at a block's first yielding voxel
}

/// Voxels labelled with bone 0 lying more than 1.5 voxels past the plane through `joint` (world) with unit normal n.
std::int64_t past_plane(const DeformedVolume& f, const std::array<double, 3>& joint, const double* n) {
    std::int64_t count = 0;
    const double margin = 1.5 * std::max({f.grid.spacing[0], f.grid.spacing[1], f.grid.spacing[2]});
    for (std::int64_t z = 0; z < f.grid.dims[2]; ++z)
        for (std::int64_t y = 0; y < f.grid.dims[1]; ++y)
            for (std::int64_t x = 0; x < f.grid.dims[0]; ++x) {
                if (f.bone[static_cast<std::size_t>((z * f.grid.dims[1] + y) * f.grid.dims[0] + x)] != 1) continue;
                const std::int64_t v[3] = {x, y, z};
                double s = 0;
                for (int a = 0; a < 3; ++a) s += n[a] * (f.grid.origin[a] + f.grid.spacing[a] * static_cast<double>(v[a]) - joint[a]);
                count += s > margin;
            }
    return count;
}

TEST_CASE("sliding contact: a straight limb folded to 150 degrees meets itself at the bisector plane", "[deform]") {
    // Bone 1 (below the joint) folds up by 150 degrees about y: its tissue presses on bone 0's. With keep_volume the
    // two meet at the bisector plane (bone 0's spheres yield past it wherever bone 1's cover), still exactly the
    // brute-force scatter with the key (yields, power); without, the radical planes of their balls decide.
    for (auto spacing : {std::array<double, 3>{1.0, 1.0, 1.0}, std::array<double, 3>{0.9, 1.2, 1.1}}) {
        const Limb L = make_limb(spacing, 2, true);
        Deformer d(L.view(), L.spheres(true));
        const auto joint = world(L.grid, L.joint);
        const auto rest = motion({0, 1, 0}, 0, joint, {0, 0, 0}), fold = motion({0, 1, 0}, 150, joint, {0, 0, 0});
        std::vector<double> mats(rest.begin(), rest.end());
        mats.insert(mats.end(), fold.begin(), fold.end());
        // the arms leave the joint along +z (bone 0) and the folded -z (bone 1); the bisector's normal points to 1
        const double t = 150 * M_PI / 180, arm1[3] = {-std::sin(t), 0, -std::cos(t)};  // R_y(t) (0, 0, -1)
        double n[3] = {arm1[0], arm1[1], arm1[2] - 1}, len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (double& c : n) c /= len;
        for (DeformMode mode : {DeformMode::Linear, DeformMode::DualQuaternion})
            for (Proximity prox : {Proximity::Power, Proximity::Nearest}) {
                INFO("spacing " << spacing[1] << " mode " << int(mode) << " prox " << int(prox));
                DeformOptions o;
                o.mode = mode;
                o.proximity = prox;
                const DeformedVolume slide = d.frame(mats.data(), o);
                require_brute_force(L, true, mats, o, slide);
                o.keep_volume = false;
                const DeformedVolume plain = d.frame(mats.data(), o);
                require_brute_force(L, true, mats, o, plain);
                CHECK(plain.stats.contact == 0);
                CHECK(slide.stats.contact > 100);
                const std::int64_t before = past_plane(plain, joint, n), after = past_plane(slide, joint, n);
                INFO("bone 0 past the plane: " << before << " plain, " << after << " with contact");
                CHECK(after * 3 < before);  // what stays: the joint's own slabs, and bone 0 where bone 1 does not reach
            }
    }
}

TEST_CASE("deform refuses non-rigid matrices and bad options, and can be cancelled", "[deform]") {
    const Limb L = make_limb({1.0, 1.0, 1.0});
    Deformer d(L.view(), L.spheres(true));
    std::vector<double> mats(32, 0.0);
    for (int b = 0; b < 2; ++b)
        for (int k = 0; k < 4; ++k) mats[16 * b + 5 * k] = 1.0;
    DeformOptions o;
    std::vector<double> scaled = mats;
    scaled[16] = 2.0;
    REQUIRE_THROWS_AS(d.frame(scaled.data(), o), Error);
    std::vector<double> nan = mats;
    nan[3] = std::nan("");
    REQUIRE_THROWS_AS(d.frame(nan.data(), o), Error);
    o.radius_scale = {1.0f, 2.0f};
    REQUIRE_THROWS_AS(d.frame(mats.data(), o), Error);
    o.radius_scale.clear();
    REQUIRE_THROWS_AS(d.frame(mats.data(), o, [](double f) { return f < 0.6; }), Cancelled);
    REQUIRE(d.frame(mats.data(), o).stats.covered > 0);  // still usable after a cancel
    {  // cancelled while the fields are built: the next frame builds them all again, as a fresh Deformer would
        const Limb S = make_limb({1.0, 1.0, 1.0}, 2, true);
        Deformer part(S.view(), S.spheres(true)), fresh(S.view(), S.spheres(true));
        const auto joint = world(S.grid, S.joint);
        const auto rest = motion({0, 1, 0}, 0, joint, {0, 0, 0}), fold = motion({0, 1, 0}, 90, joint, {0, 0, 0});
        std::vector<double> bent(rest.begin(), rest.end());
        bent.insert(bent.end(), fold.begin(), fold.end());
        DeformOptions lin;
        lin.mode = DeformMode::Linear;
        // the cancel comes after the first field, before any other is built
        REQUIRE_THROWS_AS(part.frame(bent.data(), lin, [](double f) { return f <= 0; }), Cancelled);
        const DeformedVolume a = part.frame(bent.data(), lin), b = fresh.frame(bent.data(), lin);
        REQUIRE(a.stats.covered > 0);
        CHECK(a.stats.covered == b.stats.covered);
        CHECK(a.bone == b.bone);
        CHECK(a.values == b.values);
    }
    // A bone sent millions of voxels away, and a lattice more than 64 times finer along one axis: clear errors.
    std::vector<double> far = mats;
    far[3] = 5e7;
    REQUIRE_THROWS_AS(d.frame(far.data(), o), Error);
    REQUIRE_THROWS_AS(deform_reference(L.view(), L.spheres(false), far.data(), o), Error);
    Limb flat = make_limb({1.0, 1.0, 100.0});
    Deformer df(flat.view(), flat.spheres(false));
    std::vector<double> turned = mats;  // bone 0 turned 60 degrees about x: mixes y with the coarse z
    turned[5] = turned[10] = std::cos(M_PI / 3);
    turned[6] = -std::sin(M_PI / 3);
    turned[9] = std::sin(M_PI / 3);
    REQUIRE_THROWS_WITH(df.frame(turned.data(), o), Catch::Contains("anisotropic"));
    REQUIRE(df.frame(mats.data(), o).stats.covered > 0);  // at rest the axes do not mix
    std::vector<std::int32_t> bad_bone = L.bone;
    bad_bone[3] = 5;
    BoundSpheres s = L.spheres(false);
    s.bone = bad_bone.data();
    REQUIRE_THROWS_AS(Deformer(L.view(), s), Error);
}

TEST_CASE("inverse_warp of the identity is the source", "[deform]") {
    const Limb L = make_limb({1.0, 1.0, 1.0});
    const double id[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    for (Sampling s : {Sampling::Trilinear, Sampling::Nearest}) {
        const std::vector<float> w = inverse_warp(L.view(), id, s);
        REQUIRE(w.size() == L.samples.size());
        for (std::size_t i = 0; i < w.size(); ++i) REQUIRE(w[i] == float(L.samples[i]));
    }
}

namespace {

/// The limb's bright core (220) split into two pieces by the joint plane z = 10: bone 0 above, bone 1 below.
struct CorePieces {
    std::vector<std::uint8_t> upper, lower;          // one byte a voxel, for the brute force
    std::vector<std::uint8_t> upper_bits, lower_bits;  // packed, for the pieces
    std::vector<RigidPiece> pieces;
};

std::vector<std::uint8_t> packed(const std::vector<std::uint8_t>& v) {
    std::vector<std::uint8_t> out((v.size() + 7) / 8, 0);
    for (std::size_t k = 0; k < v.size(); ++k)
        if (v[k]) out[k >> 3] = static_cast<std::uint8_t>(out[k >> 3] | (1u << (k & 7)));
    return out;
}

CorePieces core_pieces(const Limb& L) {
    CorePieces c;
    const auto n = static_cast<std::size_t>(L.grid.voxel_count());
    c.upper.assign(n, 0);
    c.lower.assign(n, 0);
    for (std::int64_t z = 0; z < L.dims[2]; ++z)
        for (std::int64_t y = 0; y < L.dims[1]; ++y)
            for (std::int64_t x = 0; x < L.dims[0]; ++x) {
                const auto i = static_cast<std::size_t>(L.grid.index(x, y, z));
                if (L.samples[i] == 220) (z >= 10 ? c.upper : c.lower)[i] = 1;
            }
    const std::array<std::int64_t, 6> all{0, 0, 0, L.dims[0], L.dims[1], L.dims[2]};
    c.upper_bits = packed(c.upper);
    c.lower_bits = packed(c.lower);
    c.pieces = {RigidPiece{0, all, c.upper_bits.data()}, RigidPiece{1, all, c.lower_bits.data()}};
    return c;
}

/// Brute force: the piece (if any; the later one wins) whose voxel the rest position of source-lattice point q
/// (through the inverse of its bone's world matrix, in double precision) rounds to; `hits`: how many do.
int piece_at(const Limb& L, const CorePieces& c, const std::vector<double>& mats, const std::int64_t* q,
             int& hits) {
    int hit = -1;
    hits = 0;
    for (int b = 0; b < 2; ++b) {
        const double* m = mats.data() + 16 * b;
        double w[3], r[3];
        for (int a = 0; a < 3; ++a) w[a] = L.grid.origin[a] + L.grid.spacing[a] * static_cast<double>(q[a]) - m[4 * a + 3];
        for (int a = 0; a < 3; ++a)  // R^T (w - t), back to the lattice
            r[a] = ((m[a] * w[0] + m[4 + a] * w[1] + m[8 + a] * w[2]) - L.grid.origin[a]) / L.grid.spacing[a];
        std::int64_t k[3];
        for (int a = 0; a < 3; ++a) k[a] = static_cast<std::int64_t>(std::floor(r[a] + 0.5));
        if (k[0] < 0 || k[1] < 0 || k[2] < 0 || k[0] >= L.dims[0] || k[1] >= L.dims[1] || k[2] >= L.dims[2]) continue;
        const auto i = static_cast<std::size_t>(L.grid.index(k[0], k[1], k[2]));
        if ((b == 0 ? c.upper : c.lower)[i]) hit = b, ++hits;
    }
    return hit;
}

}  // namespace

TEST_CASE("the rigid layer draws each piece moved by its bone over the spheres' frame", "[deform]") {
    std::mt19937 rng(3);
    const Limb L = make_limb({1.0, 1.0, 1.0});
    const CorePieces c = core_pieces(L);
    Deformer layered(L.view(), L.spheres(true));
    layered.set_rigid_layer(L.view(), c.pieces);
    for (int trial = 0; trial < 6; ++trial) {  // frames in a row: the recycled output memory is re-zeroed right
        const std::vector<double> mats = random_pose(rng, L, 60, 2);
        DeformOptions o;
        o.mode = trial % 2 ? DeformMode::DualQuaternion : DeformMode::Linear;
        o.sampling = Sampling::Nearest;
        INFO("trial " << trial);
        const DeformedVolume f = layered.frame(mats.data(), o);
        Deformer plain(L.view(), L.spheres(true));
        const std::array<std::int64_t, 6> box{f.offset[0], f.offset[1], f.offset[2],
                                              f.grid.dims[0], f.grid.dims[1], f.grid.dims[2]};
        const DeformedVolume under = plain.frame(mats.data(), o, {}, &box);
        std::int64_t drawn = 0;
        for (std::int64_t z = 0; z < f.grid.dims[2]; ++z)
            for (std::int64_t y = 0; y < f.grid.dims[1]; ++y)
                for (std::int64_t x = 0; x < f.grid.dims[0]; ++x) {
                    const auto i = static_cast<std::size_t>(f.grid.index(x, y, z));
                    const std::int64_t q[3] = {x + f.offset[0], y + f.offset[1], z + f.offset[2]};
                    int hits = 0;
                    const int b = piece_at(L, c, mats, q, hits);
                    if (b < 0) {  // the spheres' frame where no piece lands
                        REQUIRE(f.bone[i] == under.bone[i]);
                        REQUIRE(f.values[i] == under.values[i]);
                        continue;
                    }
                    drawn += hits;
                    REQUIRE(f.bone[i] == b + 1);
                    REQUIRE(f.values[i] == 220.0f);
                }
        REQUIRE(drawn == f.stats.rigid_layer);  // piece voxels drawn: where two pieces land, both count
        REQUIRE(drawn > 250);
    }
    // bad pieces: a bone the rig lacks, a box off the grid
    std::vector<RigidPiece> bad = c.pieces;
    bad[0].bone = 2;
    REQUIRE_THROWS_WITH(layered.set_rigid_layer(L.view(), bad), Catch::Contains("bones"));
    bad = c.pieces;
    bad[1].box[3] += 1;
    REQUIRE_THROWS_WITH(layered.set_rigid_layer(L.view(), bad), Catch::Contains("outside the source grid"));
}

namespace {

/// A frame in bricks holds the cropped frame `dense`: the same voxels at the same lattice places, nothing else, on
/// a box aligned to the bricks, with the covered box as its extent.
void require_same_in_bricks(const DeformedVolume& dense, const DeformedVolume& bricked) {
    REQUIRE(bricked.bricks);
    REQUIRE(dense.stats.covered == bricked.stats.covered);
    REQUIRE(dense.values.empty() == bricked.values.empty());
    for (int a = 0; a < 3; ++a) {
        REQUIRE(bricked.offset[a] % 8 == 0);
        REQUIRE(bricked.grid.dims[a] % 8 == 0);
        REQUIRE(bricked.extent[a] == dense.offset[a] - bricked.offset[a]);
        REQUIRE(bricked.extent[3 + a] == dense.grid.dims[a]);
        REQUIRE(bricked.grid.origin[a] == Approx(dense.grid.origin[a] - dense.grid.spacing[a] * static_cast<double>(bricked.extent[a])));
    }
    REQUIRE(bricked.bone.size() == static_cast<std::size_t>(bricked.grid.voxel_count()));
    std::int64_t seen = 0;
    for (std::int64_t z = 0; z < bricked.grid.dims[2]; ++z)
        for (std::int64_t y = 0; y < bricked.grid.dims[1]; ++y)
            for (std::int64_t x = 0; x < bricked.grid.dims[0]; ++x) {
                const std::size_t i = brick_index(x, y, z, bricked.grid.dims);
                const std::int64_t d[3] = {x - bricked.extent[0], y - bricked.extent[1], z - bricked.extent[2]};
                const bool inside = d[0] >= 0 && d[1] >= 0 && d[2] >= 0 && d[0] < dense.grid.dims[0] &&
                                    d[1] < dense.grid.dims[1] && d[2] < dense.grid.dims[2];
                const auto j = inside ? static_cast<std::size_t>(dense.grid.index(d[0], d[1], d[2])) : 0;
                const std::int16_t want = inside ? dense.bone[j] : 0;
                if (bricked.bone[i] != want) FAIL("bone differs at (" << x << ", " << y << ", " << z << ")");
                if (!dense.values.empty() && bricked.values[i] != (inside ? dense.values[j] : 0.0f))
                    FAIL("value differs at (" << x << ", " << y << ", " << z << ")");
                seen += want != 0;
            }
    std::int64_t labelled = 0;  // the spheres' covered voxels and the rigid layer's beside them
    for (std::size_t i = 0; i < dense.bone.size(); ++i) labelled += dense.bone[i] != 0;
    REQUIRE(seen == labelled);
    REQUIRE(seen >= dense.stats.covered);
}

}  // namespace

TEST_CASE("frames in 8³ bricks hold the cropped frames' voxels, the rigid layer's too, frame after frame", "[deform]") {
    std::mt19937 rng(11);
    const Limb L = make_limb({0.9, 1.2, 1.5});
    const CorePieces c = core_pieces(L);
    Deformer plain(L.view(), L.spheres(true)), layered(L.view(), L.spheres(true));
    layered.set_rigid_layer(L.view(), c.pieces);
    for (int trial = 0; trial < 6; ++trial) {  // in a row: the bricks' recycled memory is re-zeroed right
        const std::vector<double> mats = random_pose(rng, L, 60, 9);
        DeformOptions o;
        o.mode = trial % 3 == 0 ? DeformMode::Rigid : trial % 3 == 1 ? DeformMode::Linear : DeformMode::DualQuaternion;
        o.values = trial != 4;
        INFO("trial " << trial);
        for (Deformer* d : {&plain, &layered}) {
            DeformOptions ob = o;
            ob.bricks = true;
            const DeformedVolume dense = d->frame(mats.data(), o);
            const DeformedVolume bricked = d->frame(mats.data(), ob);
            require_same_in_bricks(dense, bricked);
        }
    }
    DeformOptions ob;
    ob.bricks = true;
    const auto rest = motion({0, 0, 1}, 0, {0, 0, 0}, {0, 0, 0});
    std::vector<double> mats(rest.begin(), rest.end());
    mats.insert(mats.end(), rest.begin(), rest.end());
    const std::array<std::int64_t, 6> box{0, 0, 0, 8, 8, 8};
    REQUIRE_THROWS_WITH(plain.frame(mats.data(), ob, {}, &box), Catch::Contains("bricks and an imposed box"));
    ob.radius_scale.assign(L.spheres(true).n, 0.0f);  // nothing covered: an empty extent
    const DeformedVolume none = plain.frame(mats.data(), ob);
    REQUIRE(none.stats.covered == 0);
    REQUIRE(none.extent[3] == 0);
}

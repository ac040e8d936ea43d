// The deformation's stages alone (native/src/deform/): the fixed-point map, the sampler, the input checks and
// smooth groups, the concave lower bound, the per-bone field (power diagram, cube ranges, corner lower bounds); each
// against a brute force on small random inputs (closed cubes onwards: test_deform_stages_decide.cpp). The whole
// pipeline against the thesis' scatter is in test_deform.cpp.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "deform/bend.hpp"
#include "deform/bone_field.hpp"
#include "deform/closed_cubes.hpp"
#include "deform/decide.hpp"
#include "deform/frame_box.hpp"
#include "deform/gather.hpp"
#include "deform/motion.hpp"
#include "deform/posed_balls.hpp"
#include "deform/queries.hpp"
#include "deform/sampler.hpp"
#include "deform/spheres.hpp"
#include "volrig/reconstruct.hpp"
#include "limb_fixture.hpp"

#include "stages_fixture.hpp"

using namespace volrig;
using namespace volrig::deform_detail;

TEST_CASE("the fixed-point map steps exactly and inverts the forward map", "[deform][stages]") {
    RandomSpheres rs(1, 1);
    const auto M = rotation_z(33, {2.5, -1.0, 0.75});
    const Motion m = bone_motions(M.data(), 1, rs.grid)[0];
    std::mt19937 rng(7);
    std::uniform_int_distribution<std::int64_t> q(-40, 40);
    for (int t = 0; t < 200; ++t) {
        const std::int64_t a[3] = {q(rng), q(rng), q(rng)};
        std::int64_t p[3], stepped[3];
        m.pull.fixed(a, p);
        for (int axis = 0; axis < 3; ++axis) {  // one step along each axis lands where a direct evaluation does
            std::int64_t b[3] = {a[0], a[1], a[2]};
            ++b[axis];
            std::copy(p, p + 3, stepped);
            m.pull.step(stepped, axis);
            std::int64_t direct[3];
            m.pull.fixed(b, direct);
            CHECK(std::equal(direct, direct + 3, stepped));
        }
        double r[3], back[3];
        Pull::to_double(p, r);
        m.forward.apply(r, back);  // forward(pull(q)) = q within the map's error
        for (int k = 0; k < 3; ++k) CHECK(std::abs(back[k] - static_cast<double>(a[k])) < 1e-7);
    }
    Grid skew = rs.grid;
    skew.spacing = {1.0, 100.0, 1.0};
    const auto R = rotation_z(45, {0, 0, 0});
    CHECK_THROWS_WITH(bone_motions(R.data(), 1, skew), Catch::Contains("too anisotropic"));
    auto far = rotation_z(0, {1e12, 0, 0});
    CHECK_THROWS_WITH(bone_motions(far.data(), 1, rs.grid), Catch::Contains("millions of voxels"));
    auto shear = rotation_z(0, {0, 0, 0});
    shear[1] = 0.3;
    CHECK_THROWS_WITH(bone_motions(shear.data(), 1, rs.grid), Catch::Contains("not a rotation"));
    auto nearly = rotation_z(1e-7, {1e-9, 0, 0});  // float noise around the identity is the identity
    const Motion id = bone_motions(nearly.data(), 1, rs.grid)[0];
    CHECK(id.R == Eigen::Matrix3d::Identity());
    CHECK(id.d == Eigen::Vector3d::Zero());
}

TEST_CASE("blended motions: equal bones blend to themselves, two rotations to the half-way one", "[deform][stages]") {
    RandomSpheres rs(1, 1);
    const auto A = rotation_z(40, {1, 2, 3}), B = rotation_z(80, {1, 2, 3}), Z = rotation_z(0, {0, 0, 0});
    std::vector<double> mats(A.begin(), A.end());
    mats.insert(mats.end(), A.begin(), A.end());
    const auto same = bone_motions(mats.data(), 2, rs.grid);
    const Weights half = {{0, 8}, {1, 8}};
    for (DeformMode mode : {DeformMode::Linear, DeformMode::DualQuaternion}) {
        const Motion m = blended_motion(same, half, 0, mode, rs.grid, Eigen::Vector3d(3, 4, 5));
        CHECK((m.R - same[0].R).cwiseAbs().maxCoeff() < 1e-12);
        CHECK((m.d - same[0].d).cwiseAbs().maxCoeff() < 1e-9);
    }
    std::vector<double> two(Z.begin(), Z.end());
    two.insert(two.end(), B.begin(), B.end());
    const auto ms = bone_motions(two.data(), 2, rs.grid);
    const Motion dq = blended_motion(ms, half, 0, DeformMode::DualQuaternion, rs.grid, Eigen::Vector3d::Zero());
    const double angle = std::atan2(dq.R(1, 0), dq.R(0, 0)) * 180 / M_PI;
    CHECK(angle == Approx(40).margin(1e-9));
}

TEST_CASE("the sampler: lattice values, trilinear midpoints, clamping and rounding", "[deform][stages]") {
    Grid g;
    g.dims = {3, 2, 2};
    std::vector<float> v(12);
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<float>(i * i);
    const Sampler<float> s{v.data(), 3, 2, 2};
    auto fx = [](double x, double y, double z) {
        return std::array<std::int64_t, 3>{std::llround(x * Pull::kUnit), std::llround(y * Pull::kUnit),
                                           std::llround(z * Pull::kUnit)};
    };
    for (std::int64_t z = 0; z < 2; ++z)
        for (std::int64_t y = 0; y < 2; ++y)
            for (std::int64_t x = 0; x < 3; ++x) {
                const auto p = fx(double(x), double(y), double(z));
                CHECK(s.trilinear(p.data()) == s.at(x, y, z));
                CHECK(s.nearest(p.data()) == s.at(x, y, z));
            }
    const auto mid = fx(0.5, 0.5, 0.5);
    double mean = 0;
    for (std::int64_t k : {0, 1, 3, 4, 6, 7, 9, 10}) mean += v[static_cast<std::size_t>(k)] / 8.0;
    CHECK(s.trilinear(mid.data()) == Approx(mean));
    const auto outside = fx(-3.0, 7.0, 0.0);  // clamped to the lattice
    CHECK(s.trilinear(outside.data()) == s.at(0, 1, 0));
    const auto half = fx(1.5, 0.0, 0.0);  // nearest rounds half up
    CHECK(s.nearest(half.data()) == s.at(2, 0, 0));
}

TEST_CASE("sphere checks and smooth groups", "[deform][stages]") {
    RandomSpheres rs(3, 6);
    BoundSpheres s = rs.spheres();
    CHECK_NOTHROW(check_spheres(rs.grid, s));
    rs.radius[2] = std::nanf("");
    CHECK_THROWS_WITH(check_spheres(rs.grid, s), Catch::Contains("sphere 2") && Catch::Contains("radius"));
    rs.radius[2] = 1;
    rs.bone[4] = 3;
    CHECK_THROWS_WITH(check_spheres(rs.grid, s), Catch::Contains("bone 3"));
    rs.bone[4] = 0;
    DeformOptions o;
    o.radius_scale = {1, 2};
    CHECK_THROWS_WITH(check_options(o, 6), Catch::Contains("radius_scale has 2 entries"));
    // Weights: spheres whose rounded weights agree share a group; a single bone is no group.
    s.bone_count = 2;
    std::vector<std::int64_t> off = {0, 2, 4, 5, 7, 8, 10};
    std::vector<std::int32_t> wb = {0, 1, 0, 1, 0, 0, 1, 1, 0, 1};
    std::vector<float> w = {0.5f, 0.5f, 0.52f, 0.48f, 1.0f, 0.25f, 0.75f, 1.0f, 0.9f, 0.1f};
    s.weight_offsets = off.data();
    s.weight_bones = wb.data();
    s.weights = w.data();
    CHECK_NOTHROW(check_spheres(rs.grid, s));
    const SmoothGroups g = smooth_groups(s, rs.grid);
    CHECK(g.group_of[0] == g.group_of[1]);  // 8/8 both (0.52 rounds to 8 sixteenths)
    CHECK(g.group_of[2] == -1);
    CHECK(g.group_of[4] == -1);
    CHECK(g.bone_of[4] == 1);
    CHECK(g.group_of[3] >= 0);
    CHECK(g.group_of[3] != g.group_of[0]);
    CHECK(g.weights.size() == 3);
    CHECK(quantized_weights(s, 5) == Weights{{0, 14}, {1, 2}});
    std::vector<float> samples(static_cast<std::size_t>(rs.grid.voxel_count()), 1.0f);
    const VolumeView v{rs.grid, DType::Float32, samples.data()};
    CHECK_NOTHROW(check_source(v, "deform"));
    samples[samples.size() / 2] = std::numeric_limits<float>::infinity();
    CHECK_THROWS_WITH(check_source(v, "deform"), Catch::Contains("deform: the source volume holds NaN or infinite"));
}

TEST_CASE("concave_lower bounds the power function from its corner values", "[deform][stages]") {
    FieldCase fc(11, 12, 5);
    auto& [rs, s2, f, rng, u] = fc;
    std::uniform_int_distribution<int> cx(2, 24), cy(2, 20), cz(2, 26);
    int tight = 0;
    for (int t = 0; t < 3000; ++t) {
        const double base[3] = {double(cx(rng)), double(cy(rng)), double(cz(rng))};
        double v[8];
        for (int c = 0; c < 8; ++c) {
            const double corner[3] = {base[0] + (c & 1), base[1] + ((c >> 1) & 1), base[2] + ((c >> 2) & 1)};
            v[c] = brute_power(f, corner, s2.data()).key;
        }
        const double w[3] = {u(rng), u(rng), u(rng)};
        const double p[3] = {base[0] + w[0], base[1] + w[1], base[2] + w[2]};
        const double exact_value = brute_power(f, p, s2.data()).key;
        const double L = concave_lower(v, w, s2.data());
        REQUIRE(L <= exact_value);
        tight += exact_value - L < 1e-6 * (1 + std::abs(exact_value));
    }
    CHECK(tight > 100);  // exact where one sphere holds the whole cube
    const double zero[3] = {0, 0, 0};
    double v[8] = {1, 2, 3, 4, 5, 6, 7, -kInf};
    CHECK(concave_lower(v, zero, s2.data()) == -kInf);
}

TEST_CASE("a bone field's words: blocks of few words in palettes, blocks of many kept whole", "[deform][stages]") {
    // A sphere on every lattice point of a 12³ region, each holding its own point: blocks there have more than 256
    // distinct labels (kept whole); the blocks at the region's rim have fewer (in palettes). Every cell's label is a
    // least-power sphere at the cell, as the brute force finds.
    RandomSpheres rs(1, 0);
    for (int z = 6; z < 18; ++z)
        for (int y = 6; y < 18; ++y)
            for (int x = 6; x < 18; ++x) {
                rs.ijk.insert(rs.ijk.end(), {z, y, x});
                rs.radius.push_back(0.7f);
                rs.radii.push_back(0.7);
                rs.bone.push_back(0);
                rs.members.push_back(static_cast<std::uint32_t>(rs.members.size()));
            }
    const auto s2 = rs.s2();
    const BoneField f = rs.field();
    const auto whole = std::count_if(f.words.at.begin(), f.words.at.end(), [](std::int64_t a) { return a < 0; });
    CHECK(whole > 0);
    CHECK(whole < static_cast<std::ptrdiff_t>(f.words.at.size()));
    std::int64_t labelled = 0;
    for (std::int64_t z = 0; z < f.dims[2]; ++z)
        for (std::int64_t y = 0; y < f.dims[1]; ++y)
            for (std::int64_t x = 0; x < f.dims[0]; ++x) {
                const std::uint32_t cell = f.cell_at(x, y, z);
                const std::uint32_t lab = label_of(f.words[cell]);
                if (cell == kNoCell || lab == kNone) continue;
                const double base[3] = {double(x + f.lo[0]), double(y + f.lo[1]), double(z + f.lo[2])};
                REQUIRE(power_of(f, lab, base, s2.data()) == Approx(brute_power(f, base, s2.data()).key).margin(1e-9));
                ++labelled;
            }
    CHECK(labelled >= 12 * 12 * 12);
    CHECK(f.words[kNoCell] == kNone);
}

TEST_CASE("a bone field: power-diagram labels, cube ranges and corner lower bounds against a brute force", "[deform][stages]") {
    FieldCase fc(21, 40, 9);
    auto& [rs, s2, f, rng, u] = fc;
    REQUIRE(!f.blocks.empty());
    REQUIRE(f.global.size() == 40);
    std::int64_t labelled = 0, empty_checked = 0, one_sphere = 0;
    for (std::int64_t z = 0; z + 1 < f.dims[2]; ++z)
        for (std::int64_t y = 0; y + 1 < f.dims[1]; ++y)
            for (std::int64_t x = 0; x + 1 < f.dims[0]; ++x) {
                const std::uint32_t cell = f.cell_at(x, y, z);
                const double base[3] = {double(x + f.lo[0]), double(y + f.lo[1]), double(z + f.lo[2])};
                if (cell == kNoCell) {  // no allocated block: nothing is covered anywhere in the cube
                    const double p[3] = {base[0] + u(rng), base[1] + u(rng), base[2] + u(rng)};
                    REQUIRE(!(brute_power(f, p, s2.data()).key < 0));
                    ++empty_checked;
                    continue;
                }
                const Best at_cell = brute_power(f, base, s2.data());
                // Every allocated cell is labelled (the z pass completes every column a kept block reads, the ones
                // that never dip below T too) with a least-power sphere there.
                const std::uint32_t lab = label_of(f.words[cell]);
                REQUIRE(lab != kNone);
                REQUIRE(power_of(f, lab, base, s2.data()) == Approx(at_cell.key).margin(1e-9));
                ++labelled;
                const CellBounds b = f.bounds[cell];
                for (int t = 0; t < 3; ++t) {
                    std::int64_t pf[3];  // a point of the cube in fixed point, as Pull gives preimages
                    for (int a = 0; a < 3; ++a)
                        pf[a] = static_cast<std::int64_t>(std::floor((base[a] + u(rng)) * Pull::kUnit));
                    const double p[3] = {Pull::to_double(pf[0]), Pull::to_double(pf[1]), Pull::to_double(pf[2])};
                    const double v = brute_power(f, p, s2.data()).key;
                    const double lower = f.corner_lower(pf, s2.data());
                    REQUIRE(lower <= v);
                    std::uint32_t corners[8];
                    f.corner_cells(x, y, z, corners);
                    const bool all_allocated = std::find(corners, corners + 8, kNoCell) == corners + 8;
                    if (same_of(f.words[cell]) && all_allocated) {  // one sphere's cube: |p|² plus an affine part
                        REQUIRE(lower == Approx(v).margin(1e-6));
                        ++one_sphere;
                    }
                    if (b.lo == kBoundMax) REQUIRE(!(v < 0));  // "covered nowhere in the cube"
                    else if (b.lo != kBoundMin) REQUIRE(b.lo * f.step <= v);
                    if (b.hi != kBoundMax) REQUIRE(v <= b.hi * f.step);
                }
            }
    CHECK(labelled > 1000);
    CHECK(empty_checked > 100);
    CHECK(one_sphere > 1000);
    // range_bounds over a region is the hull of the cubes' ranges; any_block agrees with the allocation.
    const std::int64_t a[3] = {f.lo[0] + 4, f.lo[1] + 4, f.lo[2] + 4}, b[3] = {a[0] + 5, a[1] + 6, a[2] + 3};
    const CellBounds r = f.range_bounds(a, b);
    bool allocated = false;
    for (std::int64_t z = a[2]; z <= b[2]; ++z)
        for (std::int64_t y = a[1]; y <= b[1]; ++y)
            for (std::int64_t x = a[0]; x <= b[0]; ++x) {
                const std::uint32_t c = f.cell_at(x - f.lo[0], y - f.lo[1], z - f.lo[2]);
                if (c == kNoCell) continue;
                allocated = true;
                CHECK(r.lo <= f.bounds[c].lo);
                CHECK(r.hi >= f.bounds[c].hi);
            }
    CHECK(f.any_block(a, b) == allocated);
}

TEST_CASE("a field built on a lent power-diagram lattice equals one built alone; every kept block dips below T",
          "[deform][stages]") {
    DiagramScratch diagram;  // lent to every build below: the first box is the largest, so later ones reuse stale memory
    for (const auto& [seed, n] : {std::pair<std::uint32_t, std::size_t>{21, 60}, {5, 12}, {8, 30}}) {
        const RandomSpheres rs(seed, n);
        const BoneField alone = rs.field(), lent = rs.field(&diagram);
        REQUIRE(diagram.lab.size() >= static_cast<std::size_t>(lent.dims[0] * lent.dims[1] * lent.dims[2]));
        CHECK(lent.blocks == alone.blocks);
        CHECK(lent.block_index == alone.block_index);
        CHECK(lent.words == alone.words);
        CHECK(std::equal(lent.bounds.begin(), lent.bounds.end(), alone.bounds.begin(), alone.bounds.end(),
                         [](CellBounds a, CellBounds b) { return a.lo == b.lo && a.hi == b.hi; }));
        CHECK(lent.pair_alone == alone.pair_alone);
        // The blocks are kept exactly where the power dips below T at one of their 9³ lattice points (the brute force).
        const auto s2 = rs.s2();
        for (const auto& first : lent.blocks) {
            bool dips = false;
            for (std::int64_t z = 0; z <= kBlock && !dips; ++z)
                for (std::int64_t y = 0; y <= kBlock && !dips; ++y)
                    for (std::int64_t x = 0; x <= kBlock && !dips; ++x) {
                        const double p[3] = {double(first[0] + x), double(first[1] + y), double(first[2] + z)};
                        const bool inside = p[0] < double(lent.lo[0] + lent.dims[0]) && p[1] < double(lent.lo[1] + lent.dims[1]) &&
                                            p[2] < double(lent.lo[2] + lent.dims[2]);
                        dips = inside && brute_power(lent, p, s2.data()).key < rs.T();
                    }
            CHECK(dips);
        }
    }
}

TEST_CASE("one sphere's cells: its power is the field's on all their cubes", "[deform][stages]") {
    FieldCase fc(5, 12, 3);
    auto& [rs, s2, f, rng, u] = fc;
    REQUIRE(f.pair_alone.size() == f.blocks.size());
    std::int64_t singles = 0, probed = 0, in_range = 0;
    for (std::size_t slot = 0; slot < f.blocks.size(); ++slot)
        for (int m = 0; m < 64; ++m) {
            const std::uint32_t one = f.pair_sphere(static_cast<std::int32_t>(slot), m);
            if (one == kNone) continue;
            ++singles;
            const std::int64_t a[3] = {f.blocks[slot][0] + (m & 3) * 2, f.blocks[slot][1] + ((m >> 2) & 3) * 2,
                                       f.blocks[slot][2] + (m >> 4) * 2};
            const std::int64_t b[3] = {a[0] + 1, a[1] + 1, a[2] + 1};
            REQUIRE(f.single_sphere(a, b) == one);
            for (int t = 0; t < 20; ++t) {  // anywhere in the cells' cubes: that sphere's power is the least
                const double p[3] = {a[0] + 2 * u(rng), a[1] + 2 * u(rng), a[2] + 2 * u(rng)};
                REQUIRE(power_of(f, one, p, s2.data()) == Approx(brute_power(f, p, s2.data()).key).margin(1e-9));
                ++probed;
            }
            // its range over a box is the sphere's power's: it holds every point's power
            const double box[6] = {a[0] + 0.5, a[1] + 0.25, a[2] + 1.0, a[0] + 1.5, a[1] + 2.0, a[2] + 1.75};
            const CellBounds r = sphere_box_range(f, one, box, s2.data(), f.step);
            for (int t = 0; t < 10; ++t) {
                const double p[3] = {box[0] + (box[3] - box[0]) * u(rng), box[1] + (box[4] - box[1]) * u(rng),
                                     box[2] + (box[5] - box[2]) * u(rng)};
                const double v = power_of(f, one, p, s2.data());  // (kBoundMin / kBoundMax: -inf / +inf)
                REQUIRE((r.lo == kBoundMin || r.lo * f.step <= v));
                REQUIRE((r.hi == kBoundMax || v <= r.hi * f.step));
                const CellBounds e = exact_bounds(v, 1.0 / f.step);
                REQUIRE((e.lo == kBoundMin || e.lo * f.step <= v));
                REQUIRE((e.hi == kBoundMax || v <= e.hi * f.step));
                if (e.lo != kBoundMin && e.hi != kBoundMax) REQUIRE(e.hi - e.lo <= 1);
                ++in_range;
            }
        }
    CHECK(singles > 10);
    CHECK(probed > 0);
    CHECK(in_range > 0);
    // a region reaching past the field, or over several spheres' cells, has no single sphere
    const std::int64_t a[3] = {f.lo[0] - 2, f.lo[1], f.lo[2]}, b[3] = {f.lo[0] + 40, f.lo[1] + 40, f.lo[2] + 40};
    CHECK(f.single_sphere(a, b) == kNone);
    const std::int64_t a2[3] = {f.lo[0], f.lo[1], f.lo[2]}, b2[3] = {f.lo[0] + f.dims[0] - 1, f.lo[1] + f.dims[1] - 1,
                                                                      f.lo[2] + f.dims[2] - 1};
    CHECK(f.single_sphere(a2, b2) == kNone);
}

// The deformation's stages alone (native/src/deform/), continued: closed cubes, the exact queries, the decision
// rules, the output box and the candidate blocks, posed blend spheres, rebind and volume at bends; each against a
// brute force on small random inputs.
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

TEST_CASE("closed cubes give the exact power wherever it is negative", "[deform][stages]") {
    FieldCase fc(31, 60, 13);
    auto& [rs, s2, f, rng, u] = fc;
    std::int64_t closed = 0, checked = 0;
    for (std::uint32_t cell = 1; cell < f.words.size(); ++cell) {
        if (!closed_of(f.words[cell])) continue;
        ++closed;
        const std::uint32_t slot = (cell - 1) / 512, li = (cell - 1) % 512;
        const std::int64_t c[3] = {f.blocks[slot][0] + (li & 7), f.blocks[slot][1] + ((li >> 3) & 7),
                                   f.blocks[slot][2] + (li >> 6)};
        checked += probe_closed_cube(f, c, s2.data(), rng, 8);
    }
    CHECK(closed > 50);
    CHECK(checked > 50);
    // A cube is not closed when a sphere outside its corner labels pokes in with a lower power somewhere.
    // Sphere 1 (not a corner label) pokes into the cube [0, 1]³ and has the lower power at its centre; moved
    // away so that its ball misses the cube, it cannot break closure; one that is everywhere dominated cannot either.
    BoneField two;
    two.global = {0, 1};
    const double ones[3] = {1, 1, 1}, corner0[3] = {0, 0, 0};
    const std::uint32_t S[1] = {0};
    auto closed_with = [&](double x1, double lim1, double lim0 = 1.0) {
        two.sph = {{{0.0, 0.0, 0.0}, lim0}, {{x1, 0.5, 0.5}, lim1}};
        NearSpheres near;
        for (std::uint32_t j = 0; j < 2; ++j) near.add(two, j);
        return closed_cube(two, corner0, S, 1, near, ones);
    };
    CHECK(!closed_with(1.0, 1.0));
    CHECK(closed_with(3.0, 1.0));
    CHECK(closed_with(1.0, 0.2, 16.0));  // its power exceeds sphere 0's all over the cube
}

TEST_CASE("closed cubes at a block's far faces: exact from the corner labels a query reads", "[deform][stages]") {
    // A cube in a block's last layer has corners in the next block, which is not allocated when its own points all
    // lie at T or above: a query reads no label there (kNone), so the closure test may rely only on the others. A
    // small ball poking out of a big one between the lattice points is what then goes missing (seeds that did).
    std::int64_t checked = 0, hidden = 0;
    for (std::uint32_t seed = 1; seed <= 12; ++seed) {
        std::mt19937 rng(seed + 100);
        const RandomSpheres rs = tube_spheres(rng, {1.07, 0.98, 1.23});
        const std::array<double, 3> s2 = rs.s2();
        const BoneField f = rs.field();
        for (std::uint32_t cell = 1; cell < f.words.size(); ++cell) {
            const std::uint32_t slot = (cell - 1) / 512, li = (cell - 1) % 512;
            if (!closed_of(f.words[cell]) || ((li & 7) != 7 && ((li >> 3) & 7) != 7 && (li >> 6) != 7)) continue;
            const std::int64_t c[3] = {f.blocks[slot][0] + (li & 7), f.blocks[slot][1] + ((li >> 3) & 7),
                                       f.blocks[slot][2] + (li >> 6)};
            std::uint32_t corners[8];
            f.corner_cells(c[0] - f.lo[0], c[1] - f.lo[1], c[2] - f.lo[2], corners);
            hidden += std::count(corners, corners + 8, kNoCell) > 0;
            checked += probe_closed_cube(f, c, s2.data(), rng, 64);
        }
    }
    CHECK(hidden > 100);
    CHECK(checked > 1000);
}

TEST_CASE("narrowing a sphere list to a box keeps exactly the balls meeting it, in order", "[deform][stages]") {
    FieldCase fc(8, 60, 4);
    auto& [rs, s2, f, rng, u] = fc;
    NearSpheres all, kept;
    for (std::uint32_t j = 0; j < f.sph.size(); ++j) all.add(f, j);
    std::uniform_int_distribution<std::int64_t> corner(2, 24);  // around the spheres (centres 4-25)
    std::int64_t met = 0, missed = 0;
    for (int t = 0; t < 400; ++t) {
        const double size = t % 2 ? 2.0 : 4.0;
        const double lo[3] = {double(corner(rng)), double(corner(rng)), double(corner(rng))};
        const double hi[3] = {lo[0] + size, lo[1] + size, lo[2] + size};
        kept.keep_meeting(all, lo, size, s2.data());
        std::vector<std::uint32_t> expected;
        for (std::uint32_t j = 0; j < f.sph.size(); ++j)
            if (ball_meets_box(f.sph[j], lo, hi, s2.data())) expected.push_back(j);
        REQUIRE(kept.id == expected);
        for (std::size_t k = 0; k < kept.id.size(); ++k) {
            REQUIRE(kept.lim[k] == f.sph[kept.id[k]].lim);
            for (int a = 0; a < 3; ++a) REQUIRE(kept.c[a][k] == f.sph[kept.id[k]].c[a]);
        }
        met += static_cast<std::int64_t>(expected.size());
        missed += static_cast<std::int64_t>(f.sph.size() - expected.size());
    }
    CHECK(met > 300);  // both outcomes occur often
    CHECK(missed > 400);
}

TEST_CASE("exact queries and cube bounds against a brute force", "[deform][stages]") {
    FieldCase fc(41, 80, 17, {0.9, 1.1, 1.3});
    auto& [rs, s2, f, rng, u] = fc;
    (void)u;
    std::uniform_real_distribution<double> x(2, 25), y(2, 21), z(2, 27);
    for (int t = 0; t < 2000; ++t) {
        const double p[3] = {x(rng), y(rng), z(rng)};
        const Best b = brute_power(f, p, s2.data());
        const Best e = exact(f, p, rs.grid.spacing.data(), s2.data(), false);
        REQUIRE(e.key == b.key);
        REQUIRE(e.global == b.global);
        const double pw[3] = {p[0] * rs.grid.spacing[0], p[1] * rs.grid.spacing[1], p[2] * rs.grid.spacing[2]};
        bool covered = false;
        for (std::uint32_t k = 0; k < f.sph.size(); ++k)
            covered = covered || length2(p[0] - f.sph[k].c[0], p[1] - f.sph[k].c[1], p[2] - f.sph[k].c[2], s2.data()) < f.sph[k].lim;
        REQUIRE(any_cover(f, pw, p, s2.data()) == covered);
        const Best near = exact(f, p, rs.grid.spacing.data(), s2.data(), true);
        REQUIRE((near.local != kNone) == covered);
        Cube cube;
        if (!fetch_cube(f, p, cube)) {
            REQUIRE(!(b.key < 0));
            continue;
        }
        std::uint32_t local;
        const double U = least_over_labels(f, cube.lab, p, s2.data(), false, local);
        REQUIRE(U >= b.key);
        if (cube.same || cube.closed) REQUIRE((!(b.key < 0) || U == b.key));
        REQUIRE(lower_bound(f, cube, p, s2.data(), rs.T()) <= b.key);
    }
}

TEST_CASE("the decision rules and settle", "[deform][stages]") {
    CHECK(certain(-3.0, -2.0, false));
    CHECK(!certain(-3.0, -3.0, false));   // a tie is not certain from bounds
    CHECK(!certain(1.0, 5.0, false));     // not a cover
    CHECK(!certain(-3.0, -9.0, true));    // nearest centre: a rival that may cover is never beaten by bounds
    CHECK(certain(-3.0, 0.0, true));
    CHECK(in_running<std::int16_t>(-5, 3, false));
    CHECK(!in_running<std::int16_t>(-2, -4, false));
    CHECK(in_running<std::int16_t>(-2, -4, true));
    CHECK(!in_running<std::int16_t>(0, 7, false));
    int asked = 0;
    CHECK(beats(1.0, 2.0, [&] { return ++asked, false; }));
    CHECK(!beats(1.0, 1.0, [&] { return ++asked, false; }));
    CHECK(asked == 1);  // the index is looked up only on a tie
    std::vector<BoneField> none;
    std::vector<Motion> motions;
    const double sp[3] = {1, 1, 1};
    for (bool nearest : {false, true}) {
        const FieldSet set{none, motions, sp, {1, 1, 1}, 0.75, 1.0, nearest};
        const Decider d(set);
        std::uint8_t live[3];
        const CellBounds alone[2] = {{-9, -5}, {2, 9}};  // one certain cover, one that cannot cover
        CHECK(d.settle(alone, 2, live, 1) == 0);
        CHECK((live[0] == 1 && live[1] == 0));
        const CellBounds rivals[2] = {{-9, -5}, {-7, 4}};  // a rival that may cover: open either way
        CHECK(d.settle(rivals, 2, live, 1) == kOpen);
        const CellBounds beaten[2] = {{-9, -6}, {-5, 4}};  // power: the rival's least power exceeds the cover's greatest
        CHECK(d.settle(beaten, 2, live, 1) == (nearest ? kOpen : 0));
        const CellBounds nobody[3] = {{0, 9}, {3, 5}, {kBoundMax, kBoundMax}};
        CHECK(d.settle(nobody, 3, live, 1) == kEmpty);
    }
}

TEST_CASE("the output box holds exactly the posed balls' lattice points; candidate blocks cover them", "[deform][stages]") {
    RandomSpheres rs(51, 30, {1.0, 0.7, 1.4});
    const auto s2 = rs.s2();
    std::vector<BoneField> fields{rs.field()};
    const auto M = rotation_z(27, {3.3, -4.1, 2.2});
    std::vector<Motion> motions = bone_motions(M.data(), 1, rs.grid);
    const Box bx = posed_box(fields, motions, rs.grid);
    // Brute force: every lattice point q some posed ball holds (|pull(q) − c| < r).
    std::int64_t lo[3] = {1 << 20, 1 << 20, 1 << 20}, hi[3] = {-(1 << 20), -(1 << 20), -(1 << 20)};
    std::vector<std::array<std::int64_t, 3>> covered;
    for (std::int64_t z = -20; z < 60; ++z)
        for (std::int64_t y = -20; y < 60; ++y)
            for (std::int64_t x = -20; x < 60; ++x) {
                const std::int64_t q[3] = {x, y, z};
                for (const auto& sp : fields[0].sph) {
                    if (!(moved_length2(motions[0], sp.c, q, s2.data()) < sp.lim)) continue;
                    for (int a = 0; a < 3; ++a) {
                        lo[a] = std::min(lo[a], q[a]);
                        hi[a] = std::max(hi[a], q[a]);
                    }
                    covered.push_back({x, y, z});
                    break;
                }
            }
    REQUIRE(!covered.empty());
    for (int a = 0; a < 3; ++a) {
        CHECK(bx[a] == lo[a]);
        CHECK(bx[3 + a] == hi[a] - lo[a] + 1);
    }
    // The same spheres as a field with lattice tables (bit 0) and as one without (a blend group's, bit 1).
    fields.push_back(rs.ball_field());
    CHECK(!fields[1].lattice);
    CHECK(fields[1].sph.size() == fields[0].sph.size());
    motions.push_back(motions[0]);
    const std::vector<std::uint64_t> bits = candidate_bits(FieldSet{fields, motions, rs.grid.spacing.data(), {s2[0], s2[1], s2[2]}, rs.T(), 1.0, false}, bx);
    const std::int64_t obx = (bx[3] + 7) / 8, oby = (bx[4] + 7) / 8;
    for (const auto& q : covered) {
        const std::int64_t k = (((q[2] - bx[2]) / 8) * oby + (q[1] - bx[1]) / 8) * obx + (q[0] - bx[0]) / 8;
        REQUIRE((bits[static_cast<std::size_t>(k)] & 3u) == 3u);
    }
    // crop_to_extent keeps the extent, one voxel when nothing is covered.
    DeformedVolume f = frame_on(rs.grid, {0, 0, 0, 6, 5, 4});
    f.bone = ZeroedArray<std::int16_t>(120);
    f.bone.data()[(2 * 5 + 3) * 6 + 1] = 1;
    const std::int64_t elo[3] = {1, 3, 2}, ehi[3] = {1, 3, 2};
    crop_to_extent(f, elo, ehi, &rs.grid);
    CHECK((f.grid.dims == std::array<std::int64_t, 3>{1, 1, 1}));
    CHECK((f.offset == std::array<std::int64_t, 3>{1, 3, 2}));
    CHECK(f.bone.data()[0] == 1);
    CHECK(f.grid.origin[1] == Approx(rs.grid.origin[1] + 3 * rs.grid.spacing[1]));
    CHECK_THROWS_WITH(box_of({0, 0, 0}, {3000, 3000, 3000}), Catch::Contains("more than 2^31"));
}

TEST_CASE("a blend group's candidate blocks: every voxel its posed balls hold, under a strongly shrinking blend", "[deform][stages]") {
    RandomSpheres rs(77, 25, {0.9, 1.2, 1.0});
    for (double& r : rs.radii) r *= 3;  // balls of several blocks
    const auto s2 = rs.s2();
    std::vector<BoneField> fields{rs.ball_field()};
    // Half-way linear blend of rotations 0° and 130° about z: the blended map shrinks (cos 65° across), so the
    // posed balls are ellipsoids inside the balls of their radii round their posed centres.
    const auto A = rotation_z(0, {0, 0, 0}), B = rotation_z(130, {2.5, -1.5, 0.7});
    std::vector<double> mats(A.begin(), A.end());
    mats.insert(mats.end(), B.begin(), B.end());
    const auto bones = bone_motions(mats.data(), 2, rs.grid);
    std::vector<Motion> motions{blended_motion(bones, {{0, 8}, {1, 8}}, 0, DeformMode::Linear, rs.grid,
                                               Eigen::Vector3d(12, 10, 14))};
    const Box bx = posed_box(fields, motions, rs.grid);
    const std::vector<std::uint64_t> bits =
        candidate_bits(FieldSet{fields, motions, rs.grid.spacing.data(), {s2[0], s2[1], s2[2]}, rs.T(), 1.0, false}, bx);
    const std::int64_t ob[3] = {(bx[3] + 7) / 8, (bx[4] + 7) / 8, (bx[5] + 7) / 8};
    std::int64_t covered = 0;
    std::vector<std::uint8_t> needed(bits.size(), 0);
    for (std::int64_t z = bx[2]; z < bx[2] + bx[5]; ++z)
        for (std::int64_t y = bx[1]; y < bx[1] + bx[4]; ++y)
            for (std::int64_t x = bx[0]; x < bx[0] + bx[3]; ++x) {
                const std::int64_t q[3] = {x, y, z};
                bool in = false;
                for (const auto& sp : fields[0].sph) in = in || moved_length2(motions[0], sp.c, q, s2.data()) < sp.lim;
                if (!in) continue;
                ++covered;
                const std::int64_t k = (((z - bx[2]) / 8) * ob[1] + (y - bx[1]) / 8) * ob[0] + (x - bx[0]) / 8;
                REQUIRE((bits[static_cast<std::size_t>(k)] & 1u) == 1u);
                needed[static_cast<std::size_t>(k)] = 1;
            }
    CHECK(covered > 1000);
    std::int64_t marked = 0, spare = 0;
    for (std::size_t k = 0; k < bits.size(); ++k) {
        marked += (bits[k] & 1u) != 0;
        spare += (bits[k] & 1u) != 0 && !needed[k];
    }
    CHECK(spare * 4 < marked);  // a few blocks the balls only graze (the margin), not the corners of their boxes
}

TEST_CASE("posed blend spheres: each tile's and block's kept spheres give the least power over all groups", "[deform][stages]") {
    // Three blend groups of one random set, each moved by its own blend of two rotations: the gather takes them as
    // one candidate, pruned per 32³ region, 16³ tile and 8³ block in output space (every blend is rigid). At every
    // output voxel the least (power, global index) over the kept spheres, each through its own group's fixed-point
    // map, must be the least over all spheres of all groups wherever that covers, within the kept range (the block's
    // list pruned, as the gather's, from the tile's spheres its octant masks keep for the block). Far
    // translations make the fixed-point maps' error (the margins) large.
    for (const std::array<double, 3> shift : {std::array<double, 3>{2.5, -1.5, 0.7}, std::array<double, 3>{3000.5, -2200.25, 1700.0}}) {
        RandomSpheres rs(91, 60, {0.9, 1.2, 1.05});
        for (double& r : rs.radii) r *= 2;
        const auto s2 = rs.s2();
        std::vector<BoneField> fields;
        for (std::uint32_t g = 0; g < 3; ++g) {
            std::vector<std::uint32_t> members;
            for (std::uint32_t i = g; i < rs.members.size(); i += 3) members.push_back(i);
            fields.push_back(build_ball_field(rs.grid, rs.spheres(), members, rs.radii, rs.T(), 1.0));
        }
        const auto A = rotation_z(10, shift), B = rotation_z(75, {shift[0] + 1.5, shift[1] - 0.5, shift[2] + 0.3});
        std::vector<double> mats(A.begin(), A.end());
        mats.insert(mats.end(), B.begin(), B.end());
        const auto bones = bone_motions(mats.data(), 2, rs.grid);
        std::vector<Motion> motions;
        for (const Weights& w : {Weights{{0, 12}, {1, 4}}, Weights{{0, 8}, {1, 8}}, Weights{{0, 5}, {1, 11}}})
            motions.push_back(blended_motion(bones, w, 0, DeformMode::Linear, rs.grid, Eigen::Vector3d(12, 10, 14)));
        const Box bx = posed_box(fields, motions, rs.grid);
        const FieldSet set{fields, motions, rs.grid.spacing.data(), {s2[0], s2[1], s2[2]}, rs.T(), 0.01, false};
        const PosedBalls posed = pose_balls(set, bx);
        REQUIRE(posed.ball.size() == rs.members.size());
        INFO("shift " << shift[0]);
        auto least = [&](const std::int64_t* q, const std::uint32_t* in, std::size_t n) {  // over posed balls `in`
            Best b;
            for (std::size_t j = 0; j < n; ++j) {
                const PosedBall& pb = posed.ball[in[j]];
                double p[3];
                motions[static_cast<std::size_t>(pb.field)].pull.apply(q, p);
                const BoneField& f = fields[static_cast<std::size_t>(pb.field)];
                const double v = power_of(f, pb.local, p, s2.data());
                if (b.better(v, f.global[pb.local])) b = {v, pb.local, f.global[pb.local]};
            }
            return b;
        };
        std::vector<std::uint32_t> all(posed.ball.size());
        for (std::uint32_t j = 0; j < all.size(); ++j) all[j] = j;
        const std::int64_t ob[3] = {(bx[3] + 7) / 8, (bx[4] + 7) / 8, (bx[5] + 7) / 8};
        std::vector<double> scratch;
        std::int64_t covered = 0, kept_total = 0, blocks = 0;
        std::int64_t k[3];
        for (k[2] = 0; k[2] < ob[2]; ++k[2])
            for (k[1] = 0; k[1] < ob[1]; ++k[1])
                for (k[0] = 0; k[0] < ob[0]; ++k[0]) {
                    const std::vector<std::uint32_t>& tile = posed.kept[posed.tile_of(k)];
                    double box[6];
                    std::int64_t e[3], base[3];
                    for (int a = 0; a < 3; ++a) {
                        e[a] = std::min<std::int64_t>(8, bx[3 + a] - k[a] * 8);
                        base[a] = bx[a] + k[a] * 8;
                        box[a] = static_cast<double>(base[a]);
                        box[3 + a] = box[a] + static_cast<double>(e[a] - 1);
                    }
                    const std::vector<std::uint8_t>& octants = posed.octants[posed.tile_of(k)];
                    REQUIRE(octants.size() == tile.size());
                    std::vector<std::uint32_t> in, kept;  // the tile's spheres kept for the block, as the gather
                    octant_list(tile.data(), octants.data(), tile.size(), PosedBalls::octant_of(k), in);
                    const CellBounds rg = prune_balls(posed.ball.data(), posed.rel, s2.data(), set.bound_step, box,
                                                      in.data(), in.size(), kept, scratch);
                    blocks += !kept.empty();
                    kept_total += static_cast<std::int64_t>(kept.size());
                    REQUIRE(std::is_sorted(kept.begin(), kept.end()));
                    for (std::int64_t z = 0; z < e[2]; ++z)
                        for (std::int64_t y = 0; y < e[1]; ++y)
                            for (std::int64_t x = 0; x < e[0]; ++x) {
                                const std::int64_t q[3] = {base[0] + x, base[1] + y, base[2] + z};
                                const Best truth = least(q, all.data(), all.size());
                                if (!(truth.key < 0)) continue;
                                ++covered;
                                const Best r = least(q, tile.data(), tile.size()), b = least(q, kept.data(), kept.size());
                                REQUIRE(r.global == truth.global);
                                REQUIRE(b.global == truth.global);
                                REQUIRE(b.key == truth.key);
                                REQUIRE(rg.lo * set.bound_step <= truth.key);
                                REQUIRE(truth.key <= rg.hi * set.bound_step);
                            }
                }
        INFO("covered " << covered << " kept " << kept_total << " in " << blocks << " blocks");
        CHECK(covered > 2000);
        CHECK(kept_total * 4 < blocks * 60);  // the pruning keeps a few per block, not the 60
    }
}

TEST_CASE("octant masks keep, in every octant of a box, the sphere of least power at each of its voxels", "[deform][stages]") {
    // Random spheres around random boxes (odd sizes: octants of unequal sides, or none above the split), anisotropic
    // metric: at every voxel of each octant, the least (power, index) over the spheres the masks keep for it is the
    // least over all. Many spheres, so that masks do clear bits.
    struct Ball {
        double c[3];
        double lim;
    };
    std::mt19937 rng(57);
    std::uniform_real_distribution<double> u(0, 1);
    const double s2[3] = {0.8, 1.3, 1.0};
    std::int64_t cleared = 0, checked = 0;
    for (int trial = 0; trial < 40; ++trial) {
        const std::int64_t lo[3] = {static_cast<std::int64_t>(u(rng) * 20) - 10, static_cast<std::int64_t>(u(rng) * 20),
                                    static_cast<std::int64_t>(u(rng) * 20) + 5};
        const std::int64_t half = trial % 2 ? 4 : 8, side[3] = {2 * half, 2 * half - trial % 3, trial % 5 ? 2 * half : half - 1};
        std::vector<Ball> balls(120);
        for (Ball& b : balls) {
            for (int a = 0; a < 3; ++a) b.c[a] = static_cast<double>(lo[a]) + (u(rng) * 1.6 - 0.3) * static_cast<double>(2 * half);
            b.lim = std::pow(1 + u(rng) * 2.5 * static_cast<double>(half), 2);
        }
        std::vector<std::uint32_t> list(balls.size());
        for (std::uint32_t j = 0; j < list.size(); ++j) list[j] = j;
        double box[6], split[3];
        for (int a = 0; a < 3; ++a) {
            box[a] = static_cast<double>(lo[a]);
            box[3 + a] = static_cast<double>(lo[a] + side[a] - 1);
            split[a] = static_cast<double>(lo[a] + half);
        }
        std::vector<std::uint8_t> mask(list.size());
        std::vector<double> scratch;
        octant_masks(balls.data(), 1e-9, s2, box, split, list.data(), list.size(), scratch, mask.data());
        for (const std::uint8_t m : mask) cleared += 8 - __builtin_popcount(m);
        auto least = [&](const std::int64_t* q, const std::vector<std::uint32_t>& in) {
            std::pair<double, std::uint32_t> best{kInf, 0};
            for (const std::uint32_t j : in) {
                const Ball& b = balls[j];
                const double p = length2(static_cast<double>(q[0]) - b.c[0], static_cast<double>(q[1]) - b.c[1],
                                         static_cast<double>(q[2]) - b.c[2], s2) - b.lim;
                best = std::min(best, {p, j});
            }
            return best;
        };
        std::int64_t q[3];
        for (q[2] = lo[2]; q[2] < lo[2] + side[2]; ++q[2])
            for (q[1] = lo[1]; q[1] < lo[1] + side[1]; ++q[1])
                for (q[0] = lo[0]; q[0] < lo[0] + side[0]; ++q[0]) {
                    int o = 0;
                    for (int a = 0; a < 3; ++a) o |= (q[a] >= lo[a] + half) << a;
                    std::vector<std::uint32_t> in;
                    octant_list(list.data(), mask.data(), list.size(), o, in);
                    REQUIRE(least(q, in) == least(q, list));
                    ++checked;
                }
    }
    INFO("cleared " << cleared << " of " << 40 * 120 * 8 << " bits over " << checked << " voxels");
    CHECK(cleared > 40 * 120 * 4);  // most spheres drop out of most octants
}

TEST_CASE("rebind rebuilds only the fields whose spheres changed, and frames stay equal to a fresh Deformer's", "[deform][stages]") {
    RandomSpheres rs(61, 90);
    std::vector<std::uint8_t> samples(static_cast<std::size_t>(rs.grid.voxel_count()));
    for (std::size_t i = 0; i < samples.size(); ++i) samples[i] = static_cast<std::uint8_t>(i * 37 % 251);
    const VolumeView v{rs.grid, DType::UInt8, samples.data()};
    for (std::size_t i = 0; i < rs.bone.size(); ++i) rs.bone[i] = static_cast<std::int32_t>(i % 3);
    BoundSpheres s = rs.spheres();
    s.bone_count = 3;
    std::vector<double> mats;
    for (double deg : {0.0, 20.0, -35.0}) {
        const auto m = rotation_z(deg, {1.0, 0.5, -0.5});
        mats.insert(mats.end(), m.begin(), m.end());
    }
    Deformer d(v, s);
    const DeformOptions o;
    d.frame(mats.data(), o);
    CHECK(d.reused_fields() == 0);
    for (std::size_t i = 0; i < rs.bone.size(); i += 9)  // "repaint": some of bone 0's spheres go to bone 1
        if (rs.bone[i] == 0) rs.bone[i] = 1;
    d.rebind(s);
    const DeformedVolume a = d.frame(mats.data(), o);
    CHECK(d.reused_fields() == 1);  // bone 2's field is taken over
    Deformer fresh(v, s);
    const DeformedVolume b = fresh.frame(mats.data(), o);
    REQUIRE(a.grid.dims == b.grid.dims);
    CHECK(std::equal(a.bone.data(), a.bone.data() + a.bone.size(), b.bone.data()));
    CHECK(std::equal(a.values.data(), a.values.data() + a.values.size(), b.values.data()));
    rs.radius[0] += 1;
    CHECK_THROWS_WITH(d.rebind(s), Catch::Contains("make a new Deformer"));
}

TEST_CASE("volume at bends: the slab factor, per-frame ball radii, and factors from poses", "[deform][stages]") {
    CHECK(disc_segment(1) == 0);
    CHECK(disc_segment(-1) == Approx(M_PI));
    CHECK(disc_segment(0) == Approx(M_PI / 2));
    CHECK(slab_factor(kInf, 1) == 1);                        // no crossing, no stretch: exactly 1
    CHECK(slab_factor(0, 1) == kMaxBend);                     // half the disc past the plane: √2 wanted, capped
    CHECK(slab_factor(kInf, 0.64) == Approx(1.25).margin(1e-9));  // squeezed to 0.64: 1/0.8 wider
    CHECK(slab_factor(kInf, 4) == Approx(0.5).margin(1e-9));  // stretched four-fold: thinner
    CHECK(slab_factor(-5, 1) == kMaxBend);
    CHECK(slab_factor(0.3, 1) > slab_factor(0.6, 1));
    CHECK(slab_factor(0.6, 1) > 1);

    // A blend group's radii change per frame: the k-d tree's ball boxes and largest limits follow.
    RandomSpheres rs(11, 40);
    BoneField f = rs.ball_field();
    scale_ball_field(f, rs.radii, 1.3, rs.grid);
    for (std::size_t k = 0; k < f.sph.size(); ++k)
        CHECK(f.sph[k].lim == open_ball_limit_sq(bent_radius(rs.radii[f.global[k]], 1.3)));
    for (const KdNode& n : f.nodes) {
        double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf}, top = 0;
        for (std::uint32_t k = n.begin; k < n.end; ++k)
            for (int a = 0; a < 3; ++a) {
                const double c = f.sph[k].c[a] * rs.grid.spacing[a], r = std::sqrt(f.sph[k].lim);
                lo[a] = std::min(lo[a], c - r);
                hi[a] = std::max(hi[a], c + r);
                top = std::max(top, f.sph[k].lim);
            }
        for (int a = 0; a < 3; ++a) CHECK((n.blo[a] == lo[a] && n.bhi[a] == hi[a]));
        CHECK(n.max_lim == top);
    }

    // A straight tube of spheres along x, blended across a joint at x = 16: at rest every factor is 1; bent to
    // 150 degrees the slabs grow (within the factor's bounds).
    Grid g;
    g.dims = {32, 24, 24};
    g.spacing = {1.0, 1.0, 1.0};
    std::vector<std::int32_t> ijk, bone, wb;
    std::vector<float> radius, w;
    std::vector<std::int64_t> off = {0};
    for (int x = 4; x < 28; ++x) {
        ijk.insert(ijk.end(), {12, 12, x});
        radius.push_back(4.0f);
        bone.push_back(x < 16 ? 0 : 1);
        const float t = std::clamp((static_cast<float>(x) - 10.0f) / 12.0f, 0.0f, 1.0f);
        wb.insert(wb.end(), {0, 1});
        w.insert(w.end(), {1 - t, t});
        off.push_back(static_cast<std::int64_t>(wb.size()));
    }
    const BoundSpheres s = bound_spheres(ijk, radius, bone, 2, &off, &wb, &w);
    const SmoothGroups groups = smooth_groups(s, g);
    const std::vector<double> radii(radius.begin(), radius.end());
    const BendModel m = bend_model(s, groups, radii, g);
    REQUIRE(m.gradient.size() == 1);
    for (const Eigen::Vector3d& side : m.gradient[0]) CHECK(side.normalized().dot(Eigen::Vector3d::UnitX()) == Approx(1));
    const auto rest = rotation_z(0, {0, 0, 0});
    std::vector<double> mats(rest.begin(), rest.end());
    mats.insert(mats.end(), rest.begin(), rest.end());
    for (DeformMode mode : {DeformMode::Linear, DeformMode::DualQuaternion}) {
        for (double f0 : bend_factors(m, groups, bone_motions(mats.data(), 2, g), mode)) CHECK(f0 == 1);
        // 150 degrees about z through the joint (16, 12, 12): translation = p - R p
        const double t = 150 * M_PI / 180, c = std::cos(t), sn = std::sin(t);
        std::vector<double> bent(rest.begin(), rest.end());
        bent.insert(bent.end(), {c, -sn, 0, 16 - (c * 16 - sn * 12), sn, c, 0, 12 - (sn * 16 + c * 12), 0, 0, 1, 0,
                                 0, 0, 0, 1});
        const std::vector<double> fs = bend_factors(m, groups, bone_motions(bent.data(), 2, g), mode);
        CHECK(*std::max_element(fs.begin(), fs.end()) > 1.05);
        for (double f0 : fs) CHECK((f0 >= kMinBend && f0 <= kMaxBend));

        // Sliding contact: none at rest; folded, each bone's field yields past the bisector (its normal towards the
        // other bone, turned by 75 degrees from x) within min(4, 2 tan(75°)) = 4 limb radii of the joint; so do the
        // blend groups the bisector cuts off.
        const FieldContacts still = contacts(m, groups, bone_motions(mats.data(), 2, g), mode, 2, g);
        REQUIRE(still.size() == 2 + groups.weights.size());
        for (const auto& planes : still) CHECK(planes.empty());
        const FieldContacts folded = contacts(m, groups, bone_motions(bent.data(), 2, g), mode, 2, g);
        REQUIRE(folded[0].size() == 1);
        REQUIRE(folded[1].size() == 1);
        const double turn = 75 * M_PI / 180;
        CHECK(folded[0][0].normal[0] == Approx(std::cos(turn)).margin(1e-9));
        CHECK(folded[0][0].normal[1] == Approx(std::sin(turn)).margin(1e-9));
        CHECK(folded[1][0].normal[1] == Approx(-std::sin(turn)).margin(1e-9));
        CHECK(folded[0][0].joint[0] == Approx(16).margin(0.5));
        CHECK(folded[0][0].joint[1] == Approx(12).margin(0.5));
        CHECK(folded[0][0].reach2 == Approx(16.0 * 16.0));
        const std::int64_t beyond[3] = {17, 15, 12}, before[3] = {16, 9, 12}, far[3] = {16, 12 + 17, 12};
        const double s2[3] = {1, 1, 1};
        CHECK(yields(folded[0], beyond, s2));
        CHECK_FALSE(yields(folded[0], before, s2));
        CHECK(yields(folded[1], before, s2));
        CHECK_FALSE(yields(folded[1], beyond, s2));
        CHECK_FALSE(yields(folded[0], far, s2));
        std::size_t cut = 0;
        for (std::size_t k = 2; k < folded.size(); ++k) cut += folded[k].size();
        CHECK(cut > 0);
    }
}

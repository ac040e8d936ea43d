// collide/collide.cpp: the fast path (docs/ALGORITHMS.md §8): fields paired by their posed root spheres, ball trees
// descended as dual trees, lattice points decided exactly in the boxes of intersecting ball pairs.
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <string>
#include <tuple>

#include "collide/posed.hpp"

namespace volrig {

using namespace collide_detail;

namespace {

using SpherePairs = std::vector<std::pair<std::uint32_t, std::uint32_t>>;
using Box6 = std::array<std::int64_t, 6>;

/// A field's posed root sphere.
struct Root {
    Vec3 c;
    double r;
    std::uint32_t field;
};

std::vector<Root> roots(const Posed& p) {
    std::vector<Root> out;
    for (std::size_t f = 0; f < p.part->fields.size(); ++f) {
        const BallTree& t = p.part->fields[f].tree;
        if (!t.empty()) out.push_back({p.posed(f, t.nodes[0].centre), t.nodes[0].radius(p.scale), static_cast<std::uint32_t>(f)});
    }
    std::sort(out.begin(), out.end(), [](const Root& a, const Root& b) { return a.c[0] - a.r < b.c[0] - b.r; });
    return out;
}

double dist2(const Vec3& a, const Vec3& b) {
    return (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]);
}

/// Spheres that may share a point (conservative by a hair: the motions' fixed-point rounding).
bool may_touch(double d2, double ra, double rb) {
    const double r = (ra + rb) * (1 + 1e-7) + 1e-9;
    return d2 < r * r;
}

/// Pairs of overlapping roots by a sweep along x (`self`: one list, each pair once, a field with itself too).
std::vector<std::pair<std::uint32_t, std::uint32_t>> field_pairs(const std::vector<Root>& A, const std::vector<Root>& B,
                                                                 bool self) {
    std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
    std::vector<const Root*> active_a, active_b;
    auto sweep = [&](const Root& x, std::vector<const Root*>& others, bool x_is_a) {
        const double lo = x.c[0] - x.r;
        others.erase(std::remove_if(others.begin(), others.end(), [&](const Root* o) { return o->c[0] + o->r < lo; }),
                     others.end());
        for (const Root* o : others)
            if (may_touch(dist2(x.c, o->c), x.r, o->r))
                out.emplace_back(x_is_a ? x.field : o->field, x_is_a ? o->field : x.field);
    };
    if (self) {
        for (const Root& x : A) {
            sweep(x, active_a, true);
            out.emplace_back(x.field, x.field);
            active_a.push_back(&x);
        }
        return out;
    }
    std::size_t i = 0, j = 0;
    while (i < A.size() || j < B.size()) {
        if (j == B.size() || (i < A.size() && A[i].c[0] - A[i].r <= B[j].c[0] - B[j].r)) {
            sweep(A[i], active_b, true);
            active_a.push_back(&A[i++]);
        } else {
            sweep(B[j], active_a, false);
            active_b.push_back(&B[j++]);
        }
    }
    return out;
}

/// Which ball pairs of two fields count: all of them between two bodies; for one body the eligible ones, and
/// within one field each pair once.
struct PairRule {
    bool self = false;
    int min_bone_distance = 0;
    bool ignore_rest_contact = false;
    bool keep_points = false;  ///< also list the contact voxels
    bool accept(const Posed& p, std::uint32_t i, std::uint32_t j, bool same_leaf) const {
        return !self || ((!same_leaf || i < j) && eligible(p, i, j, min_bone_distance, ignore_rest_contact));
    }
};

/// B's rest world -> A's rest world for one field pair.
struct Relative {
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    Vec3 operator()(const Vec3& x) const {
        const Eigen::Vector3d y = R * Eigen::Vector3d(x[0], x[1], x[2]) + t;
        return {y[0], y[1], y[2]};
    }
};

Relative relative(const Motion& a, const Motion& b) {
    return {a.R.transpose() * b.R, a.R.transpose() * (b.d - a.d)};
}

void leaf_pairs(const Posed& a, const Posed& b, const BallNode& na, const BallNode& nb, const BallTree& ta,
                const BallTree& tb, const Relative& X, const PairRule& rule, bool same_leaf, SpherePairs& out) {
    for (std::uint32_t u = na.begin; u < na.end; ++u) {
        const std::uint32_t i = ta.order[u];
        for (std::uint32_t v = nb.begin; v < nb.end; ++v) {
            const std::uint32_t j = tb.order[v];
            if (!(a.radius[i] > 0 && b.radius[j] > 0)) continue;
            if (!may_touch(dist2(a.c->rest_world[i], X(b.c->rest_world[j])), a.radius[i], b.radius[j])) continue;
            if (rule.accept(a, i, j, same_leaf)) out.emplace_back(i, j);
        }
    }
}

/// The ball pairs of fields fa (of a) and fb (of b) that may share a point: a dual descent in fa's rest frame.
std::int64_t descend(const Posed& a, std::size_t fa, const Posed& b, std::size_t fb, const PairRule& rule,
                     SpherePairs& out) {
    const BallTree& ta = a.part->fields[fa].tree;
    const BallTree& tb = b.part->fields[fb].tree;
    const Relative X = relative(a.motion[fa], b.motion[fb]);
    const bool same_field = rule.self && fa == fb;
    std::int64_t tests = 0;
    std::vector<std::pair<std::int32_t, std::int32_t>> stack{{0, 0}};
    while (!stack.empty()) {
        const auto [ia, ib] = stack.back();
        stack.pop_back();
        const BallNode& na = ta.nodes[static_cast<std::size_t>(ia)];
        const BallNode& nb = tb.nodes[static_cast<std::size_t>(ib)];
        const double ra = na.radius(a.scale), rb = nb.radius(b.scale);
        ++tests;
        if (!may_touch(dist2(na.centre, X(nb.centre)), ra, rb)) continue;
        if (same_field && ia == ib) {  // a field against itself: each pair of subtrees once
            if (na.leaf()) leaf_pairs(a, b, na, nb, ta, tb, X, rule, true, out);
            else {
                stack.emplace_back(na.child[0], na.child[0]);
                stack.emplace_back(na.child[0], na.child[1]);
                stack.emplace_back(na.child[1], na.child[1]);
            }
        } else if (na.leaf() && nb.leaf()) leaf_pairs(a, b, na, nb, ta, tb, X, rule, false, out);
        else open_larger(stack, na, ia, ra, nb, ib, rb);
    }
    return tests;
}

Box6 meet(const Box6& x, const Box6& y) {
    return {std::max(x[0], y[0]), std::max(x[1], y[1]), std::max(x[2], y[2]),
            std::min(x[3], y[3]), std::min(x[4], y[4]), std::min(x[5], y[5])};
}
bool empty_box(const Box6& x) { return x[0] > x[3] || x[1] > x[4] || x[2] > x[5]; }
Box6 join(const Box6& x, const Box6& y) {
    return {std::min(x[0], y[0]), std::min(x[1], y[1]), std::min(x[2], y[2]),
            std::max(x[3], y[3]), std::max(x[4], y[4]), std::max(x[5], y[5])};
}
constexpr Box6 kNoBox{INT64_MAX, INT64_MAX, INT64_MAX, INT64_MIN, INT64_MIN, INT64_MIN};

/// A candidate ball of either body: the lattice box it is rasterized over (its box within those of its partners)
/// and the bitmap slot of its bone.
struct Candidate {
    std::uint32_t sphere = 0;
    bool of_b = false;
    std::size_t slot = 0;
    Box6 region = kNoBox;
};

/// The lattice box of a body's moved ball on A's lattice.
Box6 ball_region(const Posed& a, const Posed& p, std::uint32_t i) {
    return ball_box(a.c->grid, p.posed(static_cast<std::size_t>(p.part->field_of[i]), p.c->rest_world[i]), p.radius[i]);
}

/// The balls of the ball pairs, each once per body with the union of its lens boxes; bones get bitmap slots (for one
/// body, one slot per bone whichever side of a pair its ball is on).
struct Candidates {
    std::vector<Candidate> balls;
    std::vector<std::int32_t> slot_bone;  ///< bone of each slot
    std::vector<bool> slot_of_b;          ///< two bodies: whether the slot is one of B's bones
    Box6 box = kNoBox;                    ///< union of every ball's region
};

Candidates candidates(const Posed& a, const Posed& b, const SpherePairs& pairs, bool self) {
    Candidates out;
    constexpr std::size_t kUnset = SIZE_MAX;
    std::vector<std::size_t> ball_a(a.radius.size(), kUnset), ball_b(self ? 0 : b.radius.size(), kUnset);
    std::vector<std::size_t> slot_a(a.c->bone_count, kUnset), slot_b(self ? 0 : b.c->bone_count, kUnset);
    auto ball = [&](bool side, std::uint32_t i) -> Candidate& {
        std::size_t& index = (side ? ball_b : ball_a)[i];
        if (index == kUnset) {
            const Posed& p = side ? b : a;
            std::size_t& slot = (side ? slot_b : slot_a)[static_cast<std::size_t>(p.owner(i))];
            if (slot == kUnset) {
                slot = out.slot_bone.size();
                out.slot_bone.push_back(p.owner(i));
                out.slot_of_b.push_back(side);
            }
            index = out.balls.size();
            out.balls.push_back({i, side, slot, kNoBox});
        }
        return out.balls[index];
    };
    for (const auto& [i, j] : pairs) {
        const Box6 lens = meet(ball_region(a, a, i), ball_region(a, b, j));
        if (empty_box(lens)) continue;
        Candidate& x = ball(false, i);
        x.region = join(x.region, lens);
        Candidate& y = ball(!self, j);
        y.region = join(y.region, lens);
        out.box = join(out.box, lens);
    }
    return out;
}

/// Per-bone coverage bitmaps over a slab of the candidate box (z from z0, `depth` slices).
class Slab {
public:
    Slab(const Box6& box, std::int64_t z0, std::int64_t depth, std::size_t slots)
        : box_(box), z0_(z0), depth_(depth), nx_(box[3] - box[0] + 1), ny_(box[4] - box[1] + 1),
          words_((static_cast<std::size_t>(nx_ * ny_ * depth) + 63) / 64),
          bits_(std::make_unique<std::atomic<std::uint64_t>[]>(words_ * slots)) {
        for (std::size_t k = 0; k < words_ * slots; ++k) bits_[k].store(0, std::memory_order_relaxed);
    }
    std::size_t words() const { return words_; }
    std::uint64_t word(std::size_t slot, std::size_t w) const { return bits_[slot * words_ + w].load(std::memory_order_relaxed); }
    void set(std::size_t slot, const std::int64_t* q) {
        const auto k = static_cast<std::size_t>(((q[2] - z0_) * ny_ + (q[1] - box_[1])) * nx_ + (q[0] - box_[0]));
        bits_[slot * words_ + (k >> 6)].fetch_or(std::uint64_t{1} << (k & 63), std::memory_order_relaxed);
    }
    /// Sets the bits of row (y, z) from x0 to x1 (inclusive).
    void set_row(std::size_t slot, std::int64_t y, std::int64_t z, std::int64_t x0, std::int64_t x1) {
        const std::int64_t row = ((z - z0_) * ny_ + (y - box_[1])) * nx_;
        std::size_t k = static_cast<std::size_t>(row + (x0 - box_[0]));
        const auto end = static_cast<std::size_t>(row + (x1 - box_[0]) + 1);
        while (k < end) {
            const std::size_t w = k >> 6, first = k & 63, last = std::min<std::size_t>(64, first + (end - k));
            const std::uint64_t mask = (last == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << last) - 1) &
                                       ~((std::uint64_t{1} << first) - 1);
            bits_[slot * words_ + w].fetch_or(mask, std::memory_order_relaxed);
            k += last - first;
        }
    }
    /// The lattice point of bit k.
    void point(std::size_t k, std::int64_t* q) const {
        const auto i = static_cast<std::int64_t>(k);
        q[0] = box_[0] + i % nx_;
        q[1] = box_[1] + (i / nx_) % ny_;
        q[2] = z0_ + i / (nx_ * ny_);
    }
    std::int64_t z0() const { return z0_; }
    std::int64_t z1() const { return z0_ + depth_ - 1; }

private:
    Box6 box_;
    std::int64_t z0_, depth_, nx_, ny_;
    std::size_t words_;
    std::unique_ptr<std::atomic<std::uint64_t>[]> bits_;
};

/// Marks the lattice points of candidate ball c that lie in the slab and in the ball in its bone's bitmap. The
/// decision is the exact one (the deformation's own test for A's balls, covers_from for B's) at the two ends of
/// each row; between them the points lie inside by a margin far above rounding and are set as a run. Returns the
/// points decided one by one.
std::int64_t rasterize(const Posed& a, const Posed& b, bool same, const Candidate& c, Slab& slab) {
    const Posed& p = c.of_b ? b : a;
    const Grid& g = a.c->grid;
    const Vec3 w = p.posed(static_cast<std::size_t>(p.part->field_of[c.sphere]), p.c->rest_world[c.sphere]);
    const double r = p.radius[c.sphere], cx = (w[0] - g.origin[0]) / g.spacing[0];
    const double m = 1e-3 * r / g.spacing[0] + 1e-5;  // the uncertain band at each end of a row, in voxels
    auto inside = [&](const std::int64_t* q) { return c.of_b ? covers_from(a, b, c.sphere, q, same) : a.covers(c.sphere, q); };
    const Box6& box = c.region;
    std::int64_t tests = 0, q[3];
    for (q[2] = std::max(box[2], slab.z0()); q[2] <= std::min(box[5], slab.z1()); ++q[2])
        for (q[1] = box[1]; q[1] <= box[4]; ++q[1]) {
            const double dy = (g.origin[1] + g.spacing[1] * static_cast<double>(q[1]) - w[1]);
            const double dz = (g.origin[2] + g.spacing[2] * static_cast<double>(q[2]) - w[2]);
            const double rem = r * r - dy * dy - dz * dz;
            if (rem < -1e-6 * r * r - 1e-12) continue;
            const double half = std::sqrt(std::max(rem, 0.0)) / g.spacing[0];
            const std::int64_t xa = std::max(box[0], static_cast<std::int64_t>(std::ceil(cx - half - m)));
            const std::int64_t xb = std::min(box[3], static_cast<std::int64_t>(std::floor(cx + half + m)));
            const std::int64_t ia = std::max(xa, static_cast<std::int64_t>(std::floor(cx - half + m)) + 1);
            const std::int64_t ib = std::min(xb, static_cast<std::int64_t>(std::ceil(cx + half - m)) - 1);
            auto exact = [&](std::int64_t x0, std::int64_t x1) {
                for (q[0] = x0; q[0] <= x1; ++q[0], ++tests)
                    if (inside(q)) slab.set(c.slot, q);
            };
            if (ia > ib) {
                exact(xa, xb);
                continue;
            }
            exact(xa, ia - 1);
            slab.set_row(c.slot, q[1], q[2], ia, ib);
            exact(ib + 1, xb);
        }
    return tests;
}

/// Which slot pairs form contacts: (A's bone, B's bone) for two bodies; for one body pairs of bones the rule
/// allows (lower slot first).
std::vector<std::pair<std::size_t, std::size_t>> slot_pairs(const Candidates& cs, const Posed& a, const PairRule& rule) {
    std::vector<std::pair<std::size_t, std::size_t>> out;
    const std::size_t n = cs.slot_bone.size();
    for (std::size_t x = 0; x < n; ++x)
        for (std::size_t y = rule.self ? x + 1 : 0; y < n; ++y) {
            if (!rule.self) {
                if (!cs.slot_of_b[x] && cs.slot_of_b[y]) out.emplace_back(x, y);
                continue;
            }
            const Collider::Impl& c = *a.c;
            const std::size_t xy = static_cast<std::size_t>(cs.slot_bone[x]) * c.bone_count + static_cast<std::size_t>(cs.slot_bone[y]);
            if ((rule.min_bone_distance > 0 && c.distance[xy] < rule.min_bone_distance) ||
                (rule.ignore_rest_contact && c.joined[xy]))
                continue;
            out.emplace_back(x, y);
        }
    return out;
}

/// What the combination of a slab's bitmaps finds.
struct Found {
    std::int64_t voxels = 0;
    Box6 box = kNoBox;
    std::vector<std::uint8_t> pair_hit;  ///< per slot pair
    std::vector<std::array<std::int64_t, 3>> points;  ///< the contact voxels, when kept
};

void combine(const Slab& slab, const std::vector<std::pair<std::size_t, std::size_t>>& sp, std::size_t w, bool keep,
             Found& f) {
    std::uint64_t hit = 0;
    for (std::size_t k = 0; k < sp.size(); ++k) {
        const std::uint64_t both = slab.word(sp[k].first, w) & slab.word(sp[k].second, w);
        hit |= both;
        if (both) f.pair_hit[k] = 1;
    }
    for (std::uint64_t bits = hit; bits; bits &= bits - 1) {
        std::int64_t q[3];
        slab.point(w * 64 + static_cast<std::size_t>(__builtin_ctzll(bits)), q);
        ++f.voxels;
        f.box = join(f.box, {q[0], q[1], q[2], q[0], q[1], q[2]});
        if (keep) f.points.push_back({q[0], q[1], q[2]});
    }
}

/// Bitmap bits per slab (all slots together): 32 MB.
constexpr std::int64_t kSlabBits = std::int64_t{1} << 28;

/// Rasterizes the candidates slab by slab and combines the bitmaps into the answer's voxels, box and bone pairs.
Found contact(const Posed& a, const Posed& b, const Candidates& cs, const PairRule& rule, std::int64_t& tests) {
    const auto sp = slot_pairs(cs, a, rule);
    Found total;
    total.pair_hit.assign(sp.size(), 0);
    if (sp.empty()) return total;
    const Box6& box = cs.box;
    const std::int64_t plane = (box[3] - box[0] + 1) * (box[4] - box[1] + 1);
    const std::int64_t depth = std::max<std::int64_t>(1, kSlabBits / (plane * static_cast<std::int64_t>(cs.slot_bone.size())));
    const bool same = same_lattice(a.c->grid, b.c->grid);
    std::atomic<std::int64_t> tested{0};
    for (std::int64_t z0 = box[2]; z0 <= box[5]; z0 += depth) {
        Slab slab(box, z0, std::min(depth, box[5] - z0 + 1), cs.slot_bone.size());
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, cs.balls.size(), 16), [&](const tbb::blocked_range<std::size_t>& r) {
            std::int64_t t = 0;
            for (std::size_t k = r.begin(); k != r.end(); ++k) t += rasterize(a, b, same, cs.balls[k], slab);
            tested += t;
        });
        tbb::enumerable_thread_specific<Found> found([&] {
            Found f;
            f.pair_hit.assign(sp.size(), 0);
            return f;
        });
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, slab.words(), 1024), [&](const tbb::blocked_range<std::size_t>& r) {
            Found& f = found.local();
            for (std::size_t w = r.begin(); w != r.end(); ++w) combine(slab, sp, w, rule.keep_points, f);
        });
        for (const Found& f : found) {
            total.voxels += f.voxels;
            total.box = join(total.box, f.box);
            for (std::size_t k = 0; k < sp.size(); ++k) total.pair_hit[k] |= f.pair_hit[k];
            total.points.insert(total.points.end(), f.points.begin(), f.points.end());
        }
    }
    tests = tested;
    return total;
}

Collision answer(const Posed& a, const Candidates& cs, const PairRule& rule, Found&& f) {
    Collision out;
    out.voxels = f.voxels;
    out.points = std::move(f.points);
    std::sort(out.points.begin(), out.points.end(), [](const auto& x, const auto& y) {
        return std::tie(x[2], x[1], x[0]) < std::tie(y[2], y[1], y[0]);
    });
    out.hit = f.voxels > 0;
    if (!out.hit) return out;
    const auto sp = slot_pairs(cs, a, rule);
    for (std::size_t k = 0; k < sp.size(); ++k) {
        if (!f.pair_hit[k]) continue;
        std::int32_t x = cs.slot_bone[sp[k].first], y = cs.slot_bone[sp[k].second];
        if (rule.self && x > y) std::swap(x, y);
        out.bone_pairs.emplace_back(x, y);
        out.bones_a.push_back(x);
        (rule.self ? out.bones_a : out.bones_b).push_back(y);
    }
    std::sort(out.bone_pairs.begin(), out.bone_pairs.end());
    out.bone_pairs.erase(std::unique(out.bone_pairs.begin(), out.bone_pairs.end()), out.bone_pairs.end());
    if (rule.self) out.bones_b = out.bones_a;
    for (auto* v : {&out.bones_a, &out.bones_b}) {
        std::sort(v->begin(), v->end());
        v->erase(std::unique(v->begin(), v->end()), v->end());
    }
    for (int k = 0; k < 3; ++k) {
        out.box[k] = a.c->grid.origin[k] + a.c->grid.spacing[k] * static_cast<double>(f.box[k]);
        out.box[3 + k] = a.c->grid.origin[k] + a.c->grid.spacing[k] * static_cast<double>(f.box[3 + k]);
    }
    return out;
}

Collision run(const Posed& a, const Posed& b, const PairRule& rule) {
    const std::vector<Root> ra = roots(a);
    const std::vector<Root> rb = rule.self ? ra : roots(b);
    auto fields = field_pairs(ra, rb, rule.self);
    if (rule.self) {  // fields whose owners may not touch each other
        const Collider::Impl& c = *a.c;
        fields.erase(std::remove_if(fields.begin(), fields.end(), [&](const auto& p) {
                         const std::int32_t x = a.part->fields[p.first].owner, y = a.part->fields[p.second].owner;
                         if (x < 0 || y < 0) return false;
                         const std::size_t xy = static_cast<std::size_t>(x) * c.bone_count + static_cast<std::size_t>(y);
                         return (rule.min_bone_distance > 0 && c.distance[xy] < rule.min_bone_distance) ||
                                (rule.ignore_rest_contact && c.joined[xy]);
                     }), fields.end());
    }
    CollideStats stats;
    stats.field_pairs = static_cast<std::int64_t>(fields.size());
    SpherePairs pairs;
    if (fields.size() < 8) {
        for (const auto& [fa, fb] : fields) stats.node_pairs += descend(a, fa, b, fb, rule, pairs);
    } else {  // the field pairs in parallel
        tbb::enumerable_thread_specific<std::pair<SpherePairs, std::int64_t>> local;
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, fields.size(), 1), [&](const tbb::blocked_range<std::size_t>& r) {
            auto& [found, tests] = local.local();
            for (std::size_t k = r.begin(); k != r.end(); ++k) tests += descend(a, fields[k].first, b, fields[k].second, rule, found);
        });
        for (auto& [found, tests] : local) {
            pairs.insert(pairs.end(), found.begin(), found.end());
            stats.node_pairs += tests;
        }
        std::sort(pairs.begin(), pairs.end());  // the same order (and candidate slots) whatever the threads did
    }
    stats.sphere_pairs = static_cast<std::int64_t>(pairs.size());
    Collision out;
    if (!pairs.empty()) {
        const Candidates cs = candidates(a, b, pairs, rule.self);
        if (!empty_box(cs.box)) out = answer(a, cs, rule, contact(a, b, cs, rule, stats.lattice_tests));
    }
    out.stats = stats;
    return out;
}

}  // namespace

Collision collide(const Collider& a, BoneMatrices ma, const CollideOptions& oa, const Collider& b, BoneMatrices mb,
                  const CollideOptions& ob, bool keep_points) {
    const Posed pa = pose(a.impl(), ma, oa);
    const Posed pb = pose(b.impl(), mb, ob);
    PairRule rule;
    rule.keep_points = keep_points;
    return run(pa, pb, rule);
}

Collision self_collide(const Collider& a, BoneMatrices m, const CollideOptions& o, int min_bone_distance,
                       bool ignore_rest_contact, bool keep_points) {
    check_self_options(a, min_bone_distance);
    const Posed p = pose(a.impl(), m, o);
    return run(p, p, PairRule{true, min_bone_distance, ignore_rest_contact, keep_points});
}

}  // namespace volrig

// collide/reference.cpp: brute force for tests: every lattice point of A's posed box against every moved ball.
#include <algorithm>
#include <climits>

#include "collide/posed.hpp"

namespace volrig {

using namespace collide_detail;

namespace {

using Box6 = std::array<std::int64_t, 6>;

/// The lattice box of all of A's moved balls.
Box6 posed_box(const Posed& a) {
    Box6 box{INT64_MAX, INT64_MAX, INT64_MAX, INT64_MIN, INT64_MIN, INT64_MIN};
    for (std::uint32_t i = 0; i < a.radius.size(); ++i) {
        if (!(a.radius[i] > 0)) continue;
        const Box6 b = ball_box(a.c->grid, a.posed(static_cast<std::size_t>(a.part->field_of[i]), a.c->rest_world[i]), a.radius[i]);
        for (int k = 0; k < 3; ++k) {
            box[k] = std::min(box[k], b[k]);
            box[3 + k] = std::max(box[3 + k], b[3 + k]);
        }
    }
    return box;
}

/// Every lattice point q of A's posed box with the balls of A and of B that cover it, handed to `use(q, in_a,
/// in_b)`.
template <class Use>
void scan(const Posed& a, const Posed& b, Use&& use) {
    const Box6 box = posed_box(a);
    const bool same = same_lattice(a.c->grid, b.c->grid);
    std::vector<std::uint32_t> in_a, in_b;
    std::int64_t q[3];
    for (q[2] = box[2]; q[2] <= box[5]; ++q[2])
        for (q[1] = box[1]; q[1] <= box[4]; ++q[1])
            for (q[0] = box[0]; q[0] <= box[3]; ++q[0]) {
                in_a.clear();
                in_b.clear();
                for (std::uint32_t i = 0; i < a.radius.size(); ++i)
                    if (a.covers(i, q)) in_a.push_back(i);
                if (in_a.empty()) continue;
                for (std::uint32_t j = 0; j < b.radius.size(); ++j)
                    if (covers_from(a, b, j, q, same)) in_b.push_back(j);
                use(q, in_a, in_b);
            }
}

/// Adds contact voxel q with its bone pairs.
void add(Collision& out, const Grid& g, const std::int64_t* q, const std::vector<std::pair<std::int32_t, std::int32_t>>& pairs) {
    if (pairs.empty()) return;
    for (int k = 0; k < 3; ++k) {
        const double w = g.origin[k] + g.spacing[k] * static_cast<double>(q[k]);
        out.box[k] = out.voxels ? std::min(out.box[k], w) : w;
        out.box[3 + k] = out.voxels ? std::max(out.box[3 + k], w) : w;
    }
    ++out.voxels;
    out.hit = true;
    out.points.push_back({q[0], q[1], q[2]});
    out.bone_pairs.insert(out.bone_pairs.end(), pairs.begin(), pairs.end());
}

void finish(Collision& out, bool self) {
    std::sort(out.bone_pairs.begin(), out.bone_pairs.end());
    out.bone_pairs.erase(std::unique(out.bone_pairs.begin(), out.bone_pairs.end()), out.bone_pairs.end());
    for (const auto& [x, y] : out.bone_pairs) {
        out.bones_a.push_back(x);
        (self ? out.bones_a : out.bones_b).push_back(y);
    }
    std::sort(out.bones_a.begin(), out.bones_a.end());
    out.bones_a.erase(std::unique(out.bones_a.begin(), out.bones_a.end()), out.bones_a.end());
    if (self) out.bones_b = out.bones_a;
    std::sort(out.bones_b.begin(), out.bones_b.end());
    out.bones_b.erase(std::unique(out.bones_b.begin(), out.bones_b.end()), out.bones_b.end());
}

}  // namespace

Collision collide_reference(const Collider& a, BoneMatrices ma, const CollideOptions& oa, const Collider& b,
                            BoneMatrices mb, const CollideOptions& ob) {
    const Posed pa = pose(a.impl(), ma, oa), pb = pose(b.impl(), mb, ob);
    Collision out;
    std::vector<std::pair<std::int32_t, std::int32_t>> pairs;
    scan(pa, pb, [&](const std::int64_t* q, const std::vector<std::uint32_t>& in_a, const std::vector<std::uint32_t>& in_b) {
        pairs.clear();
        for (std::uint32_t i : in_a)
            for (std::uint32_t j : in_b) pairs.emplace_back(pa.owner(i), pb.owner(j));
        add(out, pa.c->grid, q, pairs);
    });
    finish(out, false);
    return out;
}

Collision self_collide_reference(const Collider& a, BoneMatrices m, const CollideOptions& o, int min_bone_distance,
                                 bool ignore_rest_contact) {
    check_self_options(a, min_bone_distance);
    const Posed p = pose(a.impl(), m, o);
    Collision out;
    std::vector<std::pair<std::int32_t, std::int32_t>> pairs;
    scan(p, p, [&](const std::int64_t* q, const std::vector<std::uint32_t>& in, const std::vector<std::uint32_t>&) {
        pairs.clear();
        for (std::size_t u = 0; u < in.size(); ++u)
            for (std::size_t v = u + 1; v < in.size(); ++v)
                if (eligible(p, in[u], in[v], min_bone_distance, ignore_rest_contact))
                    pairs.emplace_back(std::min(p.owner(in[u]), p.owner(in[v])), std::max(p.owner(in[u]), p.owner(in[v])));
        add(out, p.c->grid, q, pairs);
    });
    finish(out, true);
    return out;
}

}  // namespace volrig

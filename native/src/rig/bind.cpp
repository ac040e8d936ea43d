// bind: skeleton points to bones by geodesic distance inside the object (see volrig/rig.hpp).
#include <Eigen/Core>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include "volrig/components.hpp"
#include "volrig/rig.hpp"

namespace volrig {

namespace {

using Vec = Eigen::Vector3d;

struct Segment {
    Vec head, dir;  // dir: unit vector head -> tail
    double length;
    /// Closest point of the segment to p.
    Vec closest(const Vec& p) const { return head + std::clamp((p - head).dot(dir), 0.0, length) * dir; }
};

/// Voxel [z, y, x] of a world position, or false when it lies outside the grid.
bool voxel_of(const Grid& g, const Vec& p, std::int32_t* zyx) {
    for (int a = 0; a < 3; ++a) {
        const double v = std::round((p[a] - g.origin[a]) / g.spacing[a]);
        if (!(v >= 0 && v < static_cast<double>(g.dims[a]))) return false;
        zyx[2 - a] = static_cast<std::int32_t>(v);
    }
    return true;
}

double smoothstep(double t) {
    t = std::clamp(t, 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

/// Rigid tissue: every point on a rigid voxel moves with one bone alone (weight 1). A rigid component whose points
/// the geodesic binding gives at least kRigidShare of their ball volume to one bone goes wholly to that bone (a
/// bone the joint plane crosses near its end), unless it spans a joint: its points of other bones that lie beyond
/// the joint region (see beyond_joint) hold at least kSpanShare of its ball volume (bones touching across joints in
/// a fine label map: at 1 and 2 mm the Visible Human's humerus, forearm and hand bones are one component, 93% of it
/// by ball volume the humerus's, which once carried the forearm's and the hand's bones with the upper arm). A
/// component spanning joints keeps each point's own bone.
constexpr double kRigidShare = 0.9;
constexpr double kSpanShare = 0.01;
/// A point of bone c lies in the joint region of bone b when c meets b at a joint and the point lies past that
/// joint's plane into c by at most max(kJointBalls ball radii, kJointLength of c's length).
constexpr double kJointBalls = 2.0;
constexpr double kJointLength = 0.25;

/// True when a point at p (ball radius r) bound to bone c lies outside the joint region of bone b (see above).
bool beyond_joint(const Rig& rig, const std::vector<Segment>& seg, std::int32_t b, std::int32_t c, const Vec& p,
                  double r) {
    const auto& jb = rig.bones[static_cast<std::size_t>(b)];
    const auto& jc = rig.bones[static_cast<std::size_t>(c)];
    const Segment& s = seg[static_cast<std::size_t>(c)];
    for (int end = 0; end < 2; ++end) {
        const std::int32_t joint = jc[static_cast<std::size_t>(end)];
        if (joint != jb[0] && joint != jb[1]) continue;
        const double along = (p - s.head).dot(s.dir);
        const double into = end == 0 ? along : s.length - along;  // past the joint's plane into c
        if (into <= std::max(kJointBalls * r, kJointLength * s.length)) return false;
    }
    return true;
}

/// Per rigid component (index 1..): the bone it goes wholly to, or -1 when its points keep their own bones.
std::vector<std::int32_t> whole_bones(const std::vector<std::int32_t>& of, const PointSet& pts, const Rig& rig,
                                      const std::vector<Segment>& seg, const std::vector<Vec>& pos,
                                      const Binding& out) {
    const std::size_t bones = rig.bones.size();
    const std::int32_t count = of.empty() ? 0 : *std::max_element(of.begin(), of.end());
    std::vector<std::vector<double>> votes(static_cast<std::size_t>(count) + 1, std::vector<double>());
    for (std::size_t i = 0; i < pts.n; ++i) {
        if (of[i] == 0) continue;
        auto& v = votes[static_cast<std::size_t>(of[i])];
        if (v.empty()) v.assign(bones, 0.0);
        v[static_cast<std::size_t>(out.bone[i])] += std::pow(static_cast<double>(pts.radius[i]), 3);
    }
    std::vector<std::int32_t> whole(votes.size(), -1);
    std::vector<double> sums(votes.size(), 0.0);
    for (std::size_t c = 1; c < votes.size(); ++c) {
        const auto& v = votes[c];
        if (v.empty()) continue;
        const auto best = std::max_element(v.begin(), v.end());
        for (double x : v) sums[c] += x;
        if (*best >= kRigidShare * sums[c]) whole[c] = static_cast<std::int32_t>(best - v.begin());
    }
    std::vector<double> beyond(votes.size(), 0.0);  // ball volume of other bones' points past the joint regions
    for (std::size_t i = 0; i < pts.n; ++i) {
        const auto c = static_cast<std::size_t>(of[i]);
        if (c == 0 || whole[c] < 0 || out.bone[i] == whole[c]) continue;
        const double r = static_cast<double>(pts.radius[i]);
        if (beyond_joint(rig, seg, whole[c], out.bone[i], pos[i], r)) beyond[c] += r * r * r;
    }
    for (std::size_t c = 1; c < votes.size(); ++c)
        if (whole[c] >= 0 && beyond[c] >= kSpanShare * sums[c]) whole[c] = -1;
    return whole;
}

void keep_rigid(const Grid& g, const std::uint8_t* rigid, const PointSet& pts, const Rig& rig,
                const std::vector<Segment>& seg, const std::vector<Vec>& pos, Binding& out) {
    const std::vector<std::int32_t> of = point_components(g, rigid, pts.ijk, pts.n);
    const std::vector<std::int32_t> whole = whole_bones(of, pts, rig, seg, pos, out);
    for (std::size_t i = 0; i < pts.n; ++i) {
        if (of[i] == 0) continue;
        const std::int32_t w = whole[static_cast<std::size_t>(of[i])];
        const std::int32_t b = w >= 0 ? w : out.bone[i];
        out.bone[i] = b;
        out.weight_bones[i] = {b, -1, -1};
        out.weights[i] = {1.f, 0.f, 0.f};
    }
}

/// Each bone as a segment: head, unit direction, length.
std::vector<Segment> bone_segments(const Rig& rig) {
    const std::size_t nb = rig.bones.size();
    std::vector<Segment> seg(nb);
    for (std::size_t b = 0; b < nb; ++b) {
        const auto& h = rig.joints[static_cast<std::size_t>(rig.bones[b][0])];
        const auto& t = rig.joints[static_cast<std::size_t>(rig.bones[b][1])];
        const Vec hv(h[0], h[1], h[2]), tv(t[0], t[1], t[2]);
        seg[b].head = hv;
        seg[b].length = (tv - hv).norm();
        seg[b].dir = (tv - hv) / seg[b].length;
    }
    return seg;
}

/// Each point's world position.
std::vector<Vec> point_positions(const Grid& g, const PointSet& pts) {
    const std::size_t n = pts.n;
    std::vector<Vec> pos(n);
    for (std::size_t i = 0; i < n; ++i) {
        const auto p = point_position(g, pts, i);
        pos[i] = Vec(p[0], p[1], p[2]);
    }
    return pos;
}

/// Step 1: each point takes the nearest bone it sees along a contained straight line
/// (dist: how far; a point that sees none keeps bone -1 and distance infinity).
void bind_direct(const Grid& g, const std::uint8_t* mask, const PointSet& pts, const std::vector<Segment>& seg,
                 const std::vector<Vec>& pos, std::vector<double>& dist, Binding& out) {
    const std::size_t n = pts.n, nb = seg.size();
    constexpr std::size_t kTries = 8;
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
        std::vector<std::pair<double, std::int32_t>> near(nb);
        for (std::size_t b = 0; b < nb; ++b)
            near[b] = {(seg[b].closest(pos[i]) - pos[i]).norm(), static_cast<std::int32_t>(b)};
        const std::size_t tries = std::min(kTries, nb);
        std::partial_sort(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(tries), near.end());
        for (std::size_t k = 0; k < tries; ++k) {
            std::int32_t q[3];
            const Segment& s = seg[static_cast<std::size_t>(near[k].second)];
            if (voxel_of(g, s.closest(pos[i]), q) && line_inside(g, mask, pts.ijk + 3 * i, q)) {
                dist[i] = near[k].first;
                out.bone[i] = near[k].second;
                return;
            }
        }
    });
}

/// Steps 2 and 3: the points step 1 left unbound, through the contained neighbour graph, else flagged.
void bind_unbound(const Grid& g, const std::uint8_t* mask, const PointSet& pts, const std::vector<Segment>& seg,
                  const std::vector<Vec>& pos, std::vector<double>& dist, Binding& out, const Progress& progress) {
    const std::size_t n = pts.n, nb = seg.size();
    const double inf = std::numeric_limits<double>::infinity();
    // 2. Geodesic: points with no contained line take the bone of the nearest bound point along the contained
    //    neighbour graph (multi-source Dijkstra).
    const bool any_unbound = std::find(out.bone.begin(), out.bone.end(), -1) != out.bone.end();
    if (any_unbound) {
        const SkeletonGraph graph = skeleton_graph(g, mask, pts, 0.0);
        report(progress, 0.7);
        shortest_paths(graph, dist, &out.bone);
        // 3. Parts of the object no bone reaches: the nearest bone in a straight line, flagged.
        for (std::size_t i = 0; i < n; ++i) {
            if (out.bone[i] >= 0) continue;
            double best = inf;
            for (std::size_t b = 0; b < nb; ++b) {
                const double d = (seg[b].closest(pos[i]) - pos[i]).norm();
                if (d < best) {
                    best = d;
                    out.bone[i] = static_cast<std::int32_t>(b);
                }
            }
            out.unreachable[i] = 1;
        }
    }
}

/// The weights of each point's owner and, when smooth, of the bones across the owner's end joints.
void bind_weights(const PointSet& pts, const Rig& rig, BindMode mode, const std::vector<Segment>& seg,
                  const std::vector<Vec>& pos, Binding& out) {
    const std::size_t n = pts.n, nb = seg.size();
    // Weights: rigid = the owner alone; smooth = a falloff across each end joint of the owner, within one radius
    // of the joint plane, towards the nearest other bone at that joint (up to half the weight at the plane).
    out.weight_bones.assign(n, {-1, -1, -1});
    out.weights.assign(n, {0.f, 0.f, 0.f});
    std::vector<std::vector<std::int32_t>> at_joint(rig.joints.size());
    for (std::size_t b = 0; b < nb; ++b)
        for (std::int32_t j : rig.bones[b]) at_joint[static_cast<std::size_t>(j)].push_back(static_cast<std::int32_t>(b));
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
        const std::int32_t b = out.bone[i];
        out.weight_bones[i][0] = b;
        out.weights[i][0] = 1.f;
        if (mode != BindMode::Smooth) return;
        const Segment& s = seg[static_cast<std::size_t>(b)];
        const double width = std::max(static_cast<double>(pts.radius[i]), 1e-9);
        std::pair<float, std::int32_t> other[2] = {{0.f, -1}, {0.f, -1}};
        for (int end = 0; end < 2; ++end) {
            const std::int32_t joint = rig.bones[static_cast<std::size_t>(b)][static_cast<std::size_t>(end)];
            std::int32_t best = -1;
            double best_d = std::numeric_limits<double>::infinity();
            for (std::int32_t c : at_joint[static_cast<std::size_t>(joint)]) {
                if (c == b) continue;
                const double d = (seg[static_cast<std::size_t>(c)].closest(pos[i]) - pos[i]).norm();
                if (d < best_d) {
                    best_d = d;
                    best = c;
                }
            }
            if (best < 0) continue;
            const double into = end == 0 ? (pos[i] - s.head).dot(s.dir) : s.length - (pos[i] - s.head).dot(s.dir);
            const float w = static_cast<float>(0.5 * (1.0 - smoothstep(into / width)));
            if (w > 1e-4f) other[end] = {w, best};
        }
        if (other[0].second == other[1].second && other[0].second >= 0) {  // one bone at both ends: merge
            other[0].first += other[1].first;
            other[1] = {0.f, -1};
        }
        float own = 1.f - other[0].first - other[1].first;
        std::array<std::pair<float, std::int32_t>, 3> all = {{{own, b}, other[0], other[1]}};
        std::stable_sort(all.begin(), all.end(), [](const auto& x, const auto& y) { return x.first > y.first; });
        for (int k = 0; k < 3; ++k) {
            out.weights[i][static_cast<std::size_t>(k)] = all[static_cast<std::size_t>(k)].second >= 0 ? all[static_cast<std::size_t>(k)].first : 0.f;
            out.weight_bones[i][static_cast<std::size_t>(k)] = all[static_cast<std::size_t>(k)].second;
        }
        out.bone[i] = all[0].second;
    });
}

}  // namespace

Binding bind(const Grid& g, const std::uint8_t* mask, const PointSet& pts, const Rig& rig, BindMode mode,
             const Progress& progress, const std::uint8_t* rigid) {
    if (!pts.radius) throw Error("bind: radii are required");
    check_points(g, mask, pts, "bind");
    check_rig(rig);
    const std::size_t n = pts.n;
    const std::vector<Segment> seg = bone_segments(rig);
    const std::vector<Vec> pos = point_positions(g, pts);

    // 1. Direct: the nearest bone whose closest point is reached along a contained straight line.
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<double> dist(n, inf);
    Binding out;
    out.bone.assign(n, -1);
    out.unreachable.assign(n, 0);
    bind_direct(g, mask, pts, seg, pos, dist, out);
    report(progress, 0.4);

    bind_unbound(g, mask, pts, seg, pos, dist, out, progress);
    report(progress, 0.9);

    bind_weights(pts, rig, mode, seg, pos, out);
    if (rigid) keep_rigid(g, rigid, pts, rig, seg, pos, out);
    report(progress, 1.0);
    return out;
}

}  // namespace volrig

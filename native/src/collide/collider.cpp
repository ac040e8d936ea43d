// collide/collider.cpp: the per-rig data (fields and their ball trees) and the per-test pose.
#include <algorithm>
#include <climits>
#include <cmath>
#include <deque>
#include <string>

#include "collide/posed.hpp"
#include "deform/bend.hpp"
#include "volrig/reconstruct.hpp"

namespace volrig {

using namespace collide_detail;
using deform_detail::Motion;

std::vector<std::int32_t> bone_distances(const std::vector<std::int32_t>& parents) {
    const std::size_t n = parents.size();
    std::vector<std::vector<std::int32_t>> next(n);
    for (std::size_t b = 0; b < n; ++b) {
        const std::int32_t p = parents[b];
        if (p < -1 || p >= static_cast<std::int32_t>(n) || p == static_cast<std::int32_t>(b))
            throw Error("collide: bone " + std::to_string(b) + " has parent " + std::to_string(p) + " outside the rig");
        if (p >= 0) {
            next[b].push_back(p);
            next[static_cast<std::size_t>(p)].push_back(static_cast<std::int32_t>(b));
        }
    }
    std::vector<std::int32_t> d(n * n, INT32_MAX);
    for (std::size_t s = 0; s < n; ++s) {  // breadth-first from every bone (rigs have tens of bones)
        std::int32_t* row = d.data() + s * n;
        std::deque<std::size_t> todo{s};
        row[s] = 0;
        while (!todo.empty()) {
            const std::size_t b = todo.front();
            todo.pop_front();
            for (std::int32_t c : next[b])
                if (row[c] == INT32_MAX) {
                    row[c] = row[b] + 1;
                    todo.push_back(static_cast<std::size_t>(c));
                }
        }
    }
    std::size_t reached = 0;  // a tree reaches each bone once from its root: a cycle leaves bones unreached
    for (std::size_t b = 0; b < n; ++b)
        if (parents[b] < 0)
            for (std::size_t c = 0; c < n; ++c) reached += d[b * n + c] != INT32_MAX;
    if (reached != n)
        throw Error("collide: the bones' parents do not form a tree (a bone is its own ancestor)");
    return d;
}

namespace {

Partition rigid_partition(const Collider::Impl& c) {
    Partition p;
    p.field_of.assign(c.bone.begin(), c.bone.end());
    std::vector<std::vector<std::uint32_t>> members(c.bone_count);
    for (std::size_t i = 0; i < c.bone.size(); ++i) members[static_cast<std::size_t>(c.bone[i])].push_back(static_cast<std::uint32_t>(i));
    std::vector<double> r(c.radius.begin(), c.radius.end());
    for (std::size_t b = 0; b < c.bone_count; ++b) {
        Field f;
        f.bone = f.owner = static_cast<std::int32_t>(b);
        f.tree = build_ball_tree(c.rest_world, r, std::move(members[b]));
        p.fields.push_back(std::move(f));
    }
    return p;
}

/// Smooth modes: one field per bone (spheres one bone moves alone) and one per blend group, as deformation moves
/// them (deform_detail::smooth_groups).
Partition smooth_partition(const Collider::Impl& c) {
    Partition p;
    p.groups = deform_detail::smooth_groups(c.view(), c.grid);
    const std::size_t bones = c.bone_count;
    p.field_of.resize(c.bone.size());
    std::vector<std::vector<std::uint32_t>> members(bones + p.groups.weights.size());
    for (std::size_t i = 0; i < c.bone.size(); ++i) {
        const std::int32_t g = p.groups.group_of[i];
        const std::size_t f = g < 0 ? static_cast<std::size_t>(p.groups.bone_of[i]) : bones + static_cast<std::size_t>(g);
        p.field_of[i] = static_cast<std::int32_t>(f);
        members[f].push_back(static_cast<std::uint32_t>(i));
    }
    std::vector<double> r(c.radius.begin(), c.radius.end());
    for (std::size_t f = 0; f < members.size(); ++f) {
        Field fd;
        if (f < bones) {  // the owner of spheres one bone moves alone is that bone, unless rounding says otherwise
            fd.bone = fd.owner = static_cast<std::int32_t>(f);
            for (std::uint32_t i : members[f])
                if (c.bone[i] != fd.bone) fd.owner = -1;
        } else {
            fd.group = static_cast<std::int32_t>(f - bones);
            fd.owner = p.groups.owner[f - bones];
        }
        fd.tree = build_ball_tree(c.rest_world, r, std::move(members[f]));
        p.fields.push_back(std::move(fd));
    }
    return p;
}

/// Whether any ball of tree x intersects any ball of tree y, both at rest.
bool trees_touch(const BallTree& x, const BallTree& y, const std::vector<Vec3>& centre, const std::vector<float>& radius) {
    if (x.empty() || y.empty()) return false;
    auto d2 = [](const Vec3& a, const Vec3& b) {
        return (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]);
    };
    std::vector<std::pair<std::int32_t, std::int32_t>> stack{{0, 0}};
    while (!stack.empty()) {
        const auto [ix, iy] = stack.back();
        stack.pop_back();
        const BallNode &nx = x.nodes[static_cast<std::size_t>(ix)], &ny = y.nodes[static_cast<std::size_t>(iy)];
        if (!(d2(nx.centre, ny.centre) < (nx.bound + ny.bound) * (nx.bound + ny.bound))) continue;
        if (nx.leaf() && ny.leaf()) {
            for (std::uint32_t u = nx.begin; u < nx.end; ++u)
                for (std::uint32_t v = ny.begin; v < ny.end; ++v) {
                    const std::uint32_t i = x.order[u], j = y.order[v];
                    const double r = static_cast<double>(radius[i]) + static_cast<double>(radius[j]);
                    if (d2(centre[i], centre[j]) < r * r) return true;
                }
        } else
            open_larger(stack, nx, ix, nx.bound, ny, iy, ny.bound);
    }
    return false;
}

/// Bone pairs whose balls intersect at rest (row-major bone_count x bone_count; a bone is joined to itself).
std::vector<std::uint8_t> joined_at_rest(const Collider::Impl& c) {
    const std::size_t n = c.bone_count;
    std::vector<std::uint8_t> joined(n * n, 0);
    for (std::size_t x = 0; x < n; ++x) {
        joined[x * n + x] = 1;
        for (std::size_t y = x + 1; y < n; ++y)
            joined[x * n + y] = joined[y * n + x] =
                trees_touch(c.rigid.fields[x].tree, c.rigid.fields[y].tree, c.rest_world, c.radius);
    }
    return joined;
}

}  // namespace

Collider::Collider(const Grid& grid, const BoundSpheres& s, std::vector<std::int32_t> parents)
    : impl_(std::make_unique<Impl>()) {
    Impl& c = *impl_;
    check_grid(grid, 1, UINT64_MAX, "collide");
    deform_detail::check_spheres(grid, s);
    if (!parents.empty() && parents.size() != s.bone_count)
        throw Error("collide: " + std::to_string(parents.size()) + " parents for a rig of " +
                    std::to_string(s.bone_count) + " bones");
    c.grid = grid;
    c.assign(s);
    c.distance = bone_distances(parents);
    c.parents = std::move(parents);
    for (std::size_t i = 0; i < s.n; ++i) {
        Vec3 idx, w;
        for (int a = 0; a < 3; ++a) {
            idx[a] = static_cast<double>(s.ijk[3 * i + 2 - a]);
            w[a] = grid.origin[a] + grid.spacing[a] * idx[a];
        }
        c.rest_index.push_back(idx);
        c.rest_world.push_back(w);
    }
    c.rigid = rigid_partition(c);
    if (c.has_weights) c.smooth = smooth_partition(c);
    c.joined = joined_at_rest(c);
}

Collider::~Collider() = default;
Collider::Collider(Collider&&) noexcept = default;
Collider& Collider::operator=(Collider&&) noexcept = default;

std::size_t Collider::bone_count() const { return impl_->bone_count; }
std::size_t Collider::sphere_count() const { return impl_->radius.size(); }
std::size_t Collider::field_count(DeformMode mode) const { return impl_->partition(mode).fields.size(); }

std::size_t Collider::memory_bytes() const {
    const Impl& c = *impl_;
    std::size_t bytes = sizeof(Impl) + c.SphereStore::memory_bytes() + c.distance.capacity() * 4 + c.joined.capacity() +
                        (c.rest_world.capacity() + c.rest_index.capacity()) * sizeof(Vec3);
    for (const Partition* p : {&c.rigid, &c.smooth}) {
        bytes += p->field_of.capacity() * 4;
        for (const Field& f : p->fields) bytes += sizeof(Field) + f.tree.memory_bytes();
    }
    return bytes;
}

namespace collide_detail {

Posed pose(const Collider::Impl& c, BoneMatrices matrices, const CollideOptions& o) {
    deform_detail::check_options(DeformOptions{o.mode, Proximity::Power, Sampling::Nearest, o.radius_scale, false},
                                 c.radius.size());
    Posed p;
    p.c = &c;
    p.part = &c.partition(o.mode);
    const std::vector<Motion> bones = deform_detail::bone_motions(matrices, c.bone_count, c.grid);
    for (const Field& f : p.part->fields) {
        if (f.group < 0) p.motion.push_back(bones[static_cast<std::size_t>(f.bone)]);
        else {
            const auto g = static_cast<std::size_t>(f.group);
            p.motion.push_back(deform_detail::blended_motion(bones, p.part->groups.weights[g], f.owner, o.mode,
                                                             c.grid, p.part->groups.pivot[g]));
        }
    }
    p.radius.resize(c.radius.size());
    for (std::size_t i = 0; i < c.radius.size(); ++i) {
        const double k = o.radius_scale.empty() ? 1.0 : o.radius_scale[i];
        p.radius[i] = static_cast<double>(c.radius[i]) * k;
    }
    if (o.mode != DeformMode::Rigid && c.has_weights && o.keep_volume)  // as deformation sizes them
        deform_detail::bend_radii(c.view(), p.part->groups, bones, o.mode, c.grid, p.radius);
    bool scaled = false;
    for (std::size_t i = 0; i < c.radius.size(); ++i) {
        if (p.radius[i] == static_cast<double>(c.radius[i])) continue;
        scaled = true;
        if (c.radius[i] > 0) p.scale = std::max(p.scale, p.radius[i] / static_cast<double>(c.radius[i]) * (1 + 1e-12));
    }
    if (scaled && p.scale == 1.0) p.scale = 1.0 + 1e-12;  // shrunk balls: the scaled bound
    for (int a = 0; a < 3; ++a) p.s2[a] = c.grid.spacing[a] * c.grid.spacing[a];
    return p;
}

Vec3 Posed::posed(std::size_t f, const Vec3& x) const {
    const Motion& m = motion[f];
    const Eigen::Vector3d y = m.R * Eigen::Vector3d(x[0], x[1], x[2]) + m.d;
    return {y[0], y[1], y[2]};
}

bool Posed::covers(std::uint32_t i, const std::int64_t* q) const {
    const double r = radius[i];
    return r > 0 && deform_detail::moved_length2(of(i), c->rest_index[i].data(), q, s2) < open_ball_limit_sq(r);
}

void check_self_options(const Collider& a, int min_bone_distance) {
    if (min_bone_distance < 1)
        throw Error("self_collide: min_bone_distance must be at least 1 (balls of one bone always overlap)");
    if (a.impl().parents.empty())
        throw Error("self_collide: the collider was built without the rig's bone parents");
}

bool same_lattice(const Grid& a, const Grid& b) { return a.spacing == b.spacing && a.origin == b.origin; }

bool covers_from(const Posed& a, const Posed& b, std::uint32_t j, const std::int64_t* q, bool same) {
    if (same) return b.covers(j, q);
    const double r = b.radius[j];
    if (!(r > 0)) return false;
    const Motion& m = b.of(j);
    Eigen::Vector3d w;
    for (int k = 0; k < 3; ++k) w[k] = a.c->grid.origin[k] + a.c->grid.spacing[k] * static_cast<double>(q[k]);
    const Eigen::Vector3d rest = m.R.transpose() * (w - m.d);
    const Vec3& c = b.c->rest_world[j];
    const double d2 = (rest[0] - c[0]) * (rest[0] - c[0]) + (rest[1] - c[1]) * (rest[1] - c[1]) +
                      (rest[2] - c[2]) * (rest[2] - c[2]);
    return d2 < open_ball_limit_sq(r);
}

bool eligible(const Posed& p, std::uint32_t i, std::uint32_t j, int min_bone_distance, bool ignore_rest_contact) {
    if (i == j) return false;
    const Collider::Impl& c = *p.c;
    if (min_bone_distance > 0) {
        const auto a = static_cast<std::size_t>(c.bone[i]), b = static_cast<std::size_t>(c.bone[j]);
        if (c.distance[a * c.bone_count + b] < min_bone_distance) return false;
    }
    return !ignore_rest_contact || !c.joined_bones(c.bone[i], c.bone[j]);
}

std::array<std::int64_t, 6> ball_box(const Grid& g, const Vec3& w, double r) {
    std::array<std::int64_t, 6> b{};
    for (int a = 0; a < 3; ++a) {
        const double c = (w[a] - g.origin[a]) / g.spacing[a], h = r / g.spacing[a] * (1 + 1e-9) + 1e-9;
        b[a] = static_cast<std::int64_t>(std::floor(c - h));
        b[3 + a] = static_cast<std::int64_t>(std::ceil(c + h));
    }
    return b;
}

}  // namespace collide_detail

}  // namespace volrig

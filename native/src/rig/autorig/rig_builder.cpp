// rig/autorig/rig_builder.cpp: chains of nodes to named bones (see rig_builder.hpp).
#include "rig/autorig/rig_builder.hpp"

#include <algorithm>
#include <cmath>

namespace volrig::rig_detail {

Chain4 RigContext::samples(const std::vector<std::uint32_t>& nodes) const {
    Chain4 out;
    out.reserve(nodes.size());
    for (std::uint32_t v : nodes) {
        const Vec& p = tree.at(v);
        out.emplace_back(p.x(), p.y(), p.z(), tree.radius(v));
    }
    return out;
}

double RigContext::reach_inside(const Vec& from, const Vec& dir, double start, double limit) const {
    const double step = 0.5 * grid.min_spacing();
    // Inside when every voxel nearest q is (a point halfway between voxels has two along that axis: the same
    // answer with the object turned or mirrored).
    auto inside = [&](const Vec& q) {
        std::int64_t lo[3], hi[3];
        for (int a = 0; a < 3; ++a) {
            const double t = (q[a] - grid.origin[a]) / grid.spacing[a];
            lo[a] = static_cast<std::int64_t>(std::ceil(t - 0.5 - 1e-9));
            hi[a] = static_cast<std::int64_t>(std::floor(t + 0.5 + 1e-9));
            if (lo[a] < 0 || hi[a] >= grid.dims[a]) return false;
        }
        for (std::int64_t z = lo[2]; z <= hi[2]; ++z)
            for (std::int64_t y = lo[1]; y <= hi[1]; ++y)
                for (std::int64_t x = lo[0]; x <= hi[0]; ++x)
                    if (!mask[grid.index(x, y, z)]) return false;
        return true;
    };
    double reach = start;
    while (reach + step <= limit && inside(from + (reach + step) * dir)) reach += step;
    return reach;
}

namespace {

/// Whether the voxel nearest q is in the object.
bool inside_nearest(const Grid& g, const std::uint8_t* mask, const Vec& q) {
    std::int64_t v[3];
    for (int a = 0; a < 3; ++a) {
        v[a] = std::llround((q[a] - g.origin[a]) / g.spacing[a]);
        if (v[a] < 0 || v[a] >= g.dims[a]) return false;
    }
    return mask[g.index(v[0], v[1], v[2])] != 0;
}

/// The cross-section's lattice: (2n+1)^2 cells `step` apart, n at most kSectionCells (a voxel apart when the
/// reach allows).
constexpr std::int64_t kSectionCells = 25;

}  // namespace

double RigContext::cross_section_ratio(const Vec& at, const Vec& dir, double reach) const {
    const Vec u = dir.unitOrthogonal(), w = dir.cross(u).normalized();
    const double step = std::max(grid.min_spacing(), reach / kSectionCells);
    const std::int64_t n = static_cast<std::int64_t>(std::ceil(reach / step)), side = 2 * n + 1;
    auto cell = [&](std::int64_t i, std::int64_t j) { return at + (static_cast<double>(i) * step) * u + (static_cast<double>(j) * step) * w; };
    if (!inside_nearest(grid, mask, at)) return 1.0;
    // Flood fill over the lattice from `at`, 4-connected, within the disc.
    std::vector<std::uint8_t> seen(static_cast<std::size_t>(side * side), 0);
    std::vector<std::pair<std::int64_t, std::int64_t>> todo{{0, 0}};
    seen[static_cast<std::size_t>(n * side + n)] = 1;
    double s1[2] = {0, 0}, s2[3] = {0, 0, 0}, count = 0;
    while (!todo.empty()) {
        const auto [i, j] = todo.back();
        todo.pop_back();
        const double x = static_cast<double>(i) * step, y = static_cast<double>(j) * step;
        s1[0] += x, s1[1] += y, s2[0] += x * x, s2[1] += x * y, s2[2] += y * y, count += 1;
        for (const auto& [di, dj] : {std::pair<std::int64_t, std::int64_t>{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
            const std::int64_t a = i + di, b = j + dj;
            if (std::abs(a) > n || std::abs(b) > n || static_cast<double>(a * a + b * b) * step * step > reach * reach)
                continue;
            std::uint8_t& s = seen[static_cast<std::size_t>((b + n) * side + (a + n))];
            if (s || !inside_nearest(grid, mask, cell(a, b))) continue;
            s = 1;
            todo.emplace_back(a, b);
        }
    }
    // The 2-D covariance's eigenvalues, each with a cell's own variance (a section one cell thick is no line).
    const double mx = s1[0] / count, my = s1[1] / count, cell_var = step * step / 12.0;
    const double xx = s2[0] / count - mx * mx + cell_var, xy = s2[1] / count - mx * my,
                 yy = s2[2] / count - my * my + cell_var;
    const double mean = 0.5 * (xx + yy), dev = std::sqrt(0.25 * (xx - yy) * (xx - yy) + xy * xy);
    return std::sqrt((mean + dev) / std::max(mean - dev, 1e-12 * mean));
}

std::int32_t bone_index(const Rig& rig, const std::string& name) {
    const auto it = std::find(rig.names.begin(), rig.names.end(), name);
    return it == rig.names.end() ? -1 : static_cast<std::int32_t>(it - rig.names.begin());
}

Vec bone_end(const Rig& rig, std::size_t b, int end) {
    const auto& j = rig.joints[static_cast<std::size_t>(rig.bones[b][static_cast<std::size_t>(end)])];
    return Vec(j[0], j[1], j[2]);
}

void move_joint(Rig& rig, std::int32_t j, const Vec& q) {
    rig.joints[static_cast<std::size_t>(j)] = {q.x(), q.y(), q.z()};
    rig.joint_points[static_cast<std::size_t>(j)] = -1;
}

void lengthen_proximal(const RigContext& c, Rig& rig, std::size_t b, double want) {
    const Vec top = bone_end(rig, b, 0), mid = bone_end(rig, b, 1);
    const double have = (top - mid).norm();
    if (have == 0 || have >= want) return;
    const Vec dir = (top - mid) / have;
    move_joint(rig, rig.bones[b][0], mid + c.reach_inside(mid, dir, have, want) * dir);
}

std::vector<std::string> numbered_names(const std::string& base, std::size_t count) {
    std::vector<std::string> names;
    for (std::size_t p = 0; p < count; ++p) {
        std::string name = base;
        if (p > 0) {
            const std::string num = std::to_string(p);
            name += "." + std::string(num.size() < 3 ? 3 - num.size() : 0, '0') + num;
        }
        names.push_back(std::move(name));
    }
    return names;
}

std::int32_t RigBuilder::joint(std::uint32_t node) {
    auto it = joint_of_node_.find(node);
    if (it != joint_of_node_.end()) return it->second;
    const auto j = static_cast<std::int32_t>(rig_.joints.size());
    const std::uint32_t point = c_.rep[node];
    const Vec& at = c_.tree.at(node);
    rig_.joints.push_back({at.x(), at.y(), at.z()});
    rig_.joint_points.push_back(point);
    joint_of_node_.emplace(node, j);
    return j;
}

std::int32_t RigBuilder::bone_of(std::uint32_t node) const {
    const auto it = bone_of_node_.find(node);
    return it == bone_of_node_.end() ? -1 : it->second;
}

std::int32_t RigBuilder::attach_bone(std::uint32_t node, double reach) const {
    const std::int32_t b = bone_of(node);
    if (b < 0 || (c_.tree.at(node) - bone_end(rig_, static_cast<std::size_t>(b), 1)).norm() > reach) return b;
    std::int32_t next = -1;
    for (std::size_t k = 0; k < rig_.bones.size(); ++k)
        if (rig_.bones[k][0] == rig_.bones[static_cast<std::size_t>(b)][1]) {
            if (next >= 0) return b;  // a branch point: no one next bone
            next = static_cast<std::int32_t>(k);
        }
    return next >= 0 ? next : b;
}

void RigBuilder::chain(const std::vector<std::uint32_t>& nodes, const std::vector<std::size_t>& cuts,
                       const std::vector<std::string>& names, std::int32_t parent) {
    std::int32_t prev = parent;
    const std::int32_t start = joint(nodes[cuts[0]]);
    if (prev < 0) {
        if (auto it = bone_ending_at_.find(start); it != bone_ending_at_.end()) prev = it->second;
        else if (auto it2 = bone_starting_at_.find(start); it2 != bone_starting_at_.end()) prev = it2->second;
    }
    for (std::size_t c = 0; c + 1 < cuts.size(); ++c) {
        const std::int32_t h = joint(nodes[cuts[c]]), t = joint(nodes[cuts[c + 1]]);
        const auto b = static_cast<std::int32_t>(rig_.bones.size());
        rig_.bones.push_back({h, t});
        rig_.names.push_back(names[c]);
        rig_.parents.push_back(prev);
        bone_ending_at_.emplace(t, b);
        bone_starting_at_.emplace(h, b);
        for (std::size_t k = cuts[c]; k <= cuts[c + 1]; ++k) bone_of_node_.emplace(nodes[k], b);
        prev = b;
    }
}

Rig RigBuilder::finish(const std::string& kind) {
    Rig rig = std::move(rig_);
    rig.kind = kind;
    std::vector<int> heads(rig.joints.size(), 0);
    for (const auto& b : rig.bones) ++heads[static_cast<std::size_t>(b[0])];
    for (std::size_t b = 0; b < rig.bones.size(); ++b) {
        const auto t = static_cast<std::size_t>(rig.bones[b][1]);
        if (heads[t] || rig.joint_points[t] < 0) continue;
        const Vec tail = bone_end(rig, b, 1), dir = (tail - bone_end(rig, b, 0)).normalized();
        const Vec end = tail + c_.reach_inside(tail, dir, 0.0, 2.0 * c_.pts.radius[rig.joint_points[t]]) * dir;
        rig.joints[t] = {end.x(), end.y(), end.z()};
        rig.joint_points[t] = -1;
    }
    return rig;
}

}  // namespace volrig::rig_detail

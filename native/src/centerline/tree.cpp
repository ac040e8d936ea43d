// TEASAR centerline trees (volrig/centerline.hpp): grow minimal-cost paths from the farthest uncovered voxel to the
// tree, cover a ball around each, prune spurs, then cut the voxel tree into branches.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "centerline/detail.hpp"
#include "volrig/centerline.hpp"

namespace volrig {

using namespace centerline_detail;

namespace {

/// A tree over voxel ids: parent[id] (-1 for the root and for voxels not on it), on[id] = 1 when on the tree.
struct VoxelTree {
    std::int32_t root = -1;
    std::vector<std::int32_t> parent;
    std::vector<std::uint8_t> on;
    std::vector<std::int32_t> children;  ///< per id: number of children on the tree
};

void cover_ball(const VoxelGraph& g, std::int32_t id, double rho, std::vector<std::uint8_t>& covered) {
    const Grid& gr = g.grid;
    const auto c = coords(gr, g.voxel[static_cast<std::size_t>(id)]);
    std::array<std::int64_t, 3> lo{}, hi{}, r{};
    for (int a = 0; a < 3; ++a) {
        r[a] = static_cast<std::int64_t>(std::floor(rho / gr.spacing[a]));
        lo[a] = std::max<std::int64_t>(0, c[a] - r[a]);
        hi[a] = std::min<std::int64_t>(gr.dims[a] - 1, c[a] + r[a]);
    }
    const double rho2 = rho * rho;
    for (std::int64_t z = lo[2]; z <= hi[2]; ++z) {
        const double dz = (z - c[2]) * gr.spacing[2];
        for (std::int64_t y = lo[1]; y <= hi[1]; ++y) {
            const double dy = (y - c[1]) * gr.spacing[1];
            if (dz * dz + dy * dy > rho2) continue;
            for (std::int64_t x = lo[0]; x <= hi[0]; ++x) {
                const double dx = (x - c[0]) * gr.spacing[0];
                if (dx * dx + dy * dy + dz * dz > rho2) continue;
                const std::int32_t b = g.id[static_cast<std::size_t>(gr.index(x, y, z))];
                if (b >= 0) covered[static_cast<std::size_t>(b)] = 1;
            }
        }
    }
}

/// The TEASAR tree from `root`; reports progress from `lo` to `hi` (the searches, then the covering by the share of
/// voxels visited).
VoxelTree grow(const VoxelGraph& g, std::int32_t root, const TreeCenterlineOptions& opt, const Progress& progress,
               double lo, double hi) {
    const std::size_t n = g.size();
    const double constant = opt.constant > 0.0 ? opt.constant : 2.0 * g.grid.min_spacing();
    std::vector<double> length, cost;
    VoxelTree t;
    t.root = root;
    voxel_distances(g, {root}, -1.0, length);
    report(progress, lo + 0.25 * (hi - lo));
    voxel_distances(g, {root}, opt.line.power, cost, &t.parent);
    report(progress, lo + 0.5 * (hi - lo));
    std::vector<std::int32_t> order;
    for (std::size_t i = 0; i < n; ++i)
        if (std::isfinite(length[i])) order.push_back(static_cast<std::int32_t>(i));
    std::sort(order.begin(), order.end(), [&](std::int32_t x, std::int32_t y) {
        return length[static_cast<std::size_t>(x)] > length[static_cast<std::size_t>(y)] ||
               (length[static_cast<std::size_t>(x)] == length[static_cast<std::size_t>(y)] && x < y);
    });
    std::vector<std::uint8_t> covered(n, 0);
    t.on.assign(n, 0);
    t.on[static_cast<std::size_t>(root)] = 1;
    cover_ball(g, root, opt.scale * g.dt[static_cast<std::size_t>(root)] + constant, covered);
    for (std::size_t k = 0; k < order.size(); ++k) {
        if (progress && (k & 0xffff) == 0)
            report(progress, lo + (0.5 + 0.5 * static_cast<double>(k) / static_cast<double>(order.size())) * (hi - lo));
        const std::int32_t target = order[k];
        if (covered[static_cast<std::size_t>(target)]) continue;
        std::int32_t p = tip_centre(g, length, target);
        if (covered[static_cast<std::size_t>(p)] || t.on[static_cast<std::size_t>(p)]) p = target;
        for (; p >= 0 && !t.on[static_cast<std::size_t>(p)]; p = t.parent[static_cast<std::size_t>(p)]) {
            t.on[static_cast<std::size_t>(p)] = 1;
            cover_ball(g, p, opt.scale * g.dt[static_cast<std::size_t>(p)] + constant, covered);
        }
        covered[static_cast<std::size_t>(target)] = 1;
    }
    t.children.assign(n, 0);
    for (std::size_t i = 0; i < n; ++i)
        if (t.on[i] && t.parent[i] >= 0) ++t.children[static_cast<std::size_t>(t.parent[i])];
    return t;
}

/// World length of the chain from leaf up to (not past) the first node with other children or the root; `top`
/// gets that node.
double chain_up(const VoxelGraph& g, const VoxelTree& t, std::int32_t leaf, std::int32_t& top) {
    double len = 0.0;
    std::int32_t p = leaf;
    while (p != t.root) {
        const std::int32_t q = t.parent[static_cast<std::size_t>(p)];
        const Vec3d a = world(g.grid, g.voxel[static_cast<std::size_t>(p)]);
        const Vec3d b = world(g.grid, g.voxel[static_cast<std::size_t>(q)]);
        len += std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
        p = q;
        if (t.children[static_cast<std::size_t>(p)] != 1) break;
    }
    top = p;
    return len;
}

/// Removes terminal branches shorter than prune * DT at their branch point, shortest first, until none is left.
void prune_spurs(const VoxelGraph& g, VoxelTree& t, double prune) {
    for (bool changed = true; changed;) {
        changed = false;
        std::vector<std::pair<double, std::int32_t>> leaves;
        for (std::size_t i = 0; i < t.on.size(); ++i)
            if (t.on[i] && t.children[i] == 0 && static_cast<std::int32_t>(i) != t.root) {
                std::int32_t top = -1;
                leaves.push_back({chain_up(g, t, static_cast<std::int32_t>(i), top), static_cast<std::int32_t>(i)});
            }
        std::sort(leaves.begin(), leaves.end());
        for (const auto& [len0, leaf] : leaves) {
            std::int32_t top = -1;
            const double len = chain_up(g, t, leaf, top);
            if (t.children[static_cast<std::size_t>(top)] < 2) continue;  // its sibling went: no longer a spur
            if (len >= prune * g.dt[static_cast<std::size_t>(top)]) continue;
            for (std::int32_t p = leaf; p != top; p = t.parent[static_cast<std::size_t>(p)]) t.on[static_cast<std::size_t>(p)] = 0;
            --t.children[static_cast<std::size_t>(top)];
            changed = true;
        }
    }
}

/// The branches of a voxel tree as id paths from the root or a branch point to a leaf or branch point, in
/// depth-first order (parents before children), with their parent branch.
void branches_of(const VoxelTree& t, std::vector<std::vector<std::int32_t>>& paths, std::vector<std::int32_t>& parents) {
    std::vector<std::vector<std::int32_t>> kids(t.on.size());
    for (std::size_t i = 0; i < t.on.size(); ++i)
        if (t.on[i] && t.parent[i] >= 0) kids[static_cast<std::size_t>(t.parent[i])].push_back(static_cast<std::int32_t>(i));
    struct Start {
        std::int32_t from, first, parent;
    };
    std::vector<Start> stack;
    if (kids[static_cast<std::size_t>(t.root)].size() == 1) {
        stack.push_back({t.root, kids[static_cast<std::size_t>(t.root)][0], -1});
    } else {
        for (std::int32_t c : kids[static_cast<std::size_t>(t.root)]) stack.push_back({t.root, c, -1});
    }
    while (!stack.empty()) {
        const Start s = stack.back();
        stack.pop_back();
        std::vector<std::int32_t> path{s.from, s.first};
        std::int32_t p = s.first;
        while (kids[static_cast<std::size_t>(p)].size() == 1) {
            p = kids[static_cast<std::size_t>(p)][0];
            path.push_back(p);
        }
        const auto self = static_cast<std::int32_t>(paths.size());
        paths.push_back(std::move(path));
        parents.push_back(s.parent);
        for (std::int32_t c : kids[static_cast<std::size_t>(p)]) stack.push_back({p, c, self});
    }
}

double path_length(const VoxelGraph& g, const std::vector<std::int32_t>& path) {
    double len = 0.0;
    for (std::size_t i = 1; i < path.size(); ++i) {
        const Vec3d a = world(g.grid, g.voxel[static_cast<std::size_t>(path[i - 1])]);
        const Vec3d b = world(g.grid, g.voxel[static_cast<std::size_t>(path[i])]);
        len += std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
    }
    return len;
}

/// Two branch points closer than the radius at the first are one (a trifurcation the voxel paths split in two):
/// an inner branch that short is prepended to its children, which then hang from its parent.
void merge_close_branch_points(const VoxelGraph& g, std::vector<std::vector<std::int32_t>>& paths,
                               std::vector<std::int32_t>& parents) {
    const std::size_t n = paths.size();
    std::vector<std::uint8_t> has_child(n, 0), gone(n, 0);
    for (std::int32_t p : parents)
        if (p >= 0) has_child[static_cast<std::size_t>(p)] = 1;
    for (std::size_t k = 0; k < n; ++k) {  // parents come before children
        if (parents[k] < 0 || !has_child[k]) continue;
        if (path_length(g, paths[k]) >= g.dt[static_cast<std::size_t>(paths[k].front())]) continue;
        gone[k] = 1;
        for (std::size_t c = k + 1; c < n; ++c) {
            if (parents[c] != static_cast<std::int32_t>(k)) continue;
            std::vector<std::int32_t> joined(paths[k].begin(), paths[k].end() - 1);
            joined.insert(joined.end(), paths[c].begin(), paths[c].end());
            paths[c] = std::move(joined);
            parents[c] = parents[k];
        }
    }
    std::vector<std::int32_t> index(n, -1);
    std::vector<std::vector<std::int32_t>> kept_paths;
    std::vector<std::int32_t> kept_parents;
    for (std::size_t k = 0; k < n; ++k) {
        if (gone[k]) continue;
        index[k] = static_cast<std::int32_t>(kept_paths.size());
        kept_paths.push_back(std::move(paths[k]));
        kept_parents.push_back(parents[k] < 0 ? -1 : index[static_cast<std::size_t>(parents[k])]);
    }
    paths = std::move(kept_paths);
    parents = std::move(kept_parents);
}

/// Mean DT along each terminal chain (the root's too); returns the leaf (or root) of the thickest.
std::int32_t thickest_end(const VoxelGraph& g, const VoxelTree& t) {
    std::vector<std::vector<std::int32_t>> paths;
    std::vector<std::int32_t> parents;
    branches_of(t, paths, parents);
    std::vector<std::uint8_t> has_child(paths.size(), 0);
    for (std::int32_t p : parents)
        if (p >= 0) has_child[static_cast<std::size_t>(p)] = 1;
    double best = -1.0;
    std::int32_t end = t.root;
    for (std::size_t k = 0; k < paths.size(); ++k) {
        const bool at_root = parents[k] < 0;
        if (!at_root && has_child[k]) continue;  // an inner branch: no end of the object
        double s = 0.0;
        for (std::int32_t id : paths[k]) s += g.dt[static_cast<std::size_t>(id)];
        s /= static_cast<double>(paths[k].size());
        if (s > best) {
            best = s;
            end = at_root ? t.root : paths[k].back();
        }
    }
    return end;
}

/// Makes `r` (a voxel on the tree) its root: the parent links from r to the old root are reversed.
void reroot(VoxelTree& t, std::int32_t r) {
    std::int32_t prev = -1;
    for (std::int32_t p = r; p >= 0;) {
        const std::int32_t next = t.parent[static_cast<std::size_t>(p)];
        t.parent[static_cast<std::size_t>(p)] = prev;
        prev = p;
        p = next;
    }
    t.root = r;
    std::fill(t.children.begin(), t.children.end(), 0);
    for (std::size_t i = 0; i < t.on.size(); ++i)
        if (t.on[i] && t.parent[i] >= 0) ++t.children[static_cast<std::size_t>(t.parent[i])];
}

void check_tree_options(const TreeCenterlineOptions& opt) {
    if (!std::isfinite(opt.scale) || opt.scale < 0.0 || opt.scale > 100.0)
        throw Error("centerline_tree: scale must be 0 to 100");
    if (!std::isfinite(opt.constant) || opt.constant < 0.0) throw Error("centerline_tree: constant must be >= 0");
    if (!std::isfinite(opt.prune) || opt.prune < 0.0 || opt.prune > 1000.0)
        throw Error("centerline_tree: prune must be 0 to 1000");
}

}  // namespace

CenterlineTree centerline_tree(const VoxelGraph& g, const std::uint8_t* mask, const Vec3d* root,
                               const TreeCenterlineOptions& opt, const Progress& progress) {
    check_tree_options(opt);
    report(progress, 0.0);
    const double snap = 2.0 * std::max({g.grid.spacing[0], g.grid.spacing[1], g.grid.spacing[2]});
    VoxelTree t;
    const EndMode root_end = root ? EndMode::Free : EndMode::Tip;
    if (root) {
        t = grow(g, snap_to_object(g, *root, snap, "centerline_tree root"), opt, progress, 0.0, 0.85);
    } else {  // grow from the farthest voxel, then take the end of the thickest terminal branch as the root
        std::vector<double> dist;
        voxel_distances(g, {thickest(g)}, -1.0, dist);
        report(progress, 0.05);
        t = grow(g, far_tip(g, dist), opt, progress, 0.05, 0.85);
        prune_spurs(g, t, opt.prune);
        const std::int32_t end = thickest_end(g, t);
        if (end != t.root) reroot(t, end);
    }
    prune_spurs(g, t, opt.prune);
    const std::int32_t r = t.root;
    CenterlineTree out;
    out.root = r;
    std::vector<std::vector<std::int32_t>> paths;
    branches_of(t, paths, out.parents);
    merge_close_branch_points(g, paths, out.parents);
    if (paths.empty()) throw Error("centerline_tree: the object around the root is a single voxel");
    std::vector<std::uint8_t> has_child(paths.size(), 0);
    for (std::int32_t p : out.parents)
        if (p >= 0) has_child[static_cast<std::size_t>(p)] = 1;
    out.branches.resize(paths.size());
    report(progress, 0.9);
    tbb::parallel_for(std::size_t{0}, paths.size(), [&](std::size_t k) {
        const bool from_branch_point = out.parents[k] >= 0 || t.children[static_cast<std::size_t>(t.root)] > 1;
        out.branches[k] = curve_of_path(g, mask, paths[k], opt.line, from_branch_point ? EndMode::Fixed : root_end,
                                        has_child[k] ? EndMode::Fixed : EndMode::Tip);
    });
    for (std::size_t k = 0; k < paths.size(); ++k) {
        const std::int32_t p = out.parents[k];
        out.generations.push_back(p < 0 ? 0 : out.generations[static_cast<std::size_t>(p)] + 1);
    }
    report(progress, 1.0);
    return out;
}

}  // namespace volrig

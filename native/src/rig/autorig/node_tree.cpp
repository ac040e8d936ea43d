// rig/autorig/node_tree.cpp: the rooted node tree (see node_tree.hpp).
#include "rig/autorig/node_tree.hpp"

#include <algorithm>
#include <unordered_map>

namespace volrig::rig_detail {

NodeTree::NodeTree(std::vector<Vec> pos, std::vector<double> rad, const std::vector<std::array<std::uint32_t, 2>>& edges)
    : pos_(std::move(pos)), rad_(std::move(rad)), adj_(pos_.size()), kept_(pos_.size(), 1) {
    for (const auto& e : edges) {
        adj_[e[0]].push_back(e[1]);
        adj_[e[1]].push_back(e[0]);
    }
    std::uint32_t root = 0;
    for (std::uint32_t i = 0; i < pos_.size(); ++i)
        if (rad_[i] > rad_[root]) root = i;
    if (!pos_.empty()) reroot(root);
}

void NodeTree::reroot(std::uint32_t root) {
    root_ = root;
    const std::size_t n = pos_.size();
    parent_.assign(n, kNone);
    depth_.assign(n, 0);
    children_.assign(n, {});
    order_.assign(1, root);
    for (std::size_t k = 0; k < order_.size(); ++k) {
        const std::uint32_t v = order_[k];
        for (std::uint32_t w : adj_[v]) {
            if (!kept_[w] || w == parent_[v]) continue;
            parent_[w] = v;
            depth_[w] = depth_[v] + 1;
            children_[v].push_back(w);
            order_.push_back(w);
        }
    }
}

std::vector<std::uint32_t> NodeTree::leaves() const {
    std::vector<std::uint32_t> l;
    for (std::uint32_t v : order_)
        if (v != root_ && children_[v].empty()) l.push_back(v);
    return l;
}

void NodeTree::prune(double s) {
    for (int pass = 0; pass < 10000; ++pass) {
        std::vector<std::uint32_t> cut_below, cut_leaf;  // each pruned spur: the junction it hangs under, its leaf
        for (std::uint32_t l : leaves()) {
            // Walk to the junction (a node with two or more children, or the root).
            std::uint32_t j = parent_[l];
            while (j != root_ && children_[j].size() == 1) j = parent_[j];
            bool covered = false;
            for (std::uint32_t k = j; k != kNone && !covered; k = parent_[k])
                covered = (at(l) - at(k)).norm() + radius(l) <= s * radius(k);
            if (covered) {
                cut_below.push_back(j);
                cut_leaf.push_back(l);
            }
        }
        // Never cut every branch of a junction in one pass: the one whose tip reaches farthest stays.
        std::unordered_map<std::uint32_t, std::vector<std::size_t>> by_junction;
        for (std::size_t k = 0; k < cut_leaf.size(); ++k) by_junction[cut_below[k]].push_back(k);
        std::vector<std::uint8_t> spare(cut_leaf.size(), 0);
        for (auto& [j, ks] : by_junction) {
            if (ks.size() < children_[j].size()) continue;
            std::size_t best = ks[0];
            for (std::size_t k : ks)
                if ((at(cut_leaf[k]) - at(j)).norm() > (at(cut_leaf[best]) - at(j)).norm()) best = k;
            spare[best] = 1;
        }
        bool changed = false;
        for (std::size_t k = 0; k < cut_leaf.size(); ++k) {
            if (spare[k]) continue;
            for (std::uint32_t v = cut_leaf[k]; v != cut_below[k]; v = parent_[v]) kept_[v] = 0;
            changed = true;
        }
        if (!changed) break;
        reroot(root_);
    }
}

void NodeTree::root_off_an_end() {
    std::uint32_t v = root_;
    while (children_[v].size() == 1) v = children_[v][0];
    if (v == root_ || children_[v].empty()) return;  // an inner root, or a path
    if ((at(root_) - at(v)).norm() > radius(v)) reroot(v);  // the end's centre outside the junction's ball
}

void NodeTree::root_path_at_thicker_end() {
    if (children_[root_].size() > 2) return;
    for (std::uint32_t v : order_)
        if (v != root_ && children_[v].size() > 1) return;
    std::vector<std::uint32_t> ends = leaves();
    if (children_[root_].size() <= 1) ends.push_back(root_);
    if (ends.size() == 2) reroot(end_radius(ends[0]) >= end_radius(ends[1]) ? ends[0] : ends[1]);
}

double NodeTree::median_sheet(const std::vector<std::uint32_t>& path, std::size_t lo, std::size_t hi) const {
    std::vector<double> flat;
    for (std::size_t k = lo; k < std::min(hi, path.size()); ++k) flat.push_back(sheet(path[k]));
    if (flat.empty()) return 1.0;
    const auto mid = flat.begin() + static_cast<std::ptrdiff_t>(flat.size() / 2);
    std::nth_element(flat.begin(), mid, flat.end());
    return *mid;
}

double NodeTree::end_radius(std::uint32_t end) const {
    double s = 0;
    int n = 0;
    for (std::uint32_t prev = kNone, cur = end; cur != kNone && n < 8; ++n) {
        s += radius(cur);
        std::uint32_t next = kNone;
        for (std::uint32_t w : adj_[cur])
            if (kept_[w] && w != prev) next = w;
        prev = cur;
        cur = next;
    }
    return n ? s / n : 0.0;
}

std::vector<std::pair<double, std::uint32_t>> NodeTree::extremities() const {
    std::vector<double> height(pos_.size(), 0.0);
    std::vector<std::uint32_t> heavy(pos_.size(), kNone);
    for (auto it = order_.rbegin(); it != order_.rend(); ++it) {
        const std::uint32_t v = *it;
        for (std::uint32_t c : children_[v]) {
            const double h = height[c] + (at(c) - at(v)).norm();
            if (heavy[v] == kNone || h > height[v]) {
                height[v] = h;
                heavy[v] = c;
            }
        }
    }
    std::vector<std::pair<double, std::uint32_t>> out;
    for (std::uint32_t l : leaves()) {
        std::uint32_t t = l;
        while (t != root_ && heavy[parent_[t]] == t) t = parent_[t];
        // How far the branch sticks out of the balls from where it attaches up to the root (internal wandering
        // does not count, nor a branch that loops back inside the body from a thin attachment).
        double outside = std::numeric_limits<double>::infinity();
        for (std::uint32_t k = t == root_ ? root_ : parent_[t]; k != kNone; k = parent_[k])
            outside = std::min(outside, (at(l) - at(k)).norm() - radius(k));
        out.emplace_back(outside, l);
    }
    std::sort(out.begin(), out.end(),
              [](const auto& a, const auto& b) { return a.first != b.first ? a.first > b.first : a.second < b.second; });
    return out;
}

std::uint32_t NodeTree::lca(std::uint32_t a, std::uint32_t b) const {
    while (depth_[a] > depth_[b]) a = parent_[a];
    while (depth_[b] > depth_[a]) b = parent_[b];
    while (a != b) {
        a = parent_[a];
        b = parent_[b];
    }
    return a;
}

std::uint32_t NodeTree::median(std::uint32_t a, std::uint32_t b, std::uint32_t c) const {
    const std::uint32_t x = lca(a, b), y = lca(b, c), z = lca(a, c);
    std::uint32_t m = x;
    if (depth_[y] > depth_[m]) m = y;
    if (depth_[z] > depth_[m]) m = z;
    return m;
}

std::vector<std::uint32_t> NodeTree::path(std::uint32_t a, std::uint32_t b) const {
    const std::uint32_t m = lca(a, b);
    std::vector<std::uint32_t> up, down;
    for (std::uint32_t v = a; v != m; v = parent_[v]) up.push_back(v);
    up.push_back(m);
    for (std::uint32_t v = b; v != m; v = parent_[v]) down.push_back(v);
    up.insert(up.end(), down.rbegin(), down.rend());
    return up;
}

Vec NodeTree::box_size(const std::vector<std::uint32_t>& nodes) const {
    Vec lo = Vec::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (std::uint32_t v : nodes) {
        lo = lo.cwiseMin(at(v));
        hi = hi.cwiseMax(at(v));
    }
    return nodes.empty() ? Vec::Zero() : Vec(hi - lo);
}

double NodeTree::extent(const std::vector<std::uint32_t>& nodes) const { return box_size(nodes).norm(); }

double NodeTree::mean_radius(const std::vector<std::uint32_t>& nodes) const {
    double s = 0;
    for (std::uint32_t v : nodes) s += radius(v);
    return nodes.empty() ? 0.0 : s / static_cast<double>(nodes.size());
}

double NodeTree::length(const std::vector<std::uint32_t>& nodes) const {
    double s = 0;
    for (std::size_t k = 1; k < nodes.size(); ++k) s += (pos_[nodes[k]] - pos_[nodes[k - 1]]).norm();
    return s;
}

Vec NodeTree::point_along(const std::vector<std::uint32_t>& nodes, double share) const {
    double left = share * length(nodes);
    for (std::size_t k = 1; k < nodes.size(); ++k) {
        const Vec a = pos_[nodes[k - 1]], b = pos_[nodes[k]];
        const double step = (b - a).norm();
        if (step >= left && step > 0) return a + (left / step) * (b - a);
        left -= step;
    }
    return pos_[nodes.back()];
}

std::vector<std::uint32_t> NodeTree::out_to_farthest(std::vector<std::uint32_t> path) const {
    std::size_t far = 0;
    for (std::size_t k = 1; k < path.size(); ++k)
        if ((at(path[k]) - at(path[0])).norm() > (at(path[far]) - at(path[0])).norm()) far = k;
    path.resize(std::min(path.size(), std::max<std::size_t>(far + 1, 2)));
    return path;
}

std::vector<std::uint32_t> NodeTree::from_own_side(std::vector<std::uint32_t> path, const Vec& across,
                                                 double mid) const {
    auto side = [&](std::size_t k) { return at(path[k]).dot(across) - mid; };
    if (path.size() < 3 || side(0) >= 0) return path;
    std::size_t own = path.size();  // the first node from which on the path stays on its side
    while (own > 0 && side(own - 1) > 0) --own;
    if (own <= 1 || own >= path.size()) return path;
    const std::vector<std::uint32_t> before(path.begin(), path.begin() + static_cast<std::ptrdiff_t>(own) + 1);
    if (length(before) > 0.5 * length(path)) return path;
    path.erase(path.begin() + 1, path.begin() + static_cast<std::ptrdiff_t>(own));
    return path;
}

}  // namespace volrig::rig_detail

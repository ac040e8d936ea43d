// common/point_grid.hpp: a uniform grid of cells over skeleton points, for neighbour searches (skeleton-tree, binding,
// autorig). Internal to the core.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "volrig/tree.hpp"

namespace volrig::common_detail {

class PointGrid {
public:
    /// Cells of `cell` voxels along each axis (at least 1).
    PointGrid(const Grid& grid, const PointSet& pts, std::array<std::int64_t, 3> cell) : cell_(cell) {
        for (int a = 0; a < 3; ++a) {
            cell_[a] = std::max<std::int64_t>(1, cell_[a]);
            ncell_[a] = (grid.dims[a] + cell_[a] - 1) / cell_[a];
        }
        entries_.resize(pts.n);
        for (std::size_t i = 0; i < pts.n; ++i) {
            const std::int32_t* p = pts.ijk + 3 * i;
            entries_[i] = {key(p[2] / cell_[0], p[1] / cell_[1], p[0] / cell_[2]), static_cast<std::uint32_t>(i)};
        }
        std::sort(entries_.begin(), entries_.end());
    }

    const std::array<std::int64_t, 3>& cell() const { return cell_; }
    const std::array<std::int64_t, 3>& cells() const { return ncell_; }

    /// Cell coordinate (x, y, z) of voxel [z, y, x].
    std::array<std::int64_t, 3> cell_of(const std::int32_t* zyx) const {
        return {zyx[2] / cell_[0], zyx[1] / cell_[1], zyx[0] / cell_[2]};
    }

    /// f(point index) for each point in cell (cx, cy, cz); out-of-range cells are empty.
    template <class F>
    void for_each_in_cell(std::int64_t cx, std::int64_t cy, std::int64_t cz, F&& f) const {
        if (cx < 0 || cy < 0 || cz < 0 || cx >= ncell_[0] || cy >= ncell_[1] || cz >= ncell_[2]) return;
        const std::uint64_t k = key(cx, cy, cz);
        auto it = std::lower_bound(entries_.begin(), entries_.end(), std::pair<std::uint64_t, std::uint32_t>{k, 0});
        for (; it != entries_.end() && it->first == k; ++it) f(it->second);
    }

    /// f(point index) for each point in the cells of the box [lo, hi] (cell coordinates, inclusive).
    template <class F>
    void for_each_in_box(const std::array<std::int64_t, 3>& lo, const std::array<std::int64_t, 3>& hi, F&& f) const {
        for (std::int64_t cz = std::max<std::int64_t>(0, lo[2]); cz <= std::min(hi[2], ncell_[2] - 1); ++cz)
            for (std::int64_t cy = std::max<std::int64_t>(0, lo[1]); cy <= std::min(hi[1], ncell_[1] - 1); ++cy)
                for (std::int64_t cx = std::max<std::int64_t>(0, lo[0]); cx <= std::min(hi[0], ncell_[0] - 1); ++cx)
                    for_each_in_cell(cx, cy, cz, f);
    }

    /// f(point index) for each point in the cells at Chebyshev ring r around cell c (r = 0: the cell itself).
    template <class F>
    void for_each_in_ring(const std::array<std::int64_t, 3>& c, std::int64_t r, F&& f) const {
        for (std::int64_t dz = -r; dz <= r; ++dz)
            for (std::int64_t dy = -r; dy <= r; ++dy) {
                const bool face = std::abs(dz) == r || std::abs(dy) == r;
                for (std::int64_t dx = -r; dx <= r; dx += (face || r == 0) ? 1 : 2 * r)
                    for_each_in_cell(c[0] + dx, c[1] + dy, c[2] + dz, f);
            }
    }

private:
    std::uint64_t key(std::int64_t cx, std::int64_t cy, std::int64_t cz) const {
        return (static_cast<std::uint64_t>(cz) * static_cast<std::uint64_t>(ncell_[1]) + static_cast<std::uint64_t>(cy)) *
                   static_cast<std::uint64_t>(ncell_[0]) +
               static_cast<std::uint64_t>(cx);
    }
    std::array<std::int64_t, 3> cell_{1, 1, 1}, ncell_{1, 1, 1};
    std::vector<std::pair<std::uint64_t, std::uint32_t>> entries_;
};

/// Union-find with path halving and union by size.
class DisjointSets {
public:
    explicit DisjointSets(std::size_t n) : parent_(n), size_(n, 1) {
        for (std::size_t i = 0; i < n; ++i) parent_[i] = static_cast<std::uint32_t>(i);
    }
    std::uint32_t find(std::uint32_t a) {
        while (parent_[a] != a) a = parent_[a] = parent_[parent_[a]];
        return a;
    }
    bool unite(std::uint32_t a, std::uint32_t b) {
        a = find(a);
        b = find(b);
        if (a == b) return false;
        if (size_[a] < size_[b]) std::swap(a, b);
        parent_[b] = a;
        size_[a] += size_[b];
        return true;
    }
    std::uint32_t size_of(std::uint32_t a) { return size_[find(a)]; }

private:
    std::vector<std::uint32_t> parent_, size_;
};

}  // namespace volrig::common_detail

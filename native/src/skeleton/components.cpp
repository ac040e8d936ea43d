#include "volrig/components.hpp"

#include <algorithm>
#include <cstring>
#include <limits>
#include <numeric>
#include <string>

#include "common/neighbourhood.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace volrig {

Components label_components(const Grid& g, const std::uint8_t* mask, const Progress& progress) {
    check_grid(g, 1, std::numeric_limits<std::uint64_t>::max(), "label_components");
    const std::int64_t nx = g.dims[0], ny = g.dims[1], n = g.voxel_count();
    const common_detail::Neighbourhood nb(g);
    Components c;
    c.labels.assign(static_cast<std::size_t>(n), 0);
    std::vector<std::int64_t> stack;
    std::int32_t next = 0;
    std::int64_t reported = 0;
    for (std::int64_t i = 0; i < n; ++i) {
        if (!mask[i] || c.labels[static_cast<std::size_t>(i)]) continue;
        if (next == std::numeric_limits<std::int32_t>::max()) throw Error("label_components: too many components");
        const std::int32_t label = ++next;
        std::int64_t size = 0;
        c.labels[static_cast<std::size_t>(i)] = label;
        stack.push_back(i);
        while (!stack.empty()) {
            const std::int64_t v = stack.back();
            stack.pop_back();
            ++size;
            const std::int64_t z = v / (nx * ny), y = (v / nx) % ny, x = v % nx;
            nb.visit(x, y, z, v, [&](int, std::int64_t j) {
                if (j >= 0 && mask[j] && !c.labels[static_cast<std::size_t>(j)]) {
                    c.labels[static_cast<std::size_t>(j)] = label;
                    stack.push_back(j);
                }
            });
        }
        c.sizes.push_back(size);
        // Report about every 2^20 voxels scanned (the scan position is the fraction done).
        if ((i >> 20) != (reported >> 20)) {
            reported = i;
            report(progress, 0.9 * static_cast<double>(i) / static_cast<double>(n));
        }
    }
    // Relabel by descending size (stable: ties keep discovery order).
    std::vector<std::int32_t> rank(c.sizes.size());
    std::iota(rank.begin(), rank.end(), 0);
    std::stable_sort(rank.begin(), rank.end(), [&](std::int32_t a, std::int32_t b) { return c.sizes[a] > c.sizes[b]; });
    std::vector<std::int32_t> relabel(c.sizes.size() + 1, 0);
    std::vector<std::int64_t> sorted(c.sizes.size());
    for (std::size_t r = 0; r < rank.size(); ++r) {
        relabel[static_cast<std::size_t>(rank[r]) + 1] = static_cast<std::int32_t>(r + 1);
        sorted[r] = c.sizes[static_cast<std::size_t>(rank[r])];
    }
    for (auto& l : c.labels) l = relabel[static_cast<std::size_t>(l)];
    c.sizes = std::move(sorted);
    report(progress, 1.0);
    return c;
}

std::vector<std::uint8_t> largest_component(const Grid& g, const std::uint8_t* mask, const Progress& progress) {
    const Components c = label_components(g, mask, progress);
    std::vector<std::uint8_t> out(c.labels.size());
    std::transform(c.labels.begin(), c.labels.end(), out.begin(), [](std::int32_t l) { return l == 1 ? 1 : 0; });
    return out;
}

namespace {

/// The mask's runs along x, row by row (row = z * ny + y): runs [row_start[row], row_start[row + 1]) of `x0`,
/// `x1` (inclusive).
struct Runs {
    std::vector<std::int64_t> row_start;
    std::vector<std::int32_t> x0, x1;
};

inline bool zero_word(const std::uint8_t* p) {
    std::uint64_t w;
    std::memcpy(&w, p, sizeof w);
    return w == 0;
}

Runs mask_runs(const Grid& g, const std::uint8_t* mask) {
    const std::int64_t nx = g.dims[0], rows = g.dims[1] * g.dims[2];
    std::vector<std::vector<std::int32_t>> per(static_cast<std::size_t>(rows));  // x0, x1 pairs of each row
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, rows), [&](const tbb::blocked_range<std::int64_t>& rg) {
        for (std::int64_t r = rg.begin(); r < rg.end(); ++r) {
            const std::uint8_t* m = mask + r * nx;
            auto& out = per[static_cast<std::size_t>(r)];
            for (std::int64_t x = 0; x < nx; ++x) {
                while (x + 8 <= nx && zero_word(m + x)) x += 8;  // the background, eight bytes at a time
                if (x >= nx || !m[x]) continue;
                const std::int64_t a = x;
                while (x + 1 < nx && m[x + 1]) ++x;
                out.push_back(static_cast<std::int32_t>(a));
                out.push_back(static_cast<std::int32_t>(x));
            }
        }
    });
    Runs runs;
    runs.row_start.assign(static_cast<std::size_t>(rows) + 1, 0);
    for (std::int64_t r = 0; r < rows; ++r) {
        const auto& v = per[static_cast<std::size_t>(r)];
        runs.row_start[static_cast<std::size_t>(r) + 1] = runs.row_start[static_cast<std::size_t>(r)] +
                                                          static_cast<std::int64_t>(v.size() / 2);
        for (std::size_t k = 0; k < v.size(); k += 2) runs.x0.push_back(v[k]), runs.x1.push_back(v[k + 1]);
    }
    return runs;
}

std::int64_t find_root(std::vector<std::int64_t>& parent, std::int64_t a) {
    while (parent[static_cast<std::size_t>(a)] != a) {
        parent[static_cast<std::size_t>(a)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(a)])];
        a = parent[static_cast<std::size_t>(a)];
    }
    return a;
}

/// Joins the runs of row `r` with those of row `s` that touch them: 26-wise when `diagonal` (x ranges within one
/// voxel), else face to face (x ranges overlapping).
void join_rows(const Runs& runs, std::int64_t r, std::int64_t s, bool diagonal, std::vector<std::int64_t>& parent) {
    std::int64_t i = runs.row_start[static_cast<std::size_t>(r)], j = runs.row_start[static_cast<std::size_t>(s)];
    const std::int64_t ie = runs.row_start[static_cast<std::size_t>(r) + 1];
    const std::int64_t je = runs.row_start[static_cast<std::size_t>(s) + 1];
    const std::int32_t reach = diagonal ? 1 : 0;
    while (i < ie && j < je) {
        const auto a0 = runs.x0[static_cast<std::size_t>(i)] - reach, a1 = runs.x1[static_cast<std::size_t>(i)] + reach;
        const auto b0 = runs.x0[static_cast<std::size_t>(j)], b1 = runs.x1[static_cast<std::size_t>(j)];
        if (a0 <= b1 && b0 <= a1) {
            const std::int64_t ra = find_root(parent, i), rb = find_root(parent, j);
            if (ra != rb) parent[static_cast<std::size_t>(std::max(ra, rb))] = std::min(ra, rb);
        }
        if (runs.x1[static_cast<std::size_t>(i)] < b1) ++i;  // the run ending first touches nothing further on
        else ++j;
    }
}

/// The mask's runs and each run's component, 1.. numbered by the component's first run in scan order.
struct RunComponents {
    Runs runs;
    std::vector<std::int32_t> number;
    std::int32_t count = 0;
};

RunComponents run_components(const Grid& g, const std::uint8_t* mask, int connectivity) {
    if (connectivity != 6 && connectivity != 26)
        throw Error("connected components: connectivity must be 6 or 26, got " + std::to_string(connectivity));
    RunComponents rc{mask_runs(g, mask), {}, 0};
    const Runs& runs = rc.runs;
    const std::int64_t ny = g.dims[1], nz = g.dims[2];
    const bool diagonal = connectivity == 26;
    std::vector<std::int64_t> parent(runs.x0.size());
    std::iota(parent.begin(), parent.end(), std::int64_t{0});
    for (std::int64_t z = 0; z < nz; ++z)
        for (std::int64_t y = 0; y < ny; ++y) {  // the rows before this one among its neighbouring rows
            const std::int64_t r = z * ny + y;
            if (y > 0) join_rows(runs, r, r - 1, diagonal, parent);
            if (z == 0) continue;
            for (std::int64_t dy = diagonal ? -1 : 0; dy <= (diagonal ? 1 : 0); ++dy)
                if (y + dy >= 0 && y + dy < ny) join_rows(runs, r, r - ny + dy, diagonal, parent);
        }
    rc.number.assign(runs.x0.size(), 0);
    for (std::size_t k = 0; k < runs.x0.size(); ++k) {
        const auto root = static_cast<std::size_t>(find_root(parent, static_cast<std::int64_t>(k)));
        if (!rc.number[root]) {  // roots are the least run of their component: seen first
            if (rc.count == std::numeric_limits<std::int32_t>::max())
                throw Error("connected components: too many components");
            rc.number[root] = ++rc.count;
        }
        rc.number[k] = rc.number[root];
    }
    return rc;
}

}  // namespace

std::vector<std::int32_t> point_components(const Grid& g, const std::uint8_t* mask, const std::int32_t* ijk,
                                           std::size_t n) {
    check_grid(g, 1, std::numeric_limits<std::uint64_t>::max(), "point_components");
    const RunComponents rc = run_components(g, mask, 26);
    const Runs& runs = rc.runs;
    const auto& number = rc.number;
    const std::int64_t ny = g.dims[1], nz = g.dims[2];
    std::vector<std::int32_t> out(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
        const std::int64_t z = ijk[3 * i], y = ijk[3 * i + 1], x = ijk[3 * i + 2];
        if (z < 0 || y < 0 || x < 0 || z >= nz || y >= ny || x >= g.dims[0]) continue;
        const std::int64_t row = z * ny + y;
        const auto b = runs.x0.begin() + runs.row_start[static_cast<std::size_t>(row)];
        const auto e = runs.x0.begin() + runs.row_start[static_cast<std::size_t>(row) + 1];
        const auto it = std::upper_bound(b, e, static_cast<std::int32_t>(x));  // the last run starting at or before x
        if (it == b) continue;
        const auto k = static_cast<std::size_t>(it - runs.x0.begin() - 1);
        if (x <= runs.x1[k]) out[i] = number[k];
    }
    return out;
}

Components scan_components(const Grid& g, const std::uint8_t* mask, int connectivity) {
    check_grid(g, 1, std::numeric_limits<std::uint64_t>::max(), "scan_components");
    const RunComponents rc = run_components(g, mask, connectivity);
    Components c;
    c.labels.assign(static_cast<std::size_t>(g.voxel_count()), 0);
    c.sizes.assign(static_cast<std::size_t>(rc.count), 0);
    const std::int64_t nx = g.dims[0], rows = g.dims[1] * g.dims[2];
    for (std::int64_t r = 0; r < rows; ++r)
        for (std::int64_t k = rc.runs.row_start[static_cast<std::size_t>(r)];
             k < rc.runs.row_start[static_cast<std::size_t>(r) + 1]; ++k) {
            const auto kk = static_cast<std::size_t>(k);
            const std::int32_t label = rc.number[kk];
            std::fill(c.labels.begin() + r * nx + rc.runs.x0[kk], c.labels.begin() + r * nx + rc.runs.x1[kk] + 1, label);
            c.sizes[static_cast<std::size_t>(label) - 1] += rc.runs.x1[kk] - rc.runs.x0[kk] + 1;
        }
    return c;
}

std::vector<std::int64_t> nearest_seed_fill(const Grid& g, const std::uint8_t* code) {
    check_grid(g, 1, std::numeric_limits<std::uint64_t>::max(), "nearest_seed_fill");
    const std::int64_t nx = g.dims[0], ny = g.dims[1], n = g.voxel_count();
    const common_detail::Neighbourhood nb(g);
    std::vector<bool> done(static_cast<std::size_t>(n), false);
    std::vector<std::int64_t> pairs;  // (filled, seed), in breadth-first order: the queue itself
    const auto take = [&](std::int64_t v, std::int64_t seed) {
        done[static_cast<std::size_t>(v)] = true;
        pairs.push_back(v);
        pairs.push_back(seed);
    };
    const auto around = [&](std::int64_t v, auto&& f) {
        nb.visit(v % nx, (v / nx) % ny, v / (nx * ny), v, f);
    };
    for (std::int64_t i = 0; i < n; ++i) {  // the first layer: voxels to fill next to a seed
        if (code[i] != 2) continue;
        std::int64_t seed = -1;
        around(i, [&](int, std::int64_t j) {
            if (seed < 0 && j >= 0 && code[j] == 1) seed = j;
        });
        if (seed >= 0) take(i, seed);
    }
    for (std::size_t head = 0; head < pairs.size(); head += 2) {  // then outwards, one step a layer
        const std::int64_t v = pairs[head], seed = pairs[head + 1];
        around(v, [&](int, std::int64_t j) {
            if (j >= 0 && code[j] == 2 && !done[static_cast<std::size_t>(j)]) take(j, seed);
        });
    }
    return pairs;
}

}  // namespace volrig

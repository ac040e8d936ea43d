#include "volrig/components.hpp"

#include <algorithm>
#include <limits>
#include <numeric>

#include "neighbourhood.hpp"

namespace volrig {

Components label_components(const Grid& g, const std::uint8_t* mask, const Progress& progress) {
    check_grid(g, 1, std::numeric_limits<std::uint64_t>::max(), "label_components");
    const std::int64_t nx = g.dims[0], ny = g.dims[1], n = g.voxel_count();
    const detail::Neighbourhood nb(g);
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

}  // namespace volrig

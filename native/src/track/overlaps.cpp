#include <algorithm>
#include <string>
#include <unordered_map>

#include "volrig/track.hpp"

namespace volrig {

namespace {

constexpr std::size_t kDensePairs = std::size_t{1} << 20;  // pair tables up to this size are dense arrays

void check_point(const Grid& g, const std::int64_t* index, const std::int32_t* label, std::size_t i) {
    if (index[i] < 0 || index[i] >= g.voxel_count())
        throw Error("point_overlaps: point " + std::to_string(i) + " lies off the grid");
    if (label[i] < 0) throw Error("point_overlaps: point " + std::to_string(i) + " has a negative feature");
}

}  // namespace

Overlaps point_overlaps(const Grid& g, const std::int32_t* next_labels, std::int32_t nb, const std::int64_t* index,
                        const std::int32_t* label, const float* weight, std::size_t n) {
    if (nb < 0) throw Error("point_overlaps: the next step's feature count must be >= 0");
    std::int32_t na = 0;
    for (std::size_t i = 0; i < n; ++i) {
        check_point(g, index, label, i);
        na = std::max(na, label[i]);
    }
    Overlaps o;
    o.totals.assign(static_cast<std::size_t>(na) + 1, 0.0);
    const auto width = static_cast<std::size_t>(nb) + 1;
    const bool dense = (static_cast<std::size_t>(na) + 1) * width <= kDensePairs;
    std::vector<double> table(dense ? (static_cast<std::size_t>(na) + 1) * width : 0, 0.0);
    std::unordered_map<std::uint64_t, double> sparse;
    for (std::size_t i = 0; i < n; ++i) {
        const std::int32_t b = next_labels[index[i]];
        if (b > nb) throw Error("point_overlaps: a next-step label exceeds its feature count");
        o.totals[static_cast<std::size_t>(label[i])] += weight[i];
        if (b <= 0 || label[i] == 0) continue;
        if (dense) table[static_cast<std::size_t>(label[i]) * width + static_cast<std::size_t>(b)] += weight[i];
        else sparse[static_cast<std::uint64_t>(label[i]) << 32 | static_cast<std::uint32_t>(b)] += weight[i];
    }
    const auto emit = [&o](std::uint64_t a, std::uint64_t b, double w) {
        o.a.push_back(static_cast<std::int32_t>(a));
        o.b.push_back(static_cast<std::int32_t>(b));
        o.weight.push_back(w);
    };
    for (std::size_t k = 0; k < table.size(); ++k)  // the dense table is in (a, b) order already
        if (table[k] != 0) emit(k / width, k % width, table[k]);
    std::vector<std::pair<std::uint64_t, double>> pairs(sparse.begin(), sparse.end());
    std::sort(pairs.begin(), pairs.end());
    for (const auto& [key, w] : pairs) emit(key >> 32, key & 0xffffffffu, w);
    return o;
}

}  // namespace volrig

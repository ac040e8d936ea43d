#include <algorithm>
#include <limits>
#include <string>
#include <unordered_map>

#include "volrig/track.hpp"

namespace volrig {

namespace {

constexpr std::size_t kAhead = 32;  // how far ahead a skeleton point's label is fetched (16-64 alike; none 1.8x slower)
constexpr std::size_t kDensePairs = std::size_t{1} << 20;  // pair tables up to this size are dense arrays

/// Sums per pair (own feature, other feature): a dense array while it is small, a hash table beyond. `cell` is
/// stable while the table lives (unordered_map nodes do not move), so a running sum can stay in a register.
class PairTable {
public:
    PairTable(std::int32_t own, std::int32_t other)
        : width_(static_cast<std::uint64_t>(other) + 1),
          dense_((static_cast<std::size_t>(own) + 1) * width_ <= kDensePairs
                     ? (static_cast<std::size_t>(own) + 1) * width_ : 0, 0.0) {}
    std::uint64_t key(std::uint64_t own, std::uint64_t other) const { return own * width_ + other; }
    double* cell(std::uint64_t k) { return dense_.empty() ? &sparse_[k] : &dense_[k]; }
    /// The nonzero sums as (own << 32 | other, sum), sorted by key; with `swap`, keyed (other << 32 | own).
    std::vector<std::pair<std::uint64_t, double>> sums(bool swap) const {
        std::vector<std::pair<std::uint64_t, double>> out;
        const auto put = [&](std::uint64_t k, double w) {
            if (w == 0) return;
            const std::uint64_t x = k / width_, y = k % width_;
            out.emplace_back(swap ? y << 32 | x : x << 32 | y, w);
        };
        for (std::size_t k = 0; k < dense_.size(); ++k) put(k, dense_[k]);
        for (const auto& [k, w] : sparse_) put(k, w);
        std::sort(out.begin(), out.end());
        return out;
    }

private:
    std::uint64_t width_;
    std::vector<double> dense_;
    std::unordered_map<std::uint64_t, double> sparse_;
};

[[noreturn]] void refuse(const std::string& why, std::size_t i) {
    throw Error("step_overlaps: point " + std::to_string(i) + " " + why);
}

/// p's points looked up in `other` (features 1..other_count) into a table over (p's feature, other's feature). The
/// sum of the current pair stays in a register until the pair changes (points in index order mostly continue the
/// pair before them); weights are added in point order all the same, and without weights counted as integers.
/// Weighted points are a skeleton's, sparse: their reads of `other` skip cache lines and are fetched kAhead points
/// ahead (every voxel of a feature, the full-volume test's points, read `other` in runs the hardware streams).
template <bool Weighted, class I, class L>
PairTable count_pairs(const Grid& g, const StepPoints<I, L>& p, const L* other, std::int32_t other_count) {
    PairTable t(p.count, other_count);
    const auto voxels = static_cast<std::uint64_t>(g.voxel_count());
    const auto own = static_cast<std::uint64_t>(p.count), next = static_cast<std::uint64_t>(other_count);
    std::uint64_t key = ~std::uint64_t{0};
    double* cell = nullptr;
    double sum = 0;
    std::int64_t run = 0;
    for (std::size_t i = 0; i < p.n; ++i) {
        if constexpr (Weighted)
            if (i + kAhead < p.n && static_cast<std::uint64_t>(p.index[i + kAhead]) < voxels)
                __builtin_prefetch(other + p.index[i + kAhead]);
        const auto v = static_cast<std::uint64_t>(p.index[i]);
        if (v >= voxels) refuse("lies off the grid", i);
        const auto a = static_cast<std::uint64_t>(static_cast<std::int64_t>(p.label[i]));
        if (a - 1 >= own) refuse("has no feature of its step (label " + std::to_string(a) + ")", i);
        const auto b = static_cast<std::uint64_t>(static_cast<std::int64_t>(other[v]));
        if (b > next) refuse("lands on a label above the other step's feature count", i);
        if (!b) continue;
        const std::uint64_t k = t.key(a, b);
        if (k != key) {
            if constexpr (Weighted) {
                if (cell) *cell = sum;
                cell = t.cell(k), sum = *cell;
            } else {
                if (cell) *cell += static_cast<double>(run);
                cell = t.cell(k), run = 0;
            }
            key = k;
        }
        if constexpr (Weighted) sum += p.weight[i];
        else ++run;
    }
    if (cell) {
        if constexpr (Weighted) *cell = sum;
        else *cell += static_cast<double>(run);
    }
    return t;
}

template <class I, class L>
void check_side(const StepPoints<I, L>& p, const char* which) {
    if (p.count < 0 || !p.labels || (p.n && (!p.index || !p.label)))
        throw Error(std::string("step_overlaps: step ") + which + " needs its labels, feature count and points");
    if (p.weight && (!p.sizes || !p.totals))
        throw Error(std::string("step_overlaps: step ") + which + "'s weighted points need sizes and totals");
    if (static_cast<std::int64_t>(p.count) > static_cast<std::int64_t>(std::numeric_limits<L>::max()))
        throw Error(std::string("step_overlaps: step ") + which + "'s feature count exceeds its label type");
}

/// The overlaps of p's features with the other step's: the sums scaled to p's voxels (weighted points).
template <class I, class L>
std::vector<std::pair<std::uint64_t, double>> one_way(const Grid& g, const StepPoints<I, L>& p, const L* other,
                                                       std::int32_t other_count, bool swap) {
    auto sums = (p.weight ? count_pairs<true, I, L>(g, p, other, other_count)
                          : count_pairs<false, I, L>(g, p, other, other_count)).sums(swap);
    if (p.weight)
        for (auto& [key, w] : sums) {
            const std::uint64_t f = swap ? key & 0xffffffffu : key >> 32;
            w = w * static_cast<double>(p.sizes[f - 1]) / p.totals[f];
        }
    return sums;
}

/// Appends pair (key >> 32, key & 0xffffffff) with its overlap.
void append(Overlaps& o, std::uint64_t key, double w) {
    o.a.push_back(static_cast<std::int32_t>(key >> 32));
    o.b.push_back(static_cast<std::int32_t>(key & 0xffffffffu));
    o.overlap.push_back(w);
}

}  // namespace

template <class I, class L>
Overlaps step_overlaps(const Grid& g, const StepPoints<I, L>& a, const StepPoints<I, L>& b, bool both) {
    check_side(a, "a");
    check_side(b, "b");
    const auto ab = one_way(g, a, b.labels, b.count, false);
    const auto ba = both ? one_way(g, b, a.labels, a.count, true) : decltype(ab){};
    Overlaps o;
    std::size_t i = 0, j = 0;  // merge the two sorted lists, the larger estimate where both have a pair
    while (i < ab.size() || j < ba.size()) {
        if (j == ba.size() || (i < ab.size() && ab[i].first < ba[j].first)) append(o, ab[i].first, ab[i].second), ++i;
        else if (i == ab.size() || ba[j].first < ab[i].first) append(o, ba[j].first, ba[j].second), ++j;
        else append(o, ab[i].first, std::max(ab[i].second, ba[j].second)), ++i, ++j;
    }
    return o;
}

Overlaps run_overlaps(const Runs& a, const Runs& b) {
    for (const Runs* r : {&a, &b}) {
        if (r->count < 0 || (r->n && (!r->row || !r->x0 || !r->x1 || !r->label)))
            throw Error("run_overlaps: each step needs its runs and feature count");
        for (std::size_t i = 0; i < r->n; ++i)
            if (r->label[i] < 1 || r->label[i] > r->count || r->x1[i] <= r->x0[i])
                throw Error("run_overlaps: run " + std::to_string(i) + " has no feature of its step or is empty");
    }
    PairTable t(a.count, b.count);
    std::size_t i = 0, j = 0;
    while (i < a.n && j < b.n) {
        if (a.row[i] != b.row[j]) {
            (a.row[i] < b.row[j] ? i : j)++;
            continue;
        }
        const std::int32_t lo = std::max(a.x0[i], b.x0[j]), hi = std::min(a.x1[i], b.x1[j]);
        if (hi > lo) *t.cell(t.key(static_cast<std::uint64_t>(a.label[i]), static_cast<std::uint64_t>(b.label[j]))) +=
            hi - lo;
        (a.x1[i] < b.x1[j] ? i : j)++;
    }
    Overlaps o;
    for (const auto& [key, w] : t.sums(false)) append(o, key, w);
    return o;
}

#define VOLRIG_STEP_OVERLAPS(I, L) \
    template Overlaps step_overlaps<I, L>(const Grid&, const StepPoints<I, L>&, const StepPoints<I, L>&, bool);
VOLRIG_STEP_OVERLAPS(std::uint32_t, std::uint8_t)
VOLRIG_STEP_OVERLAPS(std::uint32_t, std::uint16_t)
VOLRIG_STEP_OVERLAPS(std::uint32_t, std::int32_t)
VOLRIG_STEP_OVERLAPS(std::int64_t, std::uint8_t)
VOLRIG_STEP_OVERLAPS(std::int64_t, std::uint16_t)
VOLRIG_STEP_OVERLAPS(std::int64_t, std::int32_t)
#undef VOLRIG_STEP_OVERLAPS

}  // namespace volrig

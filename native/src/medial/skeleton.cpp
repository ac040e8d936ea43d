// The homotopic, classified voxel skeleton of medial_surface.hpp: simple points, anchored distance-ordered thinning,
// surface / curve / junction classification.
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <queue>

#include "volrig/medial_surface.hpp"

namespace volrig {

namespace {

constexpr int kCentre = 13;

int ctz(std::uint32_t v) { return __builtin_ctz(v); }
int popcount(std::uint32_t v) { return __builtin_popcount(v); }

int bit_of(int dx, int dy, int dz) { return (dz + 1) * 9 + (dy + 1) * 3 + (dx + 1); }

/// Per position of the 3x3x3 cube: its 26-neighbours in the cube, and its 6-neighbours in the 18-neighbourhood
/// (the cube without its corners), centre excluded from both.
struct CubeTables {
    std::array<std::uint32_t, 27> n26{}, n6in18{};
    std::uint32_t n18 = 0, faces = 0;
    CubeTables() {
        for (int i = 0; i < 27; ++i) {
            const int x = i % 3, y = (i / 3) % 3, z = i / 9;
            const int l1 = std::abs(x - 1) + std::abs(y - 1) + std::abs(z - 1);
            if (i != kCentre && l1 <= 2) n18 |= 1u << i;
            if (l1 == 1) faces |= 1u << i;
        }
        for (int i = 0; i < 27; ++i)
            for (int j = 0; j < 27; ++j) {
                if (i == j || i == kCentre || j == kCentre) continue;
                const int dx = std::abs(i % 3 - j % 3), dy = std::abs((i / 3) % 3 - (j / 3) % 3), dz = std::abs(i / 9 - j / 9);
                if (std::max({dx, dy, dz}) == 1) n26[static_cast<std::size_t>(i)] |= 1u << j;
                if (dx + dy + dz == 1 && (n18 >> j & 1u) && (n18 >> i & 1u)) n6in18[static_cast<std::size_t>(i)] |= 1u << j;
            }
    }
};

const CubeTables& tables() {
    static const CubeTables t;
    return t;
}

/// The component of `set` holding bit `seed`, grown over `adj`.
std::uint32_t component(std::uint32_t set, int seed, const std::array<std::uint32_t, 27>& adj) {
    std::uint32_t comp = 1u << seed, frontier = comp;
    while (frontier) {
        std::uint32_t grow = 0;
        for (std::uint32_t f = frontier; f; f &= f - 1) grow |= adj[static_cast<std::size_t>(ctz(f))];
        grow &= set & ~comp;
        comp |= grow;
        frontier = grow;
    }
    return comp;
}

/// The 27-bit neighbourhood of (x, y, z) in `m` (outside the array: 0).
std::uint32_t neighbourhood(const Grid& g, const std::uint8_t* m, std::int64_t x, std::int64_t y, std::int64_t z) {
    std::uint32_t bits = 0;
    const bool inner = x > 0 && y > 0 && z > 0 && x + 1 < g.dims[0] && y + 1 < g.dims[1] && z + 1 < g.dims[2];
    for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                const std::int64_t X = x + dx, Y = y + dy, Z = z + dz;
                if (!inner && (X < 0 || Y < 0 || Z < 0 || X >= g.dims[0] || Y >= g.dims[1] || Z >= g.dims[2])) continue;
                if (m[g.index(X, Y, Z)]) bits |= 1u << bit_of(dx, dy, dz);
            }
    return bits;
}

/// True when at least two lines through the centre have set voxels at both ends (bits i and 26 - i are opposite).
bool sheet_like(std::uint32_t nb) {
    int lines = 0;
    for (int i = 0; i < kCentre; ++i) lines += (nb >> i & 1u) && (nb >> (26 - i) & 1u);
    return lines >= 2;
}

}  // namespace

bool is_simple27(std::uint32_t nb) {
    const CubeTables& t = tables();
    const std::uint32_t object = nb & ~(1u << kCentre) & ((1u << 27) - 1);
    if (!object) return false;  // an isolated voxel: deleting it deletes a component
    if (component(object, ctz(object), t.n26) != object) return false;
    // Background 6-components in N18 that are 6-adjacent to the centre: exactly one.
    const std::uint32_t back = ~nb & t.n18;
    const std::uint32_t touching = back & t.faces;
    if (!touching) return false;  // an interior voxel: deleting it makes a cavity
    return (component(back, ctz(touching), t.n6in18) & touching) == touching;
}

bool is_simple(const Grid& g, const std::uint8_t* mask, std::int64_t x, std::int64_t y, std::int64_t z) {
    return is_simple27(neighbourhood(g, mask, x, y, z));
}

namespace {

/// The border: object voxels, not anchors, with a background 6-neighbour, as (DT, index) ascending.
std::vector<std::pair<float, std::int64_t>> border_by_dt(const Grid& g, const std::uint8_t* mask,
                                                         const std::uint8_t* anchors, const float* dt) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    std::vector<std::vector<std::pair<float, std::int64_t>>> per_slice(static_cast<std::size_t>(nz));
    tbb::parallel_for(std::int64_t(0), nz, [&](std::int64_t z) {
        for (std::int64_t y = 0; y < ny; ++y)
            for (std::int64_t x = 0; x < nx; ++x) {
                const std::int64_t i = g.index(x, y, z);
                if (mask[i] && !anchors[i] && (neighbourhood(g, mask, x, y, z) & tables().faces) != tables().faces)
                    per_slice[static_cast<std::size_t>(z)].push_back({dt[i], i});
            }
    });
    std::vector<std::pair<float, std::int64_t>> out;
    for (const auto& v : per_slice) out.insert(out.end(), v.begin(), v.end());
    tbb::parallel_sort(out.begin(), out.end());
    return out;
}

/// Distance-ordered thinning (Pudney 1998): object voxels on the border enter a queue by DT; a popped voxel is
/// deleted when simple, not an anchor and not a curve end; a deletion queues its object neighbours again (with
/// their own DT, so lower ones come back first), so voxels that were not simple are retried when their
/// neighbourhood changes. Only simple deletions: the result has the object's topology.
std::vector<std::uint8_t> thin(const Grid& g, const std::uint8_t* mask, const std::uint8_t* anchors, const float* dt,
                               const Progress& progress) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    std::vector<std::uint8_t> skel(mask, mask + g.voxel_count());
    using Item = std::pair<float, std::int64_t>;
    // The queue: the border sorted once, merged with a heap of the voxels queued again; both ordered by (DT,
    // index), so the voxels come out exactly as from one heap, at a fraction of its cost.
    const std::vector<Item> border = border_by_dt(g, mask, anchors, dt);
    std::vector<std::uint8_t> queued(skel.size(), 0);
    for (const Item& it : border) queued[static_cast<std::size_t>(it.second)] = 1;
    std::size_t next = 0;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> heap;
    auto push = [&](std::int64_t i) {
        if (!skel[static_cast<std::size_t>(i)] || anchors[i] || queued[static_cast<std::size_t>(i)]) return;
        queued[static_cast<std::size_t>(i)] = 1;
        heap.push({dt[i], i});
    };
    auto pop = [&]() {
        if (heap.empty() || (next < border.size() && border[next] < heap.top())) return border[next++].second;
        const std::int64_t i = heap.top().second;
        heap.pop();
        return i;
    };
    const double first = double(std::max<std::size_t>(border.size(), 1));
    for (std::uint64_t pops = 0; next < border.size() || !heap.empty(); ++pops) {
        if ((pops & 0xFFFFF) == 0) report(progress, std::min(0.95, double(pops) / (2.0 * first)));
        const std::int64_t i = pop();
        queued[static_cast<std::size_t>(i)] = 0;
        const std::int64_t x = i % nx, y = (i / nx) % ny, z = i / (nx * ny);
        const std::uint32_t nb = neighbourhood(g, skel.data(), x, y, z);
        if (popcount(nb & ~(1u << kCentre)) <= 1 || !is_simple27(nb)) continue;  // a curve end, or needed
        skel[static_cast<std::size_t>(i)] = 0;
        for (std::uint32_t f = nb & ~(1u << kCentre); f; f &= f - 1) {
            const int b = ctz(f);
            push(g.index(x + b % 3 - 1, y + (b / 3) % 3 - 1, z + b / 9 - 1));
        }
    }
    return skel;
}

}  // namespace

std::vector<std::uint8_t> thin_skeleton(const Grid& g, const std::uint8_t* mask, const std::uint8_t* anchors,
                                        const float* dt, const Progress& progress) {
    std::vector<std::uint8_t> skel = thin(g, mask, anchors, dt, progress_span(progress, 0.0, 0.9));
    report(progress, 0.9);
    // Classify: anchors are surface, and so are the kept voxels in a sheet of the skeleton (two or more lines
    // through them with skeleton voxels on both sides: a membrane the thinning kept across a gap of the
    // plane-like set, which a curve, its branch points or a rod's foot on a plate never have); the rest is curve,
    // and curve voxels touching the surface are junctions.
    std::vector<std::uint8_t> cls(skel.size(), 0);
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    tbb::parallel_for(std::int64_t(0), g.voxel_count(), [&](std::int64_t i) {
        const auto u = static_cast<std::size_t>(i);
        if (!skel[u]) return;
        cls[u] = static_cast<std::uint8_t>(anchors[i] || sheet_like(neighbourhood(g, skel.data(), i % nx, (i / nx) % ny, i / (nx * ny)))
                                               ? SkeletonClass::Surface : SkeletonClass::Curve);
    });
    std::vector<std::uint8_t> surface(skel.size());
    for (std::size_t i = 0; i < skel.size(); ++i) surface[i] = cls[i] == 1;
    tbb::parallel_for(std::int64_t(0), g.voxel_count(), [&](std::int64_t i) {
        if (cls[static_cast<std::size_t>(i)] != 2) return;
        if (neighbourhood(g, surface.data(), i % nx, (i / nx) % ny, i / (nx * ny)))
            cls[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(SkeletonClass::Junction);
    });
    report(progress, 1.0);
    return cls;
}

}  // namespace volrig

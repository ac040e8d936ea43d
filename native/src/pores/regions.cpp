// Pore network extraction: the watershed regions of the distance transform, and the pores' and throats' measures.
#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <utility>

#include "pores_internal.hpp"

namespace volrig::pores_detail {

namespace {

/// The flood's queue: one bucket a level (the DT in 1/16 of the finest spacing), the highest level first and each
/// bucket first in, first out (breadth first, so seeds on one plateau grow alike). 8 bytes a queued voxel; a
/// drained bucket's memory is freed. Index: the voxels' index type (32 bits where the grid allows: half the memory).
template <class Index>
class FloodQueue {
public:
    explicit FloodQueue(double finest) : scale_(16.0 / finest) {}
    int level_of(float d) const { return static_cast<int>(std::lround(static_cast<double>(d) * scale_)); }
    /// Queues voxel v at `level` (at most the level being drained, once draining has begun).
    void push(int level, std::int64_t v) {
        if (static_cast<std::size_t>(level) >= buckets_.size()) buckets_.resize(static_cast<std::size_t>(level) + 1);
        buckets_[static_cast<std::size_t>(level)].push_back(static_cast<Index>(v));
        top_ = std::max(top_, level);
    }
    /// The next voxel and its level; false when the queue is empty.
    bool pop(int& level, std::int64_t& v) {
        while (top_ >= 0) {
            auto& b = buckets_[static_cast<std::size_t>(top_)];
            if (head_ < b.size()) {
                v = b[head_++];
                level = top_;
                return true;
            }
            std::vector<Index>().swap(b);
            head_ = 0;
            --top_;
        }
        return false;
    }

private:
    double scale_;
    std::vector<std::vector<Index>> buckets_;
    int top_ = -1;
    std::size_t head_ = 0;
};

/// The 6 face neighbours of voxel i inside the grid, as f(neighbour).
template <class F>
void face_neighbours(const Grid& g, std::int64_t i, F&& f) {
    const std::int64_t nx = g.dims[0], nxy = g.dims[0] * g.dims[1];
    const std::int64_t x = i % nx, y = (i / nx) % g.dims[1], z = i / nxy;
    if (x > 0) f(i - 1);
    if (x + 1 < g.dims[0]) f(i + 1);
    if (y > 0) f(i - nx);
    if (y + 1 < g.dims[1]) f(i + nx);
    if (z > 0) f(i - nxy);
    if (z + 1 < g.dims[2]) f(i + nxy);
}

/// Floods from the items queued, each voxel taking the label of the voxel it was reached from.
template <class Queue>
void flood(const PoreSpace& dt, Regions& regions, Queue& queue, std::int64_t& done, const Progress& progress) {
    const double total = static_cast<double>(dt.index.count());
    int level = 0;
    std::int64_t i = 0;
    while (queue.pop(level, i)) {
        const std::int32_t label = regions.at(i);
        face_neighbours(dt.grid, i, [&](std::int64_t j) {
            if (!dt.index.pore(j)) return;
            const auto r = static_cast<std::size_t>(dt.index.rank(j));
            if (regions.labels[r] != 0) return;
            regions.labels[r] = label;
            queue.push(std::min(level, queue.level_of(dt.dt[r])), j);
        });
        if ((++done & ((std::int64_t{1} << 20) - 1)) == 0) report(progress, static_cast<double>(done) / total);
    }
}

struct PoreAcc {
    std::int64_t count = 0;
    double sum[3] = {0, 0, 0};
    float peak = 0;
    std::uint8_t faces = 0;
};

struct ThroatAcc {
    float peak = -1;
    double at[3] = {0, 0, 0};
    std::int64_t faces = 0;
};

/// World coordinate of voxel index i's centre along axis a.
inline double centre(const Grid& g, std::int64_t i, int a) {
    return g.origin[a] + (static_cast<double>(i) + 0.5) * g.spacing[a];
}

/// Adds voxel (x, y, z) of label l to its pore.
void add_pore_voxel(const Grid& g, PoreAcc& p, std::int64_t x, std::int64_t y, std::int64_t z, float d) {
    ++p.count;
    p.sum[0] += static_cast<double>(x);
    p.sum[1] += static_cast<double>(y);
    p.sum[2] += static_cast<double>(z);
    p.peak = std::max(p.peak, d);
    if (x == 0) p.faces |= XMin;
    if (x + 1 == g.dims[0]) p.faces |= XMax;
    if (y == 0) p.faces |= YMin;
    if (y + 1 == g.dims[1]) p.faces |= YMax;
    if (z == 0) p.faces |= ZMin;
    if (z + 1 == g.dims[2]) p.faces |= ZMax;
}

/// Adds the face between voxel i (label a, at x, y, z) and its neighbour along axis `axis` (label b) to their throat.
void add_interface(const Grid& g, std::unordered_map<std::uint64_t, ThroatAcc>& throats, std::int32_t a, std::int32_t b,
                   const std::int64_t (&xyz)[3], int axis, float d) {
    const auto lo = static_cast<std::uint64_t>(std::min(a, b)), hi = static_cast<std::uint64_t>(std::max(a, b));
    ThroatAcc& t = throats[(lo << 32) | hi];
    ++t.faces;
    if (d <= t.peak) return;
    t.peak = d;
    for (int k = 0; k < 3; ++k) t.at[k] = centre(g, xyz[k], k) + (k == axis ? 0.5 * g.spacing[k] : 0.0);
}

/// Fills the network's pore arrays from the accumulators.
void fill_pores(const Grid& g, const std::vector<PoreAcc>& acc, PoreNetwork& net) {
    const double voxel = g.spacing[0] * g.spacing[1] * g.spacing[2];
    for (const PoreAcc& p : acc) {
        const double c = static_cast<double>(std::max<std::int64_t>(p.count, 1));
        for (int a = 0; a < 3; ++a) net.pore_coords.push_back(g.origin[a] + (p.sum[a] / c + 0.5) * g.spacing[a]);
        net.pore_inscribed.push_back(2.0 * p.peak);
        net.pore_volume.push_back(static_cast<double>(p.count) * voxel);
        net.pore_faces.push_back(p.faces);
    }
}

/// Fills the network's throat arrays from the accumulators, in order of their pores.
void fill_throats(const Grid& g, const std::unordered_map<std::uint64_t, ThroatAcc>& throats, PoreNetwork& net) {
    std::vector<std::uint64_t> keys;
    keys.reserve(throats.size());
    for (const auto& kv : throats) keys.push_back(kv.first);
    std::sort(keys.begin(), keys.end());
    for (const std::uint64_t k : keys) {
        const ThroatAcc& t = throats.at(k);
        const auto a = static_cast<std::int32_t>(k >> 32) - 1, b = static_cast<std::int32_t>(k & 0xffffffffu) - 1;
        net.throat_conns.push_back(a);
        net.throat_conns.push_back(b);
        net.throat_inscribed.push_back(2.0 * t.peak);
        double la = 0, lb = 0;
        for (int c = 0; c < 3; ++c) {
            net.throat_coords.push_back(t.at[c]);
            la += std::pow(net.pore_coords[3 * static_cast<std::size_t>(a) + c] - t.at[c], 2);
            lb += std::pow(net.pore_coords[3 * static_cast<std::size_t>(b) + c] - t.at[c], 2);
        }
        net.throat_total_length.push_back(std::sqrt(la) + std::sqrt(lb));
        // Faces normal to x, y and z count alike: exact on isotropic grids, a mean face elsewhere.
        const double face =
            (g.spacing[0] * g.spacing[1] + g.spacing[1] * g.spacing[2] + g.spacing[0] * g.spacing[2]) / 3;
        net.throat_area.push_back(static_cast<double>(t.faces) * face);
    }
}

}  // namespace

/// flood_regions with voxel indices of type Index in the queue.
template <class Index>
Regions flood_with(const PoreSpace& dt, std::vector<std::int64_t>& seeds, const Progress& progress) {
    const std::int64_t n = dt.grid.voxel_count();
    if (seeds.size() >= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
        throw Error("pore_network: too many pores");
    Regions regions;
    regions.index = &dt.index;
    regions.labels.assign(static_cast<std::size_t>(dt.index.count()), 0);
    FloodQueue<Index> queue(dt.grid.min_spacing());
    std::int64_t done = 0;
    for (std::size_t s = 0; s < seeds.size(); ++s) {
        regions.at(seeds[s]) = static_cast<std::int32_t>(s + 1);
        queue.push(queue.level_of(dt[seeds[s]]), seeds[s]);
    }
    flood(dt, regions, queue, done, progress);
    // Pore voxels no seed reached (a 6-connected bit whose maximum lay in another bit's ball): new regions.
    for (std::int64_t i = 0; i < n; ++i) {
        if (!dt.index.pore(i) || regions.at(i) != 0) continue;
        if (seeds.size() + 1 >= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
            throw Error("pore_network: too many pores");
        seeds.push_back(i);
        regions.at(i) = static_cast<std::int32_t>(seeds.size());
        queue.push(queue.level_of(dt[i]), i);
        flood(dt, regions, queue, done, progress);
    }
    return regions;
}

Regions flood_regions(const PoreSpace& dt, std::vector<std::int64_t>& seeds, const Progress& progress) {
    if (dt.grid.voxel_count() <= static_cast<std::int64_t>(std::numeric_limits<std::uint32_t>::max()))
        return flood_with<std::uint32_t>(dt, seeds, progress);
    return flood_with<std::int64_t>(dt, seeds, progress);
}

PoreNetwork measure_network(const PoreSpace& dt, const Regions& regions, std::size_t pores) {
    const Grid& g = dt.grid;
    std::vector<PoreAcc> acc(pores);
    std::unordered_map<std::uint64_t, ThroatAcc> throats;
    const std::int64_t step[3] = {1, g.dims[0], g.dims[0] * g.dims[1]};
    for (std::int64_t z = 0; z < g.dims[2]; ++z)
        for (std::int64_t y = 0; y < g.dims[1]; ++y)
            for (std::int64_t x = 0; x < g.dims[0]; ++x) {
                const std::int64_t i = g.index(x, y, z);
                if (!dt.index.pore(i)) continue;
                const auto r = static_cast<std::size_t>(dt.index.rank(i));
                const std::int32_t a = regions.labels[r];
                const float d = dt.dt[r];
                add_pore_voxel(g, acc[static_cast<std::size_t>(a - 1)], x, y, z, d);
                const std::int64_t xyz[3] = {x, y, z};
                for (int axis = 0; axis < 3; ++axis) {
                    if (xyz[axis] + 1 >= g.dims[axis] || !dt.index.pore(i + step[axis])) continue;
                    const auto rb = static_cast<std::size_t>(dt.index.rank(i + step[axis]));
                    const std::int32_t b = regions.labels[rb];
                    if (b != a) add_interface(g, throats, a, b, xyz, axis, std::min(d, dt.dt[rb]));
                }
            }
    PoreNetwork net;
    fill_pores(g, acc, net);
    fill_throats(g, throats, net);
    return net;
}

std::vector<std::int32_t> dense_labels(const PoreSpace& dt, const Regions& regions) {
    std::vector<std::int32_t> out(static_cast<std::size_t>(dt.grid.voxel_count()), 0);
    std::size_t r = 0;
    for (std::int64_t i = 0; i < dt.grid.voxel_count(); ++i)
        if (dt.index.pore(i)) out[static_cast<std::size_t>(i)] = regions.labels[r++];
    return out;
}

}  // namespace volrig::pores_detail

// skin: weights of surface points by geodesic distance through the object (see volrig/skin.hpp).
#include "volrig/skin.hpp"

#include "common/neighbourhood.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <string>
#include <unordered_map>
#include <utility>

namespace volrig {

namespace {

using Vec3 = std::array<double, 3>;
constexpr float kInf = std::numeric_limits<float>::infinity();

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }

/// Distance from p to the segment a-b.
double segment_distance(const Vec3& p, const Vec3& a, const Vec3& b) {
    const Vec3 ab = sub(b, a), ap = sub(p, a);
    const double len2 = dot(ab, ab);
    const double t = len2 > 0 ? std::clamp(dot(ap, ab) / len2, 0.0, 1.0) : 0.0;
    return norm(sub(ap, {ab[0] * t, ab[1] * t, ab[2] * t}));
}

constexpr int kMaxInfluences = 4;

/// One object voxel's labels in one cache line: its nearest bones settled so far (nearest first), and the pushes
/// made to it (bone, distance): a push no shorter than one made for the same bone is skipped (when all kTried are
/// taken the longest is replaced; skipping less only costs time).
struct alignas(64) Cell {
    static constexpr int kTried = 6;
    std::int16_t bone[kMaxInfluences];
    float dist[kMaxInfluences];
    std::int16_t tried_bone[kTried];
    float tried_dist[kTried];
    std::uint8_t filled = 0;

    Cell() {
        std::fill(std::begin(bone), std::end(bone), std::int16_t{-1});
        std::fill(std::begin(tried_bone), std::end(tried_bone), std::int16_t{-1});
        std::fill(std::begin(dist), std::end(dist), kInf);
        std::fill(std::begin(tried_dist), std::end(tried_dist), kInf);
    }
    bool has(std::int16_t b) const {
        for (int s = 0; s < filled; ++s)
            if (bone[s] == b) return true;
        return false;
    }
    /// Records a push of bone b at distance d; false when one at most as long was made already.
    bool try_push(std::int16_t b, float d) {
        int worst = 0;
        for (int s = 0; s < kTried; ++s) {
            if (tried_bone[s] == b) {
                if (tried_dist[s] <= d) return false;
                tried_dist[s] = d;
                return true;
            }
            if (tried_bone[s] < 0) {
                worst = s;
                break;
            }
            if (tried_dist[s] > tried_dist[worst]) worst = s;
        }
        if (tried_bone[worst] < 0 || tried_dist[worst] > d) {  // keep the shorter pushes on record
            tried_bone[worst] = b;
            tried_dist[worst] = d;
        }
        return true;
    }
};

/// The object voxels, numbered densely, and each one's `k` nearest bones.
struct Labels {
    const Grid& g;
    std::vector<std::int32_t> id;      // per grid voxel: dense number, or -1 outside the object
    std::vector<std::int64_t> voxel;   // per dense number: linear grid index
    int k;
    std::vector<Cell> cell;

    Labels(const Grid& grid, const std::uint8_t* mask, int k_) : g(grid), k(k_) {
        id.assign(static_cast<std::size_t>(g.voxel_count()), -1);
        // numbered brick by brick (8³ voxels), so that a voxel's neighbours mostly lie within a few cache lines
        constexpr std::int64_t kBrick = 8;
        for (std::int64_t bz = 0; bz < g.dims[2]; bz += kBrick)
            for (std::int64_t by = 0; by < g.dims[1]; by += kBrick)
                for (std::int64_t bx = 0; bx < g.dims[0]; bx += kBrick)
                    for (std::int64_t z = bz; z < std::min(bz + kBrick, g.dims[2]); ++z)
                        for (std::int64_t y = by; y < std::min(by + kBrick, g.dims[1]); ++y)
                            for (std::int64_t x = bx; x < std::min(bx + kBrick, g.dims[0]); ++x) {
                                const std::int64_t i = g.index(x, y, z);
                                if (!mask[i]) continue;
                                if (voxel.size() >= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
                                    throw Error("skin_weights: too many object voxels");
                                id[static_cast<std::size_t>(i)] = static_cast<std::int32_t>(voxel.size());
                                voxel.push_back(i);
                            }
        if (voxel.empty()) throw Error("skin_weights: the mask is empty");
        cell.resize(voxel.size());
    }
    /// Whether voxel v can still take bone b (fewer than k bones settled, b not among them).
    bool open(std::int32_t v, std::int16_t b) const {
        const Cell& c = cell[static_cast<std::size_t>(v)];
        return c.filled < k && !c.has(b);
    }
    /// Dense number of voxel (x, y, z), or -1 outside the grid or the object.
    std::int32_t at(std::int64_t x, std::int64_t y, std::int64_t z) const {
        if (x < 0 || y < 0 || z < 0 || x >= g.dims[0] || y >= g.dims[1] || z >= g.dims[2]) return -1;
        return id[static_cast<std::size_t>(g.index(x, y, z))];
    }
    std::array<std::int64_t, 3> xyz(std::int32_t v) const {
        const std::int64_t i = voxel[static_cast<std::size_t>(v)];
        return {i % g.dims[0], (i / g.dims[0]) % g.dims[1], i / (g.dims[0] * g.dims[1])};
    }
    Vec3 centre(std::int32_t v) const {
        const auto c = xyz(v);
        return {g.origin[0] + g.spacing[0] * static_cast<double>(c[0]), g.origin[1] + g.spacing[1] * static_cast<double>(c[1]),
                g.origin[2] + g.spacing[2] * static_cast<double>(c[2])};
    }
};

struct Entry {
    float d;
    std::int32_t v;
    std::int16_t b;
    bool operator>(const Entry& o) const { return d > o.d; }
};
using Heap = std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>>;

Vec3 joint(const Rig& rig, std::size_t b, int end) {
    return rig.joints[static_cast<std::size_t>(rig.bones[b][static_cast<std::size_t>(end)])];
}

/// Bone b's sources: the object voxels its segment crosses (sampled every quarter voxel), at their distance to the
/// segment; the object voxel nearest its midpoint when it crosses none.
void push_sources(Labels& L, const Rig& rig, std::size_t b, Heap& heap) {
    const Grid& g = L.g;
    const Vec3 h = joint(rig, b, 0), t = joint(rig, b, 1);
    double steps = 0;
    for (int a = 0; a < 3; ++a) steps = std::max(steps, std::abs(t[a] - h[a]) / g.spacing[a]);
    const auto n = static_cast<std::int64_t>(std::ceil(steps * 4)) + 1;
    std::unordered_map<std::int32_t, float> near;
    for (std::int64_t s = 0; s <= n; ++s) {
        const double f = static_cast<double>(s) / static_cast<double>(n);
        std::array<std::int64_t, 3> q{};
        for (int a = 0; a < 3; ++a) q[a] = std::llround((h[a] + f * (t[a] - h[a]) - g.origin[a]) / g.spacing[a]);
        const std::int32_t v = L.at(q[0], q[1], q[2]);
        if (v >= 0 && !near.count(v)) near[v] = static_cast<float>(segment_distance(L.centre(v), h, t));
    }
    if (near.empty()) {  // a bone outside the object: start from the object voxel nearest its midpoint
        const Vec3 mid{(h[0] + t[0]) / 2, (h[1] + t[1]) / 2, (h[2] + t[2]) / 2};
        double best = std::numeric_limits<double>::infinity();
        std::int32_t arg = 0;
        for (std::int32_t v = 0; v < static_cast<std::int32_t>(L.voxel.size()); ++v) {
            const double d = norm(sub(L.centre(v), mid));
            if (d < best) best = d, arg = v;
        }
        near[arg] = static_cast<float>(segment_distance(L.centre(arg), h, t));
    }
    const auto bone = static_cast<std::int16_t>(b);
    for (const auto& [v, d] : near)
        if (L.cell[static_cast<std::size_t>(v)].try_push(bone, d)) heap.push({d, v, bone});
}

/// Step 2: every object voxel's k nearest bones along paths inside the object.
void nearest_bones(Labels& L, const Rig& rig, const Progress& progress) {
    Heap heap;
    for (std::size_t b = 0; b < rig.bones.size(); ++b) push_sources(L, rig, b, heap);
    std::array<float, 26> len{};
    for (std::size_t k = 0; k < 26; ++k) {
        const auto& o = common_detail::kOffsets[k];
        const double x = o.dx * L.g.spacing[0], y = o.dy * L.g.spacing[1], z = o.dz * L.g.spacing[2];
        len[k] = static_cast<float>(std::sqrt(x * x + y * y + z * z));
    }
    const double total = static_cast<double>(L.voxel.size()) * L.k;
    std::size_t settled = 0;
    while (!heap.empty()) {
        const Entry e = heap.top();
        heap.pop();
        if (!L.open(e.v, e.b)) continue;
        Cell& c = L.cell[static_cast<std::size_t>(e.v)];
        c.bone[c.filled] = e.b;
        c.dist[c.filled++] = e.d;
        if ((++settled & 0xffff) == 0) report(progress, 0.8 * static_cast<double>(settled) / total);
        const auto at = L.xyz(e.v);
        for (std::size_t s = 0; s < 26; ++s) {
            const auto& o = common_detail::kOffsets[s];
            const std::int32_t n = L.at(at[0] + o.dx, at[1] + o.dy, at[2] + o.dz);
            const float d = e.d + len[s];
            if (n >= 0 && L.open(n, e.b) && L.cell[static_cast<std::size_t>(n)].try_push(e.b, d)) heap.push({d, n, e.b});
        }
    }
}

/// Step 3: each bone's distance to point p (bone -> distance), from the object voxels around it; empty when no
/// object voxel lies within three voxels.
std::vector<std::pair<std::int32_t, double>> point_distances(const Labels& L, const Vec3& p) {
    const Grid& g = L.g;
    std::array<double, 3> c{};
    for (int a = 0; a < 3; ++a) c[a] = (p[a] - g.origin[a]) / g.spacing[a];
    std::vector<std::pair<std::int32_t, double>> out;
    auto add = [&](std::int32_t v) {
        const double off = norm(sub(p, L.centre(v)));
        const Cell& cell = L.cell[static_cast<std::size_t>(v)];
        for (int s = 0; s < cell.filled; ++s) {
            const std::int32_t b = cell.bone[s];
            const double d = cell.dist[s] + off;
            auto it = std::find_if(out.begin(), out.end(), [b](const auto& x) { return x.first == b; });
            if (it == out.end()) out.emplace_back(b, d);
            else it->second = std::min(it->second, d);
        }
    };
    const std::int64_t x0 = static_cast<std::int64_t>(std::floor(c[0])), y0 = static_cast<std::int64_t>(std::floor(c[1])),
                       z0 = static_cast<std::int64_t>(std::floor(c[2]));
    for (std::int64_t r = 0; r <= 3 && out.empty(); ++r)  // the cell's corners, then cubes of growing radius
        for (std::int64_t z = z0 - r; z <= z0 + 1 + r; ++z)
            for (std::int64_t y = y0 - r; y <= y0 + 1 + r; ++y)
                for (std::int64_t x = x0 - r; x <= x0 + 1 + r; ++x) {
                    const std::int32_t v = L.at(x, y, z);
                    if (v >= 0) add(v);
                }
    return out;
}

/// Each bone's radius: the median distance to it of the surface voxels (object voxels with a background or
/// grid-border 6-neighbour) it is nearest to; infinite for a bone nearest to none.
std::vector<double> bone_radii(const Labels& L, std::size_t bones) {
    std::vector<std::vector<float>> near(bones);
    for (std::int32_t v = 0; v < static_cast<std::int32_t>(L.voxel.size()); ++v) {
        const Cell& c = L.cell[static_cast<std::size_t>(v)];
        if (!c.filled) continue;
        const auto p = L.xyz(v);
        const bool surface = L.at(p[0] - 1, p[1], p[2]) < 0 || L.at(p[0] + 1, p[1], p[2]) < 0 ||
                             L.at(p[0], p[1] - 1, p[2]) < 0 || L.at(p[0], p[1] + 1, p[2]) < 0 ||
                             L.at(p[0], p[1], p[2] - 1) < 0 || L.at(p[0], p[1], p[2] + 1) < 0;
        if (surface) near[static_cast<std::size_t>(c.bone[0])].push_back(c.dist[0]);
    }
    std::vector<double> radius(bones, std::numeric_limits<double>::infinity());
    for (std::size_t b = 0; b < bones; ++b) {
        auto& d = near[b];
        if (d.empty()) continue;
        std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
        radius[b] = d[d.size() / 2];
    }
    return radius;
}

/// Step 4: the falloff across joints, the `influences` heaviest kept, normalised. A bone's falloff is measured in
/// the smaller of the point's nearest distance and the bone's own radius: a thin limb blends into the thick trunk
/// over its own width, not the trunk's.
std::vector<std::pair<std::int32_t, double>> falloff(std::vector<std::pair<std::int32_t, double>> d,
                                                     const SkinOptions& o, const std::vector<double>& radius,
                                                     double floor_distance) {
    double d0 = std::numeric_limits<double>::infinity();
    for (const auto& x : d) d0 = std::min(d0, x.second);
    for (auto& x : d) {
        const double scale = std::max(std::min(d0, radius[static_cast<std::size_t>(x.first)]), floor_distance);
        const double t = 1.0 - (x.second - d0) / scale / o.blend;
        x.second = t > 0 ? t * t : 0.0;
    }
    std::stable_sort(d.begin(), d.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
    while (!d.empty() && (d.size() > static_cast<std::size_t>(o.influences) || d.back().second <= 0)) d.pop_back();
    double sum = 0;
    for (const auto& x : d) sum += x.second;
    for (auto& x : d) x.second /= sum;
    return d;
}

void check_options(const SkinOptions& o, const std::vector<Vec3>& points) {
    if (o.influences < 1 || o.influences > kMaxInfluences)
        throw Error("skin_weights: influences must lie in 1.." + std::to_string(kMaxInfluences));
    if (!(std::isfinite(o.blend) && o.blend > 0 && o.blend <= 100)) throw Error("skin_weights: blend must lie in (0, 100]");
    for (const auto& p : points)
        if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])))
            throw Error("skin_weights: the points must be finite");
}

}  // namespace

SkinWeights skin_weights(const Grid& grid, const std::uint8_t* mask, const Rig& rig, const std::vector<Vec3>& points,
                         const SkinOptions& options, const Progress& progress) {
    check_rig(rig);
    check_options(options, points);
    if (rig.bones.size() > 32767) throw Error("skin_weights: more than 32767 bones");
    Labels L(grid, mask, std::min<int>(options.influences, static_cast<int>(rig.bones.size())));
    nearest_bones(L, rig, progress);
    const double floor_distance = 0.5 * grid.min_spacing();
    const std::vector<double> radius = bone_radii(L, rig.bones.size());
    std::vector<std::vector<std::pair<std::int32_t, double>>> rows(points.size());
    std::vector<std::uint8_t> outside(points.size(), 0);
    tbb::parallel_for(std::size_t{0}, points.size(), [&](std::size_t i) {
        auto d = point_distances(L, points[i]);
        if (d.empty()) {  // far from the object: straight distances to the bones
            outside[i] = 1;
            for (std::size_t b = 0; b < rig.bones.size(); ++b)
                d.emplace_back(static_cast<std::int32_t>(b), segment_distance(points[i], joint(rig, b, 0), joint(rig, b, 1)));
        }
        rows[i] = falloff(std::move(d), options, radius, floor_distance);
    });
    report(progress, 0.95);
    SkinWeights out;
    out.indptr.reserve(points.size() + 1);
    out.indptr.push_back(0);
    for (const auto& r : rows) {
        for (const auto& [b, w] : r) {
            out.bone.push_back(b);
            out.weight.push_back(static_cast<float>(w));
        }
        out.indptr.push_back(static_cast<std::int64_t>(out.bone.size()));
    }
    out.outside = std::move(outside);
    report(progress, 1.0);
    return out;
}

}  // namespace volrig

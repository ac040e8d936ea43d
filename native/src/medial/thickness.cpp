#include "volrig/thickness.hpp"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <deque>
#include <limits>
#include <memory>
#include <unordered_map>

#include "common/ball_scan.hpp"
#include "volrig/distance.hpp"

namespace volrig {

namespace {

struct Neighbour {
    std::int64_t dx, dy, dz;
    std::int64_t offset;  // linear index step
    double length;        // world units
};

std::vector<Neighbour> neighbours26(const Grid& g) {
    std::vector<Neighbour> out;
    for (std::int64_t dz = -1; dz <= 1; ++dz)
        for (std::int64_t dy = -1; dy <= 1; ++dy)
            for (std::int64_t dx = -1; dx <= 1; ++dx) {
                if (dx == 0 && dy == 0 && dz == 0) continue;
                const double l2 = double(dx * dx) * g.spacing[0] * g.spacing[0] +
                                  double(dy * dy) * g.spacing[1] * g.spacing[1] +
                                  double(dz * dz) * g.spacing[2] * g.spacing[2];
                out.push_back({dx, dy, dz, (dz * g.dims[1] + dy) * g.dims[0] + dx, std::sqrt(l2)});
            }
    return out;
}

/// The lattice shape of the open ball of one radius: the half-width of each row (dy, dz >= 0; the ball is
/// symmetric), exactly as painting sees it (common_detail::row_half_width), and the farthest lattice point's distance.
struct BallProfile {
    std::vector<std::int64_t> start;  ///< per dz: offset of its rows in `width` (dz = 0 .. hz, one past the end)
    std::vector<std::int64_t> width;  ///< row half-widths, dy = 0 .. rows of that dz - 1
    double reach = 0.0;               ///< distance of the farthest lattice point inside

    std::int64_t hz() const { return static_cast<std::int64_t>(start.size()) - 2; }
    /// Half-width of row (dy, dz) (any signs), -1 outside the ball.
    std::int64_t at(std::int64_t dy, std::int64_t dz) const {
        dy = dy < 0 ? -dy : dy;
        dz = dz < 0 ? -dz : dz;
        if (dz > hz()) return -1;
        const std::int64_t i = start[static_cast<std::size_t>(dz)] + dy;
        return i < start[static_cast<std::size_t>(dz) + 1] ? width[static_cast<std::size_t>(i)] : -1;
    }
};

/// The rows of a ball of radius r as seen from inside the grid: no deeper than the grid has slices (a thin slab
/// or one image, where balls are discs, needs only those rows). A clipped ball's reach is r (an upper bound: tests
/// that use it stay true), and containment past the clip reads "outside" (containments are missed, never invented).
BallProfile profile_of(double r, const Grid& g) {
    const double lim = open_ball_limit_sq(r);
    const auto& sp = g.spacing;
    BallProfile b;
    double far = 0.0;
    const std::int64_t full = ball_half_extent(r, sp[2], Metric::Euclidean);
    const std::int64_t hz = std::min(full, g.dims[2] - 1);
    if (hz < full) far = r * r;
    for (std::int64_t dz = 0; dz <= hz; ++dz) {
        b.start.push_back(static_cast<std::int64_t>(b.width.size()));
        for (std::int64_t dy = 0;; ++dy) {
            const std::int64_t w = common_detail::row_half_width(Metric::Euclidean, r, lim, dy, dz, sp);
            if (w < 0) break;
            b.width.push_back(w);
            far = std::max(far, double(w * w) * sp[0] * sp[0] + double(dy * dy) * sp[1] * sp[1] +
                                    double(dz * dz) * sp[2] * sp[2]);
        }
    }
    b.start.push_back(static_cast<std::int64_t>(b.width.size()));
    b.reach = std::sqrt(far);
    return b;
}

/// True when every lattice point of ball `in`, centred `o` voxels (x, y, z) from the centre of ball `out`, lies
/// in `out`: row by row, the run [o_x - w, o_x + w] within out's row at (dy + o_y, dz + o_z). Exact: the same
/// integer rows painting uses.
bool contains(const BallProfile& out, const BallProfile& in, const std::array<std::int64_t, 3>& o) {
    const std::int64_t ox = o[0] < 0 ? -o[0] : o[0];
    for (std::int64_t dz = -in.hz(); dz <= in.hz(); ++dz) {
        const std::size_t a = static_cast<std::size_t>(dz < 0 ? -dz : dz);
        const std::int64_t rows = in.start[a + 1] - in.start[a];
        for (std::int64_t dy = 1 - rows; dy < rows; ++dy)
            if (in.at(dy, dz) + ox > out.at(dy + o[1], dz + o[2])) return false;
    }
    return true;
}

/// A hash of floats (std::hash<float> hashes the bytes, slowly).
struct FloatHash {
    std::size_t operator()(float f) const {
        std::uint32_t u = 0;
        std::memcpy(&u, &f, sizeof u);
        return static_cast<std::size_t>(u * 0x9E3779B97F4A7C15ull >> 20);
    }
};

/// Numbers for floats, in the order first met; a volume's DT values repeat, so a direct-mapped table of the recent
/// ones answers most before the hash map.
class FloatIds {
public:
    std::size_t operator()(float r) {
        std::uint32_t bits = 0;
        std::memcpy(&bits, &r, sizeof bits);
        Recent& hit = recent_[(bits * 0x9E3779B1u) >> 24];
        if (hit.id != kNone && hit.r == r) return hit.id;
        const std::size_t id = ids_.try_emplace(r, values_.size()).first->second;
        if (id == values_.size()) values_.push_back(r);
        hit = {r, id};
        return id;
    }
    const std::vector<float>& values() const { return values_; }

private:
    static constexpr std::size_t kNone = ~std::size_t(0);
    struct Recent {
        float r = 0.0f;
        std::size_t id = kNone;
    };
    std::array<Recent, 256> recent_{};  // (indexed by the top byte of a multiplicative hash)
    std::unordered_map<float, std::size_t, FloatHash> ids_;
    std::vector<float> values_;
};

/// BallProfiles of the DT values met, per thread (a volume holds few distinct DT values), and the answers of the
/// row test (contains) asked so far: a volume asks the same few (radius, radius, offset) questions again and again.
class ProfileCache {
public:
    explicit ProfileCache(const Grid& g) : g_(g) {}
    double reach(float r) { return profiles_[id(r)].reach; }

    /// contains(profile of r_out, profile of r_in, o), remembered.
    bool holds(float r_out, float r_in, const std::array<std::int64_t, 3>& o) {
        const std::uint64_t a = id(r_out), b = id(r_in);
        if (a >= (1u << 20) || b >= (1u << 20)) return contains(profiles_[a], profiles_[b], o);  // (not remembered)
        std::uint64_t key = a << 44 | b << 24;  // offsets are at most 64 voxels (the climb's length) on each axis
        for (int i = 0; i < 3; ++i) key |= static_cast<std::uint64_t>(o[static_cast<std::size_t>(i)] + 128) << (8 * i);
        auto [it, fresh] = answers_.try_emplace(key, false);
        if (fresh) it->second = contains(profiles_[a], profiles_[b], o);
        return it->second;
    }

private:
    std::size_t id(float r) {
        const std::size_t i = ids_(r);
        if (i == profiles_.size()) profiles_.push_back(profile_of(r, g_));
        return i;
    }

    const Grid& g_;
    FloatIds ids_;
    std::deque<BallProfile> profiles_;  // (references stay valid as it grows)
    std::unordered_map<std::uint64_t, bool> answers_;
};

// Per voxel, the first pass of thickness_centres leaves: its steepest rising 26-neighbour (an index into
// neighbours26, kTop when none rises) and kHeld when a neighbour's ball holds its ball (or it is background).
constexpr std::uint8_t kTop = 0x7F, kHeld = 0x80;

/// Scratch for one row segment of the first pass.
struct Slack {
    std::vector<float> best;        ///< the largest DT(u)·kappa - |u - v| over the rising neighbours u, -inf if none
    std::vector<std::int32_t> dir;  ///< the neighbour it came from (kTop if none)
};

/// For the voxels x0 .. x1 - 1 of row (y, z), fills `s` (indexed by x): over the 26-neighbours u of v with a larger
/// DT, the largest DT(u)·kappa - |u - v| and its neighbour, where kappa^2 = (1 - 5e-7)(1 - 1e-12). v's ball lies
/// in u's when its farthest lattice point (reach) is nearer v than that: the triangle test of held_up_the_climb.
/// In float and branch-free (vectorised), so the caller keeps a margin: float's rounding here is below 5e-7 of
/// reach + step. The neighbour with the most is also the steepest ascent's next step.
void rising_neighbours(const Grid& g, const float* dt, std::int64_t y, std::int64_t z, std::int64_t x0,
                       std::int64_t x1, const std::vector<Neighbour>& nb, Slack& s) {
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    const float* row = dt + g.index(0, y, z);
    const auto kappa = static_cast<float>(std::sqrt((1.0 - 5e-7) * (1.0 - 1e-12)));
    float* best = s.best.data();
    std::int32_t* dir = s.dir.data();
    std::fill(best + x0, best + x1, -std::numeric_limits<float>::infinity());
    std::fill(dir + x0, dir + x1, std::int32_t{kTop});
    // Three neighbours at a time: those in one row (dx = -1, 0, 1). In v's own row the middle one is v itself,
    // which never rises above itself.
    for (std::size_t i = 0; i < nb.size(); ++i) {
        const Neighbour& n = nb[i];
        if (n.dx != -1 || y + n.dy < 0 || y + n.dy >= ny || z + n.dz < 0 || z + n.dz >= g.dims[2]) continue;
        const float* other = dt + g.index(0, y + n.dy, z + n.dz);
        const bool own = n.dy == 0 && n.dz == 0;
        const std::array<std::int32_t, 3> id{static_cast<std::int32_t>(i), static_cast<std::int32_t>(own ? i : i + 1),
                                             static_cast<std::int32_t>(own ? i + 1 : i + 2)};
        const std::array<float, 3> len{static_cast<float>(n.length), static_cast<float>(nb[id[1]].length),
                                       static_cast<float>(nb[id[2]].length)};
        const auto rise = [&](std::int64_t x, std::int64_t dx, float& b, std::int32_t& d) {
            const float u = other[x + dx], slack = u * kappa - len[static_cast<std::size_t>(dx + 1)];
            const bool more = (u > row[x]) & (slack > b);
            b = more ? slack : b;
            d = more ? id[static_cast<std::size_t>(dx + 1)] : d;
        };
        for (std::int64_t x = std::max<std::int64_t>(x0, 1); x < std::min(x1, nx - 1); ++x) {  // (vectorised)
            float b = best[x];
            std::int32_t d = dir[x];
            rise(x, -1, b, d);
            rise(x, 0, b, d);
            rise(x, 1, b, d);
            best[x] = b;
            dir[x] = d;
        }
        for (const std::int64_t x : {std::int64_t{0}, nx - 1}) {  // the row's ends: neighbours within the grid
            if (x >= x0 && x < x1)
                for (std::int64_t dx = -1; dx <= 1; ++dx)
                    if (x + dx >= 0 && x + dx < nx) rise(x, dx, best[x], dir[x]);
            if (nx == 1) break;  // (one voxel: both ends)
        }
    }
}

/// The first x >= from with row[x] > 0, or nx (eight voxels at a time through the background).
std::int64_t next_object(const float* row, std::int64_t from, std::int64_t nx) {
    for (; from + 8 <= nx; from += 8) {
        bool any = false;
        for (std::int64_t i = 0; i < 8; ++i) any |= row[from + i] > 0;
        if (any) break;
    }
    while (from < nx && !(row[from] > 0)) ++from;
    return from;
}

/// The first pass over row (y, z): up[v] for each of its voxels (see kTop, kHeld); the object voxels not held are
/// appended to `open`.
void mark_row(const Grid& g, const float* dt, std::int64_t y, std::int64_t z, const std::vector<Neighbour>& nb,
              double step, ProfileCache& balls, Slack& s, std::uint8_t* up, std::vector<std::int64_t>& open) {
    const std::int64_t nx = g.dims[0], at = g.index(0, y, z);
    const float* row = dt + at;
    std::fill(up + at, up + at + nx, std::uint8_t{kHeld | kTop});
    for (std::int64_t x0 = 0; x0 < nx;) {  // segments of object voxels, across gaps of up to 8 voxels
        x0 = next_object(row, x0, nx);
        std::int64_t x1 = x0;
        for (std::int64_t x = x0; x < nx && x - x1 <= 8; ++x)
            if (row[x] > 0) x1 = x + 1;
        if (x0 == x1) break;
        rising_neighbours(g, dt, y, z, x0, x1, nb, s);
        for (std::int64_t x = x0; x < x1; ++x) {
            if (!(row[x] > 0)) continue;
            const double reach = balls.reach(row[x]);
            const bool held = s.best[static_cast<std::size_t>(x)] > reach + 1e-6 * (reach + step);
            up[at + x] = static_cast<std::uint8_t>(s.dir[static_cast<std::size_t>(x)] | (held ? kHeld : 0));
            if (!held) open.push_back(at + x);
        }
        x0 = x1;
    }
}

/// True when voxel v's ball lies in the ball of a voxel up its DT's steepest ascent (`up`, at most kClimb steps):
/// first by the triangle inequality (the farthest lattice point of v's ball plus the distance between the centres
/// inside the other's limit, with a relative 1e-12 to spare), then, for the top of the climb, row by row
/// (contains). Dropping such a centre changes no voxel's thickness. (DT grows by less than a step on a lattice,
/// so the first neighbour up rarely holds the ball while one further up does.)
bool held_up_the_climb(const Grid& g, const float* dt, const std::uint8_t* up, std::int64_t v,
                       const std::vector<Neighbour>& nb, ProfileCache& balls) {
    constexpr int kClimb = 64;
    const double reach = balls.reach(dt[v]);
    std::int64_t u = v, top = -1;
    std::array<std::int64_t, 3> o{0, 0, 0};  // u - v in voxels
    double far = 0.0, lim = 0.0;  // at the top
    for (int k = 0; k < kClimb && (up[u] & kTop) != kTop; ++k) {
        const Neighbour& n = nb[up[u] & kTop];
        u += n.offset;
        o = {o[0] + n.dx, o[1] + n.dy, o[2] + n.dz};
        const double dx = double(o[0]) * g.spacing[0], dy = double(o[1]) * g.spacing[1], dz = double(o[2]) * g.spacing[2];
        far = reach + std::sqrt(dx * dx + dy * dy + dz * dz);
        lim = open_ball_limit_sq(dt[u]);
        if (far * far < lim * (1.0 - 1e-12)) return true;
        top = u;
    }
    // The row test can only succeed where the triangle bound is loose, by less than the lattice's step.
    if (top < 0 || far - std::sqrt(lim) > g.min_spacing()) return false;
    return balls.holds(dt[top], dt[v], {-o[0], -o[1], -o[2]});
}

/// A centre to paint: its voxel, its ball's diameter (the value it paints) and its row table.
struct PaintBall {
    std::int32_t x, y, z;
    float diameter;
    std::uint32_t table;  ///< into the tables, by ascending radius
};

/// One z slice painted largest ball first, so the first ball to reach a voxel sets its final value. A bit per voxel
/// marks the voxels done (set, or background: never painted), so later balls' runs find most of their voxels done
/// by a few word operations; a count per 16 x 16 tile of the voxels not done lets a ball whose cross-section's
/// bounding box meets only finished tiles (most: the balls overlap heavily) skip it whole.
class SliceCanvas {
public:
    SliceCanvas(std::int64_t nx, std::int64_t ny)
        : nx_(nx), ny_(ny), words_((nx + 63) / 64 + 1), tiles_x_((nx + 15) / 16),
          done_(static_cast<std::size_t>(ny * words_)), left_(static_cast<std::size_t>((ny + 15) / 16 * tiles_x_)) {}

    /// Starts a slice: dt and out point at its first voxel.
    void start(const float* dt, float* out) {
        out_ = out;
        left_total_ = 0;
        std::fill(left_.begin(), left_.end(), 0);
        for (std::int64_t y = 0; y < ny_; ++y) {
            std::uint64_t* bits = &done_[static_cast<std::size_t>(y * words_)];
            std::fill(bits, bits + words_, ~std::uint64_t(0));
            for (std::int64_t x0 = 0; x0 < nx_; x0 += 16) {  // one tile's row at a time
                const float* d = dt + y * nx_ + x0;
                const std::int64_t n = std::min<std::int64_t>(16, nx_ - x0);
                bool any = false;  // (most are background: first a test that vectorises)
                for (std::int64_t i = 0; i < n; ++i) any |= d[i] > 0;
                if (!any) continue;
                std::uint64_t object = 0;
                for (std::int64_t i = 0; i < n; ++i) object |= static_cast<std::uint64_t>(d[i] > 0) << i;
                bits[x0 >> 6] &= ~(object << (x0 & 63));
            }
            for (std::int64_t w = 0; w + 1 < words_; ++w) count_left(y, w, ~bits[w], +1);
        }
    }

    /// True once every object voxel of the slice is set.
    bool finished() const { return left_total_ == 0; }

    /// Paints ball b's cross-section at this slice, z.
    void paint(const BallProfile& t, const PaintBall& b, std::int64_t z) {
        const auto a = static_cast<std::size_t>(z < b.z ? b.z - z : z - b.z);
        const std::int64_t* width = t.width.data() + t.start[a];  // widest at dy = 0
        const std::int64_t rows = t.start[a + 1] - t.start[a];
        const std::int64_t y0 = std::max<std::int64_t>(0, b.y - rows + 1), y1 = std::min(ny_ - 1, b.y + rows - 1);
        if (tiles_done(std::max<std::int64_t>(0, b.x - width[0]), std::min(nx_ - 1, b.x + width[0]), y0, y1)) return;
        for (std::int64_t y = y0; y <= y1; ++y) {
            const std::int64_t w = width[y < b.y ? b.y - y : y - b.y];
            run(y, std::max<std::int64_t>(0, b.x - w), std::min(nx_ - 1, b.x + w), b.diameter);
        }
    }

private:
    bool tiles_done(std::int64_t x0, std::int64_t x1, std::int64_t y0, std::int64_t y1) const {
        for (std::int64_t ty = y0 >> 4; ty <= y1 >> 4; ++ty)
            for (std::int64_t tx = x0 >> 4; tx <= x1 >> 4; ++tx)
                if (left_[static_cast<std::size_t>(ty * tiles_x_ + tx)] != 0) return false;
        return true;
    }

    /// Adds sign times the number of voxels `open` (bits of word w of row y) to the counts of their tiles.
    void count_left(std::int64_t y, std::int64_t w, std::uint64_t open, int sign) {
        if (open == 0) return;
        std::uint64_t c = open - (open >> 1 & 0x5555555555555555u);  // a popcount per 16-bit lane (SWAR)
        c = (c & 0x3333333333333333u) + (c >> 2 & 0x3333333333333333u);
        c = (c + (c >> 4)) & 0x0F0F0F0F0F0F0F0Fu;
        c = (c + (c >> 8)) & 0x00FF00FF00FF00FFu;
        for (std::int64_t q = 0; q < 4 && 4 * w + q < tiles_x_; ++q) {
            const int n = sign * static_cast<int>(c >> (16 * q) & 0xFF);
            left_[static_cast<std::size_t>((y >> 4) * tiles_x_ + 4 * w + q)] += static_cast<std::uint16_t>(n);
            left_total_ += n;
        }
    }

    /// Sets the voxels x0 .. x1 of row y not done to d and marks them done, 64 voxels (two words) at a time.
    void run(std::int64_t y, std::int64_t x0, std::int64_t x1, float d) {
        std::uint64_t* bits = &done_[static_cast<std::size_t>(y * words_)];
        float* row = out_ + y * nx_;
        for (std::int64_t x = x0; x <= x1; x += 64) {
            const std::int64_t w = x >> 6, lo = x & 63;
            const std::uint64_t span = ~std::uint64_t(0) >> (63 - std::min<std::int64_t>(x1 - x, 63));
            std::uint64_t fresh0 = span << lo & ~bits[w], fresh1 = (span >> 1) >> (63 - lo) & ~bits[w + 1];
            if ((fresh0 | fresh1) == 0) continue;  // the common case: a larger ball got there first
            bits[w] |= fresh0;
            bits[w + 1] |= fresh1;
            count_left(y, w, fresh0, -1);
            count_left(y, w + 1, fresh1, -1);
            for (; fresh0 != 0; fresh0 &= fresh0 - 1) row[(w << 6) + __builtin_ctzll(fresh0)] = d;
            for (; fresh1 != 0; fresh1 &= fresh1 - 1) row[(w << 6) + 64 + __builtin_ctzll(fresh1)] = d;
        }
    }

    std::int64_t nx_, ny_, words_, tiles_x_;
    std::vector<std::uint64_t> done_;   ///< per row: words_ words (the last a spare, all ones)
    std::vector<std::uint16_t> left_;   ///< per 16 x 16 tile: its voxels not done
    std::int64_t left_total_ = 0;
    float* out_ = nullptr;
};

/// out[v] = the largest diameter among the balls over v, for the object voxels (DT > 0; out may be dt). `balls`
/// come sorted by row table (by radius), then by voxel (z, y, x); table t's are balls[first[t] .. first[t + 1] - 1],
/// and those over slice z the ones with |z' - z| <= its hz: a range. Slices in parallel, each on a SliceCanvas,
/// largest balls first.
void paint_largest_first(const Grid& g, const float* dt, const std::vector<BallProfile>& tables,
                         const std::vector<PaintBall>& balls, const std::vector<std::size_t>& first, float* out) {
    const std::int64_t plane = g.dims[0] * g.dims[1];
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, g.dims[2]), [&](const tbb::blocked_range<std::int64_t>& r) {
        SliceCanvas canvas(g.dims[0], g.dims[1]);
        for (std::int64_t z = r.begin(); z != r.end(); ++z) {
            canvas.start(dt + z * plane, out + z * plane);
            for (std::size_t t = tables.size(); t-- > 0 && !canvas.finished();) {
                const auto below = [](const PaintBall& b, std::int64_t v) { return b.z < v; };
                const auto end = balls.begin() + static_cast<std::ptrdiff_t>(first[t + 1]);
                const auto from = std::lower_bound(balls.begin() + static_cast<std::ptrdiff_t>(first[t]), end,
                                                   z - tables[t].hz(), below);
                for (auto b = from; b != end && b->z <= z + tables[t].hz(); ++b) canvas.paint(tables[t], *b, z);
            }
        }
    });
}

}  // namespace

std::vector<std::int64_t> thickness_centres(const Grid& g, const float* dt) {
    const std::vector<Neighbour> nb = neighbours26(g);
    double step = 0.0;
    for (const Neighbour& n : nb) step = std::max(step, n.length);
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    tbb::enumerable_thread_specific<ProfileCache> caches([&] { return ProfileCache(g); });
    // First pass: each voxel's steepest rising neighbour, and whether a neighbour's ball holds its ball (most do).
    const std::unique_ptr<std::uint8_t[]> up(new std::uint8_t[static_cast<std::size_t>(g.voxel_count())]);  // (set there)
    std::vector<std::vector<std::int64_t>> per_slice(static_cast<std::size_t>(g.dims[2]));  // not held, then centres
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, g.dims[2]), [&](const tbb::blocked_range<std::int64_t>& r) {
        Slack s{std::vector<float>(static_cast<std::size_t>(nx)), std::vector<std::int32_t>(static_cast<std::size_t>(nx))};
        for (std::int64_t z = r.begin(); z != r.end(); ++z)
            for (std::int64_t y = 0; y < ny; ++y)
                mark_row(g, dt, y, z, nb, step, caches.local(), s, up.get(), per_slice[static_cast<std::size_t>(z)]);
    });
    // Second pass: the others climb.
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, g.dims[2]), [&](const tbb::blocked_range<std::int64_t>& r) {
        ProfileCache& balls = caches.local();
        for (std::int64_t z = r.begin(); z != r.end(); ++z) {
            auto& c = per_slice[static_cast<std::size_t>(z)];
            c.erase(std::remove_if(c.begin(), c.end(),
                                   [&](std::int64_t v) { return held_up_the_climb(g, dt, up.get(), v, nb, balls); }),
                    c.end());
        }
    });
    std::vector<std::int64_t> out;
    for (const auto& c : per_slice) out.insert(out.end(), c.begin(), c.end());
    return out;
}

namespace {

/// The centres as balls to paint: one row table per distinct radius (few: painting looks widths up instead of
/// taking square roots), and the balls sorted by table (by radius), each table's in voxel order, table t's being
/// balls[first[t] .. first[t + 1] - 1].
struct Balls {
    std::vector<BallProfile> tables;
    std::vector<PaintBall> balls;
    std::vector<std::size_t> first;
};

Balls balls_of(const Grid& g, const float* dt, const std::vector<std::int64_t>& centres) {
    const std::size_t n = centres.size();
    tbb::combinable<FloatIds> seen;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& r) {
        FloatIds& ids = seen.local();
        for (std::size_t k = r.begin(); k != r.end(); ++k) ids(dt[centres[k]]);
    });
    std::vector<float> radii;
    seen.combine_each([&](const FloatIds& some) { radii.insert(radii.end(), some.values().begin(), some.values().end()); });
    std::sort(radii.begin(), radii.end());
    radii.erase(std::unique(radii.begin(), radii.end()), radii.end());
    FloatIds table_of;  // numbered in ascending order: the table of each radius
    for (const float r : radii) table_of(r);
    Balls b;
    b.tables.resize(radii.size());
    tbb::parallel_for(std::size_t(0), radii.size(), [&](std::size_t t) { b.tables[t] = profile_of(radii[t], g); });
    // A counting sort of the (ascending) centres by table.
    std::vector<std::uint32_t> table(n);
    tbb::enumerable_thread_specific<FloatIds> tables_of(table_of);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& r) {
        FloatIds& ids = tables_of.local();
        for (std::size_t k = r.begin(); k != r.end(); ++k) table[k] = static_cast<std::uint32_t>(ids(dt[centres[k]]));
    });
    b.first.assign(radii.size() + 1, 0);
    for (const std::uint32_t t : table) ++b.first[t + 1];
    for (std::size_t t = 0; t < radii.size(); ++t) b.first[t + 1] += b.first[t];
    b.balls.resize(n);
    std::vector<std::size_t> next(b.first.begin(), b.first.end() - 1);
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    for (std::size_t k = 0; k < n; ++k) {
        const std::int64_t i = centres[k];
        b.balls[next[table[k]]++] = {static_cast<std::int32_t>(i % nx), static_cast<std::int32_t>(i / nx % ny),
                                     static_cast<std::int32_t>(i / (nx * ny)), 2.0f * radii[table[k]], table[k]};
    }
    return b;
}

/// Local thickness from the DT into `out`, which may be the DT itself (the centres and their radii are taken
/// first, and each slice reads its own DT before painting it; background voxels are not written).
void thickness_into(const Grid& g, const float* dt, float* out, const Progress& progress) {
    check_grid(g, sizeof(float), std::numeric_limits<std::uint64_t>::max(), "local thickness");
    const std::vector<std::int64_t> centres = thickness_centres(g, dt);
    report(progress, 0.2);
    if (centres.size() > std::numeric_limits<std::uint32_t>::max())
        throw Error("local thickness: more than 2^32 ball centres");
    const Balls b = balls_of(g, dt, centres);
    report(progress, 0.3);
    paint_largest_first(g, dt, b.tables, b.balls, b.first, out);
    report(progress, 1.0);
}

}  // namespace

std::vector<float> local_thickness_from_dt(const Grid& g, const float* dt, const Progress& progress) {
    check_grid(g, sizeof(float), std::numeric_limits<std::uint64_t>::max(), "local thickness");
    std::vector<float> out(dt, dt + g.voxel_count());  // (background: 0 as in the DT)
    thickness_into(g, out.data(), out.data(), progress);
    return out;
}

std::vector<float> local_thickness(const Grid& g, const std::uint8_t* mask, const Progress& progress) {
    std::vector<float> dt = distance_transform(g, mask, Metric::Euclidean, progress_span(progress, 0.0, 0.4));
    thickness_into(g, dt.data(), dt.data(), progress_span(progress, 0.4, 1.0));  // (in place: no second volume)
    return dt;
}

}  // namespace volrig

// mesh/winding_mask.cpp: VoxelizeMethod::Winding's mask (mesh/winding_mask.hpp), filled block by block from the
// generalized winding number (WindingNumber, mesh/winding.cpp), with the triangles' distance tree
// (mesh/triangle_tree.hpp) telling the blocks near the surface. For Auto on an open mesh the flood's mask comes in
// as known-inside voxels, and only the others need |w|.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "mesh/triangle_tree.hpp"
#include "mesh/winding_mask.hpp"

namespace volrig::mesh_detail {

namespace {

/// Whether lattice point (x, y, z) is a corner of a cell for which open(a, b, d) holds, the cells being
/// cells[0] x cells[1] x cells[2] with cell (a, b, d) spanning lattice points a..a + 1, b..b + 1, d..d + 1 (so the
/// point is a corner of the cells (x - 1..x, y - 1..y, z - 1..z) that exist). A lattice point is evaluated only
/// when this holds, at both levels of the fill: the lattice of the 8-voxel blocks (winding_corners, open: not
/// wholly known inside) and the 3 x 3 x 3 lattice of a block split in eight (WindingFill::fill, open: a child
/// inside the grid and not wholly known inside).
template <class Open>
bool corner_needed(std::int64_t x, std::int64_t y, std::int64_t z, const std::int64_t (&cells)[3], const Open& open) {
    for (std::int64_t d = std::max<std::int64_t>(0, z - 1); d <= std::min(z, cells[2] - 1); ++d)
        for (std::int64_t b = std::max<std::int64_t>(0, y - 1); b <= std::min(y, cells[1] - 1); ++b)
            for (std::int64_t a = std::max<std::int64_t>(0, x - 1); a <= std::min(x, cells[0] - 1); ++a)
                if (open(a, b, d)) return true;
    return false;
}

/// The recursive fill of VoxelizeMethod::Winding (winding_mask). `known` (optional, on the output grid): voxels
/// already known to be inside (Auto's flood mask, which the winding mask is united with). They are set inside
/// without their |w|, and a block wholly known is filled without evaluating anything in it; every other voxel is
/// decided exactly as without `known` (the same lattice values, the same block tests), so the union is unchanged.
class WindingFill {
public:
    WindingFill(const WindingNumber& wn, const TriangleTree& tree, const Grid& out, std::uint8_t* dst,
                const std::uint8_t* known = nullptr)
        : wn_(wn), tree_(tree), nx_(out.dims[0]), ny_(out.dims[1]), nz_(out.dims[2]), dst_(dst), known_(known) {}

    /// True when every voxel of the block [x0, x0 + s)^3 (clipped to the grid) is known to be inside.
    bool all_known(std::int64_t x0, std::int64_t y0, std::int64_t z0, std::int64_t s) const {
        if (!known_) return false;
        const std::int64_t x1 = std::min(nx_, x0 + s), y1 = std::min(ny_, y0 + s), z1 = std::min(nz_, z0 + s);
        for (std::int64_t z = z0; z < z1; ++z)
            for (std::int64_t y = y0; y < y1; ++y) {
                const std::uint8_t* row = known_ + (z * ny_ + y) * nx_;
                if (std::find(row + x0, row + x1, std::uint8_t(0)) != row + x1) return false;
            }
        return true;
    }

    bool known(std::int64_t x, std::int64_t y, std::int64_t z) const {
        return known_ && known_[(z * ny_ + y) * nx_ + x] != 0;
    }

    float at(std::int64_t x, std::int64_t y, std::int64_t z) const {
        return static_cast<float>(
            std::abs(wn_({static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)})));
    }

    /// Fills the voxels of the block [x0, x0 + s)^3 (clipped to the grid) whose corners (x0 + s * (k & 1),
    /// y0 + s * (k >> 1 & 1), z0 + s * (k >> 2)) have |w| = c[k]; returns the number of inside voxels.
    std::int64_t fill(std::int64_t x0, std::int64_t y0, std::int64_t z0, std::int64_t s, const float c[8]) const {
        if (x0 >= nx_ || y0 >= ny_ || z0 >= nz_) return 0;
        if (all_known(x0, y0, z0, s)) return fill_block(x0, y0, z0, s, true);
        if (s == 1) {
            const bool in = c[0] >= 0.5f;
            dst_[(z0 * ny_ + y0) * nx_ + x0] = in ? 1 : 0;
            return in;
        }
        bool any_in = false, any_out = false, close = false;
        for (int k = 0; k < 8; ++k) {
            (c[k] >= 0.5f ? any_in : any_out) = true;
            close = close || std::abs(c[k] - 0.5f) < kWindingMargin;
        }
        const double half = 0.5 * static_cast<double>(s);
        if (!(any_in && any_out) && !close &&
            !tree_.any_within(openvdb::Vec3d(static_cast<double>(x0) + half, static_cast<double>(y0) + half,
                                             static_cast<double>(z0) + half),
                              std::sqrt(3.0) * half + 0.5)) {
            return fill_block(x0, y0, z0, s, any_in);
        }
        if (s == 2) {  // the block's eight voxels: (x0, y0, z0) known, the other seven evaluated
            const std::int64_t x1 = std::min(nx_, x0 + 2), y1 = std::min(ny_, y0 + 2), z1 = std::min(nz_, z0 + 2);
            std::int64_t count = 0;
            for (std::int64_t z = z0; z < z1; ++z)
                for (std::int64_t y = y0; y < y1; ++y)
                    for (std::int64_t x = x0; x < x1; ++x) {
                        const bool in = known(x, y, z) || (x == x0 && y == y0 && z == z0 ? c[0] : at(x, y, z)) >= 0.5f;
                        dst_[(z * ny_ + y) * nx_ + x] = in ? 1 : 0;
                        count += in;
                    }
            return count;
        }
        // |w| on the 3 x 3 x 3 lattice of step s / 2: the eight corners known, the rest evaluated where a child
        // needs them (not for children wholly outside the grid or wholly known to be inside: never read).
        const std::int64_t h = s / 2;
        bool need[8];
        for (int k = 0; k < 8; ++k) {
            const std::int64_t cx = x0 + (k & 1) * h, cy = y0 + ((k >> 1) & 1) * h, cz = z0 + (k >> 2) * h;
            need[k] = cx < nx_ && cy < ny_ && cz < nz_ && !all_known(cx, cy, cz, h);
        }
        const std::int64_t children[3] = {2, 2, 2};
        const auto child_needs = [&need](std::int64_t a, std::int64_t b, std::int64_t d) {
            return need[a | b << 1 | d << 2];
        };
        float w[27];
        for (std::int64_t k = 0; k < 3; ++k)
            for (std::int64_t j = 0; j < 3; ++j)
                for (std::int64_t i = 0; i < 3; ++i) {
                    float& wv = w[9 * k + 3 * j + i];
                    if (i != 1 && j != 1 && k != 1) {
                        wv = c[(i >> 1) | (j & 2) | ((k >> 1) << 2)];
                    } else {
                        wv = corner_needed(i, j, k, children, child_needs) ? at(x0 + i * h, y0 + j * h, z0 + k * h)
                                                                            : 0.0f;
                    }
                }
        std::int64_t count = 0;
        for (int k = 0; k < 8; ++k) {
            const int a = k & 1, b = (k >> 1) & 1, d = k >> 2;
            float cc[8];
            for (int m = 0; m < 8; ++m) cc[m] = w[9 * (d + (m >> 2)) + 3 * (b + ((m >> 1) & 1)) + a + (m & 1)];
            count += fill(x0 + a * h, y0 + b * h, z0 + d * h, h, cc);
        }
        return count;
    }

    static constexpr float kWindingMargin = 0.1f;

private:
    /// Sets the block [x0, x0 + s)^3 (clipped to the grid) to `in`; returns its inside voxels.
    std::int64_t fill_block(std::int64_t x0, std::int64_t y0, std::int64_t z0, std::int64_t s, bool in) const {
        const std::int64_t x1 = std::min(nx_, x0 + s), y1 = std::min(ny_, y0 + s), z1 = std::min(nz_, z0 + s);
        for (std::int64_t z = z0; z < z1; ++z)
            for (std::int64_t y = y0; y < y1; ++y)
                std::fill(dst_ + (z * ny_ + y) * nx_ + x0, dst_ + (z * ny_ + y) * nx_ + x1, in ? 1 : 0);
        return in ? (x1 - x0) * (y1 - y0) * (z1 - z0) : 0;
    }

    const WindingNumber& wn_;
    const TriangleTree& tree_;
    std::int64_t nx_, ny_, nz_;
    std::uint8_t* dst_;
    const std::uint8_t* known_;
};

/// The blocks of side kStride that winding_mask fills, and the lattice of their corners.
struct WindingBlocks {
    static constexpr std::int64_t kStride = 8;
    std::int64_t bx, by, bz, cx, cy, cz;

    explicit WindingBlocks(const Grid& out)
        : bx((out.dims[0] + kStride - 1) / kStride),
          by((out.dims[1] + kStride - 1) / kStride),
          bz((out.dims[2] + kStride - 1) / kStride),
          cx(bx + 1),
          cy(by + 1),
          cz(bz + 1) {}
    std::int64_t blocks() const { return bx * by * bz; }
    std::int64_t corners() const { return cx * cy * cz; }
    /// Corner k (bit 0: +x, bit 1: +y, bit 2: +z) of block b.
    std::size_t corner(std::int64_t b, int k) const {
        const std::int64_t jx = b % bx, jy = (b / bx) % by, jz = b / (bx * by);
        return static_cast<std::size_t>(((jz + (k >> 2)) * cy + jy + ((k >> 1) & 1)) * cx + jx + (k & 1));
    }
};

/// |w| at the block corners that some block not wholly known to be inside needs (the others are left at 0 and
/// never read).
std::vector<float> winding_corners(const WindingFill& filler, const WindingBlocks& B) {
    constexpr std::int64_t S = WindingBlocks::kStride;
    std::vector<std::uint8_t> open_block(static_cast<std::size_t>(B.blocks()));  // not wholly known inside
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, B.blocks()), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t b = r.begin(); b != r.end(); ++b)
            open_block[static_cast<std::size_t>(b)] =
                !filler.all_known(b % B.bx * S, (b / B.bx) % B.by * S, b / (B.bx * B.by) * S, S);
    });
    const std::int64_t blocks[3] = {B.bx, B.by, B.bz};
    const auto block_open = [&](std::int64_t a, std::int64_t b, std::int64_t d) {
        return open_block[static_cast<std::size_t>((d * B.by + b) * B.bx + a)] != 0;
    };
    std::vector<float> corner(static_cast<std::size_t>(B.corners()), 0.0f);
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, B.cz * B.cy), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t zy = r.begin(); zy != r.end(); ++zy)
            for (std::int64_t x = 0; x < B.cx; ++x)
                if (corner_needed(x, zy % B.cy, zy / B.cy, blocks, block_open))
                    corner[static_cast<std::size_t>(zy * B.cx + x)] =
                        filler.at(x * S, (zy % B.cy) * S, (zy / B.cy) * S);
    });
    return corner;
}

}  // namespace

/// VoxelizeMethod::Winding: inside when |w| >= 0.5 at the voxel centre (w the generalized winding number). |w| is
/// evaluated on the lattice of every 8th voxel (block corners, some just past the grid's far end). A block whose
/// eight corners agree, none within 0.1 of the threshold, and whose circumscribed ball (plus half a voxel) no
/// triangle enters takes their answer: w is harmonic off the surface, so it cannot swing across 0.5 and back
/// inside such a block. Any other block is split in eight (|w| evaluated at the 19 new lattice points) and its
/// children tested the same way, down to single voxels. Fills v; returns the number of inside voxels.
/// `known` (Auto: the flood's mask, on `out`): voxels taken as inside without their |w| (WindingFill).
std::int64_t winding_mask(const Mesh& mesh, const Grid& out, Volume& v, const Progress& progress,
                          const std::uint8_t* known) {
    // The mesh in the output grid's index space: voxel centres at whole coordinates.
    Mesh local;
    local.triangles = mesh.triangles;
    local.vertices.resize(mesh.vertices.size());
    std::vector<openvdb::Vec3d> points(mesh.vertices.size());
    for (std::size_t i = 0; i < points.size(); ++i)
        for (std::size_t a = 0; a < 3; ++a) {
            local.vertices[i][a] = (mesh.vertices[i][a] - out.origin[a]) / out.spacing[a];
            points[i][static_cast<int>(a)] = local.vertices[i][a];
        }
    const WindingNumber wn(local);
    const TriangleTree tree(points, local.triangles);
    report(progress, 0.05);
    v.data.assign(static_cast<std::size_t>(out.voxel_count()), 0);
    const WindingFill filler(wn, tree, out, v.data.data(), known);
    const WindingBlocks B(out);
    const std::vector<float> corner = winding_corners(filler, B);
    report(progress, 0.15);

    // Blocks in about ten slabs of block rows, so that progress is reported (and a cancel seen) between them
    // from the calling thread.
    constexpr std::int64_t S = WindingBlocks::kStride;
    const std::int64_t blocks = B.blocks(), chunk = std::max<std::int64_t>(B.bx * B.by, blocks / 10);
    std::int64_t inside = 0;
    for (std::int64_t first = 0; first < blocks; first += chunk) {
        inside += tbb::parallel_reduce(
            tbb::blocked_range<std::int64_t>(first, std::min(blocks, first + chunk), 1), std::int64_t(0),
            [&](const tbb::blocked_range<std::int64_t>& r, std::int64_t count) {
                for (std::int64_t b = r.begin(); b != r.end(); ++b) {
                    float c[8];
                    for (int k = 0; k < 8; ++k) c[k] = corner[B.corner(b, k)];
                    count += filler.fill(b % B.bx * S, (b / B.bx) % B.by * S, b / (B.bx * B.by) * S, S, c);
                }
                return count;
            },
            [](std::int64_t a, std::int64_t b) { return a + b; });
        report(progress, 0.15 + 0.8 * static_cast<double>(std::min(blocks, first + chunk)) / static_cast<double>(blocks));
    }
    return inside;
}

}  // namespace volrig::mesh_detail

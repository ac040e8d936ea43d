// The 26-neighbourhood of a voxel (docs/ALGORITHMS.md §1): 6 face (F), 12 edge (E), 8 vertex (V) neighbours.
// Internal to the core; one definition shared by the chamfer transform, the thinness score and labelling.
#pragma once

#include <array>
#include <cstdint>

#include "volrig/volume.hpp"

namespace volrig::common_detail {

struct Offset {
    int dx, dy, dz;
    int order;  ///< 1 = face, 2 = edge, 3 = vertex (number of non-zero components)
};

constexpr std::array<Offset, 26> make_offsets() {
    std::array<Offset, 26> o{};
    int k = 0;
    for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                if (!dx && !dy && !dz) continue;
                o[k++] = Offset{dx, dy, dz, (dx != 0) + (dy != 0) + (dz != 0)};
            }
    return o;
}
inline constexpr std::array<Offset, 26> kOffsets = make_offsets();

/// Linear-index steps of the 26 neighbours on one grid, and a visitor that handles the array border
/// (neighbours outside the array are reported with index -1: they are background by convention).
class Neighbourhood {
public:
    explicit Neighbourhood(const Grid& g) : nx_(g.dims[0]), ny_(g.dims[1]), nz_(g.dims[2]) {
        for (int k = 0; k < 26; ++k)
            step_[k] = (static_cast<std::int64_t>(kOffsets[k].dz) * ny_ + kOffsets[k].dy) * nx_ + kOffsets[k].dx;
    }
    /// f(k, neighbour_index) for k in 0..25; neighbour_index = -1 when outside the array.
    template <class F>
    void visit(std::int64_t x, std::int64_t y, std::int64_t z, std::int64_t idx, F&& f) const {
        if (x > 0 && y > 0 && z > 0 && x + 1 < nx_ && y + 1 < ny_ && z + 1 < nz_) {
            for (int k = 0; k < 26; ++k) f(k, idx + step_[k]);
            return;
        }
        for (int k = 0; k < 26; ++k) {
            const std::int64_t X = x + kOffsets[k].dx, Y = y + kOffsets[k].dy, Z = z + kOffsets[k].dz;
            const bool inside = X >= 0 && Y >= 0 && Z >= 0 && X < nx_ && Y < ny_ && Z < nz_;
            f(k, inside ? idx + step_[k] : std::int64_t{-1});
        }
    }

private:
    std::int64_t nx_, ny_, nz_;
    std::array<std::int64_t, 26> step_{};
};

}  // namespace volrig::common_detail

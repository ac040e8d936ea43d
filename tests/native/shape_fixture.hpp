// shape_fixture.hpp: the mask and point-set fixtures the skeleton-tree and rig tests share: a shape (grid and mask)
// and skeleton points (ijk and radii) as a PointSet.
#pragma once

#include <cstdint>
#include <vector>

#include "volrig/tree.hpp"
#include "volrig/volume.hpp"

namespace volrig {

namespace {

struct Shape {
    Grid grid;
    std::vector<std::uint8_t> mask;
    std::uint8_t at(int x, int y, int z) const { return mask[static_cast<std::size_t>(grid.index(x, y, z))]; }
};

struct Points {
    std::vector<std::int32_t> ijk;
    std::vector<float> radius;
    PointSet set() const { return PointSet{ijk.data(), radius.data(), radius.size()}; }
};

}  // namespace

}  // namespace volrig

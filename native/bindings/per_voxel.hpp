// Bindings helpers shared by the skeleton and medial bindings: a mask's grid, and a per-voxel function of a mask
// run without the GIL.
#pragma once

#include "convert.hpp"

namespace volrig::py {

using Mask = MaskArray;

inline Grid mask_grid(const Mask& m, const Vec3& spacing) { return grid_of(m, spacing, {0, 0, 0}, "mask"); }

/// A per-voxel function of a mask or a field (DT, plane measure, thickness) run without the GIL, as an array on
/// its grid.
template <class Array, class F>
py::array_t<float> per_voxel(const Array& mask, const Vec3& spacing, const py::object& progress, F f) {
    const Grid g = grid_of(mask, spacing, {0, 0, 0}, "mask");
    Progress p = progress_of(progress);
    std::vector<float> out;
    {
        py::gil_scoped_release nogil;
        out = f(g, mask.data(), p);
    }
    return to_numpy(std::move(out), g);
}

}  // namespace volrig::py

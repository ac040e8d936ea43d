// Bindings: feature tracking (a step's features; overlaps of points with the next step's features).
#include "per_voxel.hpp"
#include "volrig/track.hpp"

namespace volrig::py {

namespace {

using LabelArray = py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>;
using IndexArray = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>;

}  // namespace

void bind_track(py::module_& m) {
    m.def(
        "track_features",
        [](const Mask& mask, std::int64_t min_size) {
            const Grid g = mask_grid(mask, {1, 1, 1});
            Features f;
            {
                py::gil_scoped_release nogil;
                f = track_features(g, mask.data(), min_size);
            }
            const auto nf = static_cast<py::ssize_t>(f.sizes.size());
            return py::make_tuple(to_numpy(std::move(f.labels), g), to_numpy_shaped(std::move(f.sizes), {nf}),
                                  to_numpy_shaped(std::move(f.centroids), {nf, 3}));
        },
        py::arg("mask"), py::arg("min_size"),
        "(labels int32 [z, y, x], sizes int64, centroids (F, 3) mean index x, y, z) of the 6-connected components "
        "of at least min_size voxels, numbered in scan order");
    m.def(
        "point_overlaps",
        [](const LabelArray& next, std::int32_t next_count, const IndexArray& index, const LabelArray& label,
           const FloatArray& weight) {
            const auto n = static_cast<std::size_t>(index.size());
            if (next.ndim() != 3) throw Error("point_overlaps: next_labels must be 3-D [z, y, x]");
            if (label.size() != index.size() || weight.size() != index.size())
                throw Error("point_overlaps: index, label and weight must have one entry a point");
            const Grid g = grid_of(next, {1, 1, 1}, {0, 0, 0}, "next_labels");
            Overlaps o;
            {
                py::gil_scoped_release nogil;
                o = point_overlaps(g, next.data(), next_count, index.data(), label.data(), weight.data(), n);
            }
            const auto k = static_cast<py::ssize_t>(o.a.size());
            const auto nt = static_cast<py::ssize_t>(o.totals.size());
            return py::make_tuple(to_numpy_shaped(std::move(o.a), {k}), to_numpy_shaped(std::move(o.b), {k}),
                                  to_numpy_shaped(std::move(o.weight), {k}),
                                  to_numpy_shaped(std::move(o.totals), {nt}));
        },
        py::arg("next_labels"), py::arg("next_count"), py::arg("index"), py::arg("label"), py::arg("weight"));
}

}  // namespace volrig::py

// Bindings for volrig/skin.hpp: skin weights of surface points. Conversions only.
#include "rig_arrays.hpp"
#include "volrig/skin.hpp"

namespace volrig::py {

void bind_skin(py::module_& m) {
    m.def(
        "skin_weights",
        [](const MaskArray& mask, const Vec3& spacing, const Vec3& origin, const DoubleArray& joints,
           const IntArray& bones, const std::vector<std::string>& names, const IntArray& parents,
           const DoubleArray& points, int influences, double blend, const py::object& progress) {
            const Grid g = grid_of(mask, spacing, origin, "mask");
            const Rig r = rig_of(joints, bones, names, parents);
            if (points.ndim() != 2 || points.shape(1) != 3) throw Error("skin_weights: points must have shape (V, 3)");
            std::vector<std::array<double, 3>> pts(static_cast<std::size_t>(points.shape(0)));
            for (std::size_t i = 0; i < pts.size(); ++i)
                pts[i] = {points.data()[3 * i], points.data()[3 * i + 1], points.data()[3 * i + 2]};
            Progress p = progress_of(progress);
            SkinWeights s;
            {
                py::gil_scoped_release nogil;
                s = skin_weights(g, mask.data(), r, pts, SkinOptions{influences, blend}, p);
            }
            const auto n = static_cast<py::ssize_t>(s.bone.size()), v = static_cast<py::ssize_t>(pts.size());
            return py::make_tuple(to_numpy_shaped(std::move(s.indptr), {v + 1}), to_numpy_shaped(std::move(s.bone), {n}),
                                  to_numpy_shaped(std::move(s.weight), {n}),
                                  to_numpy_shaped(std::move(s.outside), {v}).attr("view")("bool"));
        },
        py::arg("mask"), py::arg("spacing"), py::arg("origin"), py::arg("joints"), py::arg("bones"), py::arg("names"),
        py::arg("parents"), py::arg("points"), py::arg("influences") = 4, py::arg("blend") = 1.0,
        py::arg("progress") = py::none());
}

}  // namespace volrig::py

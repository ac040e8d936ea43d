// Bindings for volrig/tree.hpp: the skeleton-tree and the containment test. Conversions only.
#include "volrig/tree.hpp"

#include "convert.hpp"

namespace volrig::py {

void bind_tree(py::module_& m) {
    m.def(
        "skeleton_tree",
        [](const MaskArray& mask, const Vec3& spacing, const Vec3& origin, const IjkArray& ijk, const FloatArray& radius,
           double alpha, double max_edge, bool bridge, const py::object& progress) {
            const Grid g = grid_of(mask, spacing, origin, "mask");
            const PointSet pts = point_set(ijk, &radius, "skeleton_tree");
            TreeOptions opt;
            opt.alpha = alpha;
            opt.max_edge = max_edge;
            opt.bridge = bridge;
            Progress p = progress_of(progress);
            SkeletonTree t;
            {
                py::gil_scoped_release nogil;
                t = skeleton_tree(g, mask.data(), pts, opt, p);
            }
            const auto ne = static_cast<py::ssize_t>(t.edges.size());
            std::vector<std::uint32_t> flat(2 * t.edges.size());
            for (std::size_t k = 0; k < t.edges.size(); ++k) {
                flat[2 * k] = t.edges[k][0];
                flat[2 * k + 1] = t.edges[k][1];
            }
            return py::make_tuple(to_numpy_shaped(std::move(flat), {ne, 2}), to_numpy_shaped(std::move(t.weights), {ne}),
                                  to_numpy_shaped(std::move(t.bridged), {ne}),
                                  to_numpy_shaped(std::move(t.component), {static_cast<py::ssize_t>(pts.n)}),
                                  t.component_count, t.max_edge);
        },
        py::arg("mask"), py::arg("spacing"), py::arg("origin"), py::arg("ijk"), py::arg("radius"), py::arg("alpha"),
        py::arg("max_edge"), py::arg("bridge"), py::arg("progress") = py::none());

    m.def(
        "line_inside",
        [](const MaskArray& mask, const std::array<std::int32_t, 3>& a, const std::array<std::int32_t, 3>& b) {
            const Grid g = grid_of(mask, {1, 1, 1}, {0, 0, 0}, "mask");
            return line_inside(g, mask.data(), a.data(), b.data());
        },
        py::arg("mask"), py::arg("a"), py::arg("b"));
}

}  // namespace volrig::py

// Bindings: distance transforms, the thinness skeleton, reconstruction, connected components.
#include "per_voxel.hpp"
#include "volrig/components.hpp"
#include "volrig/distance.hpp"
#include "volrig/reconstruct.hpp"
#include "volrig/skeleton.hpp"

namespace volrig::py {

namespace {

/// A numpy view of memory owned by `owner` (kept alive by the array).
template <class T, class A>
py::array_t<T> view(const std::vector<T, A>& v, std::vector<py::ssize_t> shape, py::handle owner) {
    return py::array_t<T>(shape, v.data(), owner);
}

/// The Skeleton class: its scores, order and points.
void bind_skeleton_class(py::module_& m) {
    py::class_<Skeleton>(m, "Skeleton")
        .def_property_readonly("metric", [](const Skeleton& s) { return std::string(metric_name(s.metric)); })
        .def_property_readonly("object_count", &Skeleton::object_count)
        .def_property_readonly("dt", [](py::object self) {
            const auto& s = self.cast<const Skeleton&>();
            return view(s.dt, {s.grid.dims[2], s.grid.dims[1], s.grid.dims[0]}, self);
        })
        .def_property_readonly("order", [](py::object self) {
            const auto& s = self.cast<const Skeleton&>();
            return view(s.order, {static_cast<py::ssize_t>(s.order.size())}, self);
        })
        .def("count_at", &Skeleton::count_at, py::arg("tp"))
        .def("tp_for_count", &Skeleton::tp_for_count, py::arg("n"))
        .def("dense_scores", [](const Skeleton& s) {
            std::vector<float> d;
            {
                py::gil_scoped_release nogil;
                d = s.dense_scores();
            }
            return to_numpy(std::move(d), s.grid);
        })
        .def("points", [](const Skeleton& s, std::size_t n) {
            n = std::min(n, s.object_count());
            // numpy allocates without zero-filling; the native pass writes every element once.
            const auto pn = static_cast<py::ssize_t>(n);
            py::array_t<std::int32_t> ijk({pn, py::ssize_t{3}});
            py::array_t<double> centers({pn, py::ssize_t{3}});
            py::array_t<float> dt(pn), sc(pn);
            std::int32_t* pi = ijk.mutable_data();
            double* pc = centers.mutable_data();
            float* pd = dt.mutable_data();
            float* ps = sc.mutable_data();
            {
                py::gil_scoped_release nogil;
                skeleton_points(s, n, pi, pc, pd, ps);
            }
            return py::make_tuple(ijk, centers, dt, sc);
        }, py::arg("n"));
}

/// Connected components: label_components, nearest_seed_fill, largest_component.
void bind_components(py::module_& m) {
    m.def(
        "label_components",
        [](const Mask& mask, const py::object& progress) {
            const Grid g = mask_grid(mask, {1, 1, 1});
            Progress p = progress_of(progress);
            Components c;
            {
                py::gil_scoped_release nogil;
                c = label_components(g, mask.data(), p);
            }
            const auto nc = static_cast<py::ssize_t>(c.sizes.size());
            return py::make_tuple(to_numpy(std::move(c.labels), g), to_numpy_shaped(std::move(c.sizes), {nc}));
        },
        py::arg("mask"), py::arg("progress") = py::none());

    m.def(
        "nearest_seed_fill",
        [](const Mask& code) {
            const Grid g = mask_grid(code, {1, 1, 1});
            std::vector<std::int64_t> pairs;
            {
                py::gil_scoped_release nogil;
                pairs = nearest_seed_fill(g, code.data());
            }
            const auto n = static_cast<py::ssize_t>(pairs.size() / 2);
            return to_numpy_shaped(std::move(pairs), {n, 2});
        },
        py::arg("code"));

    m.def(
        "largest_component",
        [](const Mask& mask, const py::object& progress) {
            const Grid g = mask_grid(mask, {1, 1, 1});
            Progress p = progress_of(progress);
            std::vector<std::uint8_t> out;
            {
                py::gil_scoped_release nogil;
                out = largest_component(g, mask.data(), p);
            }
            return to_numpy(std::move(out), g);
        },
        py::arg("mask"), py::arg("progress") = py::none());
}

}  // namespace

void bind_skeleton(py::module_& m) {
    m.def(
        "distance_transform",
        [](const Mask& mask, const Vec3& spacing, const std::string& metric, const py::object& progress) {
            const Metric mt = metric_from_name(metric);
            return per_voxel(mask, spacing, progress, [mt](const Grid& g, const std::uint8_t* data, const Progress& p) {
                return distance_transform(g, data, mt, p);
            });
        },
        py::arg("mask"), py::arg("spacing"), py::arg("metric"), py::arg("progress") = py::none());
    bind_skeleton_class(m);
    m.def(
        "skeletonize",
        [](const Mask& mask, const Vec3& spacing, const Vec3& origin, const std::string& metric,
           const py::object& progress) {
            const Grid g = grid_of(mask, spacing, origin, "mask");
            const Metric mt = metric_from_name(metric);
            Progress p = progress_of(progress);
            Skeleton s;
            {
                py::gil_scoped_release nogil;
                s = skeletonize(g, mask.data(), mt, p);
            }
            return s;
        },
        py::arg("mask"), py::arg("spacing"), py::arg("origin"), py::arg("metric"), py::arg("progress") = py::none());

    m.def(
        "reconstruct",
        [](const py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>& ijk,
           const py::array_t<float, py::array::c_style | py::array::forcecast>& radius,
           const std::array<std::int64_t, 3>& shape_zyx, const Vec3& spacing, const std::string& metric,
           const py::object& progress) {
            if (ijk.ndim() != 2 || ijk.shape(1) != 3) throw Error("reconstruct: ijk must have shape (N, 3)");
            if (radius.ndim() != 1 || radius.shape(0) != ijk.shape(0))
                throw Error("reconstruct: radius must have shape (N,) matching ijk");
            Grid g;
            g.dims = {shape_zyx[2], shape_zyx[1], shape_zyx[0]};
            g.spacing = spacing;
            const Metric mt = metric_from_name(metric);
            Progress p = progress_of(progress);
            std::vector<std::uint8_t> out;
            {
                py::gil_scoped_release nogil;
                out = reconstruct(g, mt, ijk.data(), radius.data(), static_cast<std::size_t>(ijk.shape(0)), p);
            }
            return to_numpy(std::move(out), g);
        },
        py::arg("ijk"), py::arg("radius"), py::arg("shape"), py::arg("spacing"), py::arg("metric"),
        py::arg("progress") = py::none());

    bind_components(m);
}

}  // namespace volrig::py

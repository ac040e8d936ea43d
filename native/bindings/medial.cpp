// Bindings for volrig/medial.hpp, medial_surface.hpp and thickness.hpp: the plane measure, the medial surface and
// local thickness.
#include "per_voxel.hpp"
#include "volrig/medial.hpp"
#include "volrig/medial_surface.hpp"
#include "volrig/thickness.hpp"

namespace volrig::py {

void bind_medial(py::module_& m) {
    m.def(
        "plane_measure",
        [](const Mask& mask, const Vec3& spacing, double t, const py::object& progress) {
            return per_voxel(mask, spacing, progress, [t](const Grid& g, const std::uint8_t* data, const Progress& p) {
                return plane_measure(g, data, t, p);
            });
        },
        py::arg("mask"), py::arg("spacing"), py::arg("t"), py::arg("progress") = py::none());
    m.def(
        "medial_surface",
        [](const Mask& mask, const Vec3& spacing, const Vec3& origin, double t, const py::object& progress) {
            const Grid g = grid_of(mask, spacing, origin, "mask");
            Progress p = progress_of(progress);
            MedialSurface s;
            {
                py::gil_scoped_release nogil;
                s = medial_surface(g, mask.data(), t, p);
            }
            py::list rods, radii;
            for (std::size_t k = 0; k < s.rods.size(); ++k) {
                rods.append(rows(std::move(s.rods[k])));
                radii.append(to_numpy_shaped(std::move(s.rod_radii[k]), {static_cast<py::ssize_t>(s.rod_radii[k].size())}));
            }
            const auto nv = static_cast<py::ssize_t>(s.thickness.size());
            return py::make_tuple(rows(std::move(s.vertices)), rows(std::move(s.faces)),
                                  to_numpy_shaped(std::move(s.thickness), {nv}), rods, radii,
                                  to_numpy(std::move(s.skeleton), g));
        },
        py::arg("mask"), py::arg("spacing"), py::arg("origin"), py::arg("t"), py::arg("progress") = py::none());
    m.def(
        "local_thickness",
        [](const Mask& mask, const Vec3& spacing, const py::object& progress) {
            return per_voxel(mask, spacing, progress, [](const Grid& g, const std::uint8_t* data, const Progress& p) {
                return local_thickness(g, data, p);
            });
        },
        py::arg("mask"), py::arg("spacing"), py::arg("progress") = py::none());
    m.def(
        "local_thickness_from_dt",
        [](const FloatArray& dt, const Vec3& spacing, const py::object& progress) {
            return per_voxel(dt, spacing, progress, [](const Grid& g, const float* data, const Progress& p) {
                return local_thickness_from_dt(g, data, p);
            });
        },
        py::arg("dt"), py::arg("spacing"), py::arg("progress") = py::none());
}

}  // namespace volrig::py

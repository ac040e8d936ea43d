// Bindings for volrig/mesh.hpp: conversions only. Reading and voxelizing run with the GIL released.
#include <utility>
#include <vector>

#include "convert.hpp"
#include "volrig/mesh.hpp"

namespace volrig::py {

namespace {

using Vertices = py::array_t<double, py::array::c_style | py::array::forcecast>;
using Faces = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>;

std::size_t rows_of(const py::array& a, const char* what) {
    if (a.ndim() != 2 || a.shape(1) != 3)
        throw Error(std::string("voxelize: ") + what + " must have shape (n, 3)");
    return static_cast<std::size_t>(a.shape(0));
}

}  // namespace

void bind_mesh(py::module_& m) {
    m.def(
        "read_mesh",
        [](const std::string& path) {
            Mesh mesh;
            {
                py::gil_scoped_release release;
                mesh = read_mesh(path);
            }
            return py::make_tuple(rows(std::move(mesh.vertices)), rows(std::move(mesh.triangles)));
        },
        py::arg("path"),
        "read_mesh(path) -> (vertices (V, 3) float64, triangles (F, 3) uint32): .obj .ply .off .stl .mesh, "
        "polygons fan-triangulated.");

    py::tuple endings(mesh_extensions().size());
    for (std::size_t i = 0; i < mesh_extensions().size(); ++i) endings[i] = mesh_extensions()[i];
    m.attr("MESH_EXTENSIONS") = endings;

    m.def(
        "read_tgf",
        [](const std::string& path) {
            TgfSkeleton s;
            {
                py::gil_scoped_release release;
                auto src = open_file(path);
                s = read_tgf(*src);
            }
            return py::make_tuple(rows(std::move(s.joints)), rows(std::move(s.edges)));
        },
        py::arg("path"), "read_tgf(path) -> (joints (K, 3) float64, edges (E, 2) uint32, 0-based).");

    m.def(
        "voxelize",
        [](const Vertices& vertices, const Faces& faces, double voxel_size, double padding, double closing_radius,
           const py::object& progress, const std::optional<std::array<double, 3>>& anchor, const std::string& method) {
            const std::size_t nv = rows_of(vertices, "vertices"), nf = rows_of(faces, "faces");
            VoxelizeOptions opt;
            opt.padding_voxels = padding;
            opt.closing_radius = closing_radius;
            opt.anchor = anchor;
            if (method == "flood")
                opt.method = VoxelizeMethod::Flood;
            else if (method == "winding")
                opt.method = VoxelizeMethod::Winding;
            else if (method == "auto")
                opt.method = VoxelizeMethod::Auto;
            else
                throw Error("voxelize: method must be 'auto', 'winding' or 'flood', got '" + method + "'");
            Progress p = progress_of(progress);
            Volume v;
            {
                py::gil_scoped_release release;
                const Mesh mesh = make_mesh(vertices.data(), nv, faces.data(), nf, "voxelize");
                v = voxelize(mesh, voxel_size, opt, p);
            }
            return volume_tuple(std::move(v));
        },
        py::arg("vertices"), py::arg("faces"), py::arg("voxel_size"), py::arg("padding") = 2.0,
        py::arg("closing_radius") = 1.5, py::arg("progress") = py::none(), py::arg("anchor") = py::none(),
        py::arg("method") = "flood",
        "voxelize(vertices (V, 3), faces (F, 3), voxel_size, padding=2, closing_radius=1.5, progress=None, "
        "anchor=None, method='flood')\n"
        "-> (uint8 mask [z, y, x], spacing, origin). See volrig/mesh.hpp.");
}

}  // namespace volrig::py

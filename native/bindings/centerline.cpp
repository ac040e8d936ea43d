// Bindings for volrig/centerline.hpp: centerlines, centerline trees, straightening. Conversions only.
#include "volrig/centerline.hpp"

#include <optional>

#include "convert.hpp"

namespace volrig::py {

namespace {

struct GraphInput {
    Grid grid;
    const std::uint8_t* mask;
    const float* dt;
};

GraphInput graph_input(const MaskArray& mask, const FloatArray& dt, const Vec3& spacing, const Vec3& origin) {
    GraphInput in{grid_of(mask, spacing, origin, "mask"), mask.data(), dt.data()};
    if (dt.ndim() != 3 || dt.shape(0) != mask.shape(0) || dt.shape(1) != mask.shape(1) || dt.shape(2) != mask.shape(2))
        throw Error("centerline: the distance transform must have the mask's shape");
    return in;
}

py::tuple line_tuple(Centerline&& c) {
    const auto n = static_cast<py::ssize_t>(c.points.size());
    const double length = c.length;
    return py::make_tuple(rows(std::move(c.points)), to_numpy_shaped(std::move(c.radii), {n}), length,
                          to_numpy_shaped(std::move(c.voxels), {static_cast<py::ssize_t>(c.voxels.size())}));
}

CenterlineOptions line_options(double power, double step, double smoothing, int refine) {
    CenterlineOptions o;
    o.power = power;
    o.step = step;
    o.smoothing = smoothing;
    o.refine = refine;
    return o;
}

std::vector<Vec3d> points_of(const DoubleArray& pts, const char* what) {
    if (pts.ndim() != 2 || pts.shape(1) != 3) throw Error(std::string(what) + ": points must have shape (N, 3)");
    std::vector<Vec3d> out(static_cast<std::size_t>(pts.shape(0)));
    for (std::size_t i = 0; i < out.size(); ++i)
        for (int a = 0; a < 3; ++a) out[i][static_cast<std::size_t>(a)] = pts.at(static_cast<py::ssize_t>(i), a);
    return out;
}

}  // namespace

void bind_centerline(py::module_& m) {
    m.def(
        "centerline",
        [](const MaskArray& mask, const FloatArray& dt, const Vec3& spacing, const Vec3& origin,
           std::optional<Vec3> start, std::optional<Vec3> end, double power, double step, double smoothing,
           int refine, const py::object& progress) {
            const GraphInput in = graph_input(mask, dt, spacing, origin);
            const CenterlineOptions opt = line_options(power, step, smoothing, refine);
            Progress p = progress_of(progress);
            Centerline c;
            {
                py::gil_scoped_release nogil;
                const VoxelGraph g = voxel_graph(in.grid, in.mask, in.dt);
                c = centerline(g, in.mask, start ? &*start : nullptr, end ? &*end : nullptr, opt, p);
            }
            return line_tuple(std::move(c));
        },
        py::arg("mask"), py::arg("dt"), py::arg("spacing"), py::arg("origin"), py::arg("start"), py::arg("end"),
        py::arg("power"), py::arg("step"), py::arg("smoothing"), py::arg("refine"), py::arg("progress") = py::none());

    m.def(
        "centerline_tree",
        [](const MaskArray& mask, const FloatArray& dt, const Vec3& spacing, const Vec3& origin,
           std::optional<Vec3> root, double power, double step, double smoothing, int refine, double scale,
           double constant, double prune, const py::object& progress) {
            const GraphInput in = graph_input(mask, dt, spacing, origin);
            TreeCenterlineOptions opt;
            opt.line = line_options(power, step, smoothing, refine);
            opt.scale = scale;
            opt.constant = constant;
            opt.prune = prune;
            Progress p = progress_of(progress);
            CenterlineTree t;
            {
                py::gil_scoped_release nogil;
                const VoxelGraph g = voxel_graph(in.grid, in.mask, in.dt);
                t = centerline_tree(g, in.mask, root ? &*root : nullptr, opt, p);
            }
            py::list branches;
            for (auto& b : t.branches) branches.append(line_tuple(std::move(b)));
            const auto nb = static_cast<py::ssize_t>(t.parents.size());
            return py::make_tuple(branches, to_numpy_shaped(std::move(t.parents), {nb}),
                                  to_numpy_shaped(std::move(t.generations), {nb}));
        },
        py::arg("mask"), py::arg("dt"), py::arg("spacing"), py::arg("origin"), py::arg("root"), py::arg("power"),
        py::arg("step"), py::arg("smoothing"), py::arg("refine"), py::arg("scale"), py::arg("constant"),
        py::arg("prune"), py::arg("progress") = py::none());

    m.def(
        "straighten",
        [](const FloatArray& values, const Vec3& spacing, const Vec3& origin, const DoubleArray& points,
           std::int64_t half, double step, float fill) {
            const Grid g = grid_of(values, spacing, origin, "volume");
            const std::vector<Vec3d> pts = points_of(points, "straighten");
            if (pts.size() < 2) throw Error("straighten: the centerline needs at least 2 points");
            std::vector<Vec3d> t, u, v;
            std::vector<float> out;
            {
                py::gil_scoped_release nogil;
                rotation_minimising_frames(pts, t, u, v);
                out = straighten(g, values.data(), pts, u, v, half, step, fill);
            }
            const auto n = static_cast<py::ssize_t>(pts.size()), side = static_cast<py::ssize_t>(2 * half + 1);
            return py::make_tuple(to_numpy_shaped(std::move(out), {n, side, side}), rows(std::move(t)),
                                  rows(std::move(u)), rows(std::move(v)));
        },
        py::arg("values"), py::arg("spacing"), py::arg("origin"), py::arg("points"), py::arg("half"), py::arg("step"),
        py::arg("fill"));
}

}  // namespace volrig::py

// Bindings: feature tracking (a step's features; overlaps of points with the next step's features).
#include "per_voxel.hpp"
#include "volrig/track.hpp"

namespace volrig::py {

namespace {

/// A C-contiguous 1-D array of T (or None, when `optional`): its data, with n entries (n < 0: any, set).
template <class T>
const T* column(const py::handle& h, std::ptrdiff_t& n, const char* what, bool optional = false) {
    if (optional && h.is_none()) return nullptr;
    const auto arr = py::reinterpret_borrow<py::array>(h);
    if (!py::isinstance<py::array>(h) || !arr.dtype().is(py::dtype::of<T>()) || arr.ndim() != 1 ||
        !(arr.flags() & py::array::c_style))
        throw Error(std::string("step_overlaps: ") + what + " must be a contiguous 1-D array of the expected type");
    if (n >= 0 && arr.shape(0) != n) throw Error(std::string("step_overlaps: ") + what + " has the wrong length");
    n = arr.shape(0);
    return static_cast<const T*>(arr.data());
}

template <class I, class L>
StepPoints<I, L> side_of(const py::tuple& t, Grid& g, bool first) {
    if (t.size() != 7) throw Error("step_overlaps: a step is (labels, count, index, label, weight, sizes, totals)");
    if (!py::isinstance<py::array>(t[0])) throw Error("step_overlaps: a step's labels must be a numpy array");
    const auto look = py::reinterpret_borrow<py::array>(t[0]);
    const Grid own = grid_of(look, {1, 1, 1}, {0, 0, 0}, "step_overlaps labels");
    if (!first && own.dims != g.dims) throw Error("step_overlaps: the two steps' labels differ in shape");
    g = own;
    StepPoints<I, L> p;
    p.labels = static_cast<const L*>(look.data());
    p.count = t[1].cast<std::int32_t>();
    std::ptrdiff_t n = -1, nf = p.count, nt = p.count + 1;
    p.index = column<I>(t[2], n, "index");
    p.label = column<L>(t[3], n, "label (of the labels' type)");
    p.n = static_cast<std::size_t>(n);
    p.weight = column<float>(t[4], n, "weight", true);
    p.sizes = column<std::int64_t>(t[5], nf, "sizes", true);
    p.totals = column<double>(t[6], nt, "totals", true);
    return p;
}

template <class I, class L>
py::tuple overlaps_run(const py::tuple& a, const py::tuple& b, bool both) {
    Grid g;
    const StepPoints<I, L> pa = side_of<I, L>(a, g, true), pb = side_of<I, L>(b, g, false);
    if (!py::array(b[0]).dtype().is(py::dtype::of<L>())) throw Error("step_overlaps: the steps' labels differ in type");
    Overlaps o;
    {
        py::gil_scoped_release nogil;
        o = step_overlaps(g, pa, pb, both);
    }
    const auto k = static_cast<py::ssize_t>(o.a.size());
    return py::make_tuple(to_numpy_shaped(std::move(o.a), {k}), to_numpy_shaped(std::move(o.b), {k}),
                          to_numpy_shaped(std::move(o.overlap), {k}));
}

Runs runs_of(const py::array& a, std::int32_t count) {
    if (!a.dtype().is(py::dtype::of<std::int32_t>()) || a.ndim() != 2 || a.shape(0) != 4 ||
        !(a.flags() & py::array::c_style))
        throw Error("run_overlaps: runs must be a C-contiguous int32 array (4, n): row, x0, x1, label");
    Runs r;
    r.n = static_cast<std::size_t>(a.shape(1));
    const auto* p = static_cast<const std::int32_t*>(a.data());
    r.row = p, r.x0 = p + r.n, r.x1 = p + 2 * r.n, r.label = p + 3 * r.n, r.count = count;
    return r;
}

template <class L>
py::tuple overlaps_as(const py::tuple& a, const py::tuple& b, bool both, bool small_index) {
    return small_index ? overlaps_run<std::uint32_t, L>(a, b, both) : overlaps_run<std::int64_t, L>(a, b, both);
}

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
        "step_overlaps",
        [](const py::tuple& a, const py::tuple& b, bool both) {
            const py::array look = a[0];
            const bool small_index = py::array(a[2]).dtype().is(py::dtype::of<std::uint32_t>());
            const auto label = look.dtype();
            if (label.is(py::dtype::of<std::uint8_t>())) return overlaps_as<std::uint8_t>(a, b, both, small_index);
            if (label.is(py::dtype::of<std::uint16_t>())) return overlaps_as<std::uint16_t>(a, b, both, small_index);
            if (label.is(py::dtype::of<std::int32_t>())) return overlaps_as<std::int32_t>(a, b, both, small_index);
            throw Error("step_overlaps: labels must be uint8, uint16 or int32");
        },
        py::arg("a"), py::arg("b"), py::arg("both"),
        "(a int32, b int32, overlap float64) sorted by (a, b): the overlaps of step a's features with step b's. "
        "a, b: (labels [z, y, x], count, index ascending uint32 or int64, label, weight float32 or None, sizes "
        "int64 or None, totals float64 or None), labels one type (uint8, uint16 or int32); a's points are looked up "
        "in b's labels and with both b's in a's, the larger estimate kept");
    m.def(
        "run_overlaps",
        [](const py::array& a, std::int32_t na, const py::array& b, std::int32_t nb) {
            const Runs ra = runs_of(a, na), rb = runs_of(b, nb);
            Overlaps o;
            {
                py::gil_scoped_release nogil;
                o = run_overlaps(ra, rb);
            }
            const auto k = static_cast<py::ssize_t>(o.a.size());
            return py::make_tuple(to_numpy_shaped(std::move(o.a), {k}), to_numpy_shaped(std::move(o.b), {k}),
                                  to_numpy_shaped(std::move(o.overlap), {k}));
        },
        py::arg("a"), py::arg("a_count"), py::arg("b"), py::arg("b_count"),
        "(a int32, b int32, overlap float64) sorted by (a, b): the exact overlaps of two steps' features from their "
        "runs, each int32 (4, n): row (z * ny + y), x0, x1 (past the end), label, sorted by (row, x0)");
}

}  // namespace volrig::py

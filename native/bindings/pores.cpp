// Bindings for volrig/pores.hpp: the pore network of a pore mask, and the network's transport solve.
#include "volrig/pores.hpp"
#include "convert.hpp"

namespace volrig::py {

namespace {

using IndexArray = py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>;
using FlagArray = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;

/// The network as a dict of numpy arrays (the vectors handed over without copies).
py::dict network_dict(PoreNetwork&& n, const Grid& g) {
    const auto np = static_cast<py::ssize_t>(n.pore_count()), nt = static_cast<py::ssize_t>(n.throat_count());
    py::dict d;
    d["pore_voxels"] = n.pore_voxels;
    d["pore_coords"] = to_numpy_shaped(std::move(n.pore_coords), {np, 3});
    d["pore_inscribed_diameter"] = to_numpy_shaped(std::move(n.pore_inscribed), {np});
    d["pore_volume"] = to_numpy_shaped(std::move(n.pore_volume), {np});
    d["pore_faces"] = to_numpy_shaped(std::move(n.pore_faces), {np});
    d["throat_conns"] = to_numpy_shaped(std::move(n.throat_conns), {nt, 2});
    d["throat_inscribed_diameter"] = to_numpy_shaped(std::move(n.throat_inscribed), {nt});
    d["throat_coords"] = to_numpy_shaped(std::move(n.throat_coords), {nt, 3});
    d["throat_area"] = to_numpy_shaped(std::move(n.throat_area), {nt});
    d["throat_total_length"] = to_numpy_shaped(std::move(n.throat_total_length), {nt});
    if (!n.regions.empty()) d["regions"] = to_numpy(std::move(n.regions), g);
    return d;
}

}  // namespace

void bind_pores(py::module_& m) {
    m.def(
        "pore_network",
        [](const MaskArray& mask, const Vec3& spacing, const Vec3& origin, bool regions, const py::object& progress) {
            const Grid g = grid_of(mask, spacing, origin, "mask");
            Progress p = progress_of(progress);
            PoreNetwork n;
            {
                py::gil_scoped_release nogil;
                n = extract_pore_network(g, mask.data(), p, regions);
            }
            return network_dict(std::move(n), g);
        },
        py::arg("mask"), py::arg("spacing"), py::arg("origin"), py::arg("regions") = false,
        py::arg("progress") = py::none());
    m.def(
        "network_rate",
        [](std::size_t nodes, const IndexArray& conns, const DoubleArray& g, const FlagArray& inlet,
           const FlagArray& outlet) {
            if (conns.ndim() != 2 || conns.shape(1) != 2) throw Error("network_rate: conns must have shape (M, 2)");
            if (g.ndim() != 1 || g.shape(0) != conns.shape(0)) throw Error("network_rate: g must have shape (M,)");
            const auto n = static_cast<py::ssize_t>(nodes);
            if (inlet.size() != n || outlet.size() != n)
                throw Error("network_rate: inlet and outlet need one flag a node");
            py::gil_scoped_release nogil;
            return network_rate(nodes, conns.data(), g.data(), static_cast<std::size_t>(g.shape(0)), inlet.data(),
                                outlet.data());
        },
        py::arg("nodes"), py::arg("conns"), py::arg("g"), py::arg("inlet"), py::arg("outlet"));
}

}  // namespace volrig::py

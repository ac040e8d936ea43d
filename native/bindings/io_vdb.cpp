// Bindings for OpenVDB reading and writing (volrig/io.hpp, "OpenVDB"). Conversions only.
#include <algorithm>
#include <array>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "convert.hpp"
#include "volrig/io.hpp"

namespace volrig::py {

namespace {

using Grids = std::vector<std::pair<std::string, py::array>>;

/// build_vdb over write_vdb's / build_vdb's Python arguments (C-contiguous copies where needed; float16 arrays as
/// views of half floats; the GIL released while the grids are built).
VdbGrids built_grids(const std::string& path, const Grids& grids, const std::array<double, 3>& spacing,
                     const std::array<double, 3>& origin, bool half, const std::vector<std::array<double, 3>>& origins,
                     const std::vector<std::string>& labels, const VdbMetadata& metadata) {
    if (!origins.empty() && origins.size() != grids.size())
        throw Error(path + ": " + std::to_string(origins.size()) + " origins for " + std::to_string(grids.size()) +
                    " grids");
    std::vector<py::array> keep;  // the arrays the views look at, alive while building
    std::vector<std::pair<std::string, VolumeView>> views;
    for (std::size_t i = 0; i < grids.size(); ++i) {
        const auto& [name, array] = grids[i];
        const bool halves = py::str(array.dtype()).cast<std::string>() == "float16";
        keep.push_back(py::array::ensure(halves ? py::array(array.attr("view")("uint16")) : array, py::array::c_style));
        if (!keep.back()) throw Error(path + ": grid '" + name + "' is not a numeric array");
        views.emplace_back(name, view_of(keep.back(), spacing, origins.empty() ? origin : origins[i], path.c_str(), true));
        views.back().second.half = halves;
        views.back().second.labels = std::find(labels.begin(), labels.end(), name) != labels.end();
    }
    py::gil_scoped_release release;
    return build_vdb(path, views, half, metadata);
}

}  // namespace

void bind_vdb(py::module_& m) {
    m.def(
        "read_vdb",
        [](const std::string& path, const std::string& grid, long long max_bytes,
           const std::optional<std::array<std::array<std::int64_t, 3>, 2>>& crop) {
            ReadOptions opt;
            if (max_bytes >= 0) opt.max_bytes = static_cast<std::uint64_t>(max_bytes), opt.max_bytes_given = true;
            if (crop) opt.crop = ReadOptions::IndexBox{(*crop)[0], (*crop)[1]};
            Volume v;
            {
                py::gil_scoped_release release;
                v = read_vdb(path, grid, opt);
            }
            return volume_tuple(std::move(v));
        },
        py::arg("path"), py::arg("grid") = "", py::arg("max_bytes") = -1, py::arg("crop") = py::none(),
        "read_vdb(path, grid='', max_bytes=-1, crop=None) -> (array [z, y, x], spacing (x, y, z), origin (x, y, z))\n\n"
        "Reads one scalar grid (default 'density', else the first scalar grid) densely over its active voxel\n"
        "bounding box, met with crop ((x0, y0, z0), (x1, y1, z1)), index coordinates, inclusive) when given.\n"
        "float -> float32, double -> float64, int32/int64 -> int32/int64, bool -> uint8.\n"
        "max_bytes < 0 uses the default limit.");

    m.def(
        "vdb_grids",
        [](const std::string& path) {
            std::vector<VdbGridInfo> grids;
            {
                py::gil_scoped_release release;
                grids = vdb_grids(path);
            }
            py::list out;
            for (const auto& g : grids) {
                py::dict d;
                d["name"] = g.name;
                d["type"] = g.type;
                d["bbox_min"] = py::make_tuple(g.bbox_min[0], g.bbox_min[1], g.bbox_min[2]);
                d["bbox_max"] = py::make_tuple(g.bbox_max[0], g.bbox_max[1], g.bbox_max[2]);
                d["active_voxels"] = g.active_voxels;
                out.append(d);
            }
            return out;
        },
        py::arg("path"),
        "vdb_grids(path) -> list of dict(name, type, bbox_min, bbox_max, active_voxels);\n"
        "bounding boxes are index coordinates (x, y, z), inclusive.");

    m.def(
        "write_vdb",
        [](const std::string& path, const Grids& grids, const std::array<double, 3>& spacing,
           const std::array<double, 3>& origin, bool half, const std::vector<std::array<double, 3>>& origins,
           const std::vector<std::string>& labels, const VdbMetadata& metadata) {
            VdbGrids built = built_grids(path, grids, spacing, origin, half, origins, labels, metadata);
            py::gil_scoped_release release;
            built.write(path);
        },
        py::arg("path"), py::arg("grids"), py::arg("spacing"), py::arg("origin"), py::arg("half") = false,
        py::arg("origins") = std::vector<std::array<double, 3>>{}, py::arg("labels") = std::vector<std::string>{},
        py::arg("metadata") = VdbMetadata{},
        "write_vdb(path, grids, spacing, origin, half=False, origins=[], labels=[], metadata=[])\n\n"
        "grids: list of (name, numpy array [z, y, x], or [brick z, y, x, z, y, x] in 8³ bricks as a Deformer's\n"
        "frame in bricks); spacing and origin (x, y, z), or one origin per grid\n"
        "(origins), each a whole number of voxels from the first grid's (one voxel lattice).\n"
        "float32/float64/uint8/bool arrays become float grids (half floats when half), other integer arrays\n"
        "int32 grids, and so do the integer grids named in labels (uint8 too). Only non-zero voxels are active.\n"
        "metadata: the file's string metadata, (name, value) pairs.\n"
        "Written to a temporary file and renamed.");

    py::class_<VdbGrids>(m, "VdbGrids", "Grids built by build_vdb, for one write (then freed).")
        .def(
            "write",
            [](VdbGrids& g, const std::string& path) {
                py::gil_scoped_release release;
                g.write(path);
            },
            py::arg("path"))
        .def_property_readonly("written", &VdbGrids::written);
    m.def(
        "build_vdb",
        &built_grids,
        py::arg("path"), py::arg("grids"), py::arg("spacing"), py::arg("origin"), py::arg("half") = false,
        py::arg("origins") = std::vector<std::array<double, 3>>{}, py::arg("labels") = std::vector<std::string>{},
        py::arg("metadata") = VdbMetadata{},
        "build_vdb(path, grids, spacing, origin, half=False, origins=[], labels=[], metadata=[]) -> VdbGrids\n\n"
        "write_vdb's first half: the grids built (and checked) now, written by VdbGrids.write(path) later; the\n"
        "arrays may go in between. path names the file in errors.");
}

}  // namespace volrig::py

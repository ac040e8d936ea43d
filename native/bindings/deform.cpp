// Bindings for volrig/deform.hpp: the Deformer, the thesis' brute-force reference and the inverse-warp speed
// reference. Conversions only.
#include "volrig/deform.hpp"

#include <memory>
#include <optional>
#include <utility>

#include "convert.hpp"
#include "sphere_arrays.hpp"

namespace volrig::py {

namespace {

using Box = std::optional<std::array<std::int64_t, 6>>;

struct PyDeformer {
    py::array source;  // keeps the samples alive
    SphereArrays spheres;
    std::unique_ptr<Deformer> deformer;
    py::array layer_source;  // the rigid layer's samples and pieces, kept alive
    std::vector<MaskArray> layer_pieces;
};

DeformOptions options_of(const std::string& mode, const std::string& proximity, const std::string& sampling,
                         const py::object& radius_scale, bool values, bool keep_volume) {
    DeformOptions o;
    o.mode = deform_mode_from_name(mode);
    o.proximity = proximity_from_name(proximity);
    o.sampling = sampling_from_name(sampling);
    o.values = values;
    o.keep_volume = keep_volume;
    o.radius_scale = radius_scale_of(radius_scale);
    return o;
}

py::dict frame_dict(DeformedVolume&& f) {
    py::dict d;
    if (!f.half_values.empty())  // IEEE half floats: numpy's float16
        d["values"] = to_numpy(std::move(f.half_values), f.grid, f.bricks).attr("view")("float16");
    else
        d["values"] = f.values.empty() ? py::object(py::none()) : py::object(to_numpy(std::move(f.values), f.grid, f.bricks));
    if (!f.bone8.empty())  // byte labels (DeformOptions::half, fewer than 255 bones)
        d["bone"] = to_numpy(std::move(f.bone8), f.grid, f.bricks);
    else
        d["bone"] = to_numpy(std::move(f.bone), f.grid, f.bricks);
    d["bricks"] = f.bricks;
    d["extent"] = py::make_tuple(f.extent[0], f.extent[1], f.extent[2], f.extent[3], f.extent[4], f.extent[5]);
    d["offset"] = py::make_tuple(f.offset[0], f.offset[1], f.offset[2]);
    d["origin"] = py::make_tuple(f.grid.origin[0], f.grid.origin[1], f.grid.origin[2]);
    // Frame.stats: these names are the only place Python spells them (volrig/deform.hpp, DeformStats)
    py::dict stats;
    stats["covered"] = f.stats.covered;
    stats["exact_queries"] = f.stats.exact_queries;
    stats["blended_spheres"] = f.stats.blended_spheres;
    stats["by_block"] = f.stats.by_block;
    stats["by_cube"] = f.stats.by_cube;
    stats["by_sphere"] = f.stats.by_sphere;
    stats["by_search"] = f.stats.by_search;
    stats["exact_sub_blocks"] = f.stats.exact_sub_blocks;
    stats["rigid_layer"] = f.stats.rigid_layer;
    stats["contact"] = f.stats.contact;
    d["stats"] = stats;
    return d;
}

/// The rigid pieces of a Python list of (bone, box {offset, dims}, packed bits of the box's voxels: RigidPiece); the
/// arrays stay alive in `keep`.
std::vector<RigidPiece> pieces_of(const py::list& pieces, std::vector<MaskArray>& keep) {
    std::vector<RigidPiece> out;
    for (const py::handle& h : pieces) {
        const auto t = h.cast<py::tuple>();
        if (t.size() != 3) throw Error("rigid layer: a piece is (bone, box, bits)");
        RigidPiece p;
        p.bone = t[0].cast<std::int32_t>();
        p.box = t[1].cast<std::array<std::int64_t, 6>>();
        keep.push_back(t[2].cast<MaskArray>());
        const MaskArray& v = keep.back();
        if (p.box[3] < 1 || p.box[4] < 1 || p.box[5] < 1 || p.box[3] > (1 << 30) || p.box[4] > (1 << 30) ||
            p.box[5] > (1 << 30))
            throw Error("rigid layer: a piece's box has impossible dims");
        const std::int64_t n = p.box[3] * p.box[4] * p.box[5];
        if (v.ndim() != 1 || v.shape(0) != (n + 7) / 8)
            throw Error("rigid layer: a piece's bits do not hold its box's voxels");
        p.bits = v.data();
        out.push_back(p);
    }
    return out;
}

/// LATTICE_AFTER and the Deformer class (a rig's deformation of one volume, frame after frame).
void bind_deformer_class(py::module_& m) {
    m.attr("LATTICE_AFTER") = volrig::Deformer::kLatticeAfter;
    py::class_<PyDeformer>(m, "Deformer")
        .def(py::init([](const py::array& source, const Vec3& spacing, const Vec3& origin, const IjkArray& ijk,
                         const FloatArray& radius, const Int32Array& bone, std::size_t bone_count,
                         std::optional<Int64Array> offsets, std::optional<Int32Array> wbones,
                         std::optional<FloatArray> weights) {
                 auto d = std::make_unique<PyDeformer>();
                 d->source = py::array::ensure(source, py::array::c_style);
                 if (!d->source) throw Error("deform: the source is not a numeric array");
                 d->spheres = SphereArrays{ijk, radius, bone, bone_count, std::move(offsets), std::move(wbones),
                                           std::move(weights)};
                 const VolumeView v = view_of(d->source, spacing, origin, "deform source");
                 d->deformer = std::make_unique<Deformer>(v, d->spheres.view());
                 return d;
             }),
             py::arg("source"), py::arg("spacing"), py::arg("origin"), py::arg("ijk"), py::arg("radius"),
             py::arg("bone"), py::arg("bone_count"), py::arg("weight_offsets") = py::none(),
             py::arg("weight_bones") = py::none(), py::arg("weights") = py::none())
        .def(
            "frame",
            [](PyDeformer& d, const DoubleArray& matrices, const std::string& mode, const std::string& proximity,
               const std::string& sampling, const py::object& radius_scale, bool values, const py::object& progress,
               const Box& box, bool keep_volume, bool bricks, bool half) {
                DeformOptions o = options_of(mode, proximity, sampling, radius_scale, values, keep_volume);
                o.bricks = bricks;
                o.half = half;
                const double* mat = matrices_of(matrices, d.deformer->bone_count());
                Progress p = progress_of(progress);
                DeformedVolume f;
                {
                    py::gil_scoped_release nogil;
                    f = d.deformer->frame(mat, o, p, box ? &*box : nullptr);
                }
                return frame_dict(std::move(f));
            },
            py::arg("matrices"), py::arg("mode") = "rigid", py::arg("proximity") = "power",
            py::arg("sampling") = "trilinear", py::arg("radius_scale") = py::none(), py::arg("values") = true,
            py::arg("progress") = py::none(), py::arg("box") = py::none(), py::arg("keep_volume") = true,
            py::arg("bricks") = false, py::arg("half") = false)
        .def_property_readonly("memory_bytes", [](const PyDeformer& d) { return d.deformer->memory_bytes(); })
        .def_property_readonly("kept_frame_bytes", [](const PyDeformer& d) { return d.deformer->kept_frame_bytes(); })
        .def("release_frame_memory", [](PyDeformer& d) { d.deformer->release_frame_memory(); })
        .def(
            "rebind",
            [](PyDeformer& d, const IjkArray& ijk, const FloatArray& radius, const Int32Array& bone, std::size_t bone_count,
               std::optional<Int64Array> offsets, std::optional<Int32Array> wbones, std::optional<FloatArray> weights) {
                SphereArrays next{ijk, radius, bone, bone_count, std::move(offsets), std::move(wbones), std::move(weights)};
                d.deformer->rebind(next.view());
                d.spheres = std::move(next);
            },
            py::arg("ijk"), py::arg("radius"), py::arg("bone"), py::arg("bone_count"),
            py::arg("weight_offsets") = py::none(), py::arg("weight_bones") = py::none(), py::arg("weights") = py::none())
        .def_property_readonly("reused_fields", [](const PyDeformer& d) { return d.deformer->reused_fields(); })
        .def_property(
            "lattice_after", [](const PyDeformer& d) { return d.deformer->lattice_after(); },
            [](PyDeformer& d, int frames) { d.deformer->set_lattice_after(frames); })
        .def_property_readonly("lattice_tables", [](const PyDeformer& d) { return d.deformer->lattice_tables(); })
        .def(
            "set_source",
            [](PyDeformer& d, const py::array& source, const Vec3& spacing, const Vec3& origin) {
                const py::array src = py::array::ensure(source, py::array::c_style);
                if (!src) throw Error("deform: the source is not a numeric array");
                d.deformer->set_source(view_of(src, spacing, origin, "deform source"));
                d.source = src;
            },
            py::arg("source"), py::arg("spacing"), py::arg("origin"))
        .def(
            "set_rigid_layer",
            [](PyDeformer& d, const py::array& source, const Vec3& spacing, const Vec3& origin, const py::list& pieces) {
                const py::array src = py::array::ensure(source, py::array::c_style);
                if (!src) throw Error("rigid layer: the source is not a numeric array");
                std::vector<MaskArray> keep;
                auto p = pieces_of(pieces, keep);
                d.deformer->set_rigid_layer(view_of(src, spacing, origin, "rigid layer source"), std::move(p));
                d.layer_source = src;
                d.layer_pieces = std::move(keep);
            },
            py::arg("source"), py::arg("spacing"), py::arg("origin"), py::arg("pieces"));
}

}  // namespace

void bind_deform(py::module_& m) {
    bind_deformer_class(m);
    // The option names, spelled once in the core (volrig/deform.hpp), in enum order.
    m.attr("DEFORM_MODES") = names_tuple(kDeformModeNames);
    m.attr("PROXIMITIES") = names_tuple(kProximityNames);
    m.attr("SAMPLINGS") = names_tuple(kSamplingNames);

    m.def(
        "deform_reference",
        [](const py::array& source, const Vec3& spacing, const Vec3& origin, const IjkArray& ijk,
           const FloatArray& radius, const Int32Array& bone, std::size_t bone_count, std::optional<Int64Array> offsets,
           std::optional<Int32Array> wbones, std::optional<FloatArray> weights, const DoubleArray& matrices,
           const std::string& mode, const std::string& proximity, const std::string& sampling,
           const py::object& radius_scale, bool values, const Box& box, bool keep_volume) {
            const py::array src = py::array::ensure(source, py::array::c_style);
            if (!src) throw Error("deform: the source is not a numeric array");
            const SphereArrays arrays{ijk, radius, bone, bone_count, std::move(offsets), std::move(wbones),
                                      std::move(weights)};
            const BoundSpheres s = arrays.view();
            const VolumeView v = view_of(src, spacing, origin, "deform source");
            const DeformOptions o = options_of(mode, proximity, sampling, radius_scale, values, keep_volume);
            const double* mat = matrices_of(matrices, bone_count);
            DeformedVolume f;
            {
                py::gil_scoped_release nogil;
                f = deform_reference(v, s, mat, o, {}, box ? &*box : nullptr);
            }
            return frame_dict(std::move(f));
        },
        py::arg("source"), py::arg("spacing"), py::arg("origin"), py::arg("ijk"), py::arg("radius"), py::arg("bone"),
        py::arg("bone_count"), py::arg("weight_offsets"), py::arg("weight_bones"), py::arg("weights"),
        py::arg("matrices"), py::arg("mode") = "rigid", py::arg("proximity") = "power",
        py::arg("sampling") = "trilinear", py::arg("radius_scale") = py::none(), py::arg("values") = true,
        py::arg("box") = py::none(), py::arg("keep_volume") = true);

    m.def(
        "rigid_pieces_box",
        [](const std::array<std::int64_t, 3>& shape_zyx, const Vec3& spacing, const Vec3& origin,
           const py::list& pieces, const DoubleArray& matrices, std::size_t bone_count) {
            Grid g;
            g.dims = {shape_zyx[2], shape_zyx[1], shape_zyx[0]};
            g.spacing = spacing;
            g.origin = origin;
            std::vector<MaskArray> keep;
            const auto p = pieces_of(pieces, keep);
            return rigid_pieces_box(g, p, matrices_of(matrices, bone_count), bone_count);
        },
        py::arg("shape"), py::arg("spacing"), py::arg("origin"), py::arg("pieces"), py::arg("matrices"),
        py::arg("bone_count"));

    m.def(
        "paint_rigid_pieces",
        [](const py::array& source, const Vec3& spacing, const Vec3& origin, const py::list& pieces,
           const DoubleArray& matrices, std::size_t bone_count, const std::string& sampling,
           const std::array<std::int64_t, 6>& box, std::optional<py::array_t<float, py::array::c_style>> values,
           py::array_t<std::int16_t, py::array::c_style> bone) {
            const py::array src = py::array::ensure(source, py::array::c_style);
            if (!src) throw Error("rigid layer: the source is not a numeric array");
            const VolumeView v = view_of(src, spacing, origin, "rigid layer source");
            const auto fits = [&](const py::array& a) {
                return a.ndim() == 3 && a.shape(0) == box[5] && a.shape(1) == box[4] && a.shape(2) == box[3] &&
                       a.writeable();
            };
            if (!fits(bone) || (values && !fits(*values)))
                throw Error("rigid layer: the output arrays must be writable and have the box's dims");
            std::vector<MaskArray> keep;
            const auto p = pieces_of(pieces, keep);
            const double* mat = matrices_of(matrices, bone_count);
            const Sampling smp = sampling_from_name(sampling);
            float* out_values = values ? values->mutable_data() : nullptr;
            std::int16_t* out_bone = bone.mutable_data();
            py::gil_scoped_release nogil;
            return paint_rigid_pieces(v, p, mat, bone_count, smp, box, out_values, out_bone);
        },
        py::arg("source"), py::arg("spacing"), py::arg("origin"), py::arg("pieces"), py::arg("matrices"),
        py::arg("bone_count"), py::arg("sampling"), py::arg("box"), py::arg("values").noconvert(),
        py::arg("bone").noconvert());

    m.def(
        "inverse_warp",
        [](const py::array& source, const Vec3& spacing, const Vec3& origin, const DoubleArray& matrix,
           const std::string& sampling, const Box& box) {
            const py::array src = py::array::ensure(source, py::array::c_style);
            if (!src) throw Error("inverse_warp: the source is not a numeric array");
            if (matrix.ndim() != 2 || matrix.shape(0) != 4 || matrix.shape(1) != 4)
                throw Error("inverse_warp: the matrix must be 4x4");
            const VolumeView v = view_of(src, spacing, origin, "inverse_warp source");
            const Sampling s = sampling_from_name(sampling);
            std::vector<float> out;
            {
                py::gil_scoped_release nogil;
                out = inverse_warp(v, matrix.data(), s, {}, box ? &*box : nullptr);
            }
            Grid g = v.grid;
            if (box) g.dims = {(*box)[3], (*box)[4], (*box)[5]};
            return to_numpy(std::move(out), g);
        },
        py::arg("source"), py::arg("spacing"), py::arg("origin"), py::arg("matrix"), py::arg("sampling") = "trilinear",
        py::arg("box") = py::none());
}

}  // namespace volrig::py

// Bindings for volrig/collide.hpp: the Collider, two-body and self-contact tests and their brute-force references.
// Conversions only.
#include "volrig/collide.hpp"

#include <memory>
#include <utility>

#include "convert.hpp"
#include "sphere_arrays.hpp"

namespace volrig::py {

namespace {

struct PyCollider {
    std::unique_ptr<Collider> collider;
};

CollideOptions collide_options(const std::string& mode, const py::object& radius_scale, bool keep_volume) {
    CollideOptions o;
    o.mode = deform_mode_from_name(mode);
    o.radius_scale = radius_scale_of(radius_scale);
    o.keep_volume = keep_volume;
    return o;
}

py::dict collision_dict(Collision&& c) {
    py::dict d;
    d["hit"] = c.hit;
    d["voxels"] = c.voxels;
    d["bones_a"] = c.bones_a;
    d["bones_b"] = c.bones_b;
    d["bone_pairs"] = c.bone_pairs;
    d["box"] = c.box;
    d["points"] = to_numpy_shaped(std::vector<std::int64_t>(reinterpret_cast<const std::int64_t*>(c.points.data()),
                                                            reinterpret_cast<const std::int64_t*>(c.points.data()) +
                                                                3 * c.points.size()),
                                  {static_cast<py::ssize_t>(c.points.size()), 3});
    py::dict stats;  // Collision.stats: the only place Python spells these names (volrig/collide.hpp)
    stats["field_pairs"] = c.stats.field_pairs;
    stats["node_pairs"] = c.stats.node_pairs;
    stats["sphere_pairs"] = c.stats.sphere_pairs;
    stats["lattice_tests"] = c.stats.lattice_tests;
    d["stats"] = stats;
    return d;
}

/// Runs a test without the GIL.
template <class F>
py::dict released(F&& f) {
    Collision c;
    {
        py::gil_scoped_release nogil;
        c = f();
    }
    return collision_dict(std::move(c));
}

}  // namespace

void bind_collide(py::module_& m) {
    py::class_<PyCollider>(m, "Collider")
        .def(py::init([](const Vec3& spacing, const Vec3& origin, const std::array<std::int64_t, 3>& dims,
                         const IjkArray& ijk, const FloatArray& radius, const Int32Array& bone, std::size_t bone_count,
                         std::optional<Int64Array> offsets, std::optional<Int32Array> wbones,
                         std::optional<FloatArray> weights, std::vector<std::int32_t> parents) {
                 const SphereArrays arrays{ijk, radius, bone, bone_count, std::move(offsets), std::move(wbones),
                                           std::move(weights)};
                 Grid g;
                 g.dims = dims;
                 g.spacing = spacing;
                 g.origin = origin;
                 auto c = std::make_unique<PyCollider>();
                 c->collider = std::make_unique<Collider>(g, arrays.view(), std::move(parents));
                 return c;
             }),
             py::arg("spacing"), py::arg("origin"), py::arg("dims"), py::arg("ijk"), py::arg("radius"), py::arg("bone"),
             py::arg("bone_count"), py::arg("weight_offsets") = py::none(), py::arg("weight_bones") = py::none(),
             py::arg("weights") = py::none(), py::arg("parents") = std::vector<std::int32_t>{})
        .def_property_readonly("bone_count", [](const PyCollider& c) { return c.collider->bone_count(); })
        .def_property_readonly("sphere_count", [](const PyCollider& c) { return c.collider->sphere_count(); })
        .def_property_readonly("memory_bytes", [](const PyCollider& c) { return c.collider->memory_bytes(); })
        .def("field_count", [](const PyCollider& c, const std::string& mode) {
            return c.collider->field_count(deform_mode_from_name(mode));
        });

    auto two_body = [](bool reference) {
        return [reference](const PyCollider& a, const DoubleArray& ma, const std::string& mode_a,
                           const py::object& scale_a, const PyCollider& b, const DoubleArray& mb,
                           const std::string& mode_b, const py::object& scale_b, bool points, bool keep_volume) {
            const CollideOptions oa = collide_options(mode_a, scale_a, keep_volume),
                                 ob = collide_options(mode_b, scale_b, keep_volume);
            const double* pa = matrices_of(ma, a.collider->bone_count());
            const double* pb = matrices_of(mb, b.collider->bone_count());
            return released([&] {
                return reference ? collide_reference(*a.collider, pa, oa, *b.collider, pb, ob)
                                 : collide(*a.collider, pa, oa, *b.collider, pb, ob, points);
            });
        };
    };
    auto self = [](bool reference) {
        return [reference](const PyCollider& a, const DoubleArray& ma, const std::string& mode,
                           const py::object& scale, int min_bone_distance, bool ignore_rest_contact, bool points,
                           bool keep_volume) {
            const CollideOptions o = collide_options(mode, scale, keep_volume);
            const double* p = matrices_of(ma, a.collider->bone_count());
            return released([&] {
                return reference ? self_collide_reference(*a.collider, p, o, min_bone_distance, ignore_rest_contact)
                                 : self_collide(*a.collider, p, o, min_bone_distance, ignore_rest_contact, points);
            });
        };
    };
    for (bool reference : {false, true}) {
        m.def(reference ? "collide_reference" : "collide", two_body(reference), py::arg("a"), py::arg("matrices_a"),
              py::arg("mode_a"), py::arg("radius_scale_a"), py::arg("b"), py::arg("matrices_b"), py::arg("mode_b"),
              py::arg("radius_scale_b"), py::arg("points") = false, py::arg("keep_volume") = true);
        m.def(reference ? "self_collide_reference" : "self_collide", self(reference), py::arg("a"),
              py::arg("matrices"), py::arg("mode"), py::arg("radius_scale"), py::arg("min_bone_distance"),
              py::arg("ignore_rest_contact"), py::arg("points") = false, py::arg("keep_volume") = true);
    }
}

}  // namespace volrig::py

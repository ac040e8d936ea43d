// sphere_arrays.hpp: what the deformation and collision bindings share: bound spheres given as NumPy arrays,
// bone matrices and radius scales. Conversions only.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "convert.hpp"
#include "volrig/deform.hpp"

namespace volrig::py {

using Int32Array = py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>;
using Int64Array = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>;

/// The arrays a BoundSpheres views, kept alive together.
struct SphereArrays {
    IjkArray ijk;
    FloatArray radius;
    Int32Array bone;
    std::size_t bone_count;
    std::optional<Int64Array> offsets;
    std::optional<Int32Array> wbones;
    std::optional<FloatArray> weights;

    BoundSpheres view() const {
        const PointSet p = point_set(ijk, &radius, "deform");
        if (bone.ndim() != 1 || bone.shape(0) != static_cast<py::ssize_t>(p.n))
            throw Error("deform: the binding has " + std::to_string(bone.size()) + " entries for " +
                        std::to_string(p.n) + " points: bind the same points you deform");
        BoundSpheres s;
        s.ijk = p.ijk;
        s.radius = p.radius;
        s.n = p.n;
        s.bone = bone.data();
        s.bone_count = bone_count;
        if (offsets && wbones && weights) {
            if (offsets->ndim() != 1 || offsets->shape(0) != static_cast<py::ssize_t>(p.n + 1))
                throw Error("deform: the weight matrix has " + std::to_string(offsets->size() - 1) + " rows for " +
                            std::to_string(p.n) + " points");
            const auto nnz = offsets->size() ? offsets->data()[p.n] : 0;
            if (wbones->size() != nnz || weights->size() != nnz || nnz < 0)
                throw Error("deform: the weight matrix's index and value arrays do not match its rows");
            s.weight_offsets = offsets->data();
            s.weight_bones = wbones->data();
            s.weights = weights->data();
        }
        return s;
    }
};

inline const double* matrices_of(const DoubleArray& m, std::size_t bones) {
    if (m.ndim() != 3 || m.shape(1) != 4 || m.shape(2) != 4)
        throw Error("deform: bone matrices must have shape (B, 4, 4)");
    if (static_cast<std::size_t>(m.shape(0)) != bones)
        throw Error("deform: got " + std::to_string(m.shape(0)) + " bone matrices for a rig of " +
                    std::to_string(bones) + " bones");
    return m.data();
}

/// None, or one factor per sphere.
inline std::vector<float> radius_scale_of(const py::object& radius_scale) {
    if (radius_scale.is_none()) return {};
    const FloatArray a = radius_scale.cast<FloatArray>();
    if (a.ndim() != 1) throw Error("radius_scale must be a 1-D array, one factor per point");
    return std::vector<float>(a.data(), a.data() + a.size());
}

}  // namespace volrig::py

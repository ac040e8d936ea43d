// Bindings helpers shared by the rig and skin bindings: a Rig from numpy arrays.
#pragma once

#include <string>
#include <vector>

#include "convert.hpp"
#include "volrig/rig.hpp"

namespace volrig::py {

using IntArray = py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>;

inline Rig rig_of(const DoubleArray& joints, const IntArray& bones, const std::vector<std::string>& names,
           const IntArray& parents) {
    if (joints.ndim() != 2 || joints.shape(1) != 3) throw Error("rig: joints must have shape (K, 3)");
    if (bones.ndim() != 2 || bones.shape(1) != 2) throw Error("rig: bones must have shape (B, 2)");
    if (parents.ndim() != 1) throw Error("rig: parents must have shape (B,)");
    Rig r;
    r.joints.resize(static_cast<std::size_t>(joints.shape(0)));
    for (std::size_t j = 0; j < r.joints.size(); ++j)
        r.joints[j] = {joints.data()[3 * j], joints.data()[3 * j + 1], joints.data()[3 * j + 2]};
    r.bones.resize(static_cast<std::size_t>(bones.shape(0)));
    for (std::size_t b = 0; b < r.bones.size(); ++b) r.bones[b] = {bones.data()[2 * b], bones.data()[2 * b + 1]};
    r.names = names;
    r.parents.assign(parents.data(), parents.data() + parents.shape(0));
    check_rig(r);
    return r;
}

}  // namespace volrig::py

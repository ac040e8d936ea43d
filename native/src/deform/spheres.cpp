#include "deform/spheres.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <string>

namespace volrig::deform_detail {

namespace {

template <class T>
bool all_finite(const T* data, std::size_t n) {
    std::atomic<bool> ok{true};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, std::size_t{1} << 16), [&](const tbb::blocked_range<std::size_t>& r) {
        if (!ok.load(std::memory_order_relaxed)) return;
        bool good = true;
        for (std::size_t i = r.begin(); i != r.end(); ++i) good &= std::isfinite(data[i]);
        if (!good) ok = false;
    });
    return ok;
}

}  // namespace

void SphereStore::assign(const BoundSpheres& s) {
    n = s.n;
    bone_count = s.bone_count;
    ijk.assign(s.ijk, s.ijk + 3 * s.n);
    radius.assign(s.radius, s.radius + s.n);
    set_binding(s);
}

void SphereStore::set_binding(const BoundSpheres& s) {
    bone.assign(s.bone, s.bone + s.n);
    has_weights = s.weight_offsets != nullptr;
    weight_offsets.clear();
    weight_bones.clear();
    weights.clear();
    if (!has_weights) return;
    weight_offsets.assign(s.weight_offsets, s.weight_offsets + s.n + 1);
    const auto nnz = static_cast<std::size_t>(s.weight_offsets[s.n]);
    weight_bones.assign(s.weight_bones, s.weight_bones + nnz);
    weights.assign(s.weights, s.weights + nnz);
}

BoundSpheres SphereStore::view() const {
    BoundSpheres s;
    s.ijk = ijk.data();
    s.radius = radius.data();
    s.n = n;
    s.bone = bone.data();
    s.bone_count = bone_count;
    if (has_weights) {
        s.weight_offsets = weight_offsets.data();
        s.weight_bones = weight_bones.data();
        s.weights = weights.data();
    }
    return s;
}

std::size_t SphereStore::memory_bytes() const {
    return (ijk.capacity() + bone.capacity() + weight_bones.capacity()) * sizeof(std::int32_t) +
           (radius.capacity() + weights.capacity()) * sizeof(float) + weight_offsets.capacity() * sizeof(std::int64_t);
}

void check_source(const VolumeView& v, const char* who) {
    const auto n = static_cast<std::size_t>(v.grid.voxel_count());
    const bool ok = v.dtype == DType::Float32   ? all_finite(static_cast<const float*>(v.data), n)
                    : v.dtype == DType::Float64 ? all_finite(static_cast<const double*>(v.data), n)
                                                : true;
    if (!ok) throw Error(std::string(who) + ": the source volume holds NaN or infinite samples");
}

void check_spheres(const Grid& g, const BoundSpheres& s) {
    if (s.n > 0 && (!s.ijk || !s.radius || !s.bone)) throw Error("deform: missing sphere arrays");
    if (s.bone_count == 0) throw Error("deform: the rig has no bones");
    if (s.bone_count > 32767) throw Error("deform: at most 32,767 bones are supported");
    if (s.n >= kNone) throw Error("deform: too many spheres");
    for (std::size_t i = 0; i < s.n; ++i) {
        const std::int32_t z = s.ijk[3 * i], y = s.ijk[3 * i + 1], x = s.ijk[3 * i + 2];
        if (x < 0 || y < 0 || z < 0 || x >= g.dims[0] || y >= g.dims[1] || z >= g.dims[2])
            throw Error("deform: sphere " + std::to_string(i) + " has its centre outside the source grid");
        if (!std::isfinite(s.radius[i]) || s.radius[i] < 0)
            throw Error("deform: sphere " + std::to_string(i) + " has a negative or non-finite radius");
        if (s.bone[i] < 0 || static_cast<std::size_t>(s.bone[i]) >= s.bone_count)
            throw Error("deform: sphere " + std::to_string(i) + " is bound to bone " + std::to_string(s.bone[i]) +
                        " but the rig has " + std::to_string(s.bone_count) + " bones");
    }
    if (s.weight_offsets) {
        if (s.weight_offsets[0] != 0) throw Error("deform: weight rows must start at 0");
        for (std::size_t i = 0; i < s.n; ++i) {
            if (s.weight_offsets[i + 1] < s.weight_offsets[i])
                throw Error("deform: weight rows are not increasing");
            double total = 0;
            for (std::int64_t k = s.weight_offsets[i]; k < s.weight_offsets[i + 1]; ++k) {
                if (s.weight_bones[k] < 0 || static_cast<std::size_t>(s.weight_bones[k]) >= s.bone_count)
                    throw Error("deform: sphere " + std::to_string(i) + " has a weight on bone " +
                                std::to_string(s.weight_bones[k]) + " outside the rig");
                if (!std::isfinite(s.weights[k]) || s.weights[k] < 0)
                    throw Error("deform: sphere " + std::to_string(i) + " has a negative or non-finite weight");
                total += s.weights[k];
            }
            if (!(total > 0)) throw Error("deform: sphere " + std::to_string(i) + " has no positive weight");
        }
    }
}

void check_options(const DeformOptions& o, std::size_t n) {
    if (!o.radius_scale.empty()) {
        if (o.radius_scale.size() != n)
            throw Error("deform: radius_scale has " + std::to_string(o.radius_scale.size()) + " entries for " +
                        std::to_string(n) + " spheres");
        for (float f : o.radius_scale)
            if (!std::isfinite(f) || f < 0 || f > 100)
                throw Error("deform: radius_scale entries must lie in [0, 100]");
    }
}

std::vector<double> scaled_radii(const BoundSpheres& s, const DeformOptions& o) {
    std::vector<double> r(s.n);
    for (std::size_t i = 0; i < s.n; ++i)
        r[i] = static_cast<double>(s.radius[i]) * (o.radius_scale.empty() ? 1.0 : o.radius_scale[i]);
    return r;
}

Weights quantized_weights(const BoundSpheres& s, std::size_t i) {
    Weights w;
    if (!s.weight_offsets) return {{s.bone[i], kWeightSteps}};
    double total = 0;
    for (std::int64_t k = s.weight_offsets[i]; k < s.weight_offsets[i + 1]; ++k) total += s.weights[k];
    for (std::int64_t k = s.weight_offsets[i]; k < s.weight_offsets[i + 1]; ++k) {
        const auto q = static_cast<std::int32_t>(std::lround(kWeightSteps * s.weights[k] / total));
        if (q <= 0) continue;
        auto it = std::find_if(w.begin(), w.end(), [&](const auto& e) { return e.first == s.weight_bones[k]; });
        if (it != w.end()) it->second += q;
        else w.emplace_back(s.weight_bones[k], q);
    }
    std::sort(w.begin(), w.end());
    if (w.empty()) w.emplace_back(s.bone[i], kWeightSteps);
    return w;
}

SmoothGroups smooth_groups(const BoundSpheres& s, const Grid& g) {
    SmoothGroups out;
    out.group_of.assign(s.n, -1);
    out.bone_of.assign(s.bone, s.bone + s.n);
    std::map<std::pair<std::int32_t, Weights>, std::int32_t> ids;
    std::vector<std::int64_t> count;
    for (std::size_t i = 0; i < s.n; ++i) {
        Weights w = quantized_weights(s, i);
        if (w.size() == 1) {
            out.bone_of[i] = w[0].first;
            continue;
        }
        auto [it, fresh] = ids.try_emplace({s.bone[i], w}, static_cast<std::int32_t>(out.weights.size()));
        if (fresh) {
            out.weights.push_back(std::move(w));
            out.owner.push_back(s.bone[i]);
            out.pivot.emplace_back(0, 0, 0);
            count.push_back(0);
        }
        const auto k = static_cast<std::size_t>(it->second);
        out.group_of[i] = it->second;
        for (int a = 0; a < 3; ++a)
            out.pivot[k][a] += g.origin[a] + g.spacing[a] * static_cast<double>(s.ijk[3 * i + 2 - a]);
        ++count[k];
    }
    for (std::size_t k = 0; k < count.size(); ++k) out.pivot[k] /= static_cast<double>(count[k]);
    return out;
}

}  // namespace volrig::deform_detail

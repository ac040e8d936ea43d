#include <cmath>
#include <set>
#include <string>

#include "volrig/rig.hpp"

namespace volrig {

void check_rig(const Rig& r) {
    const std::size_t nj = r.joints.size(), nb = r.bones.size();
    if (nb == 0) throw Error("rig: no bones");
    if (r.names.size() != nb || r.parents.size() != nb)
        throw Error("rig: " + std::to_string(nb) + " bones but " + std::to_string(r.names.size()) + " names and " +
                    std::to_string(r.parents.size()) + " parents");
    if (!r.joint_points.empty() && r.joint_points.size() != nj)
        throw Error("rig: joint_points must have one entry per joint");
    for (std::size_t j = 0; j < nj; ++j)
        for (double c : r.joints[j])
            if (!std::isfinite(c)) throw Error("rig: joint " + std::to_string(j) + " is not finite");
    std::set<std::string> seen;
    for (std::size_t b = 0; b < nb; ++b) {
        const std::string& name = r.names[b];
        const std::string label = "rig: bone " + std::to_string(b) + " ('" + name + "')";
        if (name.empty()) throw Error("rig: bone " + std::to_string(b) + " has an empty name");
        if (!seen.insert(name).second) throw Error("rig: bone name '" + name + "' is used twice");
        for (std::int32_t j : r.bones[b])
            if (j < 0 || static_cast<std::size_t>(j) >= nj)
                throw Error(label + " refers to joint " + std::to_string(j) + " of " + std::to_string(nj));
        const auto& h = r.joints[static_cast<std::size_t>(r.bones[b][0])];
        const auto& t = r.joints[static_cast<std::size_t>(r.bones[b][1])];
        if (h == t) throw Error(label + " has zero length");
        const std::int32_t p = r.parents[b];
        if (p < -1 || p >= static_cast<std::int32_t>(nb) || p == static_cast<std::int32_t>(b))
            throw Error(label + " has parent " + std::to_string(p));
    }
    // Acyclic: following parents from any bone ends at a root within nb steps.
    for (std::size_t b = 0; b < nb; ++b) {
        std::int32_t p = r.parents[b];
        for (std::size_t steps = 0; p >= 0; ++steps, p = r.parents[static_cast<std::size_t>(p)])
            if (steps > nb) throw Error("rig: bone parents form a cycle through bone " + std::to_string(b));
    }
}

std::array<double, 16> rest_matrix(const std::array<double, 3>& head, const std::array<double, 3>& tail) {
    double n[3] = {tail[0] - head[0], tail[1] - head[1], tail[2] - head[2]};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0) || !std::isfinite(len)) throw Error("rest_matrix: bone has zero or non-finite length");
    for (double& c : n) c /= len;
    // Blender's vec_roll_to_mat3_normalized with roll 0 (column-major b[col][row]).
    const double x = n[0], y = n[1], z = n[2];
    double theta = 1.0 + y;
    const double theta_alt = x * x + z * z;
    const double safe = 6.1e-3, critical = 2.5e-4;
    double b[3][3];
    if (theta > safe || theta_alt > critical * critical) {
        if (theta <= safe) theta = theta_alt * 0.5 + theta_alt * theta_alt * 0.125;
        b[0][0] = 1 - x * x / theta;
        b[0][1] = -x;
        b[0][2] = -x * z / theta;
        b[1][0] = x;
        b[1][1] = y;
        b[1][2] = z;
        b[2][0] = -x * z / theta;
        b[2][1] = -z;
        b[2][2] = 1 - z * z / theta;
    } else {  // pointing along -Y
        b[0][0] = -1; b[0][1] = 0; b[0][2] = 0;
        b[1][0] = 0; b[1][1] = -1; b[1][2] = 0;
        b[2][0] = 0; b[2][1] = 0; b[2][2] = 1;
    }
    std::array<double, 16> m{};
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) m[static_cast<std::size_t>(4 * c + r)] = b[c][r];
    for (int r = 0; r < 3; ++r) m[static_cast<std::size_t>(12 + r)] = head[static_cast<std::size_t>(r)];
    m[15] = 1;
    return m;
}

}  // namespace volrig

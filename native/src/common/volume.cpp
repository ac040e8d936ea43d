#include "volrig/volume.hpp"

#include <cmath>
#include <sstream>

namespace volrig {

std::size_t dtype_size(DType t) {
    switch (t) {
        case DType::UInt8:
        case DType::Int8: return 1;
        case DType::UInt16:
        case DType::Int16: return 2;
        case DType::UInt32:
        case DType::Int32:
        case DType::Float32: return 4;
        case DType::UInt64:
        case DType::Int64:
        case DType::Float64: return 8;
    }
    throw Error("unknown dtype");
}

const char* dtype_name(DType t) {
    switch (t) {
        case DType::UInt8: return "uint8";
        case DType::Int8: return "int8";
        case DType::UInt16: return "uint16";
        case DType::Int16: return "int16";
        case DType::UInt32: return "uint32";
        case DType::Int32: return "int32";
        case DType::UInt64: return "uint64";
        case DType::Int64: return "int64";
        case DType::Float32: return "float32";
        case DType::Float64: return "float64";
    }
    return "?";
}

DType dtype_from_name(const std::string& n) {
    for (DType t : {DType::UInt8, DType::Int8, DType::UInt16, DType::Int16, DType::UInt32, DType::Int32,
                    DType::UInt64, DType::Int64, DType::Float32, DType::Float64})
        if (n == dtype_name(t)) return t;
    if (n == "bool") return DType::UInt8;
    throw Error("unsupported element type '" + n + "'");
}

std::array<double, 3> world_position(const Grid& g, const std::array<double, 3>& xyz) {
    std::array<double, 3> out = g.origin;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) out[r] += g.direction[3 * r + c] * g.spacing[c] * xyz[c];
    return out;
}

namespace {

double column_dot(const Matrix3& d, int a, int b) {
    return d[a] * d[b] + d[3 + a] * d[3 + b] + d[6 + a] * d[6 + b];
}

// Direction errors, or "" when the columns are finite, of unit length and orthogonal within `tol`.
std::string direction_problem(const Matrix3& d, double tol) {
    for (double v : d)
        if (!std::isfinite(v)) return "direction matrix must be finite";
    for (int a = 0; a < 3; ++a)
        if (std::fabs(std::sqrt(column_dot(d, a, a)) - 1) > tol)
            return std::string("direction of axis ") + "xyz"[a] + " is not a unit vector";
    for (int a = 0; a < 3; ++a)
        for (int b = a + 1; b < 3; ++b)
            if (std::fabs(column_dot(d, a, b)) > tol)
                return std::string("directions of axes ") + "xyz"[a] + " and " + "xyz"[b] +
                       " are not perpendicular (sheared grids are not supported)";
    return {};
}

}  // namespace

std::string normalize_direction(Matrix3& d) {
    // Unit columns first (file formats store them with a few digits), then Gram-Schmidt.
    for (int a = 0; a < 3; ++a) {
        const double n = std::sqrt(column_dot(d, a, a));
        if (!(n > 0) || !std::isfinite(n)) return std::string("direction of axis ") + "xyz"[a] + " is zero or not finite";
        for (int r = 0; r < 3; ++r) d[3 * r + a] /= n;
    }
    std::string problem = direction_problem(d, 1e-3);
    if (!problem.empty()) return problem;
    for (int a = 1; a < 3; ++a) {
        for (int b = 0; b < a; ++b) {
            const double p = column_dot(d, a, b);
            for (int r = 0; r < 3; ++r) d[3 * r + a] -= p * d[3 * r + b];
        }
        const double n = std::sqrt(column_dot(d, a, a));
        for (int r = 0; r < 3; ++r) d[3 * r + a] /= n;
    }
    return {};
}

void check_grid(const Grid& g, std::size_t element_size, std::uint64_t max_bytes, const std::string& what) {
    for (int a = 0; a < 3; ++a) {
        if (g.dims[a] <= 0) {
            std::ostringstream s;
            s << what << ": dimensions " << g.dims[0] << " x " << g.dims[1] << " x " << g.dims[2]
              << " must all be positive";
            throw Error(s.str());
        }
        if (!std::isfinite(g.spacing[a]) || g.spacing[a] <= 0 || !std::isfinite(g.origin[a])) {
            std::ostringstream s;
            s << what << ": spacing must be finite and positive and origin finite (axis " << "xyz"[a] << ")";
            throw Error(s.str());
        }
    }
    const std::string problem = direction_problem(g.direction, 1e-3);
    if (!problem.empty()) throw Error(what + ": " + problem);
    // Overflow-safe product check.
    long double bytes = static_cast<long double>(element_size);
    for (int a = 0; a < 3; ++a) bytes *= static_cast<long double>(g.dims[a]);
    if (bytes > static_cast<long double>(max_bytes)) {
        std::ostringstream s;
        s << what << ": " << g.dims[0] << " x " << g.dims[1] << " x " << g.dims[2] << " voxels of " << element_size
          << " bytes = " << static_cast<double>(bytes) << " bytes exceeds the limit of " << max_bytes
          << " bytes (raise max_bytes if this is intended)";
        throw Error(s.str());
    }
}

}  // namespace volrig

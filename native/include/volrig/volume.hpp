// volrig/volume.hpp: the sampled volume, its grid geometry and element types.
//
// Conventions (docs/DESIGN.md, "Conventions"): voxels are stored C-order [z, y, x] with x fastest. The grid frame
// position of voxel (x, y, z) is origin + spacing * (x, y, z), in which the whole pipeline works; the patient (LPS)
// world position is origin + direction * (spacing * (x, y, z)) (docs/DESIGN.md, "Orientation"). Dimensions,
// spacing and origin are given as (x, y, z).
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "volrig/error.hpp"

namespace volrig {

/// Element types a volume may hold (numpy names in dtype_name()).
enum class DType : std::uint8_t { UInt8, Int8, UInt16, Int16, UInt32, Int32, UInt64, Int64, Float32, Float64 };

std::size_t dtype_size(DType t);
const char* dtype_name(DType t);          ///< "uint8", "int16", "float32", ...
DType dtype_from_name(const std::string& numpy_name);  ///< inverse of dtype_name; throws Error when unknown

/// A 3x3 matrix stored row-major: m[3 * row + column].
using Matrix3 = std::array<double, 9>;
constexpr Matrix3 kIdentity3{1, 0, 0, 0, 1, 0, 0, 0, 1};

/// Grid geometry: dims (x, y, z) in voxels, spacing (x, y, z) in world units per voxel, origin = world
/// position of voxel (0, 0, 0), direction = the world (LPS) directions of the voxel axes x, y, z as the columns of
/// a 3x3 matrix (identity: axis-aligned, as ITK and DICOM define it).
struct Grid {
    std::array<std::int64_t, 3> dims{0, 0, 0};
    std::array<double, 3> spacing{1.0, 1.0, 1.0};
    std::array<double, 3> origin{0.0, 0.0, 0.0};
    Matrix3 direction = kIdentity3;

    std::int64_t voxel_count() const { return dims[0] * dims[1] * dims[2]; }
    /// The finest of the three spacings.
    double min_spacing() const { return std::min({spacing[0], spacing[1], spacing[2]}); }
    /// Linear index of voxel (x, y, z) in the C-order [z, y, x] layout.
    std::int64_t index(std::int64_t x, std::int64_t y, std::int64_t z) const {
        return (z * dims[1] + y) * dims[0] + x;
    }
};

/// A non-owning view of sampled data laid out as Grid says.
struct VolumeView {
    Grid grid;
    DType dtype = DType::UInt8;
    const void* data = nullptr;
    /// The samples in 8³ bricks (brick_index; dims multiples of 8), not in C order. Only the OpenVDB writer takes
    /// such views.
    bool bricked = false;
    /// The samples are IEEE half floats (dtype UInt16 holding their bits), as a bake's frames hold their values
    /// (DeformOptions::half). Only the OpenVDB writer takes such views (into a float grid).
    bool half = false;
    /// The samples are integer labels (a frame's bone labels): the OpenVDB writer makes an Int32Grid of them
    /// whatever their type, bytes too (which it would otherwise take for a mask or an 8-bit scan).
    bool labels = false;
};

/// The element of voxel (x, y, z) in an array of 8³ bricks over dims (multiples of 8): bricks in C order [z, y, x],
/// 512 voxels each, [z, y, x] inside (VolumeView::bricked, DeformedVolume::bricks).
inline std::size_t brick_index(std::int64_t x, std::int64_t y, std::int64_t z, const std::array<std::int64_t, 3>& dims) {
    const std::int64_t brick = ((z >> 3) * (dims[1] >> 3) + (y >> 3)) * (dims[0] >> 3) + (x >> 3);
    return static_cast<std::size_t>(brick * 512 + ((z & 7) * 8 + (y & 7)) * 8 + (x & 7));
}

/// An owning volume. `data` holds voxel_count() * dtype_size(dtype) bytes in native byte order.
struct Volume {
    Grid grid;
    DType dtype = DType::UInt8;
    std::vector<std::uint8_t> data;

    VolumeView view() const { return VolumeView{grid, dtype, data.data()}; }
    std::size_t byte_size() const { return data.size(); }
};

/// World (LPS) position of voxel (x, y, z): origin + direction * (spacing * (x, y, z)).
std::array<double, 3> world_position(const Grid& g, const std::array<double, 3>& xyz);

/// Checks that a direction matrix is finite with unit-length, mutually orthogonal columns (within 1e-3); when it
/// is, re-orthonormalises it in place and returns an empty string, else says what is wrong.
std::string normalize_direction(Matrix3& d);

/// Checks that a grid's dims are positive, its spacing finite and positive, its origin finite, its direction
/// orthonormal (normalize_direction), and that
/// dims * element size stays within `max_bytes`; throws Error with `what` as the subject otherwise.
void check_grid(const Grid& grid, std::size_t element_size, std::uint64_t max_bytes, const std::string& what);

}  // namespace volrig

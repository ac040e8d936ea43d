// Conversions between numpy arrays and volrig's native types. Thin: no logic beyond layout checks.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "volrig/memory.hpp"
#include "volrig/tree.hpp"
#include "volrig/volume.hpp"

namespace volrig::py {

namespace py = pybind11;

using Vec3 = std::array<double, 3>;
using MaskArray = py::array_t<std::uint8_t, py::array::c_style>;
using IjkArray = py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>;
using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// numpy dtype for a volrig DType.
inline py::dtype to_numpy_dtype(DType t) { return py::dtype(std::string(dtype_name(t))); }

/// volrig DType of a numpy array (bool maps to uint8); throws Error on unsupported types.
inline DType from_numpy_dtype(const py::array& a) {
    if (a.dtype().kind() == 'b') return DType::UInt8;
    return dtype_from_name(py::str(a.dtype()).cast<std::string>());
}

/// Hands an owning Volume's buffer to numpy without copying: returns an array [z, y, x].
inline py::array to_numpy(Volume&& v) {
    auto* holder = new std::vector<std::uint8_t>(std::move(v.data));
    py::capsule owner(holder, [](void* p) { delete static_cast<std::vector<std::uint8_t>*>(p); });
    const auto esize = static_cast<py::ssize_t>(dtype_size(v.dtype));
    const py::ssize_t nx = v.grid.dims[0], ny = v.grid.dims[1], nz = v.grid.dims[2];
    return py::array(to_numpy_dtype(v.dtype), {nz, ny, nx}, {ny * nx * esize, nx * esize, esize}, holder->data(), owner);
}

/// Same for a plain vector of T shaped like `grid`.
template <class T>
py::array_t<T> to_numpy(std::vector<T>&& data, const Grid& grid) {
    auto* holder = new std::vector<T>(std::move(data));
    py::capsule owner(holder, [](void* p) { delete static_cast<std::vector<T>*>(p); });
    const py::ssize_t nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2];
    const auto e = static_cast<py::ssize_t>(sizeof(T));
    return py::array_t<T>({nz, ny, nx}, {ny * nx * e, nx * e, e}, holder->data(), owner);
}

/// Same for a ZeroedArray (calloc'd: its untouched pages stay shared zero pages; or pooled: see ZeroedPool). The
/// array is read-only, since a pool re-zeroes only what its writers marked.
/// With `bricks`, the array is 6-D: [brick z, y, x, z, y, x] (DeformedVolume::bricks).
template <class T>
py::array_t<T> to_numpy(ZeroedArray<T>&& data, const Grid& grid, bool bricks = false) {
    const py::ssize_t nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2];
    std::vector<py::ssize_t> shape{nz, ny, nx};
    if (bricks) shape = {nz / 8, ny / 8, nx / 8, 8, 8, 8};
    auto holder = std::make_unique<std::shared_ptr<void>>(data.owner());
    T* p = data.data();
    data = ZeroedArray<T>();
    py::capsule owner(holder.get(), [](void* q) { delete static_cast<std::shared_ptr<void>*>(q); });
    holder.release();
    py::array_t<T> a(shape, p, owner);
    py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
    return a;
}

/// A 1-D or N-D array owning a vector, with the given shape.
template <class T>
py::array_t<T> to_numpy_shaped(std::vector<T>&& data, std::vector<py::ssize_t> shape) {
    auto* holder = new std::vector<T>(std::move(data));
    py::capsule owner(holder, [](void* p) { delete static_cast<std::vector<T>*>(p); });
    return py::array_t<T>(shape, holder->data(), owner);
}

/// An (n, k) numpy array owning the flat storage of a vector of std::array<T, k> (no copy).
template <class T, std::size_t K>
py::array_t<T> rows(std::vector<std::array<T, K>>&& v) {
    static_assert(sizeof(std::array<T, K>) == K * sizeof(T), "std::array must be packed");
    auto* holder = new std::vector<std::array<T, K>>(std::move(v));
    py::capsule owner(holder, [](void* p) { delete static_cast<std::vector<std::array<T, K>>*>(p); });
    const auto n = static_cast<py::ssize_t>(holder->size());
    return py::array_t<T>({n, static_cast<py::ssize_t>(K)}, reinterpret_cast<const T*>(holder->data()), owner);
}

/// Grid of a C-contiguous 3-D array [z, y, x] with the given spacing and origin (x, y, z).
/// With `bricks`, a 6-D array [brick z, y, x, z, y, x] of 8³ bricks is taken too (DeformedVolume::bricks).
inline Grid grid_of(const py::array& a, const std::array<double, 3>& spacing, const std::array<double, 3>& origin,
                    const char* what, bool bricks = false) {
    if (bricks && a.ndim() == 6 && a.shape(3) == 8 && a.shape(4) == 8 && a.shape(5) == 8) {  // in 8³ bricks
        if (!(a.flags() & py::array::c_style)) throw Error(std::string(what) + ": array must be C-contiguous");
        Grid g;
        g.dims = {static_cast<std::int64_t>(a.shape(2)) * 8, static_cast<std::int64_t>(a.shape(1)) * 8,
                  static_cast<std::int64_t>(a.shape(0)) * 8};
        g.spacing = spacing;
        g.origin = origin;
        return g;
    }
    if (a.ndim() != 3) throw Error(std::string(what) + ": expected a 3-D array [z, y, x], got " +
                                   std::to_string(a.ndim()) + "-D");
    if (!(a.flags() & py::array::c_style)) throw Error(std::string(what) + ": array must be C-contiguous");
    Grid g;
    g.dims = {static_cast<std::int64_t>(a.shape(2)), static_cast<std::int64_t>(a.shape(1)),
              static_cast<std::int64_t>(a.shape(0))};
    g.spacing = spacing;
    g.origin = origin;
    return g;
}

/// A view of a C-contiguous numpy volume (no copy; with `bricks`, also of a 6-D array of 8³ bricks, as grid_of).
/// The array must outlive the view.
inline VolumeView view_of(const py::array& a, const std::array<double, 3>& spacing,
                          const std::array<double, 3>& origin, const char* what, bool bricks = false) {
    VolumeView v;
    v.grid = grid_of(a, spacing, origin, what, bricks);
    v.dtype = from_numpy_dtype(a);
    v.data = a.data();
    v.bricked = a.ndim() == 6;
    return v;
}

/// A tuple of the names a core list spells once (the option names, in enum order).
template <class List>
py::tuple names_tuple(const List& list) {
    py::tuple t(list.size());
    for (std::size_t k = 0; k < list.size(); ++k) t[k] = py::str(list[k]);
    return t;
}

/// Python tuple (array, spacing, origin) for a volume read from a file.
inline py::tuple volume_tuple(Volume&& v) {
    auto spacing = v.grid.spacing;
    auto origin = v.grid.origin;
    py::array arr = to_numpy(std::move(v));
    return py::make_tuple(arr, py::make_tuple(spacing[0], spacing[1], spacing[2]),
                          py::make_tuple(origin[0], origin[1], origin[2]));
}

/// Python tuple (array, spacing, origin, direction) with the direction as 9 numbers, row-major (volume.hpp).
inline py::tuple oriented_volume_tuple(Volume&& v) {
    const Matrix3 d = v.grid.direction;
    py::tuple t = volume_tuple(std::move(v));
    return py::make_tuple(t[0], t[1], t[2], py::make_tuple(d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7], d[8]));
}

/// Wraps a Python callable f(fraction) -> bool|None as a Progress (None or True continue, False cancels).
/// Must be called with the GIL held; the returned Progress acquires the GIL itself when invoked.
inline Progress progress_of(const py::object& f) {
    if (f.is_none()) return {};
    return [f](double x) {
        py::gil_scoped_acquire gil;
        py::object r = f(x);
        return r.is_none() || r.cast<bool>();
    };
}

/// A PointSet viewing (N, 3) voxel indices and, when given, (N,) radii; checks the shapes.
inline PointSet point_set(const IjkArray& ijk, const FloatArray* radius, const char* what) {
    if (ijk.ndim() != 2 || ijk.shape(1) != 3)
        throw Error(std::string(what) + ": points' ijk must have shape (N, 3)");
    PointSet p;
    p.ijk = ijk.data();
    p.n = static_cast<std::size_t>(ijk.shape(0));
    if (radius) {
        if (radius->ndim() != 1 || radius->shape(0) != ijk.shape(0))
            throw Error(std::string(what) + ": radii must have shape (N,) matching the points");
        p.radius = radius->data();
    }
    return p;
}

// Per-capability binding registrations (one file each in native/bindings/).
void bind_io(py::module_& m);
void bind_vdb(py::module_& m);
void bind_skeleton(py::module_& m);
void bind_medial(py::module_& m);
void bind_tree(py::module_& m);
void bind_rig(py::module_& m);
void bind_skin(py::module_& m);
void bind_mesh(py::module_& m);
void bind_deform(py::module_& m);
void bind_mocap(py::module_& m);
void bind_centerline(py::module_& m);
void bind_collide(py::module_& m);
void bind_drawing(py::module_& m);
void bind_track(py::module_& m);
void bind_pores(py::module_& m);

}  // namespace volrig::py

// volrig/volume.hpp: the sampled volume, its grid geometry and element types.
//
// Conventions (DESIGN.md): voxels are stored C-order [z, y, x] with x fastest; the world position of
// voxel (x, y, z) is origin + spacing * (x, y, z). Dimensions, spacing and origin are given as (x, y, z).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace volrig {

/// Allocator whose construct() default-initialises: vectors of numbers grow without being zero-filled first, for
/// buffers that are written in full right after allocation (one pass over memory instead of two).
template <class T>
struct UninitializedAllocator : std::allocator<T> {
    template <class U>
    struct rebind {
        using other = UninitializedAllocator<U>;
    };
    UninitializedAllocator() = default;
    template <class U>
    UninitializedAllocator(const UninitializedAllocator<U>&) noexcept {}
    template <class U>
    void construct(U* p) noexcept {
        ::new (static_cast<void*>(p)) U;
    }
    template <class U, class... Args>
    void construct(U* p, Args&&... args) {
        ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
};
/// A vector of numbers that `Buffer<T>(n)` leaves uninitialised.
template <class T>
using Buffer = std::vector<T, UninitializedAllocator<T>>;

/// A zero-filled array from calloc: pages the program never writes stay shared zero pages, so a large, mostly
/// empty output costs memory only where it is written. `release()` hands the buffer over (free it with std::free).
template <class T>
class ZeroedArray {
public:
    ZeroedArray() = default;
    explicit ZeroedArray(std::size_t n) : n_(n) {
        if (n == 0) return;
        p_.reset(static_cast<T*>(std::calloc(n, sizeof(T))));
        if (!p_) throw std::bad_alloc();
    }
    T* data() { return p_.get(); }
    const T* data() const { return p_.get(); }
    std::size_t size() const { return n_; }
    bool empty() const { return n_ == 0; }
    T& operator[](std::size_t i) { return p_.get()[i]; }
    const T& operator[](std::size_t i) const { return p_.get()[i]; }
    bool operator==(const ZeroedArray& o) const {
        return n_ == o.n_ && (n_ == 0 || std::memcmp(p_.get(), o.p_.get(), n_ * sizeof(T)) == 0);
    }
    T* release() {
        n_ = 0;
        return p_.release();
    }

private:
    struct Free {
        void operator()(T* p) const { std::free(p); }
    };
    std::unique_ptr<T, Free> p_;
    std::size_t n_ = 0;
};

/// Element types a volume may hold (numpy names in dtype_name()).
enum class DType : std::uint8_t { UInt8, Int8, UInt16, Int16, UInt32, Int32, UInt64, Int64, Float32, Float64 };

std::size_t dtype_size(DType t);
const char* dtype_name(DType t);          ///< "uint8", "int16", "float32", ...
DType dtype_from_name(const std::string& numpy_name);  ///< inverse of dtype_name; throws Error when unknown

/// Grid geometry: dims (x, y, z) in voxels, spacing (x, y, z) in world units per voxel, origin = world
/// position of voxel (0, 0, 0).
struct Grid {
    std::array<std::int64_t, 3> dims{0, 0, 0};
    std::array<double, 3> spacing{1.0, 1.0, 1.0};
    std::array<double, 3> origin{0.0, 0.0, 0.0};

    std::int64_t voxel_count() const { return dims[0] * dims[1] * dims[2]; }
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
};

/// An owning volume. `data` holds voxel_count() * dtype_size(dtype) bytes in native byte order.
struct Volume {
    Grid grid;
    DType dtype = DType::UInt8;
    std::vector<std::uint8_t> data;

    VolumeView view() const { return VolumeView{grid, dtype, data.data()}; }
    std::size_t byte_size() const { return data.size(); }
};

/// Base of every error volrig raises on bad input or misuse.
struct Error : std::runtime_error {
    using std::runtime_error::runtime_error;
};
/// A file that cannot be read as what it claims to be; the message starts with the file name.
struct FileFormatError : Error {
    using Error::Error;
};
/// A file that does not exist or cannot be opened.
struct FileNotFound : Error {
    using Error::Error;
};
/// Raised when a progress callback asked to stop.
struct Cancelled : Error {
    using Error::Error;
};

/// Progress/cancel callback: receives the fraction done in [0, 1]; returns false to cancel.
/// volrig calls it only from the thread that started the operation, between parallel chunks.
using Progress = std::function<bool(double)>;

/// Calls `progress(fraction)` if set and throws Cancelled when it returns false.
void report(const Progress& progress, double fraction);

/// Checks that a grid's dims are positive and that dims * element size stays below `max_bytes`;
/// throws Error with `what` as the subject otherwise.
void check_grid(const Grid& grid, std::size_t element_size, std::uint64_t max_bytes, const std::string& what);

}  // namespace volrig

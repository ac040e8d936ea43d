// volrig/volume.hpp: the sampled volume, its grid geometry and element types.
//
// Conventions (DESIGN.md): voxels are stored C-order [z, y, x] with x fastest; the world position of
// voxel (x, y, z) is origin + spacing * (x, y, z). Dimensions, spacing and origin are given as (x, y, z).
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>
#include <functional>
#include <memory>
#include <mutex>
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

/// The granularity, in bytes, at which pooled arrays record their writes (ZeroedArray::mark_written) and the pool
/// zeroes them again: finer than a 4 KiB page, because a frame's covered runs are short rows.
constexpr std::size_t kZeroGranule = 256;

/// A zero-filled array. By default from calloc: pages the program never writes stay shared zero pages, so a large,
/// mostly empty output costs memory only where it is written. A ZeroedPool hands out arrays over recycled memory
/// instead; writers then say which elements they wrote (mark_written), so that the pool zeroes only those granules
/// before the memory is handed out again. Move-only; `owner()` keeps the memory alive (for views such as numpy's).
template <class T>
class ZeroedArray {
public:
    ZeroedArray() = default;
    explicit ZeroedArray(std::size_t n) {
        if (n == 0) return;
        void* p = std::calloc(n, sizeof(T));
        if (!p) throw std::bad_alloc();
        owner_ = std::shared_ptr<void>(p, [](void* q) { std::free(q); });
        p_ = static_cast<T*>(p);
        n_ = n;
    }
    /// n elements at p (zero-filled), kept alive by `owner`; `written`, when given, holds one flag per kZeroGranule
    /// bytes from `base` on, which mark_written sets.
    ZeroedArray(T* p, std::size_t n, std::shared_ptr<void> owner, std::atomic<std::uint8_t>* written, const void* base)
        : owner_(std::move(owner)), p_(p), n_(n), written_(written), base_(static_cast<const char*>(base)) {}
    ZeroedArray(ZeroedArray&& o) noexcept { *this = std::move(o); }
    ZeroedArray& operator=(ZeroedArray&& o) noexcept {
        if (this != &o) {
            owner_ = std::move(o.owner_);
            p_ = std::exchange(o.p_, nullptr);
            n_ = std::exchange(o.n_, 0);
            written_ = std::exchange(o.written_, nullptr);
            base_ = std::exchange(o.base_, nullptr);
        }
        return *this;
    }
    ZeroedArray(const ZeroedArray&) = delete;
    ZeroedArray& operator=(const ZeroedArray&) = delete;

    T* data() { return p_; }
    const T* data() const { return p_; }
    std::size_t size() const { return n_; }
    bool empty() const { return n_ == 0; }
    T& operator[](std::size_t i) { return p_[i]; }
    const T& operator[](std::size_t i) const { return p_[i]; }
    bool operator==(const ZeroedArray& o) const {
        return n_ == o.n_ && (n_ == 0 || std::memcmp(p_, o.p_, n_ * sizeof(T)) == 0);
    }
    /// Notes that elements [i0, i1) were written (needed for pooled arrays; any thread may call it).
    void mark_written(std::size_t i0, std::size_t i1) {
        if (!written_ || i1 <= i0) return;
        const auto first = static_cast<std::size_t>(reinterpret_cast<const char*>(p_ + i0) - base_) / kZeroGranule;
        const auto last = static_cast<std::size_t>(reinterpret_cast<const char*>(p_ + i1) - 1 - base_) / kZeroGranule;
        for (std::size_t k = first; k <= last; ++k) written_[k].store(1, std::memory_order_relaxed);
    }
    /// Shares the ownership of the memory (it is freed, or recycled, when the last owner goes).
    const std::shared_ptr<void>& owner() const { return owner_; }

private:
    std::shared_ptr<void> owner_;
    T* p_ = nullptr;
    std::size_t n_ = 0;
    std::atomic<std::uint8_t>* written_ = nullptr;  // per granule (pooled arrays)
    const char* base_ = nullptr;                    // where granule 0 starts
};

/// Recycles the large zero-filled outputs of a sequence of frames: an array given back (when its last owner goes)
/// keeps its pages, and the next take() re-zeroes only the granules marked written, instead of the kernel faulting in
/// and zeroing fresh pages one by one. Keeps at most `keep` free blocks of memory; thread-safe.
class ZeroedPool : public std::enable_shared_from_this<ZeroedPool> {
public:
    static std::shared_ptr<ZeroedPool> create(std::size_t keep = 2);
    ~ZeroedPool();
    ZeroedPool(const ZeroedPool&) = delete;
    ZeroedPool& operator=(const ZeroedPool&) = delete;

    /// n zeroed elements; writers must mark_written what they write.
    template <class T>
    ZeroedArray<T> take(std::size_t n) {
        if (n == 0) return {};
        if (n > static_cast<std::size_t>(-1) / 2 / sizeof(T)) throw std::bad_alloc();
        Slab* s = acquire(n * sizeof(T));
        std::weak_ptr<ZeroedPool> pool = weak_from_this();
        std::shared_ptr<void> owner(s->p, [pool, s](void*) { give_back(pool, s); });
        return ZeroedArray<T>(static_cast<T*>(s->p), n, std::move(owner), s->written.get(), s->p);
    }
    /// Frees the memory kept for reuse.
    void trim();
    /// Bytes kept for reuse (mapped; resident only where earlier frames wrote).
    std::size_t kept_bytes() const;

    struct Slab {
        void* p = nullptr;
        std::size_t bytes = 0;
        std::unique_ptr<std::atomic<std::uint8_t>[]> written;  // a flag per kZeroGranule bytes
        ~Slab();
    };

private:
    explicit ZeroedPool(std::size_t keep) : keep_(keep) {}
    Slab* acquire(std::size_t bytes);
    static void give_back(const std::weak_ptr<ZeroedPool>& pool, Slab* s);
    mutable std::mutex mutex_;
    std::vector<std::unique_ptr<Slab>> free_;
    std::size_t keep_;
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

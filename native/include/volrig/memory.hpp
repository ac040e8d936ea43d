// volrig/memory.hpp: memory for large outputs: vectors that skip zero-filling (Buffer), zero-filled arrays that cost
// memory only where written (ZeroedArray) and the pool that recycles them from frame to frame (ZeroedPool).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
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
/// keeps the pages it wrote, and the next take() re-zeroes only the granules marked written, instead of the kernel
/// faulting in and zeroing fresh pages one by one; pages zeroed for a use that did not write them go back to the
/// kernel when it ends. A use may name its layout (what each element stands for, such as a frame's box): memory last
/// used under another layout is given back to the kernel where it was written instead of re-zeroed, since the new
/// use would write other places and the old pages would stay resident beside the new ones until it ends. Keeps at
/// most `keep` free blocks of memory; thread-safe.
class ZeroedPool : public std::enable_shared_from_this<ZeroedPool> {
public:
    static std::shared_ptr<ZeroedPool> create(std::size_t keep = 2);
    ~ZeroedPool();
    ZeroedPool(const ZeroedPool&) = delete;
    ZeroedPool& operator=(const ZeroedPool&) = delete;

    /// n zeroed elements; writers must mark_written what they write. `layout` (0: none) names what the elements
    /// stand for; memory last used under another one is given back where written, not re-zeroed.
    template <class T>
    ZeroedArray<T> take(std::size_t n, std::uint64_t layout = 0) {
        if (n == 0) return {};
        if (n > static_cast<std::size_t>(-1) / 2 / sizeof(T)) throw std::bad_alloc();
        Slab* s = acquire(n * sizeof(T), layout == 0 ? 0 : layout * 31 + sizeof(T));
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
        std::unique_ptr<std::atomic<std::uint8_t>[]> zeroed;   // likewise: zeroed when last handed out
        std::uint64_t layout = 0;                              // of the last use (with the element size)
        ~Slab();
    };

private:
    explicit ZeroedPool(std::size_t keep) : keep_(keep) {}
    Slab* acquire(std::size_t bytes, std::uint64_t layout);
    static void give_back(const std::weak_ptr<ZeroedPool>& pool, Slab* s);
    mutable std::mutex mutex_;
    std::vector<std::unique_ptr<Slab>> free_;
    std::size_t keep_;
};

}  // namespace volrig

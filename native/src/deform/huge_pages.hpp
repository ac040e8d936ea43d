// deform/huge_pages.hpp: huge-page backing for the large tables the deformation reads at random every frame.
#pragma once

#include <cstddef>
#include <cstdlib>
#include <new>
#include <vector>

#include "volrig/memory.hpp"

namespace volrig::deform_detail {

/// An allocator for the large per-rig tables read at random every frame: 2 MiB aligned and marked for transparent
/// huge pages (where the kernel offers them), so that lookups spread over hundreds of MB do not miss the TLB.
/// madvise(MADV_HUGEPAGE) over [p, p + bytes); failure is ignored (advice only).
void advise_huge(void* p, std::size_t bytes);

/// Its construct() default-initialises (UninitializedAllocator's): resize() leaves a table of plain numbers
/// unwritten, so that its builder's threads fault its pages in as they fill it, in parallel.
template <class T>
struct HugePageAllocator : UninitializedAllocator<T> {
    using value_type = T;
    template <class U>
    struct rebind {
        using other = HugePageAllocator<U>;
    };
    HugePageAllocator() = default;
    template <class U>
    HugePageAllocator(const HugePageAllocator<U>&) {}
    T* allocate(std::size_t n) {
        const std::size_t bytes = n * sizeof(T);
        constexpr std::size_t kHuge = std::size_t{2} << 20;
        if (bytes < 2 * kHuge) return static_cast<T*>(::operator new(bytes));
        void* p = nullptr;
        if (posix_memalign(&p, kHuge, bytes) != 0) throw std::bad_alloc();
        advise_huge(p, bytes / kHuge * kHuge);  // advice only: failure leaves ordinary pages
        return static_cast<T*>(p);
    }
    void deallocate(T* p, std::size_t n) {
        if (n * sizeof(T) < 2 * (std::size_t{2} << 20)) ::operator delete(p);
        else std::free(p);
    }
    template <class U>
    bool operator==(const HugePageAllocator<U>&) const { return true; }
    template <class U>
    bool operator!=(const HugePageAllocator<U>&) const { return false; }
};
template <class T>
using HugeVector = std::vector<T, HugePageAllocator<T>>;

/// Asks the kernel to back the 2 MiB-aligned interior of a large existing buffer (the source volume, sampled at
/// random every frame) with huge pages, collapsing it now where the kernel can (Linux 6.1+). Contents are
/// unchanged; any failure leaves ordinary pages.
void advise_huge_pages(const void* data, std::size_t bytes);

}  // namespace volrig::deform_detail

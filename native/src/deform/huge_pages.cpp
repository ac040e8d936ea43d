#include "deform/huge_pages.hpp"

#include <cstdint>

#include <sys/mman.h>

namespace volrig::deform_detail {

void advise_huge(void* p, std::size_t bytes) { madvise(p, bytes, MADV_HUGEPAGE); }

void advise_huge_pages(const void* data, std::size_t bytes) {
    constexpr std::uintptr_t kHuge = std::uintptr_t{2} << 20;
    const auto a = (reinterpret_cast<std::uintptr_t>(data) + kHuge - 1) & ~(kHuge - 1);
    const auto b = (reinterpret_cast<std::uintptr_t>(data) + bytes) & ~(kHuge - 1);
    if (b <= a) return;
    void* p = reinterpret_cast<void*>(a);
    madvise(p, b - a, MADV_HUGEPAGE);
    madvise(p, b - a, 25 /* MADV_COLLAPSE, absent from older headers; EINVAL on older kernels */);
}

}  // namespace volrig::deform_detail

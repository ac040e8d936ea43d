// The zeroed memory frames are written into (volrig/memory.hpp): a ZeroedPool recycles what dropped arrays held,
// re-zeroing only the granules they marked written, and giving back to the kernel the pages a use did not write.
#include <catch2/catch.hpp>

#include <sys/mman.h>

#include <cstdint>
#include <vector>

#include "volrig/memory.hpp"

using namespace volrig;

TEST_CASE("a ZeroedPool hands its memory out again zeroed, and outlives nothing it must not", "[memory]") {
    auto pool = ZeroedPool::create(2);
    const float* first = nullptr;
    {
        ZeroedArray<float> a = pool->take<float>(300000);
        REQUIRE(a.size() == 300000);
        for (std::size_t i = 0; i < a.size(); ++i) REQUIRE(a[i] == 0.0f);
        for (std::size_t i = 10; i < 5000; ++i) a[i] = 1.0f;
        a.mark_written(10, 5000);
        a[299999] = 2.0f;
        a.mark_written(299999, 300000);
        first = a.data();
        REQUIRE(pool->kept_bytes() == 0);
    }
    REQUIRE(pool->kept_bytes() >= 300000 * sizeof(float));
    {
        ZeroedArray<float> b = pool->take<float>(290000);  // fits: the same memory, re-zeroed where it was written
        REQUIRE(b.data() == first);
        std::size_t nonzero = 0;
        for (std::size_t i = 0; i < b.size(); ++i) nonzero += b[i] != 0.0f;
        REQUIRE(nonzero == 0);
        REQUIRE(b.data()[299999] == 0.0f);  // beyond the new size, still inside the reused memory
        ZeroedArray<std::int16_t> c = pool->take<std::int16_t>(1000);  // the pool is empty now: fresh memory
        REQUIRE(c.data() != static_cast<const void*>(first));
        ZeroedArray<float> moved = std::move(b);
        REQUIRE(b.empty());
        REQUIRE(moved.data() == first);
    }
    REQUIRE(pool->kept_bytes() > 0);
    pool->trim();
    REQUIRE(pool->kept_bytes() == 0);
    ZeroedArray<std::int16_t> late = pool->take<std::int16_t>(5000);
    pool.reset();  // the array keeps its memory; it is freed, not returned, when it goes
    late[4999] = 7;
    late.mark_written(4999, 5000);
    REQUIRE(late[4999] == 7);
    REQUIRE_THROWS_AS(ZeroedPool::create()->take<double>(std::size_t(-1) / 4), std::bad_alloc);
}

namespace {

/// Resident pages of [p, p + bytes) (page-aligned p), by mincore.
std::size_t resident_pages(const void* p, std::size_t bytes) {
    const std::size_t pages = (bytes + 4095) / 4096;
    std::vector<unsigned char> in(pages);
    REQUIRE(mincore(const_cast<void*>(p), pages * 4096, in.data()) == 0);
    std::size_t n = 0;
    for (unsigned char c : in) n += c & 1;
    return n;
}

}  // namespace

TEST_CASE("a ZeroedPool keeps resident what the last use wrote, not what every use wrote", "[memory]") {
    auto pool = ZeroedPool::create(1);
    constexpr std::size_t n = 1 << 20;  // 4 MiB of floats: 1024 pages
    const float* at = nullptr;
    {
        ZeroedArray<float> a = pool->take<float>(n);
        for (std::size_t i = 0; i < n / 2; ++i) a[i] = 1.0f;  // the first half: 512 pages
        a.mark_written(0, n / 2);
        at = a.data();
    }
    REQUIRE(resident_pages(at, n * 4) >= 512);
    {
        ZeroedArray<float> b = pool->take<float>(n);  // re-zeroed: still resident while in use
        REQUIRE(b.data() == at);
        for (std::size_t i = n / 2; i < n / 2 + 1024 * 100; ++i) b[i] = 2.0f;  // 100 other pages
        b.mark_written(n / 2, n / 2 + 1024 * 100);
        b[10] = 3.0f;  // and one of the old ones
        b.mark_written(10, 11);
    }
    // given back: the old pages it did not write went back to the kernel
    const std::size_t kept = resident_pages(at, n * 4);
    REQUIRE(kept >= 101);
    REQUIRE(kept <= 110);
    ZeroedArray<float> c = pool->take<float>(n);  // and all of it reads zero again
    REQUIRE(c.data() == at);
    for (std::size_t i = 0; i < n; ++i) REQUIRE(c[i] == 0.0f);
}

TEST_CASE("a ZeroedPool gives back what a use under another layout wrote, instead of re-zeroing it", "[memory]") {
    auto pool = ZeroedPool::create(1);
    constexpr std::size_t n = 1 << 20;  // 4 MiB of floats: 1024 pages
    const float* at = nullptr;
    {
        ZeroedArray<float> a = pool->take<float>(n, 7);
        for (std::size_t i = 0; i < n / 2; ++i) a[i] = 1.0f;  // 512 pages
        a.mark_written(0, n / 2);
        at = a.data();
    }
    {
        ZeroedArray<float> same = pool->take<float>(n, 7);  // the same layout: re-zeroed in place, still resident
        REQUIRE(same.data() == at);
        REQUIRE(resident_pages(at, n * 4) >= 512);
        for (std::size_t i = 0; i < n / 2; ++i) REQUIRE(same[i] == 0.0f);
        for (std::size_t i = 0; i < n / 2; ++i) same[i] = 1.0f;
        same.mark_written(0, n / 2);
    }
    {
        ZeroedArray<float> other = pool->take<float>(n, 8);  // another layout: nothing of the old use stays resident
        REQUIRE(other.data() == at);
        REQUIRE(resident_pages(at, n * 4) <= 2);
        for (std::size_t i = n / 2; i < n / 2 + 1024 * 100; ++i) other[i] = 2.0f;  // 100 other pages
        other.mark_written(n / 2, n / 2 + 1024 * 100);
        REQUIRE(resident_pages(at, n * 4) >= 100);
        REQUIRE(resident_pages(at, n * 4) <= 110);
    }
    // the same key with another element size is another layout too
    ZeroedArray<std::int16_t> bone = pool->take<std::int16_t>(n, 8);
    REQUIRE(static_cast<const void*>(bone.data()) == static_cast<const void*>(at));
    REQUIRE(resident_pages(at, n * 4) <= 2);
    for (std::size_t i = 0; i < n; ++i) REQUIRE(bone[i] == 0);  // (reading maps the zero page, which mincore counts)
}

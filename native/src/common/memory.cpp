// common/memory.cpp: the ZeroedPool (volrig/memory.hpp).
#include "volrig/memory.hpp"

#include <sys/mman.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace volrig {

namespace {

constexpr std::size_t kPage = 4096;

/// Zeroes the granules of `s` marked written since it was handed out, a run of them at a time, and moves the marks
/// to `zeroed` (release_stale's).
void rezero_written(ZeroedPool::Slab& s) {
    char* base = static_cast<char*>(s.p);
    std::atomic<std::uint8_t>* flags = s.written.get();
    std::atomic<std::uint8_t>* zeroed = s.zeroed.get();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, s.bytes / kZeroGranule, 65536),
                      [&](const tbb::blocked_range<std::size_t>& rg) {
                          for (std::size_t k = rg.begin(); k != rg.end();) {
                              if (!flags[k].load(std::memory_order_relaxed)) {
                                  ++k;
                                  continue;
                              }
                              std::size_t e = k;
                              for (; e != rg.end() && flags[e].load(std::memory_order_relaxed); ++e) {
                                  flags[e].store(0, std::memory_order_relaxed);
                                  zeroed[e].store(1, std::memory_order_relaxed);
                              }
                              std::memset(base + k * kZeroGranule, 0, (e - k) * kZeroGranule);
                              k = e;
                          }
                      });
}

/// Gives back to the kernel, a run at a time, the pages of `s` for which `release(first granule, last + 1)` holds
/// (it may clear the marks it reads).
template <class Release>
void release_pages(ZeroedPool::Slab& s, Release&& release) {
    constexpr std::size_t per_page = kPage / kZeroGranule;
    char* base = static_cast<char*>(s.p);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, s.bytes / kPage, 4096), [&](const tbb::blocked_range<std::size_t>& rg) {
        std::size_t run = rg.end();  // the first page of a run to give back
        auto flush = [&](std::size_t end) {
            if (run < end) madvise(base + run * kPage, (end - run) * kPage, MADV_DONTNEED);
            run = rg.end();
        };
        for (std::size_t page = rg.begin(); page != rg.end(); ++page) {
            if (!release(page * per_page, (page + 1) * per_page)) flush(page);
            else if (run == rg.end()) run = page;
        }
        flush(rg.end());
    });
}

/// Gives back to the kernel every page of `s` holding a granule marked written, and clears the marks: the slab reads
/// zero again without being written, and holds nothing resident (a use under another layout).
void release_written(ZeroedPool::Slab& s) {
    std::atomic<std::uint8_t>* written = s.written.get();
    release_pages(s, [&](std::size_t k0, std::size_t k1) {
        bool any = false;
        for (std::size_t k = k0; k < k1; ++k) any = written[k].exchange(0, std::memory_order_relaxed) || any;
        return any;
    });
}

/// Gives the pages that were zeroed for the slab's last use (rezero_written) and that it did not write back to the
/// kernel, and clears those marks: a slab kept for reuse then holds resident only what its last frame wrote, not
/// the union of what all its frames wrote (frames' boxes move, and their covered bricks with them).
void release_stale(ZeroedPool::Slab& s) {
    std::atomic<std::uint8_t>* written = s.written.get();
    std::atomic<std::uint8_t>* zeroed = s.zeroed.get();
    release_pages(s, [&](std::size_t k0, std::size_t k1) {
        bool was = false, now = false;
        for (std::size_t k = k0; k < k1; ++k) {
            was = zeroed[k].exchange(0, std::memory_order_relaxed) || was;
            now = now || written[k].load(std::memory_order_relaxed);
        }
        return was && !now;
    });
}

}  // namespace

ZeroedPool::Slab::~Slab() {
    if (p) munmap(p, bytes);
}

std::shared_ptr<ZeroedPool> ZeroedPool::create(std::size_t keep) {
    return std::shared_ptr<ZeroedPool>(new ZeroedPool(keep));
}

ZeroedPool::~ZeroedPool() = default;

ZeroedPool::Slab* ZeroedPool::acquire(std::size_t bytes, std::uint64_t layout) {
    std::unique_ptr<Slab> s;
    {  // the smallest free slab that is large enough
        std::lock_guard<std::mutex> lock(mutex_);
        std::size_t best = free_.size();
        for (std::size_t k = 0; k < free_.size(); ++k)
            if (free_[k]->bytes >= bytes && (best == free_.size() || free_[k]->bytes < free_[best]->bytes)) best = k;
        if (best < free_.size()) {
            s = std::move(free_[best]);
            free_.erase(free_.begin() + static_cast<std::ptrdiff_t>(best));
        }
    }
    if (s) {
        if (layout != 0 && layout != s->layout) release_written(*s);
        else rezero_written(*s);
        s->layout = layout;
        return s.release();
    }
    // Fresh memory, with headroom: the frames of a sequence differ in size, and pages never written cost nothing.
    const std::size_t cap = (bytes + bytes / 4 + kPage - 1) / kPage * kPage;
    void* p = mmap(nullptr, cap, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    s = std::make_unique<Slab>();
    s->p = p;
    s->bytes = cap;
    s->written.reset(new std::atomic<std::uint8_t>[cap / kZeroGranule]());
    s->zeroed.reset(new std::atomic<std::uint8_t>[cap / kZeroGranule]());
    s->layout = layout;
    return s.release();
}

void ZeroedPool::give_back(const std::weak_ptr<ZeroedPool>& pool, Slab* s) {
    std::unique_ptr<Slab> owned(s);
    if (auto p = pool.lock()) {
        release_stale(*owned);
        std::lock_guard<std::mutex> lock(p->mutex_);
        p->free_.push_back(std::move(owned));
        if (p->free_.size() > p->keep_) p->free_.erase(p->free_.begin());  // the oldest goes
    }
}

void ZeroedPool::trim() {
    std::vector<std::unique_ptr<Slab>> gone;  // freed after the lock is released
    std::lock_guard<std::mutex> lock(mutex_);
    gone.swap(free_);
}

std::size_t ZeroedPool::kept_bytes() const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::size_t n = 0;
    for (const auto& s : free_) n += s->bytes;
    return n;
}

}  // namespace volrig

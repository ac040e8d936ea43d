#include "volrig/volume.hpp"

#include <cmath>
#include <sstream>

#include <sys/mman.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

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

void report(const Progress& progress, double fraction) {
    if (progress && !progress(fraction)) throw Cancelled("cancelled");
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

// ---- ZeroedPool ---------------------------------------------------------------------------------------------

namespace volrig {

namespace {
constexpr std::size_t kPage = 4096;
}

ZeroedPool::Slab::~Slab() {
    if (p) munmap(p, bytes);
}

std::shared_ptr<ZeroedPool> ZeroedPool::create(std::size_t keep) {
    return std::shared_ptr<ZeroedPool>(new ZeroedPool(keep));
}

ZeroedPool::~ZeroedPool() = default;

ZeroedPool::Slab* ZeroedPool::acquire(std::size_t bytes) {
    std::unique_ptr<Slab> s;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        std::size_t best = free_.size();
        for (std::size_t k = 0; k < free_.size(); ++k)
            if (free_[k]->bytes >= bytes && (best == free_.size() || free_[k]->bytes < free_[best]->bytes)) best = k;
        if (best < free_.size()) {
            s = std::move(free_[best]);
            free_.erase(free_.begin() + static_cast<std::ptrdiff_t>(best));
        }
    }
    if (s) {  // re-zero the granules written since it was handed out, a run of them at a time
        char* base = static_cast<char*>(s->p);
        std::atomic<std::uint8_t>* flags = s->written.get();
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, s->bytes / kZeroGranule, 65536),
                          [&](const tbb::blocked_range<std::size_t>& rg) {
                              for (std::size_t k = rg.begin(); k != rg.end();) {
                                  if (!flags[k].load(std::memory_order_relaxed)) {
                                      ++k;
                                      continue;
                                  }
                                  std::size_t e = k;
                                  for (; e != rg.end() && flags[e].load(std::memory_order_relaxed); ++e)
                                      flags[e].store(0, std::memory_order_relaxed);
                                  std::memset(base + k * kZeroGranule, 0, (e - k) * kZeroGranule);
                                  k = e;
                              }
                          });
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
    return s.release();
}

void ZeroedPool::give_back(const std::weak_ptr<ZeroedPool>& pool, Slab* s) {
    std::unique_ptr<Slab> owned(s);
    if (auto p = pool.lock()) {
        std::lock_guard<std::mutex> lock(p->mutex_);
        p->free_.push_back(std::move(owned));
        if (p->free_.size() > p->keep_) p->free_.erase(p->free_.begin());  // the oldest goes
    }
}

void ZeroedPool::trim() {
    std::vector<std::unique_ptr<Slab>> gone;
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

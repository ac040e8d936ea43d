// io_fixture.hpp: what the volume I/O tests (test_io*.cpp) share: byte and file helpers, temporary folders,
// random volumes, raw data of given values, error expectations and a NIfTI header builder.
#pragma once

#include <catch2/catch.hpp>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <set>
#include <string>
#include <sys/stat.h>
#include <unistd.h>
#include <vector>

#include "volrig/io.hpp"

using namespace volrig;
namespace fs = std::filesystem;

namespace {

using Bytes = std::vector<std::uint8_t>;

const DType kAllTypes[] = {DType::UInt8, DType::Int8,  DType::UInt16,  DType::Int16,  DType::UInt32,
                           DType::Int32, DType::UInt64, DType::Int64, DType::Float32, DType::Float64};

inline Bytes bytes(const std::string& s) { return Bytes(s.begin(), s.end()); }
inline Bytes operator+(Bytes a, const Bytes& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}
inline Bytes operator+(const std::string& a, const Bytes& b) { return bytes(a) + b; }

inline Bytes compress(const Bytes& in, bool gzip) {
    z_stream z{};
    REQUIRE(deflateInit2(&z, 6, Z_DEFLATED, gzip ? 31 : 15, 8, Z_DEFAULT_STRATEGY) == Z_OK);
    Bytes out(deflateBound(&z, in.size()) + 64);
    z.next_in = const_cast<Bytef*>(in.data());
    z.avail_in = static_cast<uInt>(in.size());
    z.next_out = out.data();
    z.avail_out = static_cast<uInt>(out.size());
    REQUIRE(deflate(&z, Z_FINISH) == Z_STREAM_END);
    out.resize(z.total_out);
    deflateEnd(&z);
    return out;
}
inline Bytes gzip(const Bytes& in) { return compress(in, true); }
inline Bytes zlib(const Bytes& in) { return compress(in, false); }

inline void write_file(const fs::path& p, const Bytes& b) {
    std::ofstream f(p, std::ios::binary);
    f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    REQUIRE(f.good());
}
inline Bytes read_file(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return Bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

struct TempDir {
    fs::path path;
    TempDir() {
        std::string t = (fs::temp_directory_path() / "volrig_io_XXXXXX").string();
        REQUIRE(mkdtemp(t.data()) != nullptr);
        path = t;
    }
    ~TempDir() {
        std::error_code ec;
        fs::permissions(path, fs::perms::owner_all, fs::perm_options::add, ec);
        fs::remove_all(path, ec);
    }
    std::string operator/(const std::string& name) const { return (path / name).string(); }
    std::vector<std::string> entries() const {
        std::vector<std::string> out;
        for (auto& e : fs::directory_iterator(path)) out.push_back(e.path().filename().string());
        std::sort(out.begin(), out.end());
        return out;
    }
};

/// A volume filled with pseudo-random bytes (so every byte position of every element is exercised).
inline Volume random_volume(DType t, std::array<std::int64_t, 3> dims, std::uint32_t seed = 1) {
    Volume v;
    v.dtype = t;
    v.grid.dims = dims;
    v.grid.spacing = {0.5, 1.25, 3.0};
    v.grid.origin = {-10.5, 2.0, 0.001};
    v.data.resize(static_cast<std::size_t>(v.grid.voxel_count()) * dtype_size(t));
    std::uint32_t x = seed * 2654435761u + 1;
    for (auto& b : v.data) {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        b = static_cast<std::uint8_t>(x);
    }
    return v;
}

template <class T>
std::vector<T> values(const Volume& v) {
    REQUIRE(v.data.size() % sizeof(T) == 0);
    std::vector<T> out(v.data.size() / sizeof(T));
    std::memcpy(out.data(), v.data.data(), v.data.size());
    return out;
}

template <class T>
Bytes raw_of(std::initializer_list<T> vals, bool big_endian = false) {
    Bytes out;
    for (T v : vals) {
        std::uint8_t b[sizeof(T)];
        std::memcpy(b, &v, sizeof(T));
        if (big_endian) std::reverse(b, b + sizeof(T));
        out.insert(out.end(), b, b + sizeof(T));
    }
    return out;
}

inline Volume read_mem(Volume (*reader)(const ByteSource&, const ReadOptions&), const Bytes& b, const std::string& name,
                ReadOptions opt = {}) {
    auto src = memory_source(b.data(), b.size(), name);
    return reader(*src, opt);
}

/// The message of what f throws ("(no error)" when it throws nothing).
inline std::string message_of(const std::function<void()>& f) {
    try {
        f();
    } catch (const std::exception& e) {
        return e.what();
    }
    return "(no error)";
}

/// Runs f and checks it throws E whose message contains every part.
template <class E = FileFormatError, class F>
void expect_error(F&& f, std::initializer_list<std::string> parts) {
    try {
        f();
    } catch (const E& e) {
        const std::string m = e.what();
        INFO("message: " << m);
        for (const auto& p : parts) CHECK(m.find(p) != std::string::npos);
        return;
    }
    std::string all;
    for (const auto& p : parts) all += "'" + p + "' ";
    FAIL("no exception; expected one mentioning " << all);
}

inline void check_same(const Volume& a, const Volume& b) {
    CHECK(a.dtype == b.dtype);
    CHECK(a.grid.dims == b.grid.dims);
    for (int i = 0; i < 3; ++i) {
        CHECK(a.grid.spacing[i] == b.grid.spacing[i]);
        CHECK(a.grid.origin[i] == b.grid.origin[i]);
    }
    CHECK(a.data == b.data);
}

// ---- NIfTI header builder --------------------------------------------------------------------------------------

struct Nifti {
    bool big = false;
    std::int32_t sizeof_hdr = 348;
    std::string magic = "n+1";
    std::int16_t dim[8] = {3, 2, 3, 4, 1, 1, 1, 1};
    std::int16_t datatype = 2, bitpix = 8;
    float pixdim[8] = {1, 1.5f, 2.0f, 2.5f, 1, 1, 1, 1};
    float vox_offset = 352;
    float slope = 0, inter = 0;
    std::int16_t qform = 0, sform = 0;
    float qoffset[3] = {0, 0, 0};
    float srow[3][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};

    template <class T>
    void put(Bytes& h, std::size_t at, T v) const {
        std::uint8_t b[sizeof(T)];
        std::memcpy(b, &v, sizeof(T));
        if (big) std::reverse(b, b + sizeof(T));
        std::memcpy(h.data() + at, b, sizeof(T));
    }
    /// The 348-byte header, padded with zero bytes to vox_offset when `pad` (single-file layout).
    Bytes header(bool pad = true) const {
        Bytes h(348, 0);
        put(h, 0, sizeof_hdr);
        for (int i = 0; i < 8; ++i) put(h, 40 + 2 * static_cast<std::size_t>(i), dim[i]);
        put(h, 70, datatype);
        put(h, 72, bitpix);
        for (int i = 0; i < 8; ++i) put(h, 76 + 4 * static_cast<std::size_t>(i), pixdim[i]);
        put(h, 108, vox_offset);
        put(h, 112, slope);
        put(h, 116, inter);
        put(h, 252, qform);
        put(h, 254, sform);
        for (int i = 0; i < 3; ++i) put(h, 268 + 4 * static_cast<std::size_t>(i), qoffset[i]);
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c) put(h, 280 + 16 * static_cast<std::size_t>(r) + 4 * static_cast<std::size_t>(c), srow[r][c]);
        std::memcpy(h.data() + 344, magic.data(), std::min<std::size_t>(magic.size(), 4));
        if (pad && std::isfinite(vox_offset) && vox_offset > 348 && vox_offset < 1e6)
            h.resize(static_cast<std::size_t>(vox_offset), 0);
        return h;
    }
};

inline std::string shared_data() { return VOLRIG_SHARED_DATA; }
inline bool have_shared_data() { return fs::is_directory(shared_data()); }

}  // namespace

// Tests for volrig/io.hpp (NRRD, MetaImage, NIfTI-1, raw; atomic writes): round trips, hand-written headers for
// each feature, every kind of bad input, and the real scans in ../shared/data when present.
#include <catch2/catch.hpp>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
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

Bytes bytes(const std::string& s) { return Bytes(s.begin(), s.end()); }
Bytes operator+(Bytes a, const Bytes& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}
Bytes operator+(const std::string& a, const Bytes& b) { return bytes(a) + b; }

Bytes compress(const Bytes& in, bool gzip) {
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
Bytes gzip(const Bytes& in) { return compress(in, true); }
Bytes zlib(const Bytes& in) { return compress(in, false); }

void write_file(const fs::path& p, const Bytes& b) {
    std::ofstream f(p, std::ios::binary);
    f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    REQUIRE(f.good());
}
Bytes read_file(const fs::path& p) {
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
Volume random_volume(DType t, std::array<std::int64_t, 3> dims, std::uint32_t seed = 1) {
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

Volume read_mem(Volume (*reader)(const ByteSource&, const ReadOptions&), const Bytes& b, const std::string& name,
                ReadOptions opt = {}) {
    auto src = memory_source(b.data(), b.size(), name);
    return reader(*src, opt);
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

void check_same(const Volume& a, const Volume& b) {
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

std::string shared_data() { return VOLRIG_SHARED_DATA; }
bool have_shared_data() { return fs::is_directory(shared_data()); }

}  // namespace

// =================================================================================================================
// Round trips
// =================================================================================================================

TEST_CASE("NRRD round trip for every dtype, gzip and raw", "[io][nrrd]") {
    TempDir dir;
    for (DType t : kAllTypes) {
        for (bool gz : {true, false}) {
            INFO(dtype_name(t) << (gz ? " gzip" : " raw"));
            const Volume v = random_volume(t, {5, 4, 3}, static_cast<std::uint32_t>(t) + 1);
            const std::string path = dir / (std::string("rt_") + dtype_name(t) + (gz ? ".nrrd" : "_raw.nrrd"));
            write_nrrd(path, v.view(), gz);
            check_same(read_volume(path), v);
        }
    }
    // Only the written files remain (no temporary names).
    for (const auto& e : dir.entries()) CHECK(e.find(".tmp-") == std::string::npos);
}

TEST_CASE("MetaImage round trip for every dtype, compressed and not", "[io][metaimage]") {
    TempDir dir;
    for (DType t : kAllTypes) {
        for (bool z : {true, false}) {
            INFO(dtype_name(t) << (z ? " compressed" : " raw"));
            const Volume v = random_volume(t, {3, 5, 2}, static_cast<std::uint32_t>(t) + 11);
            const std::string path = dir / (std::string("rt_") + dtype_name(t) + (z ? ".mha" : "_raw.mha"));
            write_metaimage(path, v.view(), z);
            check_same(read_volume(path), v);
        }
    }
}

TEST_CASE("Writers keep awkward spacing and origin exactly", "[io]") {
    TempDir dir;
    Volume v = random_volume(DType::Float32, {2, 2, 2});
    v.grid.spacing = {0.1, 1.0 / 3.0, 1e-7};
    v.grid.origin = {-123.456789012345, 1e300, -0.0};
    write_nrrd(dir / "a.nrrd", v.view());
    write_metaimage(dir / "a.mha", v.view());
    check_same(read_volume(dir / "a.nrrd"), v);
    check_same(read_volume(dir / "a.mha"), v);
}

TEST_CASE("MetaImage writer fills in CompressedDataSize", "[io][metaimage]") {
    TempDir dir;
    const Volume v = random_volume(DType::Int16, {8, 8, 8});
    write_metaimage(dir / "c.mha", v.view(), true);
    const Bytes file = read_file(dir / "c.mha");
    const std::string text(file.begin(), file.end());
    const auto at = text.find("CompressedDataSize = ");
    REQUIRE(at != std::string::npos);
    const auto data_at = text.find("ElementDataFile = LOCAL\n") + std::strlen("ElementDataFile = LOCAL\n");
    CHECK(std::stoull(text.substr(at + 21)) == file.size() - data_at);
}

TEST_CASE("Writers refuse bad volumes", "[io]") {
    TempDir dir;
    Volume v = random_volume(DType::UInt8, {2, 2, 2});
    v.grid.spacing[1] = std::nan("");
    CHECK_THROWS_AS(write_nrrd(dir / "x.nrrd", v.view()), Error);
    v.grid.spacing[1] = 1;
    v.grid.dims[2] = 0;
    CHECK_THROWS_AS(write_metaimage(dir / "x.mha", v.view()), Error);
    CHECK(dir.entries().empty());
}

// =================================================================================================================
// Atomic writes
// =================================================================================================================

TEST_CASE("write_atomically renames into place and cleans up on failure", "[io][atomic]") {
    TempDir dir;
    const std::string target = dir / "out.bin";
    write_file(target, bytes("old"));
    std::string seen_tmp;
    CHECK_THROWS_AS(write_atomically(target,
                                     [&](const std::string& tmp) {
                                         seen_tmp = tmp;
                                         write_file(tmp, bytes("partial"));
                                         throw Error("boom");
                                     }),
                    Error);
    CHECK(fs::path(seen_tmp).parent_path() == fs::path(target).parent_path());
    CHECK(!fs::exists(seen_tmp));
    CHECK(read_file(target) == bytes("old"));
    CHECK(dir.entries() == std::vector<std::string>{"out.bin"});

    write_atomically(target, [&](const std::string& tmp) { write_file(tmp, bytes("new")); });
    CHECK(read_file(target) == bytes("new"));
    CHECK(dir.entries() == std::vector<std::string>{"out.bin"});
}

TEST_CASE("Writers into a missing or read-only folder fail and leave nothing", "[io][atomic]") {
    TempDir dir;
    const Volume v = random_volume(DType::UInt8, {4, 4, 4});
    expect_error<FileNotFound>([&] { write_nrrd(dir / "missing/x.nrrd", v.view()); }, {"missing/x.nrrd", "cannot create"});
    CHECK(dir.entries().empty());
    if (::geteuid() != 0) {  // root ignores permissions
        fs::create_directory(dir.path / "ro");
        fs::permissions(dir.path / "ro", fs::perms::owner_read | fs::perms::owner_exec);
        expect_error<Error>([&] { write_metaimage(dir / "ro/x.mha", v.view()); }, {"ro/x.mha", "cannot create"});
        fs::permissions(dir.path / "ro", fs::perms::owner_all);
        CHECK(fs::is_empty(dir.path / "ro"));
    }
    // Target is a directory: the rename fails, the temporary file is removed.
    fs::create_directory(dir.path / "isdir.nrrd");
    fs::create_directory(dir.path / "isdir.nrrd" / "keep");
    CHECK_THROWS_AS(write_nrrd(dir / "isdir.nrrd", v.view()), Error);
    for (const auto& e : dir.entries()) CHECK(e.find(".tmp-") == std::string::npos);
}

// =================================================================================================================
// Sources, dispatch, limits
// =================================================================================================================

TEST_CASE("open_file and read_volume report missing files and unknown formats", "[io]") {
    TempDir dir;
    expect_error<FileNotFound>([&] { open_file(dir / "nope.raw"); }, {"nope.raw", "no such file"});
    expect_error<FileNotFound>([&] { read_volume(dir / "nope.nrrd"); }, {"nope.nrrd"});
    expect_error<FileNotFound>([&] { read_volume(dir / "nope.nii.gz"); }, {"nope.nii.gz"});
    write_file(dir / "x.txt", bytes("hello"));
    expect_error<FileFormatError>([&] { read_volume(dir / "x.txt"); }, {"x.txt", "unknown volume format"});
    expect_error<FileNotFound>([&] { read_volume(dir.path.string() + "/.nrrd"); }, {".nrrd"});
    fs::create_directory(dir.path / "d.nrrd");
    expect_error<FileNotFound>([&] { read_volume(dir / "d.nrrd"); }, {"d.nrrd", "directory"});
}

TEST_CASE("ByteSource reads exactly or says what is missing", "[io]") {
    const Bytes b = bytes("0123456789");
    auto src = memory_source(b.data(), b.size(), "mem.bin");
    char buf[4];
    src->read(6, buf, 4);
    CHECK(std::string(buf, 4) == "6789");
    expect_error([&] { src->read(8, buf, 4); }, {"mem.bin", "4 bytes at offset 8"});
    expect_error([&] { src->read(std::numeric_limits<std::uint64_t>::max(), buf, 4); }, {"mem.bin"});
    expect_error([&] { src->open_sibling("x.raw"); },
                 {"mem.bin", "detached data files are not available for in-memory input"});
    TempDir dir;
    write_file(dir / "f.bin", b);
    auto f = open_file(dir / "f.bin");
    CHECK(f->size() == 10);
    CHECK(f->name() == dir / "f.bin");
    expect_error([&] { f->read(7, buf, 4); }, {"f.bin", "but the file holds 10 bytes"});
    expect_error<FileNotFound>([&] { f->open_sibling("other.raw"); }, {"f.bin", "other.raw"});
    auto sib = f->open_sibling("f.bin");
    CHECK(sib->size() == 10);
    auto abs = f->open_sibling(dir / "f.bin");
    CHECK(abs->size() == 10);
}

TEST_CASE("default_max_bytes honours VOLRIG_MAX_BYTES", "[io]") {
    const char* old = std::getenv("VOLRIG_MAX_BYTES");
    const std::string saved = old ? old : "";
    ::unsetenv("VOLRIG_MAX_BYTES");
    CHECK(default_max_bytes() == (std::uint64_t(16) << 30));
    ::setenv("VOLRIG_MAX_BYTES", "1000", 1);
    CHECK(default_max_bytes() == 1000);
    ::setenv("VOLRIG_MAX_BYTES", "2M", 1);
    CHECK(default_max_bytes() == (std::uint64_t(2) << 20));
    ::setenv("VOLRIG_MAX_BYTES", "3GiB", 1);
    CHECK(default_max_bytes() == (std::uint64_t(3) << 30));
    ::setenv("VOLRIG_MAX_BYTES", "lots", 1);
    CHECK(default_max_bytes() == (std::uint64_t(16) << 30));
    ::setenv("VOLRIG_MAX_BYTES", "64", 1);
    {
        ReadOptions opt;
        CHECK(opt.max_bytes == 64);
        const Bytes b = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 5\nencoding: raw\n\n" + Bytes(80, 1);
        expect_error([&] { read_mem(read_nrrd, b, "limit.nrrd", opt); }, {"limit.nrrd", "exceeds the limit of 64"});
    }
    if (old)
        ::setenv("VOLRIG_MAX_BYTES", saved.c_str(), 1);
    else
        ::unsetenv("VOLRIG_MAX_BYTES");
}

TEST_CASE("read_raw reads the layout it is given", "[io][raw]") {
    TempDir dir;
    const Bytes data = Bytes{9, 9, 9} + raw_of<std::int16_t>({1, -2, 300, -400, 5, 6}, true);
    write_file(dir / "v.raw", data);
    RawLayout layout;
    layout.dims = {3, 2, 1};
    layout.dtype = DType::Int16;
    layout.big_endian = true;
    layout.offset = 3;
    layout.spacing = {2, 2, 2};
    layout.origin = {1, 2, 3};
    auto src = open_file(dir / "v.raw");
    const Volume v = read_raw(*src, layout);
    CHECK(values<std::int16_t>(v) == std::vector<std::int16_t>{1, -2, 300, -400, 5, 6});
    CHECK(v.grid.spacing == std::array<double, 3>{2, 2, 2});
    CHECK(v.grid.origin == std::array<double, 3>{1, 2, 3});

    layout.dims = {3, 2, 2};
    expect_error([&] { read_raw(*src, layout); }, {"v.raw", "3x2x2 int16 = 24 bytes but the file holds 12"});
    layout.dims = {1 << 20, 1 << 20, 1};
    expect_error([&] { read_raw(*src, layout); }, {"v.raw", "exceeds the limit"});
    layout.dims = {3, -2, 1};
    expect_error([&] { read_raw(*src, layout); }, {"v.raw", "must all be positive"});
    layout.dims = {3, 2, 1};
    layout.offset = 1000;
    expect_error([&] { read_raw(*src, layout); }, {"v.raw", "past its end"});
    layout.offset = 0;
    layout.spacing = {1, std::nan(""), 1};
    expect_error([&] { read_raw(*src, layout); }, {"v.raw", "spacing"});
}

// =================================================================================================================
// NRRD features
// =================================================================================================================

TEST_CASE("NRRD: the tooth-like attached raw header", "[io][nrrd]") {
    const Bytes data = raw_of<std::uint8_t>({1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12});
    const Bytes b = "NRRD0004\n# Complete NRRD file format specification at:\n"
                    "# http://teem.sourceforge.net/nrrd/format.html\ntype: uint8_t\ndimension: 3\n"
                    "space: left-posterior-superior\nsizes: 3 2 2\nspace directions: (0.5,0,0) (0,-2,0) (0,0,3)\n"
                    "kinds: domain domain domain\nendian: little\nencoding: raw\nspace origin: (1.5,-2,100)\n\n" +
                    data;
    const Volume v = read_mem(read_nrrd, b, "tooth-like.nrrd");
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{3, 2, 2});
    CHECK(v.grid.spacing == std::array<double, 3>{0.5, 2, 3});
    CHECK(v.grid.origin == std::array<double, 3>{1.5, -2, 100});
    CHECK(v.data == data);
}

TEST_CASE("NRRD: every type alias", "[io][nrrd]") {
    const std::pair<const char*, DType> aliases[] = {
        {"uchar", DType::UInt8}, {"unsigned char", DType::UInt8}, {"uint8", DType::UInt8}, {"uint8_t", DType::UInt8},
        {"signed char", DType::Int8}, {"int8", DType::Int8}, {"int8_t", DType::Int8}, {"short", DType::Int16},
        {"short int", DType::Int16}, {"signed short", DType::Int16}, {"signed short int", DType::Int16},
        {"int16", DType::Int16}, {"int16_t", DType::Int16}, {"ushort", DType::UInt16},
        {"unsigned short", DType::UInt16}, {"unsigned short int", DType::UInt16}, {"uint16", DType::UInt16},
        {"uint16_t", DType::UInt16}, {"int", DType::Int32}, {"signed int", DType::Int32}, {"int32", DType::Int32},
        {"int32_t", DType::Int32}, {"uint", DType::UInt32}, {"unsigned int", DType::UInt32},
        {"uint32", DType::UInt32}, {"uint32_t", DType::UInt32}, {"longlong", DType::Int64},
        {"long long", DType::Int64}, {"long long int", DType::Int64}, {"signed long long", DType::Int64},
        {"signed long long int", DType::Int64}, {"int64", DType::Int64}, {"int64_t", DType::Int64},
        {"ulonglong", DType::UInt64}, {"unsigned long long", DType::UInt64},
        {"unsigned long long int", DType::UInt64}, {"uint64", DType::UInt64}, {"uint64_t", DType::UInt64},
        {"float", DType::Float32}, {"double", DType::Float64}, {"Unsigned  Short", DType::UInt16}};
    for (const auto& [name, t] : aliases) {
        INFO(name);
        const Bytes b = "NRRD0005\ntype: " + std::string(name) + "\ndimension: 3\nsizes: 2 1 1\nendian: little\n"
                        "encoding: raw\n\n" + Bytes(2 * dtype_size(t), 7);
        const Volume v = read_mem(read_nrrd, b, "alias.nrrd");
        CHECK(v.dtype == t);
        CHECK(v.data == Bytes(2 * dtype_size(t), 7));
    }
}

TEST_CASE("NRRD: detached header with line skip and byte skip", "[io][nrrd]") {
    TempDir dir;
    fs::create_directory(dir.path / "data");
    const Bytes payload = raw_of<std::uint16_t>({10, 20, 30, 40, 50, 60}, true);
    write_file(dir / "data/v.raw", bytes("junk line 1\njunk line 2\n") + Bytes{0xEE, 0xEE} + payload);
    write_file(dir / "v.nhdr", bytes("NRRD0004\ntype: ushort\ndimension: 2\nsizes: 3 2\nspacings: 0.25 4\n"
                                     "endian: big\nencoding: raw\nline skip: 2\nbyte skip: 2\n"
                                     "data file: data/v.raw\n"));
    const Volume v = read_volume(dir / "v.nhdr");
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{3, 2, 1});
    CHECK(v.grid.spacing == std::array<double, 3>{0.25, 4, 1});
    CHECK(values<std::uint16_t>(v) == std::vector<std::uint16_t>{10, 20, 30, 40, 50, 60});

    // "datafile" spelling, byte skip -1 (data at the end), an absolute path
    write_file(dir / "w.nhdr", bytes("NRRD0004\ntype: ushort\ndimension: 2\nsizes: 3 2\nendian: big\n"
                                     "encoding: raw\nbyte skip: -1\ndatafile: " + (dir / "data/v.raw") + "\n\n"));
    CHECK(values<std::uint16_t>(read_volume(dir / "w.nhdr")) == std::vector<std::uint16_t>{10, 20, 30, 40, 50, 60});

    // the data file is missing
    write_file(dir / "m.nhdr", bytes("NRRD0004\ntype: uchar\ndimension: 1\nsizes: 3\nencoding: raw\n"
                                     "data file: gone.raw\n"));
    expect_error<FileNotFound>([&] { read_volume(dir / "m.nhdr"); }, {"m.nhdr", "gone.raw"});
    // line skip past the end
    write_file(dir / "l.nhdr", bytes("NRRD0004\ntype: uchar\ndimension: 1\nsizes: 3\nencoding: raw\nline skip: 9\n"
                                     "data file: data/v.raw\n"));
    expect_error([&] { read_volume(dir / "l.nhdr"); }, {"l.nhdr", "line skip 9 runs past the end"});
    // in memory, a detached header cannot be followed
    const Bytes mem = read_file(dir / "v.nhdr");
    expect_error([&] { read_mem(read_nrrd, mem, "mem.nhdr"); }, {"mem.nhdr", "detached data files are not available"});
}

TEST_CASE("NRRD: gzip encoding, with byte skip, multi-member", "[io][nrrd]") {
    const Bytes data = raw_of<float>({1.5f, -2.f, 3.25f, 4.f, 5.f, 6.f, 7.f, 8.f});
    const std::string h = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\nencoding: gzip\n";
    CHECK(read_mem(read_nrrd, h + "\n" + gzip(data), "g.nrrd").data == data);
    CHECK(read_mem(read_nrrd, h + "byte skip: 3\n\n" + gzip(Bytes{1, 2, 3} + data), "g.nrrd").data == data);
    // concatenated gzip members (cat a.gz b.gz)
    const Bytes first(data.begin(), data.begin() + 13), second(data.begin() + 13, data.end());
    CHECK(read_mem(read_nrrd, h + "\n" + gzip(first) + gzip(second), "g.nrrd").data == data);
    // "gz" spelling and zlib (not gzip) streams are decoded too
    const std::string hz = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\nencoding: gz\n\n";
    CHECK(read_mem(read_nrrd, hz + zlib(data), "z.nrrd").data == data);
}

TEST_CASE("NRRD: big endian, ascii, CRLF, comments, key/values, 2-D, 4-D with a unit axis", "[io][nrrd]") {
    SECTION("big endian double") {
        const Bytes b = "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 1 1\nendian: big\nencoding: raw\n\n" +
                        raw_of<double>({1.25, -7e100}, true);
        CHECK(values<double>(read_mem(read_nrrd, b, "be.nrrd")) == std::vector<double>{1.25, -7e100});
    }
    SECTION("ascii") {
        const Bytes b = bytes("NRRD0004\ntype: float\ndimension: 2\nsizes: 3 2\nencoding: ascii\n\n"
                              "1.5 -2\n3e2,\t+4\n  nan\n-inf\n");
        const auto v = values<float>(read_mem(read_nrrd, b, "a.nrrd"));
        CHECK(v[0] == 1.5f);
        CHECK(v[1] == -2.f);
        CHECK(v[2] == 300.f);
        CHECK(v[3] == 4.f);
        CHECK(std::isnan(v[4]));
        CHECK(v[5] == -std::numeric_limits<float>::infinity());
        const Bytes ints = bytes("NRRD0004\ntype: short\ndimension: 1\nsizes: 4\nencoding: text\n\n-32768 32767 1e2 7.0");
        CHECK(values<std::int16_t>(read_mem(read_nrrd, ints, "i.nrrd")) == std::vector<std::int16_t>{-32768, 32767, 100, 7});
        expect_error([&] { read_mem(read_nrrd, bytes("NRRD0004\ntype: uchar\ndimension: 1\nsizes: 2\nencoding: txt\n\n1 256"), "o.nrrd"); },
                     {"o.nrrd", "text value #2 '256' is not a valid uint8"});
        expect_error([&] { read_mem(read_nrrd, bytes("NRRD0004\ntype: int\ndimension: 1\nsizes: 2\nencoding: ascii\n\n1 1.5"), "f.nrrd"); },
                     {"f.nrrd", "'1.5' is not a valid int32"});
        expect_error([&] { read_mem(read_nrrd, bytes("NRRD0004\ntype: int\ndimension: 1\nsizes: 3\nencoding: ascii\n\n1 2 x"), "x.nrrd"); },
                     {"x.nrrd", "'x'"});
        expect_error([&] { read_mem(read_nrrd, bytes("NRRD0004\ntype: int\ndimension: 1\nsizes: 3\nencoding: ascii\n\n1   2  "), "t.nrrd"); },
                     {"t.nrrd", "truncated: 2 of 3 values"});
        expect_error([&] { read_mem(read_nrrd, bytes("NRRD0004\ntype: int\ndimension: 1\nsizes: 30\nencoding: ascii\n\n1 2"), "r.nrrd"); },
                     {"r.nrrd", "30 values", "holds 3 bytes of text"});
    }
    SECTION("CRLF, comments, key/value pairs, unknown fields") {
        const Bytes b = "NRRD0004\r\n# a comment\r\ncreator:=someone: with colons\r\ntype: uchar\r\ncontent: x\r\n"
                        "dimension: 3\r\nsizes: 1 2 1\r\nencoding: raw\r\nthicknesses: 1 1 1\r\n\r\n" +
                        Bytes{4, 5};
        CHECK(read_mem(read_nrrd, b, "crlf.nrrd").data == Bytes{4, 5});
    }
    SECTION("4-D with a stub/scalar axis, and with a size-1 domain axis") {
        const Bytes b = "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 1 2 3 1\nkinds: scalar domain domain domain\n"
                        "space directions: none (2,0,0) (0,3,0) (0,0,4)\nencoding: raw\n\n" + Bytes(6, 1);
        const Volume v = read_mem(read_nrrd, b, "4d.nrrd");
        CHECK(v.grid.dims == std::array<std::int64_t, 3>{2, 3, 1});
        CHECK(v.grid.spacing == std::array<double, 3>{2, 3, 4});
        const Bytes c = "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 2 3 4 1\nencoding: raw\n\n" + Bytes(24, 1);
        CHECK(read_mem(read_nrrd, c, "4d.nrrd").grid.dims == std::array<std::int64_t, 3>{2, 3, 4});
    }
    SECTION("axis mins give the origin when there is no space origin") {
        const Bytes b = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\naxis mins: -1 2.5 nan\nspacings: 1 1 1\n"
                        "encoding: raw\n\n" + Bytes{1};
        CHECK(read_mem(read_nrrd, b, "mins.nrrd").grid.origin == std::array<double, 3>{-1, 2.5, 0});
    }
}

// =================================================================================================================
// NRRD bad input
// =================================================================================================================

TEST_CASE("NRRD: bad headers name the file and the problem", "[io][nrrd][errors]") {
    const std::string ok_tail = "encoding: raw\n\n";
    auto hdr = [](const std::string& fields) { return bytes("NRRD0004\n" + fields + "\n") + Bytes(64, 0); };
    auto err = [&](const Bytes& b, std::initializer_list<std::string> parts) {
        expect_error([&] { read_mem(read_nrrd, b, "bad.nrrd"); }, parts);
    };
    err(bytes("NRRX0004\n"), {"bad.nrrd", "not a NRRD file"});
    err(Bytes{}, {"bad.nrrd", "not a NRRD file"});
    err(bytes("NRRD000"), {"bad.nrrd", "not a NRRD file"});
    err(hdr("type: uchar\ndimension: 3\nencoding: raw\n"), {"bad.nrrd", "missing field 'sizes'"});
    err(hdr("dimension: 3\nsizes: 1 1 1\nencoding: raw\n"), {"bad.nrrd", "missing field 'type'"});
    err(hdr("type: uchar\nsizes: 1 1 1\nencoding: raw\n"), {"bad.nrrd", "missing field 'dimension'"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\n"), {"bad.nrrd", "missing field 'encoding'"});
    err(hdr("type: quaternion\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n"), {"bad.nrrd", "type 'quaternion'"});
    err(hdr("type: block\nblock size: 4\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n"), {"bad.nrrd", "type 'block'", "not supported"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: bzip2\n"), {"bad.nrrd", "bzip2", "not supported"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: hex\n"), {"bad.nrrd", "hex", "not supported"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: zip\n"), {"bad.nrrd", "'zip'"});
    err(hdr("type: short\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n"), {"bad.nrrd", "missing field 'endian'", "int16"});
    err(hdr("type: short\ndimension: 3\nsizes: 1 1 1\nendian: middle\nencoding: raw\n"), {"bad.nrrd", "endian 'middle'"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 3 -4 5\nencoding: raw\n"), {"bad.nrrd", "line 4", "sizes '3 -4 5'", "positive"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 3 0 5\nencoding: raw\n"), {"bad.nrrd", "positive"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 3 4\nencoding: raw\n"), {"bad.nrrd", "must list 3 sizes"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 99999999999999999999 1 1\nencoding: raw\n"), {"bad.nrrd", "positive integers"});
    err(hdr("type: uchar\ndimension: 0\nsizes: \nencoding: raw\n"), {"bad.nrrd", "dimension '0'"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1048576 1048576 1\nencoding: raw\n"), {"bad.nrrd", "exceeds the limit"});
    err(hdr("type: double\ndimension: 3\nsizes: 9223372036854775807 9223372036854775807 9223372036854775807\nendian: little\nencoding: raw\n"),
        {"bad.nrrd", "exceeds the limit"});
    err(hdr("type: uchar\ndimension: 4\nsizes: 2 2 2 2\nencoding: raw\n"), {"bad.nrrd", "4-D", "not supported"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 3 2 2\nkinds: RGB-color domain domain\nencoding: raw\n"),
        {"bad.nrrd", "'RGB-color' of size 3", "multi-component"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspacings: 1 nan 1\nencoding: raw\n"), {"bad.nrrd", "spacing along y", "nan"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspacings: 1 0 1\nencoding: raw\n"), {"bad.nrrd", "spacing along y"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspace directions: (1,0,0) (0,nan,0) (0,0,1)\nencoding: raw\n"),
        {"bad.nrrd", "spacing along y"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspace directions: (1,0,0) (0,1,0)\nencoding: raw\n"),
        {"bad.nrrd", "space directions", "one vector"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspace directions: (1,0,0) (0,1,0) (0,0,x)\nencoding: raw\n"),
        {"bad.nrrd", "space directions"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspace origin: (1,inf,0)\nencoding: raw\n"), {"bad.nrrd", "space origin", "finite"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nspace origin: 1 2 3\nencoding: raw\n"), {"bad.nrrd", "space origin"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\ndata file: LIST\n"), {"bad.nrrd", "several files"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\ndata file: s%03d.raw 1 10 1 2\n"), {"bad.nrrd", "several files"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\nbyte skip: -2\n"), {"bad.nrrd", "byte skip '-2'"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: gzip\nbyte skip: -1\n"), {"bad.nrrd", "only valid with raw"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\nbyte skip: 1000\n"), {"bad.nrrd", "byte skip 1,000 runs past the end"});
    err(hdr("type: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\nline skip: x\n"), {"bad.nrrd", "line skip 'x'"});
    err(hdr("type: uchar\ndimension: 3\nthis line has no separator\n"), {"bad.nrrd", "line 4", "expected 'field: value'"});
    err(bytes("NRRD0004\ntype: uchar\ndimension: 1\nsizes: 3\nencoding: raw\n"), {"bad.nrrd", "no data"});
    err(bytes("NRRD0004\n") + Bytes(2 << 20, 'a'), {"bad.nrrd", "longer than 1 MiB"});
}

TEST_CASE("NRRD: per-axis fields give one entry per axis", "[io][nrrd][errors]") {
    auto hdr = [](const std::string& fields) {
        return bytes("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 1 1\n" + fields + "encoding: raw\n\n") + Bytes{7, 9};
    };
    auto err = [&](const std::string& fields, std::initializer_list<std::string> parts) {
        expect_error([&] { read_mem(read_nrrd, hdr(fields), "axes.nrrd"); }, parts);
    };
    err("spacings: 1 1\n", {"axes.nrrd", "line 5", "spacings '1 1'", "one number per axis (3)"});
    err("spacings: 1 x 1\n", {"axes.nrrd", "spacings '1 x 1'", "must be numbers"});
    err("axis mins: 0 0\n", {"axes.nrrd", "axis mins '0 0'", "one number per axis (3)"});
    err("axis mins: 0 y 0\n", {"axes.nrrd", "axis mins '0 y 0'", "must be numbers"});
    err("kinds: domain domain\n", {"axes.nrrd", "kinds 'domain domain'", "one kind per axis (3)"});
    expect_error([&] {
        read_mem(read_nrrd, bytes("NRRD0004\ntype: uchar\ndimension: 2\nsizes: 1 1\nkinds: vector vector\n"
                                  "encoding: raw\n\n") + Bytes{1},
                 "axes.nrrd");
    }, {"axes.nrrd", "no spatial axes"});

    // Well-formed: the axis mins give the origin, a unit component axis is dropped, spacings keep their magnitude.
    const Volume v = read_mem(read_nrrd, hdr("axis mins: 5 6 7\nspacings: -0.5 2 3\n"), "axes.nrrd");
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{2, 1, 1});
    CHECK(v.grid.origin == std::array<double, 3>{5, 6, 7});
    CHECK(v.grid.spacing == std::array<double, 3>{0.5, 2, 3});
    CHECK(v.data == std::vector<std::uint8_t>{7, 9});
    const Bytes comp = bytes("NRRD0004\ntype: uchar\ndimension: 4\nsizes: 1 2 1 1\nkinds: vector domain domain domain\n"
                             "encoding: raw\n\n") + Bytes{4, 8};
    const Volume w = read_mem(read_nrrd, comp, "axes.nrrd");
    CHECK(w.grid.dims == std::array<std::int64_t, 3>{2, 1, 1});
    CHECK(w.data == std::vector<std::uint8_t>{4, 8});
}

TEST_CASE("NRRD and MetaImage: of several bad fields, the first in reading order is named", "[io][errors]") {
    // NRRD: type, then dimension and sizes, per-axis fields, grid, encoding, endian, data file, skips.
    auto nrrd = [](const std::string& fields) { return bytes("NRRD0004\n" + fields + "\n") + Bytes(8, 0); };
    expect_error([&] { read_mem(read_nrrd, nrrd("type: quux\ndimension: 0\nencoding: zip\n"), "o.nrrd"); },
                 {"o.nrrd", "type 'quux'"});
    expect_error([&] { read_mem(read_nrrd, nrrd("type: uchar\ndimension: 1\nsizes: 2\nspacings: 1 1\nencoding: zip\n"),
                                "o.nrrd"); },
                 {"o.nrrd", "spacings"});
    expect_error([&] { read_mem(read_nrrd, nrrd("type: short\ndimension: 1\nsizes: 2\nencoding: zip\n"), "o.nrrd"); },
                 {"o.nrrd", "encoding 'zip'"});
    expect_error([&] { read_mem(read_nrrd, nrrd("type: short\ndimension: 1\nsizes: 2\nencoding: raw\nbyte skip: -7\n"),
                                "o.nrrd"); },
                 {"o.nrrd", "missing field 'endian'"});
    // MetaImage: NDims, DimSize, ElementType, spacing and origin, encoding flags, data file.
    auto meta = [](const std::string& fields) { return bytes(fields + "ElementDataFile = LOCAL\n") + Bytes(8, 0); };
    expect_error([&] { read_mem(read_metaimage, meta("NDims = 3\nDimSize = 2 0 2\nElementType = MET_NONE\n"), "o.mha"); },
                 {"o.mha", "DimSize"});
    expect_error([&] { read_mem(read_metaimage, meta("NDims = 1\nDimSize = 2\nElementType = MET_NONE\nOffset = x\n"),
                                "o.mha"); },
                 {"o.mha", "ElementType = 'MET_NONE'"});
    expect_error([&] { read_mem(read_metaimage, meta("NDims = 1\nDimSize = 2\nElementType = MET_UCHAR\nOffset = inf\n"
                                                     "BinaryData = perhaps\n"), "o.mha"); },
                 {"o.mha", "line 4", "Offset = 'inf'", "must be finite"});
    expect_error([&] { read_mem(read_metaimage, meta("NDims = 1\nDimSize = 2\nElementType = MET_UCHAR\n"
                                                     "BinaryData = perhaps\nHeaderSize = -3\n"), "o.mha"); },
                 {"o.mha", "BinaryData = 'perhaps'", "True or False"});
}

TEST_CASE("NRRD: data shorter than the header says", "[io][nrrd][errors]") {
    const Bytes b = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 103 94 161\nencoding: raw\n\n" + Bytes(1000000, 3);
    expect_error([&] { read_mem(read_nrrd, b, "tooth.nrrd"); },
                 {"tooth.nrrd: header says 103x94x161 uint8 = 1,558,802 bytes but the file holds 1,000,000"});
    const Bytes be = "NRRD0004\ntype: int16\ndimension: 3\nsizes: 2 2 2\nendian: big\nencoding: raw\nbyte skip: -1\n\n" + Bytes(15, 3);
    expect_error([&] { read_mem(read_nrrd, be, "short.nrrd"); }, {"short.nrrd", "= 16 bytes but the file holds 15"});
}

TEST_CASE("NRRD: broken gzip data", "[io][nrrd][errors][gzip]") {
    const std::string h = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 10 10 10\nencoding: gzip\n\n";
    const Bytes zeros1000(1000, 0);
    auto err = [&](const Bytes& b, std::initializer_list<std::string> parts, ReadOptions opt = {}) {
        expect_error([&] { read_mem(read_nrrd, b, "z.nrrd", opt); }, parts);
    };
    SECTION("ok") { CHECK(read_mem(read_nrrd, h + gzip(zeros1000), "z.nrrd").data == zeros1000); }
    SECTION("stream shorter than declared") {
        err(h + gzip(Bytes(600, 0)), {"z.nrrd", "truncated: 600 of 1,000 bytes"});
    }
    SECTION("compressed bytes cut off") {
        Bytes z = gzip(random_volume(DType::UInt8, {10, 10, 10}).data);
        z.resize(z.size() / 2);
        err(h + z, {"z.nrrd", "truncated"});
        Bytes full = gzip(zeros1000);
        full.resize(full.size() - 4);  // all data there, the gzip trailer (length) is not
        err(h + full, {"z.nrrd", "truncated", "end marker"});
    }
    SECTION("wrong gzip length / checksum in the trailer") {
        Bytes z = gzip(zeros1000);
        z[z.size() - 1] ^= 0x55;  // ISIZE
        err(h + z, {"z.nrrd", "corrupt compressed data", "incorrect length check"});
        Bytes c = gzip(zeros1000);
        c[c.size() - 6] ^= 0x55;  // CRC32
        err(h + c, {"z.nrrd", "corrupt compressed data", "incorrect data check"});
    }
    SECTION("gzip bomb: many zeros, header declares fewer bytes") {
        const Bytes bomb = gzip(Bytes(10 << 20, 0));  // 10 MiB of zeros in ~10 KiB
        CHECK(bomb.size() < 20000);
        err(h + bomb, {"z.nrrd", "more data than the header declares"});
    }
    SECTION("header declares 100 GB with a tiny stream: refused before allocating") {
        const std::string big = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 100000 1000 1000\nencoding: gzip\n\n";
        ReadOptions unlimited;
        unlimited.max_bytes = std::uint64_t(1) << 62;
        err(big + gzip(zeros1000), {"z.nrrd", "header declares 100,000,000,000 bytes but", "compressed bytes can inflate to at most"},
            unlimited);
        err(big + gzip(zeros1000), {"z.nrrd", "exceeds the limit"});  // the default 16 GiB limit says no first
    }
    SECTION("garbage instead of a stream") {
        err(h + bytes("this is not compressed at all, not even a little"), {"z.nrrd", "corrupt compressed data"});
        err(bytes(h), {"z.nrrd", "truncated: 0 of 1,000"});
    }
}

// =================================================================================================================
// MetaImage
// =================================================================================================================

TEST_CASE("MetaImage: LOCAL raw, ElementSize, Position, ElementByteOrderMSB, MET_LONG", "[io][metaimage]") {
    const Bytes data = raw_of<std::int32_t>({-1, 2, -3, 4, 5, 6}, true);
    const Bytes b = "NDims = 3\nDimSize = 3 2 1\nElementSize = 2 3 -4\nPosition = 1 2 3\nElementByteOrderMSB = True\n"
                    "ElementType = MET_LONG\nElementDataFile = LOCAL\n" + data;
    const Volume v = read_mem(read_metaimage, b, "l.mha");
    CHECK(v.dtype == DType::Int32);  // MetaIO's MET_LONG is 4 bytes
    CHECK(values<std::int32_t>(v) == std::vector<std::int32_t>{-1, 2, -3, 4, 5, 6});
    CHECK(v.grid.spacing == std::array<double, 3>{2, 3, 4});
    CHECK(v.grid.origin == std::array<double, 3>{1, 2, 3});

    const Bytes ul = bytes("ObjectType = Image\nNDims = 2\nDimSize = 2 1\nElementType = MET_ULONG\n"
                           "BinaryDataByteOrderMSB = False\nElementDataFile = LOCAL\n") + raw_of<std::uint32_t>({7, 4000000000u});
    const Volume u = read_mem(read_metaimage, ul, "ul.mha");
    CHECK(u.dtype == DType::UInt32);
    CHECK(u.grid.dims == std::array<std::int64_t, 3>{2, 1, 1});
    CHECK(values<std::uint32_t>(u) == std::vector<std::uint32_t>{7, 4000000000u});
}

TEST_CASE("MetaImage: every element type", "[io][metaimage]") {
    const std::pair<const char*, DType> types[] = {
        {"MET_UCHAR", DType::UInt8},  {"MET_CHAR", DType::Int8},        {"MET_USHORT", DType::UInt16},
        {"MET_SHORT", DType::Int16},  {"MET_UINT", DType::UInt32},      {"MET_INT", DType::Int32},
        {"MET_ULONG", DType::UInt32}, {"MET_LONG", DType::Int32},       {"MET_ULONG_LONG", DType::UInt64},
        {"MET_LONG_LONG", DType::Int64}, {"MET_FLOAT", DType::Float32}, {"MET_DOUBLE", DType::Float64}};
    for (const auto& [name, t] : types) {
        INFO(name);
        const Bytes b = "NDims = 3\nDimSize = 2 1 1\nElementType = " + std::string(name) +
                        "\nElementDataFile = LOCAL\n" + Bytes(2 * dtype_size(t), 9);
        CHECK(read_mem(read_metaimage, b, "t.mha").dtype == t);
    }
}

TEST_CASE("MetaImage: detached data, HeaderSize, compression, text", "[io][metaimage]") {
    TempDir dir;
    const Bytes data = raw_of<std::int16_t>({1, -2, 3, -4, 5, -6, 7, -8});
    SECTION("HeaderSize -1: data at the end of the data file") {
        write_file(dir / "v.raw", Bytes(100, 0xAB) + data);
        write_file(dir / "v.mhd", bytes("ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nHeaderSize = -1\n"
                                        "ElementSpacing = 1 1 1.5\nOffset = -1 -2 -3\nElementType = MET_SHORT\n"
                                        "ElementDataFile = v.raw\n"));
        const Volume v = read_volume(dir / "v.mhd");
        CHECK(values<std::int16_t>(v) == std::vector<std::int16_t>{1, -2, 3, -4, 5, -6, 7, -8});
        CHECK(v.grid.spacing == std::array<double, 3>{1, 1, 1.5});
        CHECK(v.grid.origin == std::array<double, 3>{-1, -2, -3});
    }
    SECTION("HeaderSize N") {
        write_file(dir / "v.raw", Bytes(100, 0xAB) + data + Bytes(5, 0));
        write_file(dir / "v.mhd", bytes("NDims = 3\nDimSize = 2 2 2\nHeaderSize = 100\nElementType = MET_SHORT\n"
                                        "ElementDataFile = v.raw\n"));
        CHECK(values<std::int16_t>(read_volume(dir / "v.mhd")) == std::vector<std::int16_t>{1, -2, 3, -4, 5, -6, 7, -8});
    }
    SECTION("compressed .zraw with an understated CompressedDataSize (as VTK's frog)") {
        const Bytes z = zlib(data);
        write_file(dir / "v.zraw", z);
        write_file(dir / "v.mhd", bytes("NDims = 3\nDimSize = 2 2 2\nCompressedData = True\nCompressedDataSize = " +
                                        std::to_string(z.size() - 3) + "\nElementType = MET_SHORT\nElementDataFile = v.zraw\n"));
        CHECK(values<std::int16_t>(read_volume(dir / "v.mhd")) == std::vector<std::int16_t>{1, -2, 3, -4, 5, -6, 7, -8});
    }
    SECTION("compressed LOCAL without CompressedDataSize, big endian") {
        const Bytes b = "NDims = 3\nDimSize = 2 2 2\nCompressedData = True\nBinaryDataByteOrderMSB = True\n"
                        "ElementType = MET_SHORT\nElementDataFile = LOCAL\n" +
                        zlib(raw_of<std::int16_t>({1, -2, 3, -4, 5, -6, 7, -8}, true));
        CHECK(values<std::int16_t>(read_mem(read_metaimage, b, "c.mha")) == std::vector<std::int16_t>{1, -2, 3, -4, 5, -6, 7, -8});
    }
    SECTION("text data (BinaryData = False), CRLF") {
        const Bytes b = bytes("NDims = 2\r\nDimSize = 2 2\r\nBinaryData = False\r\nElementType = MET_FLOAT\r\n"
                              "ElementDataFile = LOCAL\r\n0.5 1.5\r\n-2 4e1\r\n");
        CHECK(values<float>(read_mem(read_metaimage, b, "t.mha")) == std::vector<float>{0.5f, 1.5f, -2.f, 40.f});
    }
    SECTION("missing data file") {
        write_file(dir / "m.mhd", bytes("NDims = 3\nDimSize = 2 2 2\nElementType = MET_SHORT\nElementDataFile = nothere.raw\n"));
        expect_error<FileNotFound>([&] { read_volume(dir / "m.mhd"); }, {"m.mhd", "nothere.raw"});
    }
}

TEST_CASE("MetaImage: bad headers name the file and the problem", "[io][metaimage][errors]") {
    auto err = [&](const std::string& header, std::initializer_list<std::string> parts, const Bytes& data = Bytes(64, 0)) {
        expect_error([&] { read_mem(read_metaimage, bytes(header) + data, "bad.mha"); }, parts);
    };
    const std::string tail = "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n";
    err("", {"bad.mha", "empty file"}, {});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n", {"bad.mha", "no ElementDataFile"}, {});
    err("\x89PNG\r\n", {"bad.mha", "expected 'Key = Value'"});
    err("DimSize = 2 2 2\n" + tail, {"bad.mha", "missing field 'NDims'"});
    err("NDims = 3\n" + tail, {"bad.mha", "missing field 'DimSize'"});
    err("NDims = 3\nDimSize = 2 2 2\nElementDataFile = LOCAL\n", {"bad.mha", "missing field 'ElementType'"});
    err("ObjectType = Mesh\nNDims = 3\nDimSize = 2 2 2\n" + tail, {"bad.mha", "ObjectType = 'Mesh'"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_FLOAT_ARRAY\nElementDataFile = LOCAL\n", {"bad.mha", "MET_FLOAT_ARRAY", "not supported"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_GIBBERISH\nElementDataFile = LOCAL\n", {"bad.mha", "MET_GIBBERISH"});
    err("NDims = 3\nDimSize = 2 2 2\nElementNumberOfChannels = 3\n" + tail, {"bad.mha", "ElementNumberOfChannels", "multi-channel"});
    err("NDims = 4\nDimSize = 2 2 2 5\n" + tail, {"bad.mha", "4-D image", "not supported"});
    err("NDims = 3\nDimSize = 2 -2 2\n" + tail, {"bad.mha", "DimSize = '2 -2 2'", "positive"});
    err("NDims = 3\nDimSize = 2 0 2\n" + tail, {"bad.mha", "positive"});
    err("NDims = 3\nDimSize = 2 2\n" + tail, {"bad.mha", "must give 3 sizes"});
    err("NDims = 3\nDimSize = 1048576 1048576 1\n" + tail, {"bad.mha", "exceeds the limit"});
    err("NDims = x\nDimSize = 2 2 2\n" + tail, {"bad.mha", "NDims = 'x'"});
    err("NDims = 3\nDimSize = 2 2 2\nElementSpacing = 1 nan 1\n" + tail, {"bad.mha", "ElementSpacing", "finite"});
    err("NDims = 3\nDimSize = 2 2 2\nElementSpacing = 1 0 1\n" + tail, {"bad.mha", "ElementSpacing", "non-zero"});
    err("NDims = 3\nDimSize = 2 2 2\nOffset = 1 2\n" + tail, {"bad.mha", "Offset", "3 numbers"});
    err("NDims = 3\nDimSize = 2 2 2\nCompressedData = Maybe\n" + tail, {"bad.mha", "CompressedData", "True or False"});
    err("NDims = 3\nDimSize = 2 2 2\nHeaderSize = -5\n" + tail, {"bad.mha", "HeaderSize"});
    err("NDims = 3\nDimSize = 2 2 2\nCompressedData = True\nHeaderSize = -1\n" + tail, {"bad.mha", "HeaderSize", "-1"});
    err("NDims = 3\nDimSize = 2 2 2\nHeaderSize = 1000\n" + tail, {"bad.mha", "HeaderSize 1,000 runs past the end"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = LIST\n", {"bad.mha", "several files"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = s%03d.raw 1 2 1\n", {"bad.mha", "several files"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = \n", {"bad.mha", "ElementDataFile", "empty"});
    err("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = x.raw\n", {"bad.mha", "detached data files are not available"});
    err("NDims = 3\nDimSize = 10 10 10\n" + tail, {"bad.mha", "header says 10x10x10 uint8 = 1,000 bytes but the file holds 64"});
    err("NDims = 3\nDimSize = 10 10 10\nCompressedData = True\nCompressedDataSize = 5000\n" + tail,
        {"bad.mha", "CompressedDataSize 5,000 but the file holds 64"});
    err("NDims = 3\nDimSize = 10 10 10\nCompressedData = True\n" + tail, {"bad.mha", "truncated: 100 of 1,000 bytes"}, zlib(Bytes(100, 1)));
    err("NDims = 3\nDimSize = 10 10 10\nCompressedData = True\n" + tail, {"bad.mha", "more data than the header declares"},
        zlib(Bytes(1 << 20, 1)));
    err("NDims = 3\nDimSize = 100000 1000 1000\nCompressedData = True\n" + tail, {"bad.mha", "exceeds the limit"}, zlib(Bytes(100, 1)));
    {
        ReadOptions unlimited;
        unlimited.max_bytes = std::uint64_t(1) << 62;
        const Bytes b = "NDims = 3\nDimSize = 100000 1000 1000\nCompressedData = True\n" + tail + zlib(Bytes(100, 1));
        expect_error([&] { read_mem(read_metaimage, b, "bomb.mha", unlimited); }, {"bomb.mha", "can inflate to at most"});
    }
    err("NDims = 3\nDimSize = 2 2 2\nCompressedData = True\n" + tail, {"bad.mha", "corrupt compressed data"}, bytes("not zlib at all!"));
    err("NDims = 3\nDimSize = 2 1 1\nBinaryData = False\n" + tail, {"bad.mha", "'z' is not a valid uint8"}, bytes("1 z"));
}

// =================================================================================================================
// NIfTI-1
// =================================================================================================================

TEST_CASE("NIfTI: single file, both byte orders, every datatype", "[io][nifti]") {
    const std::pair<std::int16_t, DType> types[] = {
        {2, DType::UInt8},     {4, DType::Int16},     {8, DType::Int32},    {16, DType::Float32}, {64, DType::Float64},
        {256, DType::Int8},    {512, DType::UInt16},  {768, DType::UInt32}, {1024, DType::Int64}, {1280, DType::UInt64}};
    for (bool big : {false, true}) {
        for (const auto& [code, t] : types) {
            INFO(dtype_name(t) << (big ? " big" : " little"));
            Nifti n;
            n.big = big;
            n.datatype = code;
            n.bitpix = static_cast<std::int16_t>(8 * dtype_size(t));
            const Volume ref = random_volume(t, {2, 3, 4}, code);
            Bytes data = ref.data;
            if (big)
                for (std::size_t i = 0; i < data.size(); i += dtype_size(t))
                    std::reverse(data.begin() + static_cast<std::ptrdiff_t>(i),
                                 data.begin() + static_cast<std::ptrdiff_t>(i + dtype_size(t)));
            const Volume v = read_mem(read_nifti, n.header() + data, "v.nii");
            CHECK(v.dtype == t);
            CHECK(v.grid.dims == std::array<std::int64_t, 3>{2, 3, 4});
            CHECK(v.grid.spacing == std::array<double, 3>{1.5, 2, 2.5});
            CHECK(v.data == ref.data);
        }
    }
}

TEST_CASE("NIfTI: scl_slope/scl_inter", "[io][nifti]") {
    Nifti n;
    n.dim[1] = 4;
    n.dim[2] = 1;
    n.dim[3] = 1;
    n.datatype = 4;
    n.bitpix = 16;
    const Bytes data = raw_of<std::int16_t>({-1000, 0, 1, 3000});
    SECTION("applied: float32 result") {
        n.slope = 0.5f;
        n.inter = -10;
        const Volume v = read_mem(read_nifti, n.header() + data, "s.nii");
        CHECK(v.dtype == DType::Float32);
        CHECK(values<float>(v) == std::vector<float>{-510.f, -10.f, -9.5f, 1490.f});
    }
    SECTION("applied, big endian") {
        n.big = true;
        n.slope = 2;
        n.inter = 1;
        const Volume v = read_mem(read_nifti, n.header() + raw_of<std::int16_t>({-1000, 0, 1, 3000}, true), "s.nii");
        CHECK(values<float>(v) == std::vector<float>{-1999.f, 1.f, 3.f, 6001.f});
    }
    SECTION("slope 0 or (1, 0): untouched") {
        n.slope = 0;
        n.inter = 5;
        CHECK(read_mem(read_nifti, n.header() + data, "s.nii").dtype == DType::Int16);
        n.slope = 1;
        n.inter = 0;
        CHECK(values<std::int16_t>(read_mem(read_nifti, n.header() + data, "s.nii")) ==
              std::vector<std::int16_t>{-1000, 0, 1, 3000});
    }
    SECTION("float64 data stays float64; huge results saturate to inf in float32") {
        n.datatype = 64;
        n.bitpix = 64;
        n.slope = 3;
        const Volume v = read_mem(read_nifti, n.header() + raw_of<double>({1, 2, 1e300, -1}), "d.nii");
        CHECK(v.dtype == DType::Float64);
        CHECK(values<double>(v) == std::vector<double>{3, 6, 3e300, -3});
        n.datatype = 1280;
        n.slope = 3e38f;
        const Volume w = read_mem(read_nifti, n.header() + raw_of<std::uint64_t>({0, 1, 2, ~0ull}), "u.nii");
        CHECK(w.dtype == DType::Float32);
        CHECK(values<float>(w)[3] == std::numeric_limits<float>::infinity());
    }
    SECTION("NaN or infinite slope is refused") {
        n.slope = std::numeric_limits<float>::quiet_NaN();
        expect_error([&] { read_mem(read_nifti, n.header() + data, "nan.nii"); }, {"nan.nii", "scl_slope", "nan"});
        n.slope = std::numeric_limits<float>::infinity();
        expect_error([&] { read_mem(read_nifti, n.header() + data, "inf.nii"); }, {"inf.nii", "scl_slope", "inf"});
        n.slope = 2;
        n.inter = std::numeric_limits<float>::infinity();
        expect_error([&] { read_mem(read_nifti, n.header() + data, "inf.nii"); }, {"inf.nii", "scl_inter"});
    }
}

TEST_CASE("NIfTI: origin from sform or qform, extensions, 4-D with one volume", "[io][nifti]") {
    Nifti n;
    n.qoffset[0] = 1;
    n.qoffset[1] = 2;
    n.qoffset[2] = 3;
    n.srow[0][3] = -10;
    n.srow[1][3] = -20;
    n.srow[2][3] = -30;
    const Bytes data(24, 5);
    // no qform/sform code: NIfTI's "method 1", the qoffsets as given, no rotation
    CHECK(read_mem(read_nifti, n.header() + data, "0.nii").grid.origin == std::array<double, 3>{1, 2, 3});
    // NIfTI's RAS becomes LPS: x and y negated (tests/native/test_io_orientation.cpp tests rotations)
    n.qform = 1;
    const Grid q = read_mem(read_nifti, n.header() + data, "q.nii").grid;
    CHECK(q.origin == std::array<double, 3>{-1, -2, 3});
    CHECK(q.direction == Matrix3{-1, 0, 0, 0, -1, 0, 0, 0, 1});
    n.sform = 2;
    const Grid sf = read_mem(read_nifti, n.header() + data, "s.nii").grid;
    CHECK(sf.origin == std::array<double, 3>{10, 20, -30});
    CHECK(sf.direction == Matrix3{-1, 0, 0, 0, -1, 0, 0, 0, 1});
    n.vox_offset = 496;  // header extensions before the data
    n.pixdim[1] = -1.5f;  // negative pixdim: spacing is |pixdim|
    n.dim[0] = 5;
    const Volume v = read_mem(read_nifti, n.header() + data, "e.nii");
    CHECK(v.data == data);
    CHECK(v.grid.spacing[0] == 1.5);
    n.dim[0] = 2;  // 2-D: pixdim[3] is ignored even when 0
    n.dim[3] = 7;
    n.pixdim[3] = 0;
    CHECK(read_mem(read_nifti, n.header() + Bytes(6, 5), "2d.nii").grid.dims == std::array<std::int64_t, 3>{2, 3, 1});
}

TEST_CASE("NIfTI: .hdr/.img pair and .nii.gz", "[io][nifti]") {
    TempDir dir;
    Nifti n;
    n.magic = "ni1";
    n.vox_offset = 0;
    n.datatype = 512;
    n.bitpix = 16;
    const Volume ref = random_volume(DType::UInt16, {2, 3, 4}, 5);
    write_file(dir / "pair.hdr", n.header(false));
    write_file(dir / "pair.img", ref.data);
    CHECK(read_volume(dir / "pair.hdr").data == ref.data);
    write_file(dir / "UP.HDR", n.header(false));
    write_file(dir / "UP.IMG", ref.data);
    CHECK(read_volume(dir / "UP.HDR").data == ref.data);
    write_file(dir / "lonely.hdr", n.header(false));
    expect_error<FileNotFound>([&] { read_volume(dir / "lonely.hdr"); }, {"lonely.hdr", "lonely.img"});
    expect_error([&] { read_mem(read_nifti, n.header(false), "mem.hdr"); }, {"mem.hdr", "detached data files are not available"});
    write_file(dir / "short.hdr", n.header(false));
    write_file(dir / "short.img", Bytes(10, 0));
    expect_error([&] { read_volume(dir / "short.hdr"); }, {"short.hdr", "2x3x4 uint16 = 48 bytes but data file", "short.img holds 10"});

    Nifti s;
    s.datatype = 512;
    s.bitpix = 16;
    s.big = true;
    Bytes be = ref.data;
    for (std::size_t i = 0; i < be.size(); i += 2) std::swap(be[i], be[i + 1]);
    write_file(dir / "v.nii.gz", gzip(s.header() + be));
    const Volume v = read_volume(dir / "v.nii.gz");
    CHECK(v.data == ref.data);
    CHECK(v.grid.spacing == std::array<double, 3>{1.5, 2, 2.5});
    // a .nii that is gzip-compressed anyway is recognised by its bytes
    write_file(dir / "actually_gz.nii", gzip(s.header() + be));
    CHECK(read_volume(dir / "actually_gz.nii").data == ref.data);
}

TEST_CASE("NIfTI: bad headers name the file and the problem", "[io][nifti][errors]") {
    auto err = [&](const Nifti& n, std::initializer_list<std::string> parts, const Bytes& data = Bytes(24, 0)) {
        expect_error([&] { read_mem(read_nifti, n.header() + data, "bad.nii"); }, parts);
    };
    expect_error([&] { read_mem(read_nifti, Bytes(100, 0), "tiny.nii"); }, {"tiny.nii", "holds 100 bytes, less than the 348-byte"});
    expect_error([&] { read_mem(read_nifti, Bytes{}, "empty.nii"); }, {"empty.nii", "holds 0 bytes"});
    {
        Nifti n;
        n.sizeof_hdr = 540;
        err(n, {"bad.nii", "NIfTI-2", "not supported"});
        n.big = true;
        err(n, {"bad.nii", "NIfTI-2"});
        n.sizeof_hdr = 12345;
        err(n, {"bad.nii", "not a NIfTI-1 file", "sizeof_hdr"});
    }
    {
        Nifti n;
        n.magic = "abc";
        err(n, {"bad.nii", "Analyze 7.5"});
    }
    {
        Nifti n;
        n.dim[0] = 4;
        n.dim[4] = 5;
        err(n, {"bad.nii", "4-D NIfTI (5 volumes) not supported"});
        n.dim[0] = 8;
        err(n, {"bad.nii", "dim[0] = 8"});
        n.dim[0] = 3;
        n.dim[2] = -3;
        err(n, {"bad.nii", "dim[2] = -3 must be positive"});
        n.dim[2] = 0;
        err(n, {"bad.nii", "dim[2] = 0"});
        n.dim[1] = n.dim[2] = n.dim[3] = 32767;
        err(n, {"bad.nii", "exceeds the limit"});
    }
    {
        Nifti n;
        n.datatype = 32;
        n.bitpix = 64;
        err(n, {"bad.nii", "complex64", "not supported"});
        n.datatype = 128;
        n.bitpix = 24;
        err(n, {"bad.nii", "RGB24"});
        n.datatype = 2304;
        n.bitpix = 32;
        err(n, {"bad.nii", "RGBA32"});
        n.datatype = 3;
        err(n, {"bad.nii", "unknown datatype 3"});
        n.datatype = 16;
        n.bitpix = 8;
        err(n, {"bad.nii", "bitpix 8 disagrees with datatype 16 (float32, 32 bits)"});
    }
    {
        Nifti n;
        n.pixdim[2] = 0;
        err(n, {"bad.nii", "pixdim[2] = 0"});
        n.pixdim[2] = std::numeric_limits<float>::quiet_NaN();
        err(n, {"bad.nii", "pixdim[2] = nan"});
    }
    {
        Nifti n;
        n.sform = 1;
        n.srow[1][3] = std::numeric_limits<float>::infinity();
        err(n, {"bad.nii", "srow_y", "finite"});
    }
    {
        Nifti n;
        n.vox_offset = 100;
        err(n, {"bad.nii", "vox_offset 100", "at least 352"});
        n.vox_offset = std::numeric_limits<float>::quiet_NaN();
        err(n, {"bad.nii", "vox_offset nan"});
        n.vox_offset = -1;
        err(n, {"bad.nii", "vox_offset -1"});
        n.vox_offset = 3e38f;
        err(n, {"bad.nii", "vox_offset"});
        n.vox_offset = 1e9f;
        err(n, {"bad.nii", "header says 2x3x4 uint8 = 24 bytes but the file holds 0", "past its end"});
    }
    {
        Nifti n;
        err(n, {"bad.nii", "header says 2x3x4 uint8 = 24 bytes but the file holds 20"}, Bytes(20, 0));
        const Bytes garbage = random_volume(DType::UInt8, {400, 1, 1}).data;
        expect_error([&] { read_mem(read_nifti, garbage, "garbage.nii"); }, {"garbage.nii", "not a NIfTI-1 file"});
    }
}

TEST_CASE("NIfTI: broken .nii.gz", "[io][nifti][errors][gzip]") {
    Nifti n;
    const Bytes full = n.header() + Bytes(24, 7);
    auto err = [&](const Bytes& file, std::initializer_list<std::string> parts, ReadOptions opt = {}) {
        expect_error([&] { read_mem(read_nifti, file, "bad.nii.gz", opt); }, parts);
    };
    CHECK(read_mem(read_nifti, gzip(full), "ok.nii.gz").data == Bytes(24, 7));
    err(gzip(Bytes(full.begin(), full.begin() + 200)), {"bad.nii.gz", "truncated: 200 of 348 bytes"});
    err(gzip(Bytes(full.begin(), full.end() - 4)), {"bad.nii.gz", "truncated: 372 of 376 bytes"});
    err(gzip(full + Bytes(1 << 20, 0)), {"bad.nii.gz", "more data than the header declares"});
    Bytes cut = gzip(full);
    cut.resize(cut.size() - 10);
    err(cut, {"bad.nii.gz", "truncated"});
    Bytes corrupt = gzip(full);
    corrupt[corrupt.size() / 2] ^= 0xff;
    corrupt[corrupt.size() / 2 + 1] ^= 0xff;
    CHECK_THROWS_AS(read_mem(read_nifti, corrupt, "c.nii.gz"), FileFormatError);
    Nifti big;
    big.dim[1] = big.dim[2] = big.dim[3] = 32767;
    big.datatype = 64;
    big.bitpix = 64;
    ReadOptions unlimited;
    unlimited.max_bytes = std::uint64_t(1) << 62;
    err(gzip(big.header()), {"bad.nii.gz", "can inflate to at most"}, unlimited);
}

// =================================================================================================================
// Fuzz seed corpus: every seed must parse or fail with a volrig error (regression for fuzzer findings)
// =================================================================================================================

TEST_CASE("Fuzz corpus files never crash the readers", "[io][fuzz]") {
    const fs::path corpus = VOLRIG_FUZZ_CORPUS;
    if (!fs::is_directory(corpus)) {
        WARN("no fuzz corpus at " << corpus << ": skipped");
        return;
    }
    ReadOptions opt;
    opt.max_bytes = 64 << 20;
    int files = 0;
    for (const char* sub : {"nrrd", "metaimage", "nifti"}) {
        if (!fs::is_directory(corpus / sub)) continue;
        for (const auto& e : fs::directory_iterator(corpus / sub)) {
            const Bytes b = read_file(e.path());
            INFO(e.path());
            for (auto reader : {read_nrrd, read_metaimage, read_nifti}) {
                try {
                    read_mem(reader, b, e.path().filename().string(), opt);
                } catch (const Error&) {
                }
            }
            ++files;
        }
    }
    CHECK(files > 0);
}

// =================================================================================================================
// Real scans in ../shared/data
// =================================================================================================================

namespace {

struct Stats {
    double min = 0, max = 0, sum = 0;
    std::size_t distinct = 0;
};

template <class T>
Stats stats_of(const Volume& v) {
    const auto vals = values<T>(v);
    Stats s;
    s.min = static_cast<double>(*std::min_element(vals.begin(), vals.end()));
    s.max = static_cast<double>(*std::max_element(vals.begin(), vals.end()));
    long double sum = 0;
    for (T x : vals) sum += x;
    s.sum = static_cast<double>(sum);
    s.distinct = std::set<T>(vals.begin(), vals.end()).size();
    return s;
}

bool skip_without_data() {
    if (have_shared_data()) return false;
    WARN("shared test data not found at " << shared_data() << ": real-file tests skipped");
    return true;
}

template <class T>
T at(const Volume& v, std::int64_t x, std::int64_t y, std::int64_t z) {
    T out;
    std::memcpy(&out, v.data.data() + v.grid.index(x, y, z) * static_cast<std::int64_t>(sizeof(T)), sizeof(T));
    return out;
}

}  // namespace

TEST_CASE("Real: frogtissue.mhd (zlib .zraw)", "[io][real]") {
    if (skip_without_data()) return;
    const Volume v = read_volume(shared_data() + "/frogtissue/frogtissue.mhd");
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{500, 470, 136});
    CHECK(v.dtype == DType::UInt8);
    CHECK(v.grid.spacing == std::array<double, 3>{1, 1, 1.5});
    const Stats s = stats_of<std::uint8_t>(v);
    CHECK(s.min == 0);
    CHECK(s.max == 29);
    CHECK(s.distinct == 26);  // background + 25 tissues
    CHECK(s.sum == 12279472);
    CHECK(at<std::uint8_t>(v, 250, 235, 68) == 6);
}

TEST_CASE("Real: HeadMRVolume.mhd (raw)", "[io][real]") {
    if (skip_without_data()) return;
    const Volume v = read_volume(shared_data() + "/headmr/HeadMRVolume.mhd");
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{48, 62, 42});
    CHECK(v.dtype == DType::UInt8);
    CHECK(v.grid.spacing == std::array<double, 3>{4, 4, 4});
    const Stats s = stats_of<std::uint8_t>(v);
    CHECK(s.sum == 3058332);
    CHECK(s.max == 255);
    CHECK(at<std::uint8_t>(v, 24, 31, 21) == 79);
}

TEST_CASE("Real: tooth.nrrd (raw, attached)", "[io][real]") {
    if (skip_without_data()) return;
    const Volume v = read_volume(shared_data() + "/tooth/tooth.nrrd");
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{103, 94, 161});
    CHECK(v.dtype == DType::UInt8);
    CHECK(v.grid.spacing == std::array<double, 3>{1, 1, 1});
    const Stats s = stats_of<std::uint8_t>(v);
    CHECK(s.sum == 160814065);
    CHECK(s.distinct == 256);
    CHECK(at<std::uint8_t>(v, 51, 47, 80) == 154);
}

TEST_CASE("Real: LIDC2.mha (zlib, LOCAL)", "[io][real]") {
    if (skip_without_data()) return;
    const Volume v = read_volume(shared_data() + "/lidc2/LIDC2.mha");
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{256, 256, 133});
    CHECK(v.dtype == DType::UInt8);
    CHECK(v.grid.spacing[0] == Approx(1.40625));
    CHECK(v.grid.spacing[1] == Approx(1.40625));
    CHECK(v.grid.spacing[2] == Approx(2.5));
    CHECK(v.grid.origin[1] == Approx(360));
    CHECK(v.grid.origin[2] == Approx(332.5));
    const Stats s = stats_of<std::uint8_t>(v);
    CHECK(s.sum == 61489178);
    CHECK(at<std::uint8_t>(v, 128, 128, 66) == 128);
}

TEST_CASE("Real: TotalSegmentator NIfTI (.nii.gz)", "[io][real]") {
    if (skip_without_data()) return;
    // sform diag(3, 3, 3) in RAS: in LPS the origin's x and y change sign and the direction is diag(-1, -1, 1)
    const std::array<double, 3> origin{177.95632934570312, -11.319000244140625, 94.3017578125};
    {
        const Volume v = read_volume(shared_data() + "/totalseg/example_ct.nii.gz");
        CHECK(v.grid.dims == std::array<std::int64_t, 3>{122, 101, 112});
        CHECK(v.dtype == DType::Int32);
        CHECK(v.grid.spacing == std::array<double, 3>{3, 3, 3});
        CHECK(v.grid.origin == origin);
        CHECK(v.grid.direction == Matrix3{-1, 0, 0, 0, -1, 0, 0, 0, 1});
        const Stats s = stats_of<std::int32_t>(v);
        CHECK(s.min == -1207);
        CHECK(s.max == 3382);
        CHECK(s.sum == -496851173);
        CHECK(at<std::int32_t>(v, 61, 50, 56) == 164);
    }
    {
        const Volume v = read_volume(shared_data() + "/totalseg/example_ct_sm.nii.gz");
        CHECK(v.grid.dims == std::array<std::int64_t, 3>{122, 101, 30});
        CHECK(v.dtype == DType::Int16);
        const Stats s = stats_of<std::int16_t>(v);
        CHECK(s.min == -1100);
        CHECK(s.max == 1207);
        CHECK(s.sum == -130894872);
    }
    {
        const Volume v = read_volume(shared_data() + "/totalseg/example_seg.nii.gz");  // vox_offset 13168 (extensions)
        CHECK(v.grid.dims == std::array<std::int64_t, 3>{122, 101, 30});
        CHECK(v.dtype == DType::UInt8);
        const Stats s = stats_of<std::uint8_t>(v);
        CHECK(s.min == 0);
        CHECK(s.max == 117);
        CHECK(s.distinct == 42);
        CHECK(s.sum == 2734697);
    }
}

TEST_CASE("Real: airway bronchial tree (.nii.gz, 168 MB decoded)", "[io][real]") {
    if (skip_without_data()) return;
    const Volume v = read_volume(shared_data() + "/airway/Patient1_bronchialTree.nii.gz");
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{497, 331, 512});
    CHECK(v.dtype == DType::Int16);
    CHECK(v.grid.spacing[0] == Approx(0.55078125));
    CHECK(v.grid.spacing[2] == Approx(0.7000195980072021));
    CHECK(v.grid.origin[0] == Approx(143.53399658203125));  // qform (sform_code 0), identity in RAS: x negated
    CHECK(v.grid.origin[2] == Approx(1033.239990234375));
    const Stats s = stats_of<std::int16_t>(v);
    CHECK(s.min == 0);
    CHECK(s.max == 1);
    CHECK(s.sum == 207263);
}

TEST_CASE("Real: files round-trip through the writers", "[io][real]") {
    if (skip_without_data()) return;
    TempDir dir;
    const Volume v = read_volume(shared_data() + "/headmr/HeadMRVolume.mhd");
    write_nrrd(dir / "h.nrrd", v.view(), true);
    write_metaimage(dir / "h.mha", v.view(), true);
    check_same(read_volume(dir / "h.nrrd"), v);
    check_same(read_volume(dir / "h.mha"), v);
    // Truncating a real compressed file gives a clear error, never a crash.
    Bytes lidc = read_file(shared_data() + "/lidc2/LIDC2.mha");
    lidc.resize(lidc.size() / 2);
    write_file(dir / "half.mha", lidc);
    expect_error([&] { read_volume(dir / "half.mha"); }, {"half.mha", "CompressedDataSize"});
    Bytes ct = read_file(shared_data() + "/totalseg/example_ct_sm.nii.gz");
    ct.resize(ct.size() / 2);
    write_file(dir / "half.nii.gz", ct);
    expect_error([&] { read_volume(dir / "half.nii.gz"); }, {"half.nii.gz", "truncated"});
}

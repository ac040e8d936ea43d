// Tests for the OpenVDB reader/writer (volrig/io.hpp, "OpenVDB").
#include <catch2/catch.hpp>

#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <unistd.h>

#include "volrig/io.hpp"

namespace fs = std::filesystem;
using namespace volrig;

namespace {

/// A fresh empty folder under the system temp folder, removed at scope exit.
struct TempDir {
    fs::path dir;
    TempDir() {
        static std::atomic<int> counter{0};
        dir = fs::temp_directory_path() /
              ("volrig_test_vdb_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
        fs::remove_all(dir);
        fs::create_directories(dir);
    }
    ~TempDir() {
        std::error_code ec;
        fs::remove_all(dir, ec);
    }
    std::string operator/(const std::string& name) const { return (dir / name).string(); }
};

template <class T>
Volume make_volume(std::array<std::int64_t, 3> dims, std::array<double, 3> spacing, std::array<double, 3> origin,
                   DType dtype) {
    Volume v;
    v.grid.dims = dims;
    v.grid.spacing = spacing;
    v.grid.origin = origin;
    v.dtype = dtype;
    v.data.assign(static_cast<std::size_t>(v.grid.voxel_count()) * sizeof(T), 0);
    return v;
}

template <class T>
T* values(Volume& v) { return reinterpret_cast<T*>(v.data.data()); }
template <class T>
const T* values(const Volume& v) { return reinterpret_cast<const T*>(v.data.data()); }

/// A float volume with a deterministic pattern; about a third of the voxels are zero, the corners are not.
Volume pattern_volume(std::array<std::int64_t, 3> dims = {21, 13, 10}) {
    Volume v = make_volume<float>(dims, {0.5, 1.25, 2.0}, {-3.0, 4.0, 10.5}, DType::Float32);
    float* p = values<float>(v);
    const Grid& g = v.grid;
    for (std::int64_t z = 0; z < g.dims[2]; ++z)
        for (std::int64_t y = 0; y < g.dims[1]; ++y)
            for (std::int64_t x = 0; x < g.dims[0]; ++x) {
                const std::int64_t i = g.index(x, y, z);
                p[i] = (x + 2 * y + 3 * z) % 3 == 0 ? 0.0f
                                                   : 0.25f * static_cast<float>(x) - 1.5f * y + 0.75f * z + 0.1f;
            }
    p[g.index(0, 0, 0)] = 7.0f;
    p[g.index(g.dims[0] - 1, g.dims[1] - 1, g.dims[2] - 1)] = -2.0f;
    return v;
}

std::int64_t nonzero_count(const Volume& v) {
    std::int64_t n = 0;
    const float* p = values<float>(v);
    for (std::int64_t i = 0; i < v.grid.voxel_count(); ++i) n += p[i] != 0.0f;
    return n;
}

void require_same_geometry(const Grid& a, const Grid& b) {
    for (int k = 0; k < 3; ++k) {
        REQUIRE(a.dims[k] == b.dims[k]);
        REQUIRE(a.spacing[k] == Approx(b.spacing[k]).epsilon(1e-12));
        REQUIRE(a.origin[k] == Approx(b.origin[k]).epsilon(1e-12).margin(1e-12));
    }
}

std::string message_of(const std::function<void()>& f) {
    try {
        f();
    } catch (const std::exception& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST_CASE("write_vdb then read_vdb round-trips values, spacing, origin and the active count", "[vdb]") {
    TempDir tmp;
    const std::string path = tmp / "pattern.vdb";
    const Volume v = pattern_volume();
    write_vdb(path, {{"density", v.view()}});
    REQUIRE(fs::exists(path));

    const Volume r = read_vdb(path);
    REQUIRE(r.dtype == DType::Float32);
    require_same_geometry(r.grid, v.grid);
    REQUIRE(r.data == v.data);

    const auto grids = vdb_grids(path);
    REQUIRE(grids.size() == 1);
    CHECK(grids[0].name == "density");
    CHECK(grids[0].type == "float");
    CHECK(grids[0].active_voxels == nonzero_count(v));
    CHECK(grids[0].bbox_min == std::array<std::int64_t, 3>{0, 0, 0});
    CHECK(grids[0].bbox_max == std::array<std::int64_t, 3>{20, 12, 9});
}

TEST_CASE("read_vdb crops to the active bounding box and moves the origin with it", "[vdb]") {
    TempDir tmp;
    const std::string path = tmp / "crop.vdb";
    Volume v = make_volume<float>({30, 20, 12}, {0.5, 2.0, 1.5}, {10.0, -4.0, 1.0}, DType::Float32);
    float* p = values<float>(v);
    for (std::int64_t z = 3; z <= 7; ++z)
        for (std::int64_t y = 5; y <= 6; ++y)
            for (std::int64_t x = 11; x <= 25; ++x) p[v.grid.index(x, y, z)] = static_cast<float>(x + 100 * y + z);
    write_vdb(path, {{"density", v.view()}});

    const Volume r = read_vdb(path, "density");
    CHECK(r.grid.dims == std::array<std::int64_t, 3>{15, 2, 5});
    CHECK(r.grid.origin[0] == Approx(10.0 + 0.5 * 11));
    CHECK(r.grid.origin[1] == Approx(-4.0 + 2.0 * 5));
    CHECK(r.grid.origin[2] == Approx(1.0 + 1.5 * 3));
    for (std::int64_t z = 0; z < 5; ++z)
        for (std::int64_t y = 0; y < 2; ++y)
            for (std::int64_t x = 0; x < 15; ++x)
                REQUIRE(values<float>(r)[r.grid.index(x, y, z)] == p[v.grid.index(x + 11, y + 5, z + 3)]);
}

TEST_CASE("constant 8^3 blocks (stored as tiles) and large grids round-trip", "[vdb]") {
    TempDir tmp;
    const std::string path = tmp / "blocks.vdb";
    Volume v = make_volume<float>({67, 41, 35}, {1, 1, 1}, {0, 0, 0}, DType::Float32);
    float* p = values<float>(v);
    for (std::int64_t z = 0; z < 35; ++z)
        for (std::int64_t y = 0; y < 41; ++y)
            for (std::int64_t x = 0; x < 67; ++x) {
                const double d = std::hypot(x - 33.0, y - 20.0, z - 17.0);
                p[v.grid.index(x, y, z)] = d < 16 ? 3.0f : (d < 19 ? static_cast<float>(19 - d) : 0.0f);
            }
    p[0] = 1.0f;  // pin the bounding box to the whole grid
    p[v.grid.voxel_count() - 1] = 1.0f;
    write_vdb(path, {{"density", v.view()}});
    const Volume r = read_vdb(path);
    require_same_geometry(r.grid, v.grid);
    REQUIRE(r.data == v.data);
    CHECK(vdb_grids(path)[0].active_voxels == nonzero_count(v));
}

TEST_CASE("half floats round-trip within half precision", "[vdb]") {
    TempDir tmp;
    const std::string full = tmp / "full.vdb", halved = tmp / "half.vdb";
    const Volume v = pattern_volume({40, 30, 20});
    write_vdb(full, {{"density", v.view()}}, false);
    write_vdb(halved, {{"density", v.view()}}, true);
    CHECK(fs::file_size(halved) < fs::file_size(full));
    const Volume r = read_vdb(halved);
    require_same_geometry(r.grid, v.grid);
    const float* a = values<float>(v);
    const float* b = values<float>(r);
    for (std::int64_t i = 0; i < v.grid.voxel_count(); ++i)
        REQUIRE(b[i] == Approx(a[i]).epsilon(1.0 / 1024).margin(1e-6));
}

TEST_CASE("mixed float and integer grids; integer types become int32, uint8 becomes float", "[vdb]") {
    TempDir tmp;
    const std::string path = tmp / "mixed.vdb";
    const Volume density = pattern_volume();
    Volume bone = make_volume<std::int16_t>(density.grid.dims, density.grid.spacing, density.grid.origin, DType::Int16);
    Volume mask = make_volume<std::uint8_t>(density.grid.dims, density.grid.spacing, density.grid.origin, DType::UInt8);
    for (std::int64_t i = 0; i < bone.grid.voxel_count(); ++i) {
        values<std::int16_t>(bone)[i] = static_cast<std::int16_t>(i % 7 == 0 ? 0 : (i % 5) - 2 + (i % 3) * 1000);
        values<std::uint8_t>(mask)[i] = static_cast<std::uint8_t>(values<float>(density)[i] > 0 ? 1 : 0);
    }
    write_vdb(path, {{"density", density.view()}, {"bone", bone.view()}, {"mask", mask.view()}});

    const auto grids = vdb_grids(path);
    REQUIRE(grids.size() == 3);
    std::map<std::string, std::string> types;
    for (const auto& g : grids) types[g.name] = g.type;
    CHECK(types["density"] == "float");
    CHECK(types["bone"] == "int32");
    CHECK(types["mask"] == "float");

    const Volume rd = read_vdb(path, "density");
    CHECK(rd.data == density.data);
    const Volume rb = read_vdb(path, "bone");
    REQUIRE(rb.dtype == DType::Int32);
    // The bone grid's bbox may be smaller than the density's: compare through world positions.
    std::array<std::int64_t, 3> shift{};
    for (int a = 0; a < 3; ++a)
        shift[a] = std::lround((rb.grid.origin[a] - bone.grid.origin[a]) / bone.grid.spacing[a]);
    for (std::int64_t z = 0; z < rb.grid.dims[2]; ++z)
        for (std::int64_t y = 0; y < rb.grid.dims[1]; ++y)
            for (std::int64_t x = 0; x < rb.grid.dims[0]; ++x)
                REQUIRE(values<std::int32_t>(rb)[rb.grid.index(x, y, z)] ==
                        values<std::int16_t>(bone)[bone.grid.index(x + shift[0], y + shift[1], z + shift[2])]);
    const Volume rm = read_vdb(path, "mask");
    REQUIRE(rm.dtype == DType::Float32);
    for (std::int64_t i = 0; i < rm.grid.voxel_count(); ++i) {
        const float m = values<float>(rm)[i];
        REQUIRE((m == 0.0f || m == 1.0f));
    }
}

TEST_CASE("integers outside int32 are refused", "[vdb]") {
    TempDir tmp;
    const std::string path = tmp / "big.vdb";
    Volume v = make_volume<std::uint32_t>({4, 3, 2}, {1, 1, 1}, {0, 0, 0}, DType::UInt32);
    values<std::uint32_t>(v)[v.grid.index(1, 2, 1)] = 3000000000u;
    const std::string msg = message_of([&] { write_vdb(path, {{"labels", v.view()}}); });
    CHECK_THAT(msg, Catch::Contains("3000000000") && Catch::Contains("(1, 2, 1)") && Catch::Contains("int32"));
    CHECK_FALSE(fs::exists(path));

    Volume w = make_volume<std::int64_t>({4, 3, 2}, {1, 1, 1}, {0, 0, 0}, DType::Int64);
    values<std::int64_t>(w)[3] = -2147483648LL;  // fits
    values<std::int64_t>(w)[5] = 2147483647LL;   // fits
    write_vdb(path, {{"labels", w.view()}});
    const Volume r = read_vdb(path, "labels");
    CHECK(vdb_grids(path)[0].active_voxels == 2);
    values<std::int64_t>(w)[7] = -2147483649LL;
    CHECK_THROWS_AS(write_vdb(path, {{"labels", w.view()}}), Error);
}

TEST_CASE("grid selection: default density, else the first scalar grid; missing grids are named", "[vdb]") {
    TempDir tmp;
    const Volume v = pattern_volume();
    Volume bone = make_volume<std::int32_t>(v.grid.dims, v.grid.spacing, v.grid.origin, DType::Int32);
    values<std::int32_t>(bone)[5] = 3;

    const std::string two = tmp / "two.vdb";
    write_vdb(two, {{"bone", bone.view()}, {"density", v.view()}});
    CHECK(read_vdb(two).dtype == DType::Float32);  // density, though bone comes first
    CHECK(read_vdb(two, "bone").dtype == DType::Int32);

    const std::string only_bone = tmp / "bone.vdb";
    write_vdb(only_bone, {{"bone", bone.view()}});
    const Volume r = read_vdb(only_bone);
    CHECK(r.dtype == DType::Int32);
    CHECK(r.grid.dims == std::array<std::int64_t, 3>{1, 1, 1});
    CHECK(values<std::int32_t>(r)[0] == 3);

    const std::string msg = message_of([&] { read_vdb(two, "temperature"); });
    CHECK_THROWS_AS(read_vdb(two, "temperature"), FileFormatError);
    CHECK_THAT(msg, Catch::StartsWith(two) && Catch::Contains("temperature") && Catch::Contains("'bone'") &&
                        Catch::Contains("'density'"));
}

TEST_CASE("unreadable files raise FileFormatError or FileNotFound naming the file", "[vdb]") {
    TempDir tmp;
    const std::string missing = tmp / "missing.vdb";
    CHECK_THROWS_AS(read_vdb(missing), FileNotFound);
    CHECK_THROWS_AS(vdb_grids(missing), FileNotFound);

    const std::string garbage = tmp / "garbage.vdb";
    {
        std::ofstream f(garbage, std::ios::binary);
        for (int i = 0; i < 4096; ++i) f.put(static_cast<char>((i * 7919) & 0xff));
    }
    CHECK_THROWS_AS(read_vdb(garbage), FileFormatError);
    CHECK_THROWS_AS(vdb_grids(garbage), FileFormatError);
    CHECK_THAT(message_of([&] { read_vdb(garbage); }), Catch::StartsWith(garbage));

    const std::string empty = tmp / "empty.vdb";
    std::ofstream(empty, std::ios::binary).close();
    CHECK_THROWS_AS(read_vdb(empty), FileFormatError);

    // Truncations at many points of a valid file: always an error naming the file, never a crash or a result.
    const std::string good = tmp / "good.vdb";
    const Volume v = pattern_volume({40, 33, 27});
    write_vdb(good, {{"density", v.view()}});
    std::vector<char> bytes(fs::file_size(good));
    std::ifstream(good, std::ios::binary).read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    const std::string cut = tmp / "cut.vdb";
    for (std::size_t n : {std::size_t{3}, std::size_t{8}, std::size_t{20}, std::size_t{100}, std::size_t{300},
                          bytes.size() / 4, bytes.size() / 2, bytes.size() * 3 / 4, bytes.size() - 50,
                          bytes.size() - 1}) {
        {
            std::ofstream f(cut, std::ios::binary | std::ios::trunc);
            f.write(bytes.data(), static_cast<std::streamsize>(n));
        }
        INFO("truncated to " << n << " of " << bytes.size() << " bytes");
        const std::string msg = message_of([&] { read_vdb(cut, "density"); });
        CHECK_THAT(msg, Catch::StartsWith(cut));
        CHECK_THROWS_AS(read_vdb(cut, "density"), FileFormatError);
    }
}

TEST_CASE("write_vdb writes grids of different boxes on one lattice, each where it lies", "[vdb]") {
    TempDir tmp;
    const std::string path = tmp / "boxes.vdb";
    const Volume a = pattern_volume({10, 8, 6});
    Volume b = pattern_volume({4, 5, 3});
    for (int k = 0; k < 3; ++k) b.grid.origin[k] = a.grid.origin[k] + (k + 3) * a.grid.spacing[k];
    write_vdb(path, {{"density", a.view()}, {"part", b.view()}});
    const Volume r = read_vdb(path, "part");
    require_same_geometry(r.grid, b.grid);
    CHECK(r.data == b.data);
    require_same_geometry(read_vdb(path, "density").grid, a.grid);
}

TEST_CASE("write_vdb refuses grids off one lattice, duplicate or empty names and no grids", "[vdb]") {
    TempDir tmp;
    const std::string path = tmp / "bad.vdb";
    const Volume a = pattern_volume({10, 8, 6});
    Volume b = pattern_volume({10, 8, 7});
    b.grid.origin[0] += 0.25 * b.grid.spacing[0];
    CHECK_THAT(message_of([&] { write_vdb(path, {{"density", a.view()}, {"other", b.view()}}); }),
               Catch::Contains("lattice") && Catch::Contains("'other'"));
    b = pattern_volume({10, 8, 6});
    b.grid.spacing[1] = 1.3;
    CHECK_THROWS_AS(write_vdb(path, {{"density", a.view()}, {"other", b.view()}}), Error);
    b.grid.spacing[1] = a.grid.spacing[1];
    b.grid.origin[2] += 0.5;
    CHECK_THROWS_AS(write_vdb(path, {{"density", a.view()}, {"other", b.view()}}), Error);
    CHECK_THROWS_AS(write_vdb(path, {{"density", a.view()}, {"density", a.view()}}), Error);
    CHECK_THROWS_AS(write_vdb(path, {{"", a.view()}}), Error);
    CHECK_THROWS_AS(write_vdb(path, {}), Error);
    CHECK_FALSE(fs::exists(path));
    CHECK_THROWS_AS(write_vdb(tmp / "no/such/folder/x.vdb", {{"density", a.view()}}), Error);
}

TEST_CASE("the written transform puts voxel (i, j, k) at origin + spacing * (i, j, k)", "[vdb]") {
    TempDir tmp;
    const std::string path = tmp / "xf.vdb";
    const Volume v = pattern_volume();
    write_vdb(path, {{"density", v.view()}}, true);

    openvdb::initialize();
    openvdb::io::File file(path);
    file.open(false);
    auto grid = file.readGrid("density");
    file.close();
    CHECK(grid->getName() == "density");
    CHECK(grid->getGridClass() == openvdb::GRID_FOG_VOLUME);
    CHECK(grid->saveFloatAsHalf());
    const auto& xf = grid->transform();
    CHECK(xf.isLinear());
    const openvdb::Vec3d o = xf.indexToWorld(openvdb::Coord(0, 0, 0));
    for (int a = 0; a < 3; ++a) CHECK(o[a] == Approx(v.grid.origin[a]));
    const openvdb::Vec3d w = xf.indexToWorld(openvdb::Coord(3, 5, 7));
    CHECK(w[0] == Approx(v.grid.origin[0] + 3 * v.grid.spacing[0]));
    CHECK(w[1] == Approx(v.grid.origin[1] + 5 * v.grid.spacing[1]));
    CHECK(w[2] == Approx(v.grid.origin[2] + 7 * v.grid.spacing[2]));
    CHECK(xf.voxelSize()[0] == Approx(0.5));
    CHECK(xf.voxelSize()[1] == Approx(1.25));
    CHECK(xf.voxelSize()[2] == Approx(2.0));
}

TEST_CASE("read_vdb refuses rotated and frustum transforms and oversized grids", "[vdb]") {
    TempDir tmp;
    openvdb::initialize();
    auto write_one = [](const std::string& path, openvdb::math::Transform::Ptr xf) {
        auto g = openvdb::FloatGrid::create(0.0f);
        g->setName("density");
        g->tree().setValue(openvdb::Coord(1, 2, 3), 1.0f);
        g->tree().setValue(openvdb::Coord(40, 50, 60), 2.0f);
        g->setTransform(xf);
        openvdb::io::File f(path);
        f.write(openvdb::GridPtrVec{g});
        f.close();
    };
    auto rotated = openvdb::math::Transform::createLinearTransform(0.5);
    rotated->postRotate(0.3, openvdb::math::Z_AXIS);
    write_one(tmp / "rotated.vdb", rotated);
    CHECK_THAT(message_of([&] { read_vdb(tmp / "rotated.vdb"); }), Catch::Contains("rotated"));
    CHECK_THROWS_AS(read_vdb(tmp / "rotated.vdb"), FileFormatError);

    write_one(tmp / "frustum.vdb", openvdb::math::Transform::createFrustumTransform(
                                       openvdb::BBoxd(openvdb::Vec3d(0), openvdb::Vec3d(100)), 0.5, 10.0));
    CHECK_THAT(message_of([&] { read_vdb(tmp / "frustum.vdb"); }), Catch::Contains("nonlinear"));

    auto mirrored = openvdb::math::Transform::createLinearTransform(1.0);
    mirrored->postScale(openvdb::Vec3d(1, -1, 1));
    write_one(tmp / "mirrored.vdb", mirrored);
    CHECK_THROWS_AS(read_vdb(tmp / "mirrored.vdb"), FileFormatError);

    auto plain = openvdb::math::Transform::createLinearTransform(0.25);
    write_one(tmp / "plain.vdb", plain);
    const Volume r = read_vdb(tmp / "plain.vdb");
    CHECK(r.grid.dims == std::array<std::int64_t, 3>{40, 49, 58});
    CHECK(r.grid.spacing[1] == Approx(0.25));
    CHECK(r.grid.origin[2] == Approx(0.75));

    ReadOptions small;
    small.max_bytes = 40 * 49 * 58 * 4 - 1;
    CHECK_THAT(message_of([&] { read_vdb(tmp / "plain.vdb", "", small); }), Catch::Contains("exceeds"));
    CHECK_THROWS_AS(read_vdb(tmp / "plain.vdb", "", small), FileFormatError);
    small.max_bytes += 1;
    CHECK_NOTHROW(read_vdb(tmp / "plain.vdb", "", small));
}

TEST_CASE("read_vdb reads double, int64 and bool grids, instances and files without stats metadata", "[vdb]") {
    TempDir tmp;
    openvdb::initialize();
    auto xf = openvdb::math::Transform::createLinearTransform(2.0);
    auto dbl = openvdb::DoubleGrid::create(0.0);
    dbl->setName("temperature");
    dbl->tree().setValue(openvdb::Coord(-3, 4, 5), 1.5);
    dbl->tree().setValue(openvdb::Coord(-1, 6, 5), -2.25);
    auto i64 = openvdb::Int64Grid::create(0);
    i64->setName("ids");
    i64->tree().setValue(openvdb::Coord(0, 0, 0), std::int64_t{1} << 40);
    auto bl = openvdb::BoolGrid::create(false);
    bl->setName("inside");
    bl->tree().setValue(openvdb::Coord(1, 1, 1), true);
    bl->tree().setValue(openvdb::Coord(2, 1, 1), true);
    auto inst = dbl->copyGrid();  // shares dbl's tree: written as an instance
    inst->setName("temperature_copy");
    openvdb::GridPtrVec grids{dbl, i64, bl, inst};
    for (auto& g : grids) g->setTransform(xf->copy());
    const std::string path = tmp / "others.vdb";
    {
        openvdb::io::File f(path);
        f.setGridStatsMetadataEnabled(false);
        f.write(grids);
        f.close();
    }
    const auto info = vdb_grids(path);
    REQUIRE(info.size() == 4);
    CHECK(info[0].name == "temperature");
    CHECK(info[0].type == "double");
    CHECK(info[0].active_voxels == 2);
    CHECK(info[0].bbox_min == std::array<std::int64_t, 3>{-3, 4, 5});
    CHECK(info[0].bbox_max == std::array<std::int64_t, 3>{-1, 6, 5});
    CHECK(info[3].active_voxels == 2);

    const Volume d = read_vdb(path);  // no density: the first scalar grid
    REQUIRE(d.dtype == DType::Float64);
    CHECK(d.grid.dims == std::array<std::int64_t, 3>{3, 3, 1});
    CHECK(d.grid.origin == std::array<double, 3>{-6.0, 8.0, 10.0});
    CHECK(d.grid.spacing == std::array<double, 3>{2.0, 2.0, 2.0});
    CHECK(values<double>(d)[0] == 1.5);
    CHECK(values<double>(d)[d.grid.index(2, 2, 0)] == -2.25);
    const Volume c = read_vdb(path, "temperature_copy");
    CHECK(c.data == d.data);
    const Volume n = read_vdb(path, "ids");
    REQUIRE(n.dtype == DType::Int64);
    CHECK(values<std::int64_t>(n)[0] == (std::int64_t{1} << 40));
    const Volume b = read_vdb(path, "inside");
    REQUIRE(b.dtype == DType::UInt8);
    CHECK(b.grid.dims == std::array<std::int64_t, 3>{2, 1, 1});
    CHECK(values<std::uint8_t>(b)[0] == 1);
    CHECK(values<std::uint8_t>(b)[1] == 1);

    auto vec = openvdb::Vec3SGrid::create();
    vec->setName("velocity");
    vec->tree().setValue(openvdb::Coord(0), openvdb::Vec3s(1, 2, 3));
    const std::string vpath = tmp / "vec.vdb";
    openvdb::io::File(vpath).write(openvdb::GridPtrVec{vec});
    CHECK_THAT(message_of([&] { read_vdb(vpath, "velocity"); }), Catch::Contains("vec3s"));
    CHECK_THAT(message_of([&] { read_vdb(vpath); }), Catch::Contains("no scalar grid"));
}

TEST_CASE("build_vdb builds now and writes once; a view in 8³ bricks gives the C-order volume's grid", "[vdb]") {
    TempDir tmp;
    const Volume v = pattern_volume({24, 16, 8});
    std::vector<float> bricks(static_cast<std::size_t>(v.grid.voxel_count()));  // the same samples brick by brick
    for (std::int64_t z = 0; z < 8; ++z)
        for (std::int64_t y = 0; y < 16; ++y)
            for (std::int64_t x = 0; x < 24; ++x)
                bricks[brick_index(x, y, z, v.grid.dims)] = values<float>(v)[v.grid.index(x, y, z)];
    const VolumeView bricked{v.grid, DType::Float32, bricks.data(), true};
    const std::string path = tmp / "bricks.vdb";
    VdbGrids built = build_vdb(path, {{"density", bricked}});
    REQUIRE_FALSE(fs::exists(path));
    REQUIRE_FALSE(built.written());
    built.write(path);
    REQUIRE(built.written());
    REQUIRE_THROWS_WITH(built.write(path), Catch::Contains("written already"));
    const Volume r = read_vdb(path);
    require_same_geometry(r.grid, v.grid);
    REQUIRE(r.data == v.data);
    // bricks need whole bricks; a moved-from VdbGrids writes nothing
    Volume odd = pattern_volume();
    VolumeView odd_view = odd.view();
    odd_view.bricked = true;
    REQUIRE_THROWS_WITH(build_vdb(path, {{"density", odd_view}}), Catch::Contains("multiples of 8"));
    VdbGrids moved = std::move(built);
    REQUIRE_THROWS_WITH(built.write(tmp / "moved.vdb"), Catch::Contains("moved"));
    REQUIRE_FALSE(fs::exists(tmp / "moved.vdb"));
}

namespace {

std::string file_bytes(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

/// The file's bytes without the header's random UUID (36 characters after magic, versions and the offsets flag).
std::string without_uuid(std::string bytes) {
    REQUIRE(bytes.size() > 57);
    bytes.replace(21, 36, 36, '-');
    return bytes;
}

}  // namespace

TEST_CASE("a bake's grids are written as OpenVDB writes them, bricked or not, and read with delayed loading",
          "[vdb]") {
    TempDir tmp;
    // 480 leaf-sized blocks (more than one parallel run of leaves): constant full blocks (tiles), half-empty
    // blocks, varied values, empty blocks; bone labels on another pattern (int16, and bytes marked as labels)
    const std::array<std::int64_t, 3> dims{96, 64, 40};
    Volume v = make_volume<float>(dims, {0.5, 0.5, 0.75}, {-3.0, 4.0, 10.5}, DType::Float32);
    Volume labels = make_volume<std::int16_t>(dims, {0.5, 0.5, 0.75}, {-3.0, 4.0, 10.5}, DType::Int16);
    Volume bytes = make_volume<std::uint8_t>(dims, {0.5, 0.5, 0.75}, {-3.0, 4.0, 10.5}, DType::UInt8);
    const Grid& g = v.grid;
    for (std::int64_t z = 0; z < dims[2]; ++z)
        for (std::int64_t y = 0; y < dims[1]; ++y)
            for (std::int64_t x = 0; x < dims[0]; ++x) {
                const std::int64_t block = (x / 8 + y / 8 + z / 8) % 4, i = g.index(x, y, z);
                values<float>(v)[i] = block == 0 ? 0.0f : block == 1 ? 2.5f : block == 2 ? (x + y > 60 ? 0.0f : 1.0f)
                                                                                  : 0.01f * static_cast<float>(x * y - z);
                const auto label = static_cast<std::int16_t>(x < 40 ? 0 : 1 + (x + 2 * y) / 30);
                values<std::int16_t>(labels)[i] = label;
                values<std::uint8_t>(bytes)[i] = static_cast<std::uint8_t>(label);
            }
    const auto to_bricks = [&](const Volume& src, std::size_t size) {
        std::vector<unsigned char> out(src.data.size());
        for (std::int64_t z = 0; z < dims[2]; ++z)
            for (std::int64_t y = 0; y < dims[1]; ++y)
                for (std::int64_t x = 0; x < dims[0]; ++x)
                    std::memcpy(out.data() + brick_index(x, y, z, dims) * size,
                                src.data.data() + static_cast<std::size_t>(g.index(x, y, z)) * size, size);
        return out;
    };
    auto vb = to_bricks(v, 4), lb = to_bricks(labels, 2), bb = to_bricks(bytes, 1);
    VolumeView bytes_view = bytes.view();
    bytes_view.labels = true;
    VolumeView bytes_bricked{g, DType::UInt8, bb.data(), true};
    bytes_bricked.labels = true;
    const std::string dense = tmp / "dense.vdb", bricked = tmp / "bricked.vdb", ref = tmp / "openvdb.vdb";
    for (const bool as_half : {true, false}) {
        write_vdb(dense, {{"density", v.view()}, {"bone", labels.view()}, {"bytes", bytes_view}}, as_half);
        write_vdb(bricked, {{"density", VolumeView{g, DType::Float32, vb.data(), true}},
                            {"bone", VolumeView{g, DType::Int16, lb.data(), true}}, {"bytes", bytes_bricked}}, as_half);
        REQUIRE(without_uuid(file_bytes(dense)) == without_uuid(file_bytes(bricked)));
        if (as_half) {  // the values as half floats (a bake's frames hold them so): the file their floats give
            std::vector<std::uint16_t> hb(vb.size() / 4);
            for (std::size_t i = 0; i < hb.size(); ++i) {
                float f;
                std::memcpy(&f, vb.data() + 4 * i, 4);
                hb[i] = openvdb::math::half(f).bits();
            }
            VolumeView halves{g, DType::UInt16, hb.data(), true};
            halves.half = true;
            const std::string from_halves = tmp / "halves.vdb";
            write_vdb(from_halves, {{"density", halves}, {"bone", VolumeView{g, DType::Int16, lb.data(), true}},
                                    {"bytes", bytes_bricked}}, true);
            REQUIRE(without_uuid(file_bytes(from_halves)) == without_uuid(file_bytes(bricked)));
        }
        // OpenVDB reads the grids whole and writes them again: the same bytes
        openvdb::GridPtrVec grids;
        {
            openvdb::io::File in(bricked);
            in.open(false);
            for (const char* name : {"density", "bone", "bytes"}) grids.push_back(in.readGrid(name));
            in.close();
        }
        REQUIRE(grids[1]->type() == "Tree_int32_5_4_3");
        REQUIRE(grids[0]->saveFloatAsHalf() == as_half);
        openvdb::io::File out(ref);
        out.write(grids);
        out.close();
        REQUIRE(without_uuid(file_bytes(ref)) == without_uuid(file_bytes(bricked)));
        // delayed loading (as Blender reads: memory-mapped, leaves loaded when touched) seeks by the leaves'
        // compressed sizes and mask bytes written here: every value as the whole read gives it
        openvdb::io::File lazy(bricked);
        lazy.setCopyMaxBytes(0);
        lazy.open(true);
        for (std::size_t k = 0; k < grids.size(); ++k) {
            const auto got = lazy.readGrid(grids[k]->getName());
            std::int64_t checked = 0;
            if (k == 0) {
                const auto& a = static_cast<const openvdb::FloatGrid&>(*got);
                const auto& b = static_cast<const openvdb::FloatGrid&>(*grids[k]);
                REQUIRE(a.tree().leafCount() == b.tree().leafCount());
                REQUIRE(a.activeVoxelCount() == b.activeVoxelCount());
                for (auto it = b.cbeginValueOn(); it; ++it, ++checked)
                    REQUIRE(a.tree().getValue(it.getCoord()) == *it);
            } else {
                const auto& a = static_cast<const openvdb::Int32Grid&>(*got);
                const auto& b = static_cast<const openvdb::Int32Grid&>(*grids[k]);
                REQUIRE(a.activeVoxelCount() == b.activeVoxelCount());
                for (auto it = b.cbeginValueOn(); it; ++it, ++checked)
                    REQUIRE(a.tree().getValue(it.getCoord()) == *it);
            }
            REQUIRE(checked > 0);
        }
        lazy.close();
    }
    // and the values are the volume's
    const Volume r = read_vdb(bricked);
    REQUIRE(r.grid.dims == std::array<std::int64_t, 3>{96, 64, 40});
    REQUIRE(r.data == v.data);
}

TEST_CASE("the file's string metadata is written as OpenVDB writes it", "[vdb]") {
    TempDir tmp;
    Volume v = make_volume<float>({16, 8, 8}, {1.0, 1.0, 1.0}, {0.0, 0.0, 0.0}, DType::Float32);
    for (std::size_t i = 0; i < 16 * 8 * 8; ++i) values<float>(v)[i] = static_cast<float>(i % 7);
    const std::string path = tmp / "meta.vdb", ref = tmp / "openvdb.vdb";
    const VdbMetadata meta{{"volrig_tissues", "[{\"key\": \"bone\"}]"}, {"note", ""}};
    write_vdb(path, {{"density", v.view()}}, false, meta);
    openvdb::io::File in(path);
    in.open(false);
    const openvdb::MetaMap::Ptr got = in.getMetadata();
    openvdb::GridPtrVec grids{in.readGrid("density")};
    in.close();
    REQUIRE(got->metaCount() == 2);
    REQUIRE(got->metaValue<std::string>("volrig_tissues") == "[{\"key\": \"bone\"}]");
    REQUIRE(got->metaValue<std::string>("note").empty());
    openvdb::io::File out(ref);
    out.write(grids, *got);
    out.close();
    REQUIRE(without_uuid(file_bytes(ref)) == without_uuid(file_bytes(path)));
    REQUIRE_THROWS_WITH(write_vdb(path, {{"density", v.view()}}, false, {{"", "x"}}),
                        Catch::Contains("metadata entry needs a non-empty name"));
}

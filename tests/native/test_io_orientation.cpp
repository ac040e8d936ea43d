// Tests for the grids' orientation (volume.hpp direction, io.hpp readers and writers): NRRD space directions in
// RAS/LPS, MetaImage TransformMatrix and AnatomicalOrientation, NIfTI sform and qform, and one volume saved with
// its axes permuted and flipped in every format giving the same voxels at the same world positions.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <unistd.h>
#include <vector>

#include "volrig/io.hpp"

using namespace volrig;
namespace fs = std::filesystem;

namespace {

using Bytes = std::vector<std::uint8_t>;
using Vec3 = std::array<double, 3>;

Bytes operator+(Bytes a, const Bytes& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

fs::path temp_dir(const std::string& name) {
    fs::path d = fs::temp_directory_path() / ("volrig_orientation_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

void write_text(const fs::path& p, const std::string& s, const Bytes& data = {}) {
    std::ofstream f(p, std::ios::binary);
    f.write(s.data(), static_cast<std::streamsize>(s.size()));
    f.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
    REQUIRE(f.good());
}

// Rotation by `deg` degrees about z, then `deg2` about x (row-major).
Matrix3 rotation(double deg, double deg2) {
    const double a = deg * M_PI / 180, b = deg2 * M_PI / 180;
    const Matrix3 z{std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a), 0, 0, 0, 1};
    const Matrix3 x{1, 0, 0, 0, std::cos(b), -std::sin(b), 0, std::sin(b), std::cos(b)};
    Matrix3 m{};
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            for (int k = 0; k < 3; ++k) m[3 * r + c] += x[3 * r + k] * z[3 * k + c];
    return m;
}

void check_direction(const Grid& g, const Matrix3& want, double tol = 1e-6) {
    for (int i = 0; i < 9; ++i) CHECK(g.direction[i] == Approx(want[i]).margin(tol));
}

// A uint16 volume whose voxels hold distinct values (0 = empty) in an asymmetric pattern.
Volume phantom(const Matrix3& direction) {
    Volume v;
    v.grid.dims = {6, 5, 4};
    v.grid.spacing = {0.5, 0.75, 1.25};
    v.grid.origin = {10, -20, 30};
    v.grid.direction = direction;
    v.dtype = DType::UInt16;
    v.data.assign(static_cast<std::size_t>(v.grid.voxel_count()) * 2, 0);
    auto* p = reinterpret_cast<std::uint16_t*>(v.data.data());
    for (std::int64_t i = 0; i < v.grid.voxel_count(); ++i)
        if ((i * 7) % 3 != 0 || i % 5 == 0) p[i] = static_cast<std::uint16_t>(i + 1);
    return v;
}

// The same samples with new axis a = old axis perm[a], reversed when flip[a]; geometry adjusted so every voxel
// keeps its world position.
Volume permuted(const Volume& in, const std::array<int, 3>& perm, const std::array<bool, 3>& flip) {
    Volume out;
    out.dtype = in.dtype;
    const Grid& g = in.grid;
    std::array<double, 3> first{};  // old index of new voxel (0, 0, 0)
    for (int a = 0; a < 3; ++a) {
        const int o = perm[a];
        out.grid.dims[a] = g.dims[o];
        out.grid.spacing[a] = g.spacing[o];
        for (int r = 0; r < 3; ++r) out.grid.direction[3 * r + a] = (flip[a] ? -1 : 1) * g.direction[3 * r + o];
        first[o] = flip[a] ? static_cast<double>(g.dims[o] - 1) : 0;
    }
    out.grid.origin = world_position(g, first);
    out.data.assign(in.data.size(), 0);
    const auto* src = reinterpret_cast<const std::uint16_t*>(in.data.data());
    auto* dst = reinterpret_cast<std::uint16_t*>(out.data.data());
    const auto& d = out.grid.dims;
    for (std::int64_t z = 0; z < d[2]; ++z)
        for (std::int64_t y = 0; y < d[1]; ++y)
            for (std::int64_t x = 0; x < d[0]; ++x) {
                const std::int64_t n[3] = {x, y, z};
                std::int64_t o[3] = {0, 0, 0};
                for (int a = 0; a < 3; ++a) o[perm[a]] = flip[a] ? d[a] - 1 - n[a] : n[a];
                dst[out.grid.index(x, y, z)] = src[g.index(o[0], o[1], o[2])];
            }
    return out;
}

// value -> world position of every non-empty voxel.
std::map<std::uint16_t, Vec3> world_of_values(const Volume& v) {
    std::map<std::uint16_t, Vec3> out;
    const auto* p = reinterpret_cast<const std::uint16_t*>(v.data.data());
    const auto& d = v.grid.dims;
    for (std::int64_t z = 0; z < d[2]; ++z)
        for (std::int64_t y = 0; y < d[1]; ++y)
            for (std::int64_t x = 0; x < d[0]; ++x) {
                const std::uint16_t value = p[v.grid.index(x, y, z)];
                if (value)
                    out[value] = world_position(v.grid, {static_cast<double>(x), static_cast<double>(y),
                                                         static_cast<double>(z)});
            }
    return out;
}

void check_same_world(const Volume& want, const Volume& got, double tol) {
    const auto a = world_of_values(want), b = world_of_values(got);
    REQUIRE(a.size() == b.size());
    double worst = 0;
    for (const auto& [value, pos] : a) {
        REQUIRE(b.count(value));
        for (int r = 0; r < 3; ++r) worst = std::max(worst, std::fabs(pos[r] - b.at(value)[r]));
    }
    CHECK(worst < tol);
}

template <class T>
void put(Bytes& h, std::size_t at, T v) {
    std::memcpy(h.data() + at, &v, sizeof(T));
}

// A single-file NIfTI-1 of a uint16 volume with its geometry as an sform (RAS: x and y negated), or as a qform
// when `quaternion` gives (b, c, d, qfac).
Bytes nifti_of(const Volume& v, const std::array<double, 4>* quaternion = nullptr) {
    Bytes h(352, 0);
    put<std::int32_t>(h, 0, 348);
    const std::int16_t dim[8] = {3, static_cast<std::int16_t>(v.grid.dims[0]), static_cast<std::int16_t>(v.grid.dims[1]),
                                 static_cast<std::int16_t>(v.grid.dims[2]), 1, 1, 1, 1};
    for (std::size_t i = 0; i < 8; ++i) put(h, 40 + 2 * i, dim[i]);
    put<std::int16_t>(h, 70, 512);
    put<std::int16_t>(h, 72, 16);
    put<float>(h, 76, quaternion ? static_cast<float>((*quaternion)[3]) : 1.0f);
    for (std::size_t a = 0; a < 3; ++a) put(h, 80 + 4 * a, static_cast<float>(v.grid.spacing[a]));
    put<float>(h, 108, 352);
    const double ras[3] = {-1, -1, 1};
    if (quaternion) {
        put<std::int16_t>(h, 252, 1);
        for (std::size_t i = 0; i < 3; ++i) put(h, 256 + 4 * i, static_cast<float>((*quaternion)[i]));
        for (std::size_t r = 0; r < 3; ++r) put(h, 268 + 4 * r, static_cast<float>(ras[r] * v.grid.origin[r]));
    } else {
        put<std::int16_t>(h, 254, 2);
        for (std::size_t r = 0; r < 3; ++r) {
            for (std::size_t c = 0; c < 3; ++c)
                put(h, 280 + 16 * r + 4 * c, static_cast<float>(ras[r] * v.grid.direction[3 * r + c] * v.grid.spacing[c]));
            put(h, 280 + 16 * r + 12, static_cast<float>(ras[r] * v.grid.origin[r]));
        }
    }
    std::memcpy(h.data() + 344, "n+1", 4);
    return h;
}

Volume read_bytes(const Bytes& b, const std::string& name, Volume (*reader)(const ByteSource&, const ReadOptions&)) {
    auto src = memory_source(b.data(), b.size(), name);
    return reader(*src, ReadOptions{});
}

}  // namespace

TEST_CASE("world_position and normalize_direction", "[orientation]") {
    Grid g;
    g.spacing = {2, 3, 4};
    g.origin = {1, 1, 1};
    g.direction = {0, -1, 0, 1, 0, 0, 0, 0, 1};  // x axis along +y, y axis along -x
    const Vec3 p = world_position(g, {1, 1, 1});
    CHECK(p[0] == Approx(1 - 3));
    CHECK(p[1] == Approx(1 + 2));
    CHECK(p[2] == Approx(1 + 4));

    Matrix3 d{2, 0, 0, 0, 0.5, 0, 0, 0, 3};  // scaled columns are made unit
    CHECK(normalize_direction(d).empty());
    for (int i = 0; i < 9; ++i) CHECK(d[i] == Approx(kIdentity3[i]));
    Matrix3 sheared{1, 0.5, 0, 0, 1, 0, 0, 0, 1};
    CHECK(normalize_direction(sheared).find("not perpendicular") != std::string::npos);
    Matrix3 zero{1, 0, 0, 0, 0, 0, 0, 0, 1};
    CHECK(normalize_direction(zero).find("axis y") != std::string::npos);
    Grid bad = g;
    bad.dims = {1, 1, 1};
    bad.direction = sheared;
    CHECK_THROWS_WITH(check_grid(bad, 1, 100, "thing"), Catch::Contains("thing: directions of axes x and y"));
}

TEST_CASE("NRRD: space directions and space RAS/LPS become an LPS direction; the writer round-trips it",
          "[orientation][nrrd]") {
    const std::string head = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 1 1\nencoding: raw\n";
    auto read = [&](const std::string& fields) {
        const std::string text = head + fields + "\n";
        Bytes b(text.begin(), text.end());
        b.push_back(1);
        b.push_back(2);
        return read_bytes(b, "o.nrrd", read_nrrd);
    };
    // RAS: x and y change sign, origin too.
    Volume v = read("space: right-anterior-superior\nspace directions: (0,2,0) (-3,0,0) (0,0,4)\n"
                    "space origin: (10,20,30)\n");
    CHECK(v.grid.spacing == std::array<double, 3>{2, 3, 4});
    check_direction(v.grid, {0, 1, 0, -1, 0, 0, 0, 0, 1});
    CHECK(v.grid.origin == std::array<double, 3>{-10, -20, 30});
    // LPS: kept as given.
    v = read("space: LPS\nspace directions: (0,2,0) (-3,0,0) (0,0,4)\nspace origin: (10,20,30)\n");
    check_direction(v.grid, {0, -1, 0, 1, 0, 0, 0, 0, 1});
    CHECK(v.grid.origin == std::array<double, 3>{10, 20, 30});
    // No space directions: axis-aligned.
    v = read("spacings: 1 2 3\n");
    check_direction(v.grid, kIdentity3);
    // Errors name the field.
    CHECK_THROWS_WITH(read("space: RAS\nspace directions: (1,0,0) (1,1,0) (0,0,1)\n"),
                      Catch::Contains("o.nrrd: line 7: space directions") && Catch::Contains("not perpendicular"));
    CHECK_THROWS_WITH(read("space: right-anterior-superior-time\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n"),
                      Catch::Contains("o.nrrd: line 6: space") && Catch::Contains("is not supported"));

    const fs::path dir = temp_dir("nrrd");
    const Volume p = phantom(rotation(30, -20));
    write_nrrd((dir / "p.nrrd").string(), p.view(), true);
    const Volume back = read_volume((dir / "p.nrrd").string());
    check_direction(back.grid, p.grid.direction, 1e-12);
    CHECK(back.data == p.data);
    fs::remove_all(dir);
}

TEST_CASE("MetaImage: TransformMatrix (ITK's layout), AnatomicalOrientation; the writer round-trips them",
          "[orientation][metaimage]") {
    auto read = [&](const std::string& fields) {
        const std::string text = "ObjectType = Image\nNDims = 3\nDimSize = 2 1 1\nElementType = MET_UCHAR\n" +
                                 fields + "ElementDataFile = LOCAL\n";
        Bytes b(text.begin(), text.end());
        b.push_back(1);
        b.push_back(2);
        return read_bytes(b, "o.mha", read_metaimage);
    };
    // ITK writes the direction of axis a as numbers 3a..3a+2.
    Volume v = read("TransformMatrix = 0 1 0 -1 0 0 0 0 1\n");
    check_direction(v.grid, {0, -1, 0, 1, 0, 0, 0, 0, 1});
    v = read("AnatomicalOrientation = RAI\n");
    check_direction(v.grid, kIdentity3);
    v = read("AnatomicalOrientation = LPS\n");  // axes come from L, P, S: they point to R, A, I
    check_direction(v.grid, {-1, 0, 0, 0, -1, 0, 0, 0, -1});
    v = read("AnatomicalOrientation = ???\n");  // unknown: axis-aligned
    check_direction(v.grid, kIdentity3);
    CHECK_THROWS_WITH(read("TransformMatrix = 1 0 0 0 1 0\n"), Catch::Contains("o.mha: line 5: TransformMatrix"));
    CHECK_THROWS_WITH(read("TransformMatrix = 1 0 0 1 0 0 0 0 1\n"), Catch::Contains("not perpendicular"));

    const fs::path dir = temp_dir("mha");
    const Volume p = phantom(rotation(-75, 40));
    write_metaimage((dir / "p.mha").string(), p.view(), false);
    const Volume back = read_volume((dir / "p.mha").string());
    check_direction(back.grid, p.grid.direction, 1e-12);
    CHECK(back.data == p.data);
    Volume flipped = p;
    flipped.grid.direction = {-1, 0, 0, 0, -1, 0, 0, 0, 1};
    write_metaimage((dir / "f.mha").string(), flipped.view(), false);
    std::ifstream f(dir / "f.mha");
    const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    CHECK(text.find("AnatomicalOrientation = LPI\n") != std::string::npos);
    CHECK(text.find("TransformMatrix = -1 0 0 0 -1 0 0 0 1\n") != std::string::npos);
    fs::remove_all(dir);
}

TEST_CASE("NIfTI: sform and qform rotations, RAS to LPS", "[orientation][nifti]") {
    Volume p = phantom(rotation(30, 0));
    Volume v = read_bytes(nifti_of(p) + Bytes(p.data.begin(), p.data.end()), "o.nii", read_nifti);
    check_direction(v.grid, p.grid.direction, 1e-6);
    for (int a = 0; a < 3; ++a) CHECK(v.grid.origin[a] == Approx(p.grid.origin[a]));
    CHECK(v.data == p.data);
    // qform: 90 degrees about z in RAS (b, c, d) = (0, 0, sin 45), qfac -1 flips the third axis.
    p.grid.direction = {0, 1, 0, -1, 0, 0, 0, 0, -1};  // RAS (0,-1,0 | 1,0,0 | 0,0,-1) in LPS
    const std::array<double, 4> q{0, 0, std::sqrt(0.5), -1};
    v = read_bytes(nifti_of(p, &q) + Bytes(p.data.begin(), p.data.end()), "q.nii", read_nifti);
    check_direction(v.grid, p.grid.direction, 1e-6);
    CHECK(v.grid.origin[0] == Approx(10));
    CHECK(v.grid.origin[1] == Approx(-20));
}

TEST_CASE("One volume saved with permuted and flipped axes reads back the same in every format",
          "[orientation][nrrd][metaimage][nifti]") {
    const fs::path dir = temp_dir("perm");
    const Volume base = phantom(rotation(25, 10));
    const std::array<int, 3> perms[] = {{0, 1, 2}, {2, 0, 1}, {1, 2, 0}, {2, 1, 0}};
    const std::array<bool, 3> flips[] = {{false, false, false}, {true, false, true}, {false, true, false}};
    int n = 0;
    for (const auto& perm : perms)
        for (const auto& flip : flips) {
            const Volume v = permuted(base, perm, flip);
            check_same_world(base, v, 1e-9);  // the test's own permutation keeps positions
            const std::string stem = (dir / ("v" + std::to_string(n++))).string();
            write_nrrd(stem + ".nrrd", v.view(), true);
            write_metaimage(stem + ".mha", v.view(), true);
            const Bytes nii = nifti_of(v);
            write_text(stem + ".nii", std::string(nii.begin(), nii.end()), v.data);
            check_same_world(base, read_volume(stem + ".nrrd"), 1e-9);
            check_same_world(base, read_volume(stem + ".mha"), 1e-9);
            check_same_world(base, read_volume(stem + ".nii"), 1e-4);  // NIfTI stores float32
        }
    fs::remove_all(dir);
}

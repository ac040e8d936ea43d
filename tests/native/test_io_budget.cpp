// Tests for the readers' file budget (ReadOptions::max_bytes_given, io_detail::check_budget): a small file that
// demands more than 1 GB and more than 1000 times its size is refused before anything is allocated, naming the file,
// the demand and how to allow it; a caller that gives max_bytes decides alone. (PNG and TIFF: test_io_hostile.py.)
#include <catch2/catch.hpp>

#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <string>
#include <unistd.h>

#include "io/io_detail.hpp"
#include "io_fixture.hpp"
#include "volrig/io.hpp"

namespace fs = std::filesystem;
using namespace volrig;

TEST_CASE("check_budget: more than 1 GB and more than 1000x the file is refused unless max_bytes was given",
          "[io][budget]") {
    ::unsetenv("VOLRIG_MAX_BYTES");
    ReadOptions opt;
    CHECK_NOTHROW(io_detail::check_budget("a", 1000000000, 1, opt, "x"));       // 1 GB: not more than 1 GB
    CHECK_NOTHROW(io_detail::check_budget("a", 2000000000, 2000000, opt, "x"));  // 1000x exactly
    const std::string m = message_of([&] { io_detail::check_budget("a.tif", 2000000001, 2000000, opt, "the pixels"); });
    CHECK(m == "a.tif: the pixels need 2,000,000,001 bytes from a file of 2,000,000 bytes: more than 1 GB and more "
               "than 1,000 times the file, so it is refused as broken or hostile; if the file is right, allow it with "
               "max_bytes=2000000001 (Python) or VOLRIG_MAX_BYTES=2000000001 in the environment");
    opt.max_bytes_given = true;
    CHECK_NOTHROW(io_detail::check_budget("a", 2000000001, 2000000, opt, "x"));
    opt.max_bytes_given = false;
    ::setenv("VOLRIG_MAX_BYTES", "4G", 1);
    CHECK_NOTHROW(io_detail::check_budget("a", 2000000001, 2000000, opt, "x"));
    ::unsetenv("VOLRIG_MAX_BYTES");
}

TEST_CASE("read_vdb: two voxels far apart are refused as a 1.2 GB dense box from a small file", "[io][budget][vdb]") {
    ::unsetenv("VOLRIG_MAX_BYTES");
    openvdb::initialize();
    const fs::path path = fs::temp_directory_path() / ("volrig_budget_" + std::to_string(::getpid()) + ".vdb");
    auto g = openvdb::FloatGrid::create(0.0f);
    g->setName("density");
    g->tree().setValue(openvdb::Coord(0, 0, 0), 1.0f);
    g->tree().setValue(openvdb::Coord(999, 999, 299), 2.0f);
    openvdb::io::File(path.string()).write(openvdb::GridPtrVec{g});
    const std::string m = message_of([&] { read_vdb(path.string()); });
    CHECK(m.rfind(path.string() + ": grid 'density' as a dense 1000 x 1000 x 300 box (the active voxels' bounding "
                                  "box) need 1,200,000,000 bytes from a file of ",
                  0) == 0);
    CHECK(m.find("max_bytes=1200000000") != std::string::npos);
    CHECK(m.find("; or read part of it with crop=(min, max) in the grid's index coordinates (its active voxels lie "
                 "in (0, 0, 0) .. (999, 999, 299))") != std::string::npos);
    // The crop the message offers: a box around one voxel reads it alone, at its world place.
    ReadOptions crop;
    crop.crop = ReadOptions::IndexBox{{990, 995, 290}, {1200, 1200, 400}};
    const Volume v = read_vdb(path.string(), "", crop);
    CHECK(v.grid.dims == std::array<std::int64_t, 3>{10, 5, 10});
    CHECK(v.grid.origin == std::array<double, 3>{990.0, 995.0, 290.0});
    const auto* f = reinterpret_cast<const float*>(v.data.data());
    CHECK(f[v.grid.voxel_count() - 1] == 2.0f);
    CHECK(std::count(f, f + v.grid.voxel_count(), 0.0f) == v.grid.voxel_count() - 1);
    crop.crop = ReadOptions::IndexBox{{-50, -50, -50}, {-1, 10, 10}};
    CHECK(message_of([&] { read_vdb(path.string(), "", crop); }) ==
          path.string() + ": grid 'density': the crop box (-50, -50, -50) .. (-1, 10, 10) holds none of the active "
                          "voxels, which lie in (0, 0, 0) .. (999, 999, 299)");
    crop.crop = ReadOptions::IndexBox{{5, 0, 0}, {4, 10, 10}};
    CHECK(message_of([&] { read_vdb(path.string(), "", crop); }).find("min must not exceed its max") !=
          std::string::npos);
    // A caller's max_bytes decides alone (here: refused by it, without the budget's words).
    ReadOptions opt;
    opt.max_bytes = 1000;
    opt.max_bytes_given = true;
    const std::string limited = message_of([&] { read_vdb(path.string(), "", opt); });
    CHECK(limited.find("refused as broken or hostile") == std::string::npos);
    CHECK(limited.find(path.string()) == 0);
    fs::remove(path);
}

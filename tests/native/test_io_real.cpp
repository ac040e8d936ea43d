// Tests for volrig/io.hpp on files: the fuzz seed corpus, and the real scans in ../shared/data when present.
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

#include "io_fixture.hpp"

using namespace volrig;
namespace fs = std::filesystem;

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

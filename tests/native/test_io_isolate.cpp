// Tests for run_isolated / isolated_volume (io/isolate.cpp): a decoder run in a child process whose crash becomes a
// FileFormatError naming the file, whose errors keep their class, whose warnings and result reach the caller, and
// which may use TBB after the parent did.
#include <catch2/catch.hpp>

#include <tbb/parallel_for.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "io/io_detail.hpp"
#include "io_fixture.hpp"
#include "volrig/io.hpp"

using namespace volrig;

namespace {

Volume small_volume() {
    Volume v;
    v.grid.dims = {3, 2, 2};
    v.grid.spacing = {0.5, 1.0, 2.0};
    v.grid.origin = {1.0, -2.0, 3.0};
    v.dtype = DType::Int16;
    v.data.resize(12 * 2);
    for (std::size_t i = 0; i < v.data.size(); ++i) v.data[i] = static_cast<std::uint8_t>(i * 7);
    return v;
}

}  // namespace

TEST_CASE("isolated_volume: the child's volume and warnings reach the caller", "[io][isolate]") {
    std::vector<std::string> warnings;
    ReadOptions opt;
    opt.warn = [&](const std::string& w) { warnings.push_back(w); };
    const Volume want = small_volume();
    const Volume got = io_detail::isolated_volume("x.dcm", "the decoder", opt, [&](const ReadOptions& o) {
        o.warn("first");
        o.warn("second");
        return small_volume();
    });
    CHECK(got.data == want.data);
    CHECK(got.dtype == DType::Int16);
    CHECK(got.grid.dims == want.grid.dims);
    CHECK(got.grid.spacing == want.grid.spacing);
    CHECK(got.grid.origin == want.grid.origin);
    CHECK(warnings == std::vector<std::string>{"first", "second"});
}

TEST_CASE("isolated_volume: a child that aborts or segfaults is a FileFormatError naming the file", "[io][isolate]") {
    const auto abort_in_child = [](const ReadOptions&) -> Volume {
        std::fputs("decoder.cpp:42: assertion `precision >= 1' failed\n", stderr);
        std::abort();
    };
    CHECK_THROWS_AS(io_detail::isolated_volume("scan.dcm", "the decoder", ReadOptions{}, abort_in_child),
                    FileFormatError);
    const std::string m = message_of([&] { io_detail::isolated_volume("scan.dcm", "the decoder", ReadOptions{}, abort_in_child); });
    CHECK(m.rfind("scan.dcm: the decoder crashed on this file (killed by signal 6", 0) == 0);
    CHECK(m.find("assertion `precision >= 1' failed") != std::string::npos);
    const std::string s = message_of([&] {
        io_detail::isolated_volume("a.vdb", "OpenVDB's reader", ReadOptions{}, [](const ReadOptions&) -> Volume {
            std::raise(SIGSEGV);
            return {};
        });
    });
    CHECK(s.rfind("a.vdb: OpenVDB's reader crashed on this file (killed by signal 11", 0) == 0);
    // A reader of several files names the one it was decoding.
    const std::string r = message_of([&] {
        io_detail::isolated_volume("series", "the decoder", ReadOptions{}, [](const ReadOptions& o) -> Volume {
            o.reading("series/1.dcm");
            o.reading("series/2.dcm");
            std::abort();
        });
    });
    CHECK(r.rfind("series: the decoder crashed on series/2.dcm (killed by signal 6", 0) == 0);
}

TEST_CASE("isolated_volume: the child's errors keep their class and message", "[io][isolate]") {
    const auto throwing = [](int kind) {
        return [kind](const ReadOptions&) -> Volume {
            if (kind == 0) throw FileFormatError("f.dcm: broken");
            if (kind == 1) throw FileNotFound("g.dcm: no such file");
            throw Error("h.dcm: something else");
        };
    };
    CHECK_THROWS_MATCHES(io_detail::isolated_volume("f", "d", ReadOptions{}, throwing(0)), FileFormatError,
                         Catch::Message("f.dcm: broken"));
    CHECK_THROWS_MATCHES(io_detail::isolated_volume("g", "d", ReadOptions{}, throwing(1)), FileNotFound,
                         Catch::Message("g.dcm: no such file"));
    CHECK_THROWS_MATCHES(io_detail::isolated_volume("h", "d", ReadOptions{}, throwing(2)), Error,
                         Catch::Message("h.dcm: something else"));
    // A child that returns without a result (here: exits) is a crash too.
    const std::string m = message_of([] {
        io_detail::isolated_volume("e", "d", ReadOptions{}, [](const ReadOptions&) -> Volume { std::_Exit(0); });
    });
    CHECK(m == "e: d crashed on this file (it stopped without a result): it is corrupt or uses a feature the decoder "
               "cannot handle");
}

TEST_CASE("isolated_volume: TBB works in the child after the parent used it", "[io][isolate]") {
    std::atomic<int> sum{0};
    tbb::parallel_for(0, 1000, [&](int i) { sum += i; });
    REQUIRE(sum == 499500);
    const Volume v = io_detail::isolated_volume("t", "d", ReadOptions{}, [](const ReadOptions&) {
        Volume out = small_volume();
        std::atomic<int> s{0};
        tbb::parallel_for(0, 1000, [&](int i) { s += i; });
        out.data[0] = static_cast<std::uint8_t>(s % 251);
        return out;
    });
    CHECK(v.data[0] == 499500 % 251);
}

TEST_CASE("isolated_volume: a volume larger than the pipe's buffer arrives whole", "[io][isolate]") {
    const Volume v = io_detail::isolated_volume("big", "d", ReadOptions{}, [](const ReadOptions&) {
        Volume out;
        out.grid.dims = {256, 256, 64};
        out.dtype = DType::UInt16;
        out.data.resize(256 * 256 * 64 * 2);
        for (std::size_t i = 0; i < out.data.size(); ++i) out.data[i] = static_cast<std::uint8_t>(i % 253);
        return out;
    });
    REQUIRE(v.data.size() == 256u * 256 * 64 * 2);
    bool same = true;
    for (std::size_t i = 0; i < v.data.size(); ++i) same = same && v.data[i] == static_cast<std::uint8_t>(i % 253);
    CHECK(same);
}

TEST_CASE("decoder_limits: memory from the file's budget, CPU time from what it may hold", "[io][isolate]") {
    const io_detail::ChildLimits fuzz = io_detail::decoder_limits(std::uint64_t(64) << 20, std::uint64_t(64) << 20);
    CHECK(fuzz.memory == (std::uint64_t(448) << 20));
    CHECK(fuzz.cpu_seconds == 5);  // 5 + 67 MB at 100 MB/s, rounded down
    const std::uint64_t all = std::numeric_limits<std::uint64_t>::max();
    CHECK(io_detail::decoder_limits(all, all).memory == 0);
    CHECK(io_detail::decoder_limits(all, all).cpu_seconds == 0);
    // A small file: 1 GB of budget (budget_of), but 1000 times its 10,000 bytes of work; a folder: max_bytes.
    const TempDir dir;
    write_file(dir.path / "small.vdb", Bytes(10000, 0));
    const io_detail::ChildLimits small = io_detail::decoder_limits((dir.path / "small.vdb").string(), ReadOptions{});
    CHECK(small.memory == 3 * io_detail::kBudgetFloor + (std::uint64_t(256) << 20));
    CHECK(small.cpu_seconds == 5);  // 5 + 10 MB at 100 MB/s, rounded down
    write_file(dir.path / "large.vdb", Bytes(2000000, 0));  // 2 GB of work: 20 s more
    CHECK(io_detail::decoder_limits((dir.path / "large.vdb").string(), ReadOptions{}).cpu_seconds == 25);
    ReadOptions given;
    given.max_bytes = std::uint64_t(1) << 20;
    given.max_bytes_given = true;
    CHECK(io_detail::decoder_limits((dir.path / "small.vdb").string(), given).memory == (std::uint64_t(259) << 20));
    CHECK(io_detail::decoder_limits(dir.path.string(), ReadOptions{}).memory ==
          io_detail::decoder_limits(ReadOptions{}.max_bytes, 0).memory);
}

TEST_CASE("isolated_volume: a decoder asking for far more memory than the file's budget fails at once", "[io][isolate]") {
    // OpenVDB reads a string of any length a corrupt file claims (fuzz_vdb found 1.7 GB).
    ReadOptions opt;
    opt.max_bytes = std::uint64_t(1) << 20;
    opt.max_bytes_given = true;
    const auto greedy = [](const ReadOptions&) -> Volume {
        std::string claimed(std::size_t(4) << 30, ' ');  // 4 GiB, as a corrupt header claims
        Volume v = small_volume();
        v.data[0] = static_cast<std::uint8_t>(claimed[claimed.size() / 2]);
        return v;
    };
    const std::string m = message_of([&] { io_detail::isolated_volume("big.vdb", "OpenVDB's reader", opt, greedy); });
    CHECK(m.rfind("big.vdb: ", 0) == 0);
    // Without sanitizers std::bad_alloc comes back as the budget's message; AddressSanitizer's allocator aborts
    // the child instead, which is a crash on this file.
    CHECK((m.find("needed more than the 259 MiB this file may use") != std::string::npos ||
           m.find("crashed on this file") != std::string::npos));
    CHECK_THROWS_AS(io_detail::isolated_volume("big.vdb", "OpenVDB's reader", opt, greedy), FileFormatError);
}

TEST_CASE("run_isolated: a decoder that runs past its CPU time is stopped", "[io][isolate]") {
    // fuzz_vdb found a 10 KB file on which OpenVDB's topology reader loops for minutes.
    const std::string m = message_of([] {
        io_detail::run_isolated("loop.vdb", "OpenVDB's reader", {0, 1}, [](io_detail::IsolatedOutput&) {
            volatile std::uint64_t n = 0;
            for (;;) n = n + 1;
        }, [](io_detail::IsolatedInput&) {});
    });
    CHECK(m.rfind("loop.vdb: OpenVDB's reader crashed on this file (killed by signal 24", 0) == 0);
}

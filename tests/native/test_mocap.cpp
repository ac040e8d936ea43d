// Tests for volrig/mocap.hpp: the BVH reader on files written here (every construct of the format, every kind of
// malformed input, truncation at every byte), the fuzz seed corpus, and CMU subject 131 in ../shared/data when
// present.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "volrig/mocap.hpp"

using namespace volrig;
namespace fs = std::filesystem;

namespace {

using C = BvhChannel;

BvhMotion bvh(const std::string& text, const std::string& name = "clip.bvh", ReadOptions opt = {}) {
    auto src = memory_source(reinterpret_cast<const std::uint8_t*>(text.data()), text.size(), name);
    return read_bvh(*src, opt);
}

/// Reads the text and checks it fails with a FileFormatError whose message starts with the file name and contains
/// every part.
void expect_error(const std::string& text, std::initializer_list<std::string> parts, ReadOptions opt = {}) {
    try {
        bvh(text, "bad.bvh", opt);
    } catch (const FileFormatError& e) {
        const std::string m = e.what();
        INFO("message: " << m);
        CHECK(m.rfind("bad.bvh: ", 0) == 0);
        for (const auto& p : parts) CHECK(m.find(p) != std::string::npos);
        return;
    }
    std::string all;
    for (const auto& p : parts) all += "'" + p + "' ";
    FAIL("no FileFormatError; expected one mentioning " << all);
}

std::string replace(std::string s, const std::string& from, const std::string& to) {
    const auto at = s.find(from);
    REQUIRE(at != std::string::npos);
    return s.replace(at, from.size(), to);
}

/// A root with six channels, a two-joint leg ending in an End Site, and a spine: 15 channels, 3 frames.
const std::string kClip = R"(HIERARCHY
ROOT Hips
{
	OFFSET 0.0 0.0 0.0
	CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
	JOINT LeftUpLeg
	{
		OFFSET 1.0 -0.5 0.0
		CHANNELS 3 Zrotation Xrotation Yrotation
		JOINT LeftLeg
		{
			OFFSET 0.0 -4.0 0.0
			CHANNELS 3 Zrotation Xrotation Yrotation
			End Site
			{
				OFFSET 0.0 -4.0 0.25
			}
		}
	}
	JOINT Spine
	{
		OFFSET 0.0 1.0 0.0
		CHANNELS 3 Zrotation Xrotation Yrotation
	}
}
MOTION
Frames: 3
Frame Time: 0.0333333
0.0 9.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0
0.5 9.1 0.2 5.0 -3.5 1.25 10 20 30 -45.0 0.0 0.0 1e1 -2.5E-1 .5
1.0 9.2 0.4 -90 90 180 0 0 0 0 0 0 0 0 -0.0
)";

bool skip_without_data() {
    if (fs::is_directory(std::string(VOLRIG_SHARED_DATA) + "/bvh")) return false;
    WARN("shared test data not found at " << VOLRIG_SHARED_DATA << "/bvh: real-BVH tests skipped");
    return true;
}

}  // namespace

TEST_CASE("BVH: hierarchy, channels and motion are read as written", "[bvh]") {
    const BvhMotion m = bvh(kClip);
    REQUIRE(m.joints.size() == 4);
    CHECK(m.joints[0].name == "Hips");
    CHECK(m.joints[0].parent == -1);
    CHECK(m.joints[1].name == "LeftUpLeg");
    CHECK(m.joints[1].parent == 0);
    CHECK(m.joints[2].parent == 1);
    CHECK(m.joints[3].name == "Spine");
    CHECK(m.joints[3].parent == 0);
    CHECK(m.joints[1].offset == std::array<double, 3>{1.0, -0.5, 0.0});
    CHECK(m.joints[0].channels ==
          std::vector<C>{C::Xposition, C::Yposition, C::Zposition, C::Zrotation, C::Xrotation, C::Yrotation});
    CHECK(m.joints[2].channels == std::vector<C>{C::Zrotation, C::Xrotation, C::Yrotation});
    CHECK(m.joints[0].line == 2);
    CHECK(m.joints[3].line == 20);
    REQUIRE(m.end_sites.size() == 1);
    CHECK(m.end_sites[0].parent == 2);
    CHECK(m.end_sites[0].offset == std::array<double, 3>{0.0, -4.0, 0.25});
    CHECK(m.channel_count == 15);
    CHECK(m.frame_count == 3);
    CHECK(m.frame_time == 0.0333333);
    REQUIRE(m.frames.size() == 45);
    CHECK(m.frames[15 + 1] == 9.1);
    CHECK(m.frames[15 + 4] == -3.5);
    CHECK(m.frames[15 + 12] == 10.0);   // 1e1
    CHECK(m.frames[15 + 13] == -0.25);  // -2.5E-1
    CHECK(m.frames[15 + 14] == 0.5);    // .5
    CHECK(m.frames[30 + 5] == 180.0);
    CHECK(std::string(bvh_channel_name(C::Yrotation)) == "Yrotation");
}

TEST_CASE("BVH: layout variants (CRLF, braces inline, names with spaces, several roots, 0 channels, BOM)", "[bvh]") {
    const BvhMotion a = bvh(
        "\xEF\xBB\xBFhierarchy\r\nROOT Hips {\r\n  OFFSET 0 0 0 CHANNELS 6 Xposition Yposition Zposition Yrotation "
        "Xrotation Zrotation\r\n  JOINT Left Arm { OFFSET 1 0 0 CHANNELS 2 xrotation YROTATION End Site { OFFSET 1 0 "
        "0 } }\r\n  JOINT Right Arm{OFFSET -1 0 0 CHANNELS 0}\r\n}\r\nROOT Prop { OFFSET 5 0 0 CHANNELS 3 Xposition "
        "Yposition Zposition }\r\nmotion\r\nframes:1\r\nFRAME TIME :  0.5\r\n\r\n0 0 0 10 20 30 1 2 7 8 9\r\n\r\n");
    REQUIRE(a.joints.size() == 4);
    CHECK(a.joints[1].name == "Left Arm");
    CHECK(a.joints[1].channels == std::vector<C>{C::Xrotation, C::Yrotation});
    CHECK(a.joints[2].name == "Right Arm");
    CHECK(a.joints[2].channels.empty());
    CHECK(a.joints[3].parent == -1);
    CHECK(a.joints[3].offset[0] == 5.0);
    CHECK(a.channel_count == 11);
    CHECK(a.frame_time == 0.5);
    CHECK(a.frames.back() == 9.0);
    // The last frame may end the file without a newline; tabs separate numbers.
    const BvhMotion b = bvh("HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 1 Zrotation\n}\nMOTION\nFrames: 2\n"
                            "Frame Time: 1\n1\n\t2\t");
    CHECK(b.frames == std::vector<double>{1.0, 2.0});
}

TEST_CASE("BVH: malformed hierarchies give clear errors naming the line", "[bvh]") {
    expect_error("", {"empty file"});
    expect_error("MOTION\nFrames: 1\n", {"line 1", "not a BVH file", "'MOTION'"});
    expect_error(replace(kClip, "ROOT Hips", "ROOT"), {"line 2", "ROOT without a name"});
    expect_error(replace(kClip, "JOINT Spine", "JOINT LeftLeg"), {"line 20", "'LeftLeg'", "used twice", "line 10"});
    expect_error(replace(kClip, "CHANNELS 3 Zrotation Xrotation Yrotation\n\t\tJOINT",
                         "CHANNELS 3 Zrotation Xrotation\n\t\tJOINT"),
                 {"line 9", "'LeftUpLeg'", "declares 3 channels but names 2"});
    expect_error(replace(kClip, "CHANNELS 3 Zrotation Xrotation Yrotation\n\t\tJOINT",
                         "CHANNELS 2 Zrotation Xrotation Yrotation\n\t\tJOINT"),
                 {"line 9", "declares 2 channels but names more", "'Yrotation'"});
    expect_error(replace(kClip, "Zrotation Xrotation Yrotation\n\t\tJOINT", "Zrotation Wrotation Yrotation\n\t\tJOINT"),
                 {"line 9", "unknown channel 'Wrotation'", "Xposition"});
    expect_error(replace(kClip, "Zrotation Xrotation Yrotation\n\t\tJOINT", "Zrotation Zrotation Yrotation\n\t\tJOINT"),
                 {"line 9", "names Zrotation twice"});
    expect_error(replace(kClip, "CHANNELS 3 Zrotation Xrotation Yrotation\n\t\tJOINT", "CHANNELS 7\n\t\tJOINT"),
                 {"line 9", "declares 7 channels", "at most 6"});
    expect_error(replace(kClip, "CHANNELS 3 Zrotation Xrotation Yrotation\n\t\tJOINT", "CHANNELS x\n\t\tJOINT"),
                 {"line 9", "count 'x' is not a whole number"});
    expect_error(replace(kClip, "OFFSET 1.0 -0.5 0.0", "OFFSET 1.0 -0.5"), {"line 9", "OFFSET", "three numbers"});
    expect_error(replace(kClip, "OFFSET 1.0 -0.5 0.0", "OFFSET 1.0 -0.5 0.0 4"), {"line 8", "more than three"});
    expect_error(replace(kClip, "OFFSET 1.0 -0.5 0.0", "OFFSET 1.0 inf 0.0"), {"line 8", "'inf' is not finite"});
    expect_error(replace(kClip, "OFFSET 1.0 -0.5 0.0", "CHANNELS 0"), {"line 8", "expected OFFSET", "'CHANNELS'"});
    expect_error(replace(kClip, "\t\t\t\tOFFSET 0.0 -4.0 0.25\n", "\t\t\t\tOFFSET 0.0 -4.0 0.25 CHANNELS 1 Xrotation\n"),
                 {"line 16", "End Site", "'CHANNELS'", "only an OFFSET"});
    expect_error(replace(kClip, "End Site", "End Sight"), {"line 14", "expected 'End Site'"});
    expect_error(replace(kClip, "JOINT Spine\n\t{", "JOINT Spine\n"), {"line 22", "expected '{'", "'OFFSET'"});
    expect_error(replace(kClip, "\t}\n}\nMOTION", "\t}\nMOTION"), {"line 25", "MOTION in joint 'Hips'", "missing"});
    expect_error(replace(kClip, "}\nMOTION", "}\n}\nMOTION"), {"line 26", "'}' without a ROOT or JOINT"});
    expect_error(replace(kClip, "JOINT Spine", "Bone Spine"), {"line 20", "unexpected 'Bone'", "'Hips'"});
    expect_error("HIERARCHY\nMOTION\nFrames: 1\n", {"line 2", "MOTION before any ROOT"});
    expect_error(replace(kClip, "\nMOTION", "\nJOINT x { OFFSET 0 0 0 CHANNELS 0 }\nMOTION"),
                 {"line 26", "JOINT outside any ROOT"});
    expect_error(replace(kClip, "MOTION", "MOTION 3"), {"line 26", "unexpected '3' after MOTION"});
    expect_error(std::string("HIERARCHY\nROOT a\0b\n", 20), {"line 2", "binary data"});
    // Absurd joint counts stop at the limit, before the file is read further.
    std::string many = "HIERARCHY\nROOT r { OFFSET 0 0 0 CHANNELS 0\n";
    for (std::size_t i = 0; i < kBvhMaxJoints; ++i) many += "JOINT j" + std::to_string(i) + " { OFFSET 0 0 0 CHANNELS 0 }\n";
    expect_error(many, {"more than 10,000 joints"});
    expect_error("HIERARCHY\nROOT " + std::string(1001, 'n') + "\n", {"line 2", "longer than 1,000 bytes"});
}

TEST_CASE("BVH: malformed motion gives clear errors naming the line and frame", "[bvh]") {
    const std::string head = kClip.substr(0, kClip.find("Frames:"));
    const std::string row = "1 2 3 4 5 6 7 8 9 10 11 12 13 14 15\n";
    expect_error(head, {"ends after MOTION", "Frames"});
    expect_error(head + "Frame Time: 1\n", {"line 27", "expected 'Frames: <count>'"});
    expect_error(head + "Frames: three\n", {"line 27", "'three' is not a whole number"});
    expect_error(head + "Frames: -2\n", {"line 27", "'-2'"});
    expect_error(head + "Frames: 0\nFrame Time: 1\n", {"line 27", "Frames: 0", "no motion"});
    expect_error(head + "Frames: 1\n", {"ends before 'Frame Time:'"});
    expect_error(head + "Frames: 1\nFrame Time: 0\n" + row, {"line 28", "positive"});
    expect_error(head + "Frames: 1\nFrame Time: -0.01\n" + row, {"line 28", "positive"});
    expect_error(head + "Frames: 1\nFrame Time: nan\n" + row, {"line 28", "positive"});
    expect_error(head + "Frames: 1\nFrame Time: fast\n" + row, {"line 28", "'fast' is not a number"});
    expect_error(head + "Frames: 1\nTime: 1\n" + row, {"line 28", "expected 'Frame Time: <seconds>'"});
    // Rows: exact counts, numbers, finite.
    expect_error(head + "Frames: 2\nFrame Time: 1\n" + row + "100000000000 200000000000 300000000000\n",
                 {"line 30", "frame 1 has 3 numbers but the hierarchy has 15 channels"});
    expect_error(head + "Frames: 2\nFrame Time: 1\n" + row + "1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17\n",
                 {"line 30", "frame 1 has 17 numbers"});
    expect_error(head + "Frames: 1\nFrame Time: 1\n1 2 3 4 5 6 7 8 nine 10 11 12 13 14 15\n",
                 {"line 29", "frame 0, channel 8", "'LeftUpLeg' Yrotation", "'nine' is not a number"});
    expect_error(head + "Frames: 1\nFrame Time: 1\n1 2 3 4 5 6 7 8 9 10 11 12 13 14 1.5.2\n",
                 {"line 29", "channel 14 ('Spine' Yrotation)", "'1.5.2'"});
    expect_error(head + "Frames: 1\nFrame Time: 1\n1 2 3 4 5 6 7 8 9 10 11 12 13 14 1,5\n", {"'1,5'"});
    expect_error(head + "Frames: 1\nFrame Time: 1\n1 2 -inf 4 5 6 7 8 9 10 11 12 13 14 15\n",
                 {"line 29", "'Hips' Zposition", "'-inf' is not finite"});
    expect_error(head + "Frames: 1\nFrame Time: 1\n1 2 3 4 5 6 7 8 9 10 11 12 13 14 1e999\n", {"'1e999'"});
    expect_error(head + "Frames: 1\nFrame Time: 1\n" + row + row, {"line 30", "more motion rows than the 1 frames"});
    // Truncation and lying counts are found before any allocation: the bytes after the header must hold the rows.
    expect_error(head + "Frames: 3\nFrame Time: 1\n" + row + row, {"line 27", "need at least", "follow"});
    expect_error(head + "Frames: 999999999999999\nFrame Time: 1\n" + row,
                 {"line 27", "999,999,999,999,999 frames of 15 channels", "truncated, or a wrong frame count"});
    expect_error(head + "Frames: 99999999999999999999\nFrame Time: 1\n" + row, {"line 27", "not a whole number"});
    std::string rows;
    for (int i = 0; i < 3; ++i) rows += row;
    ReadOptions small;
    small.max_bytes = 200;  // 3 frames x 15 channels x 8 bytes = 360
    expect_error(head + "Frames: 3\nFrame Time: 1\n" + rows, {"line 27", "360 bytes, above the limit of 200"}, small);
    expect_error(head + "Frames: 3\nFrame Time: 1\n" + row + std::string(60, '\n'), {"ends after 1 of 3 frames"});
    // No channels at all: nothing to animate.
    expect_error("HIERARCHY\nROOT r { OFFSET 0 0 0 CHANNELS 0 }\nMOTION\nFrames: 1\nFrame Time: 1\n\n",
                 {"no channels"});
}

TEST_CASE("BVH: every truncation and random corruption reads or fails with a FileFormatError", "[bvh]") {
    for (std::size_t n = 0; n < kClip.size(); ++n) {
        INFO("first " << n << " bytes");
        try {
            const BvhMotion m = bvh(kClip.substr(0, n));
            // Cut inside the last number of the last row: still a valid file with another last value.
            CHECK(n >= kClip.find("1.0 9.2 0.4"));
            CHECK(m.frames.size() == 45);
        } catch (const FileFormatError& e) {
            CHECK(std::string(e.what()).rfind("clip.bvh: ", 0) == 0);
        }
    }
    std::mt19937 rng(6);
    int read = 0;
    for (int trial = 0; trial < 3000; ++trial) {
        std::string s = kClip;
        const int edits = 1 + static_cast<int>(rng() % 4);
        for (int e = 0; e < edits; ++e) {
            const std::size_t at = rng() % s.size();
            switch (rng() % 3) {
                case 0: s[at] = static_cast<char>(rng() % 256); break;
                case 1: s.erase(at, 1 + rng() % 8); break;
                default: s.insert(at, 1, " {}\n-.e9Z"[rng() % 10]); break;
            }
        }
        try {
            const BvhMotion m = bvh(s);
            ++read;
            CHECK(m.frames.size() == m.frame_count * m.channel_count);
            for (double v : m.frames) CHECK(std::isfinite(v));
        } catch (const FileFormatError&) {
        }
    }
    CHECK(read > 0);  // some edits (a digit changed, a blank added) leave a valid file
}

TEST_CASE("BVH fuzz corpus files never crash the reader", "[bvh][fuzz]") {
    const fs::path corpus = fs::path(VOLRIG_FUZZ_CORPUS) / "bvh";
    if (!fs::is_directory(corpus)) {
        WARN("no fuzz corpus at " << corpus << ": skipped");
        return;
    }
    int good = 0, bad = 0;
    for (const auto& e : fs::directory_iterator(corpus)) {
        const std::string name = e.path().filename().string();
        INFO(name);
        std::ifstream f(e.path(), std::ios::binary);
        const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
        try {
            bvh(text, name);
            CHECK(name.rfind("w_", 0) == 0);  // the well-formed seeds read
            ++good;
        } catch (const FileFormatError& err) {
            CHECK(name.rfind("bad_", 0) == 0);  // the broken ones fail, naming themselves
            CHECK(std::string(err.what()).rfind(name + ": ", 0) == 0);
            ++bad;
        }
    }
    CHECK(good >= 4);
    CHECK(bad >= 15);
}

TEST_CASE("Real: CMU subject 131 walk and hop", "[bvh][real]") {
    if (skip_without_data()) return;
    const std::string dir = std::string(VOLRIG_SHARED_DATA) + "/bvh/";
    const BvhMotion walk = read_bvh(dir + "131_01.bvh");
    CHECK(walk.joints.size() == 31);
    CHECK(walk.end_sites.size() == 7);
    CHECK(walk.channel_count == 6 + 30 * 3);
    CHECK(walk.frame_count == 994);
    CHECK(walk.frame_time == Approx(1.0 / 120).epsilon(1e-4));
    CHECK(walk.joints[0].name == "Hips");
    CHECK(walk.joints[3].name == "LeftKnee");
    CHECK(walk.joints[3].offset[1] == -6.85026);
    CHECK(walk.frames[0] == 5.23);           // first row: 5.2300 16.9002 -33.8986 ...
    CHECK(walk.frames[2] == -33.8986);
    const BvhMotion hop = read_bvh(dir + "131_03.bvh");
    CHECK(hop.joints.size() == 31);
    CHECK(hop.frame_count == 1102);
    CHECK(hop.frames.size() == 1102 * 96);
}

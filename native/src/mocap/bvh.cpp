// mocap/bvh.cpp: the BVH reader of volrig/mocap.hpp.
//
// The hierarchy is read as a stream of words (braces are words of their own, wherever they stand) with the line
// of each, the motion line by line (one frame per line). The file is read through a LineReader in chunks, never
// whole. Nothing is allocated for the motion before the declared frame count has been checked against the bytes
// that follow the header and against ReadOptions::max_bytes.
#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "io/io_detail.hpp"
#include "volrig/mocap.hpp"

namespace volrig {

namespace {

using io_detail::at_line;
using io_detail::fail;
using io_detail::quoted;
using io_detail::with_commas;

constexpr std::size_t kMaxNameBytes = 1000;
constexpr std::size_t kMaxChannelsPerJoint = 6;

constexpr BvhChannel kChannels[] = {BvhChannel::Xposition, BvhChannel::Yposition, BvhChannel::Zposition,
                                    BvhChannel::Xrotation, BvhChannel::Yrotation, BvhChannel::Zrotation};

bool channel_of(std::string_view s, BvhChannel& c) {
    for (BvhChannel k : kChannels)
        if (io_detail::iequals(s, bvh_channel_name(k))) {
            c = k;
            return true;
        }
    return false;
}

/// Words of a line: runs of non-blank characters, with '{' and '}' always words of their own.
void split_hierarchy_words(std::string_view line, std::vector<std::string_view>& out) {
    out.clear();
    std::size_t i = 0;
    auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; };
    auto brace = [](char c) { return c == '{' || c == '}'; };
    while (i < line.size()) {
        if (blank(line[i])) {
            ++i;
        } else if (brace(line[i])) {
            out.push_back(line.substr(i++, 1));
        } else {
            std::size_t j = i;
            while (j < line.size() && !blank(line[j]) && !brace(line[j])) ++j;
            out.push_back(line.substr(i, j - i));
            i = j;
        }
    }
}

/// Strips a case-insensitive keyword (and a ':' after it) from the front of a MOTION header line; false when the
/// line does not start with it.
bool header_value(std::string_view line, std::string_view keyword, std::string_view& value) {
    std::string_view s = io_detail::trim(line);
    if (s.size() < keyword.size() || !io_detail::iequals(s.substr(0, keyword.size()), keyword)) return false;
    s = io_detail::trim(s.substr(keyword.size()));
    if (s.empty() || s[0] != ':') return false;
    value = io_detail::trim(s.substr(1));
    return true;
}

class BvhReader {
public:
    BvhReader(const ByteSource& src, const ReadOptions& opt) : name_(src.name()), opt_(opt), lines_(src) {}

    BvhMotion read() {
        read_hierarchy();
        read_motion_header();
        read_frames();
        return std::move(m_);
    }

private:
    // ---- words of the hierarchy ------------------------------------------------------------------------------

    /// Loads the next line holding words; false at the end of the file.
    bool load_line() {
        std::string_view line;
        while (lines_.next(line)) {
            io_detail::refuse_binary(name_, lines_.line_number(), line, "BVH");
            if (lines_.line_number() == 1 && line.substr(0, 3) == "\xEF\xBB\xBF") line.remove_prefix(3);  // BOM
            split_hierarchy_words(line, words_);
            at_ = 0;
            if (!words_.empty()) return true;
        }
        words_.clear();
        at_ = 0;
        return false;
    }
    /// The next word without consuming it; false at the end of the file.
    bool peek(std::string_view& w) {
        if (at_ == words_.size() && !load_line()) return false;
        w = words_[at_];
        return true;
    }
    bool next(std::string_view& w) {
        if (!peek(w)) return false;
        ++at_;
        return true;
    }
    /// The next word, failing with "the file ends <where> (truncated?)" at the end of the file.
    std::string_view need(const std::string& where) {
        std::string_view w;
        if (!next(w)) fail(name_, "the file ends " + where + " (truncated?)");
        return w;
    }
    std::string here() const { return at_line(lines_.line_number()); }
    /// "joint 'LeftKnee' (line 17)".
    std::string joint_label(std::int32_t j) const {
        const BvhJoint& b = m_.joints[static_cast<std::size_t>(j)];
        return "joint " + quoted(b.name) + " (line " + std::to_string(b.line) + ")";
    }

    // ---- hierarchy -------------------------------------------------------------------------------------------

    void read_hierarchy() {
        std::string_view w;
        if (!next(w)) fail(name_, "empty file: not a BVH file");
        if (!io_detail::iequals(w, "HIERARCHY"))
            fail(name_, here() + "not a BVH file: it starts with " + quoted(w) + ", not HIERARCHY");
        std::vector<std::int32_t> open;  // joints whose '}' has not been read yet
        for (;;) {
            if (!next(w)) {
                if (!open.empty())
                    fail(name_, "the file ends inside " + joint_label(open.back()) + " (truncated?)");
                fail(name_, "the file ends before MOTION (truncated?)");
            }
            const std::string inside = open.empty() ? std::string() : " in " + joint_label(open.back());
            if (io_detail::iequals(w, "ROOT")) {
                if (!open.empty()) fail(name_, here() + "ROOT" + inside + " (a '}' is missing before it)");
                open.push_back(read_joint("ROOT", -1));
            } else if (io_detail::iequals(w, "JOINT")) {
                if (open.empty()) fail(name_, here() + "JOINT outside any ROOT");
                open.push_back(read_joint("JOINT", open.back()));
            } else if (io_detail::iequals(w, "End")) {
                if (open.empty()) fail(name_, here() + "End Site outside any ROOT");
                read_end_site(open.back());
            } else if (w == "}") {
                if (open.empty()) fail(name_, here() + "'}' without a ROOT or JOINT to close");
                open.pop_back();
            } else if (io_detail::iequals(w, "MOTION")) {
                if (!open.empty()) fail(name_, here() + "MOTION" + inside + " (its '}' is missing)");
                if (m_.joints.empty()) fail(name_, here() + "MOTION before any ROOT: the hierarchy is empty");
                if (at_ != words_.size())
                    fail(name_, here() + "unexpected " + quoted(words_[at_]) + " after MOTION");
                return;
            } else {
                fail(name_, here() + "unexpected " + quoted(w) +
                                (open.empty() ? " (expected ROOT or MOTION)"
                                              : inside + " (expected JOINT, End Site or '}')"));
            }
        }
    }

    /// After ROOT/JOINT: the name (the rest of the line up to a '{'), '{', OFFSET and CHANNELS. Returns the index.
    std::int32_t read_joint(const char* keyword, std::int32_t parent) {
        const std::int64_t line = lines_.line_number();
        std::string joint_name;
        while (at_ < words_.size() && words_[at_] != "{" && words_[at_] != "}") {
            if (!joint_name.empty()) joint_name += ' ';
            joint_name.append(words_[at_++]);
            if (joint_name.size() > kMaxNameBytes)
                fail(name_, here() + keyword + " name is longer than " + with_commas(kMaxNameBytes) + " bytes");
        }
        if (joint_name.empty()) fail(name_, here() + keyword + " without a name");
        if (m_.joints.size() >= kBvhMaxJoints)
            fail(name_, here() + "more than " + with_commas(kBvhMaxJoints) + " joints");
        const auto [it, fresh] = seen_.emplace(joint_name, line);
        if (!fresh)
            fail(name_, here() + "joint name " + quoted(joint_name) + " is used twice (first on line " +
                            std::to_string(it->second) + ")");
        BvhJoint j;
        j.name = std::move(joint_name);
        j.parent = parent;
        j.line = line;
        const std::string what = std::string(keyword) + " " + quoted(j.name);
        const std::string_view brace = need("after " + what);
        if (brace != "{") fail(name_, here() + "expected '{' after " + what + ", got " + quoted(brace));
        expect_keyword("OFFSET", what);
        j.offset = read_offset(what);
        expect_keyword("CHANNELS", what);
        j.channels = read_channels(what);
        m_.channel_count += j.channels.size();
        m_.joints.push_back(std::move(j));
        return static_cast<std::int32_t>(m_.joints.size() - 1);
    }

    void read_end_site(std::int32_t parent) {
        const std::string_view site = need("after End");
        if (!io_detail::iequals(site, "Site")) fail(name_, here() + "expected 'End Site', got 'End " + std::string(site) + "'");
        const std::string what = "End Site of " + joint_label(parent);
        const std::string_view brace = need("after End Site");
        if (brace != "{") fail(name_, here() + "expected '{' after End Site, got " + quoted(brace));
        expect_keyword("OFFSET", what);
        BvhEndSite e;
        e.parent = parent;
        e.offset = read_offset(what);
        const std::string_view close = need("inside the " + what);
        if (close != "}")
            fail(name_, here() + "unexpected " + quoted(close) + " in the " + what + " (it holds only an OFFSET)");
        m_.end_sites.push_back(e);
    }

    void expect_keyword(const char* keyword, const std::string& what) {
        const std::string_view w = need("in " + what + " before its " + keyword);
        if (!io_detail::iequals(w, keyword))
            fail(name_, here() + "expected " + keyword + " in " + what + ", got " + quoted(w));
    }

    std::array<double, 3> read_offset(const std::string& what) {
        std::array<double, 3> p{};
        for (int a = 0; a < 3; ++a) {
            const std::string_view w = need("in the OFFSET of " + what);
            double& v = p[static_cast<std::size_t>(a)];
            if (!io_detail::parse_double(w, v))
                fail(name_, here() + "OFFSET of " + what + " needs three numbers: " + std::string(1, "xyz"[a]) + " " +
                                quoted(w) + " is not a number");
            if (!std::isfinite(v))
                fail(name_, here() + "OFFSET of " + what + ": " + std::string(1, "xyz"[a]) + " " + quoted(w) +
                                " is not finite");
        }
        std::string_view w;
        double extra = 0;
        if (peek(w) && io_detail::parse_double(w, extra))
            fail(name_, here() + "OFFSET of " + what + " has more than three numbers (" + quoted(w) + ")");
        return p;
    }

    std::vector<BvhChannel> read_channels(const std::string& what) {
        const std::string_view w = need("in the CHANNELS of " + what);
        const std::string count_line = here();  // count mismatches are reported on the CHANNELS line
        std::int64_t n = 0;
        if (!io_detail::parse_int(w, n) || n < 0)
            fail(name_, here() + "CHANNELS of " + what + ": the count " + quoted(w) + " is not a whole number");
        if (n > static_cast<std::int64_t>(kMaxChannelsPerJoint))
            fail(name_, here() + "CHANNELS of " + what + " declares " + std::to_string(n) +
                            " channels (a joint has at most 6: X/Y/Z position and rotation)");
        std::vector<BvhChannel> out;
        for (std::int64_t k = 0; k < n; ++k) {
            std::string_view c;
            if (!peek(c)) fail(name_, "the file ends in the CHANNELS of " + what + " (truncated?)");
            BvhChannel ch{};
            if (!channel_of(c, ch)) {
                if (c == "{" || c == "}" || io_detail::iequals(c, "JOINT") || io_detail::iequals(c, "End") ||
                    io_detail::iequals(c, "MOTION"))
                    fail(name_, count_line + "CHANNELS of " + what + " declares " + std::to_string(n) +
                                    " channels but names " + std::to_string(k));
                fail(name_, here() + "CHANNELS of " + what + ": unknown channel " + quoted(c) +
                                " (known: Xposition Yposition Zposition Xrotation Yrotation Zrotation)");
            }
            for (BvhChannel o : out)
                if (o == ch)
                    fail(name_, here() + "CHANNELS of " + what + " names " + bvh_channel_name(ch) + " twice");
            out.push_back(ch);
            ++at_;
        }
        std::string_view c;
        BvhChannel extra{};
        if (peek(c) && channel_of(c, extra))
            fail(name_, count_line + "CHANNELS of " + what + " declares " + std::to_string(n) +
                            " channels but names more (" + quoted(c) + ")");
        return out;
    }

    // ---- motion ----------------------------------------------------------------------------------------------

    /// The next non-blank line of the motion; false at the end of the file.
    bool motion_line(std::string_view& line) {
        while (lines_.next(line)) {
            io_detail::refuse_binary(name_, lines_.line_number(), line, "BVH");
            if (!io_detail::trim(line).empty()) return true;
        }
        return false;
    }

    void read_motion_header() {
        std::string_view line, value;
        if (!motion_line(line)) fail(name_, "the file ends after MOTION: no 'Frames:' line (truncated?)");
        if (!header_value(line, "Frames", value))
            fail(name_, here() + "expected 'Frames: <count>' after MOTION, got " + quoted(io_detail::trim(line)));
        std::int64_t frames = 0;
        if (!io_detail::parse_int(value, frames) || frames < 0)
            fail(name_, here() + "Frames: " + quoted(value) + " is not a whole number");
        if (frames == 0) fail(name_, here() + "Frames: 0 (the file holds no motion)");
        const std::int64_t frames_line = lines_.line_number();

        if (!motion_line(line)) fail(name_, "the file ends before 'Frame Time:' (truncated?)");
        if (!header_value(line, "Frame Time", value))
            fail(name_, here() + "expected 'Frame Time: <seconds>' after Frames, got " + quoted(io_detail::trim(line)));
        double t = 0;
        if (!io_detail::parse_double(value, t)) fail(name_, here() + "Frame Time: " + quoted(value) + " is not a number");
        if (!std::isfinite(t) || t <= 0)
            fail(name_, here() + "Frame Time: " + quoted(value) + " must be a positive number of seconds");
        m_.frame_time = t;

        // Each number takes at least two bytes (a digit and a separator; the last one may end the file).
        const std::uint64_t c = m_.channel_count;
        if (c == 0) fail(name_, at_line(frames_line) + "the hierarchy has no channels: nothing moves");
        const auto f = static_cast<std::uint64_t>(frames);
        const std::uint64_t have = lines_.remaining();
        const long double numbers = static_cast<long double>(f) * static_cast<long double>(c);
        if (f > (have + 1) / 2 / c)
            fail(name_, at_line(frames_line) + "Frames: " + with_commas(f) + " frames of " + with_commas(c) +
                            " channels need at least " +
                            with_commas(static_cast<std::uint64_t>(std::min(2 * numbers - 1, 1.8e19L))) +
                            " bytes but only " + with_commas(have) + " follow (truncated, or a wrong frame count)");
        const long double bytes = numbers * sizeof(double);
        if (bytes > static_cast<long double>(opt_.max_bytes))
            fail(name_, at_line(frames_line) + with_commas(f) + " frames of " + with_commas(c) + " channels take " +
                            with_commas(static_cast<std::uint64_t>(bytes)) + " bytes, above the limit of " +
                            with_commas(opt_.max_bytes) + " bytes (raise max_bytes if this is intended)");
        m_.frame_count = f;
    }

    /// "LeftKnee Zrotation" for a column of a frame row.
    std::string channel_label(std::uint64_t column) const {
        for (const BvhJoint& j : m_.joints) {
            if (column < j.channels.size())
                return quoted(j.name) + " " + bvh_channel_name(j.channels[static_cast<std::size_t>(column)]);
            column -= j.channels.size();
        }
        return "?";
    }

    void read_frames() {
        const std::uint64_t c = m_.channel_count, f_count = m_.frame_count;
        m_.frames.resize(static_cast<std::size_t>(f_count * c));
        double* out = m_.frames.data();
        std::string_view line;
        for (std::uint64_t f = 0; f < f_count; ++f) {
            if (!motion_line(line))
                fail(name_, "the file ends after " + with_commas(f) + " of " + with_commas(f_count) +
                                " frames (truncated?)");
            std::uint64_t k = 0;
            std::size_t i = 0;
            for (;;) {
                while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
                if (i == line.size()) break;
                std::size_t j = i;
                while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
                const std::string_view tok = line.substr(i, j - i);
                i = j;
                if (k >= c) {  // too many: only counted, for the message below
                    ++k;
                    continue;
                }
                double v = 0;
                if (!io_detail::parse_double(tok, v))
                    fail(name_, here() + "frame " + with_commas(f) + ", channel " + std::to_string(k) + " (" +
                                    channel_label(k) + "): " + quoted(tok) + " is not a number");
                if (!std::isfinite(v))
                    fail(name_, here() + "frame " + with_commas(f) + ", channel " + std::to_string(k) + " (" +
                                    channel_label(k) + "): " + quoted(tok) + " is not finite");
                out[k++] = v;
            }
            if (k != c)
                fail(name_, here() + "frame " + with_commas(f) + " has " + with_commas(k) + " numbers but the "
                                "hierarchy has " + with_commas(c) + " channels");
            out += c;
        }
        if (motion_line(line))
            fail(name_, here() + "more motion rows than the " + with_commas(f_count) + " frames 'Frames:' declares (" +
                            quoted(io_detail::trim(line)) + ")");
    }

    const std::string& name_;
    const ReadOptions& opt_;
    io_detail::LineReader lines_;
    std::vector<std::string_view> words_;  // words of the current hierarchy line
    std::size_t at_ = 0;                   // next unread word
    std::unordered_map<std::string, std::int64_t> seen_;  // joint name -> line
    BvhMotion m_;
};

}  // namespace

const char* bvh_channel_name(BvhChannel c) {
    switch (c) {
        case BvhChannel::Xposition: return "Xposition";
        case BvhChannel::Yposition: return "Yposition";
        case BvhChannel::Zposition: return "Zposition";
        case BvhChannel::Xrotation: return "Xrotation";
        case BvhChannel::Yrotation: return "Yrotation";
        case BvhChannel::Zrotation: return "Zrotation";
    }
    return "?";
}

BvhMotion read_bvh(const ByteSource& src, const ReadOptions& opt) { return BvhReader(src, opt).read(); }

BvhMotion read_bvh(const std::string& path, const ReadOptions& opt) {
    const auto src = open_file(path);
    return read_bvh(*src, opt);
}

}  // namespace volrig

// io/io_detail.cpp: the text helpers shared by the file readers and writers (io/io_detail.hpp): messages, tokens and
// numbers, and the LineReader of the line-based formats.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstring>
#include <system_error>

#include "io/io_detail.hpp"

namespace volrig::io_detail {

void fail(const std::string& name, const std::string& what) { throw FileFormatError(name + ": " + what); }

std::string with_commas(std::uint64_t n) {
    std::string digits = std::to_string(n), out;
    out.reserve(digits.size() + digits.size() / 3);
    for (std::size_t i = 0; i < digits.size(); ++i) {
        if (i && (digits.size() - i) % 3 == 0) out += ',';
        out += digits[i];
    }
    return out;
}

std::string quoted(std::string_view s) {
    constexpr std::size_t kMax = 60;
    std::string out = "'";
    for (std::size_t i = 0; i < s.size() && i < kMax; ++i) {
        const auto c = static_cast<unsigned char>(s[i]);
        out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
    }
    if (s.size() > kMax) out += "...";
    return out + "'";
}

std::string describe(const std::array<std::int64_t, 3>& dims, DType t) {
    return std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" + std::to_string(dims[2]) + " " +
           dtype_name(t);
}

std::string_view trim(std::string_view s) {
    const char* ws = " \t\r\n\v\f";
    const auto b = s.find_first_not_of(ws);
    if (b == std::string_view::npos) return {};
    const auto e = s.find_last_not_of(ws);
    return s.substr(b, e - b + 1);
}

std::string lower(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

bool iequals(std::string_view a, std::string_view b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i])))
            return false;
    return true;
}

std::vector<std::string_view> split_words(std::string_view s, bool commas) {
    std::vector<std::string_view> out;
    std::size_t i = 0;
    auto sep = [&](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || (commas && c == ','); };
    while (i < s.size()) {
        while (i < s.size() && sep(s[i])) ++i;
        std::size_t j = i;
        while (j < s.size() && !sep(s[j])) ++j;
        if (j > i) out.push_back(s.substr(i, j - i));
        i = j;
    }
    return out;
}

std::string errno_text(int e) { return std::system_category().message(e); }

std::string at_line(std::int64_t line) { return "line " + std::to_string(line) + ": "; }

void refuse_binary(const std::string& name, std::int64_t line_no, std::string_view line, const char* format) {
    if (line.find('\0') != std::string_view::npos)
        fail(name, at_line(line_no) + "binary data (a NUL byte) where " + format + " text was expected");
}

bool LineReader::next(std::string_view& line) {
    std::size_t scan = pos_;
    for (;;) {
        const void* nl = std::memchr(buf_.data() + scan, '\n', buf_.size() - scan);
        if (nl) {
            const auto end = static_cast<std::size_t>(static_cast<const char*>(nl) - buf_.data());
            return take(line, end, end + 1);
        }
        if (buf_.size() - pos_ > kMaxLine)
            fail(src_.name(), at_line(line_ + 1) + "line is longer than " + with_commas(kMaxLine) + " bytes");
        if (base_ + buf_.size() >= size_) {  // the last line has no newline
            if (pos_ == buf_.size()) return false;
            return take(line, buf_.size(), buf_.size());
        }
        // Keep the unfinished line, read the next chunk after it.
        buf_.erase(0, pos_);
        base_ += pos_;
        pos_ = 0;
        scan = buf_.size();
        const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(kTextChunk, size_ - base_ - buf_.size()));
        buf_.resize(scan + n);
        src_.read(base_ + scan, &buf_[scan], n);
    }
}

bool LineReader::take(std::string_view& line, std::size_t end, std::size_t next) {
    line = std::string_view(buf_.data() + pos_, end - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos_ = next;
    ++line_;
    return true;
}

bool parse_int(std::string_view s, std::int64_t& out) {
    s = trim(s);
    if (!s.empty() && s[0] == '+') s.remove_prefix(1);
    if (s.empty()) return false;
    auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
    return ec == std::errc() && end == s.data() + s.size();
}

bool parse_double(std::string_view s, double& out) {
    s = trim(s);
    if (!s.empty() && s[0] == '+') s.remove_prefix(1);
    if (s.empty()) return false;
    auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
    return ec == std::errc() && end == s.data() + s.size();
}

std::string format_double(double v) {
    char buf[64];
    auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
    if (ec != std::errc()) return "nan";
    return std::string(buf, end);
}

}  // namespace volrig::io_detail

// io.cpp: byte sources, raw voxels, format dispatch, atomic writes and the helpers the format readers share.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <system_error>
#include <type_traits>

#include "inflate.hpp"
#include "io_detail.hpp"
#include "volrig/io.hpp"

namespace volrig {

namespace {

std::string errno_text(int e) { return std::system_category().message(e); }

constexpr std::uint64_t kDefaultMaxBytes = std::uint64_t(16) << 30;

class FileSource final : public ByteSource {
public:
    explicit FileSource(std::string path) : path_(std::move(path)) {
        if (path_.empty()) throw FileNotFound("(empty path): no such file");
        fd_ = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
        if (fd_ < 0) {
            const int e = errno;
            if (e == ENOENT || e == ENOTDIR) throw FileNotFound(path_ + ": no such file");
            throw FileNotFound(path_ + ": cannot open: " + errno_text(e));
        }
        struct stat st {};
        if (::fstat(fd_, &st) != 0) {
            const int e = errno;
            ::close(fd_);
            throw FileNotFound(path_ + ": cannot open: " + errno_text(e));
        }
        if (S_ISDIR(st.st_mode)) {
            ::close(fd_);
            throw FileNotFound(path_ + ": is a directory, not a file");
        }
        if (!S_ISREG(st.st_mode)) {
            ::close(fd_);
            throw FileFormatError(path_ + ": not a regular file");
        }
        size_ = static_cast<std::uint64_t>(st.st_size);
    }
    ~FileSource() override {
        if (fd_ >= 0) ::close(fd_);
    }
    FileSource(const FileSource&) = delete;
    FileSource& operator=(const FileSource&) = delete;

    std::uint64_t size() const override { return size_; }
    const std::string& name() const override { return path_; }

    void read(std::uint64_t offset, void* dst, std::size_t n) const override {
        if (offset > size_ || n > size_ - offset)
            detail::fail(path_, "expected " + detail::with_commas(n) + " bytes at offset " +
                                    detail::with_commas(offset) + " but the file holds " +
                                    detail::with_commas(size_) + " bytes");
        auto* p = static_cast<char*>(dst);
        while (n > 0) {
            const std::size_t step = std::min<std::size_t>(n, std::size_t(1) << 30);
            const ssize_t r = ::pread(fd_, p, step, static_cast<off_t>(offset));
            if (r < 0) {
                if (errno == EINTR) continue;
                detail::fail(path_, "read error: " + errno_text(errno));
            }
            if (r == 0) detail::fail(path_, "the file became shorter while it was being read");
            p += r;
            offset += static_cast<std::uint64_t>(r);
            n -= static_cast<std::size_t>(r);
        }
    }

    std::unique_ptr<ByteSource> open_sibling(const std::string& relative_name) const override {
        if (relative_name.empty()) detail::fail(path_, "the data file name is empty");
        for (unsigned char c : relative_name)
            if (c < 0x20 || c == 0x7f)
                detail::fail(path_, "data file name " + detail::quoted(relative_name) + " contains control characters");
        std::filesystem::path p(relative_name);
        if (!p.is_absolute()) p = std::filesystem::path(path_).parent_path() / p;
        try {
            return std::make_unique<FileSource>(p.string());
        } catch (const FileNotFound& e) {
            throw FileNotFound(path_ + ": data file " + detail::quoted(relative_name) + " cannot be opened (" +
                               e.what() + ")");
        }
    }

private:
    std::string path_;
    int fd_ = -1;
    std::uint64_t size_ = 0;
};

class MemorySource final : public ByteSource {
public:
    MemorySource(const std::uint8_t* data, std::size_t n, std::string name)
        : bytes_(data, data + (data ? n : 0)), name_(std::move(name)) {}
    std::uint64_t size() const override { return bytes_.size(); }
    const std::string& name() const override { return name_; }
    void read(std::uint64_t offset, void* dst, std::size_t n) const override {
        if (offset > bytes_.size() || n > bytes_.size() - offset)
            detail::fail(name_, "expected " + detail::with_commas(n) + " bytes at offset " +
                                    detail::with_commas(offset) + " but the data holds " +
                                    detail::with_commas(bytes_.size()) + " bytes");
        if (n) std::memcpy(dst, bytes_.data() + offset, n);
    }
    std::unique_ptr<ByteSource> open_sibling(const std::string&) const override {
        detail::fail(name_, "detached data files are not available for in-memory input");
    }

private:
    std::vector<std::uint8_t> bytes_;
    std::string name_;
};

}  // namespace

std::uint64_t default_max_bytes() {
    const char* env = std::getenv("VOLRIG_MAX_BYTES");
    if (!env || !*env) return kDefaultMaxBytes;
    // Digits with an optional binary suffix K, M, G or T; anything else falls back to the default.
    std::string_view s = detail::trim(env);
    std::uint64_t value = 0;
    auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
    if (ec != std::errc() || end == s.data()) return kDefaultMaxBytes;
    std::string_view rest = detail::trim(std::string_view(end, static_cast<std::size_t>(s.data() + s.size() - end)));
    int shift = 0;
    if (!rest.empty()) {
        const char c = static_cast<char>(std::toupper(static_cast<unsigned char>(rest[0])));
        shift = c == 'K' ? 10 : c == 'M' ? 20 : c == 'G' ? 30 : c == 'T' ? 40 : -1;
        if (shift < 0 || !(rest.size() == 1 || detail::iequals(rest.substr(1), "B") || detail::iequals(rest.substr(1), "iB")))
            return kDefaultMaxBytes;
    }
    if (shift && value > (std::numeric_limits<std::uint64_t>::max() >> shift)) return kDefaultMaxBytes;
    return value << shift;
}

std::unique_ptr<ByteSource> open_file(const std::string& path) { return std::make_unique<FileSource>(path); }

std::unique_ptr<ByteSource> memory_source(const std::uint8_t* data, std::size_t n, std::string name) {
    return std::make_unique<MemorySource>(data, n, std::move(name));
}

Volume read_raw(const ByteSource& src, const RawLayout& layout, const ReadOptions& opt) {
    Grid g;
    g.dims = layout.dims;
    g.spacing = layout.spacing;
    g.origin = layout.origin;
    detail::check_volume(src.name(), g, layout.dtype, opt.max_bytes);
    detail::DataLocation loc;
    loc.src = &src;
    loc.header = src.name();
    loc.offset = layout.offset;
    loc.claimant = "the layout";
    return detail::read_raw_voxels(loc, g, layout.dtype, layout.big_endian);
}

Volume read_volume(const std::string& path, const ReadOptions& opt) {
    const std::string low = detail::lower(path);
    auto ends = [&](const char* e) {
        const std::size_t n = std::strlen(e);
        return low.size() >= n && low.compare(low.size() - n, n, e) == 0;
    };
    if (ends(".vdb")) return read_vdb(path, "", opt);
    enum class Kind { Nrrd, Meta, Nifti } kind;
    if (ends(".nrrd") || ends(".nhdr"))
        kind = Kind::Nrrd;
    else if (ends(".mhd") || ends(".mha"))
        kind = Kind::Meta;
    else if (ends(".nii") || ends(".nii.gz") || ends(".hdr"))
        kind = Kind::Nifti;
    else
        throw FileFormatError(path + ": unknown volume format (known endings: .nrrd .nhdr .mhd .mha .nii .nii.gz "
                                     ".hdr .vdb; raw files need read_raw)");
    auto src = open_file(path);
    switch (kind) {
        case Kind::Nrrd: return read_nrrd(*src, opt);
        case Kind::Meta: return read_metaimage(*src, opt);
        case Kind::Nifti: break;
    }
    return read_nifti(*src, opt);
}

void write_atomically(const std::string& path, const std::function<void(const std::string& tmp_path)>& write) {
    static std::atomic<unsigned long> counter{0};
    if (path.empty()) throw Error("cannot write to an empty path");
    const std::string tmp =
        path + ".tmp-" + std::to_string(static_cast<long>(::getpid())) + "-" + std::to_string(++counter);
    try {
        write(tmp);
    } catch (...) {
        std::remove(tmp.c_str());
        throw;
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const int e = errno;
        std::remove(tmp.c_str());
        throw Error(path + ": cannot move the written file into place: " + errno_text(e));
    }
}

// ---- shared reader/writer internals --------------------------------------------------------------------------

namespace detail {

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

std::uint64_t check_volume(const std::string& name, const Grid& g, DType t, std::uint64_t max_bytes) {
    try {
        check_grid(g, dtype_size(t), max_bytes, name);
    } catch (const FileFormatError&) {
        throw;
    } catch (const Error& e) {
        throw FileFormatError(e.what());
    }
    return static_cast<std::uint64_t>(g.voxel_count()) * dtype_size(t);
}

Volume allocate(const Grid& g, DType t) {
    Volume v;
    v.grid = g;
    v.dtype = t;
    v.data.resize(static_cast<std::size_t>(g.voxel_count()) * dtype_size(t));
    return v;
}

bool host_is_big_endian() {
    const std::uint16_t one = 1;
    std::uint8_t first = 0;
    std::memcpy(&first, &one, 1);
    return first == 0;
}

namespace {
template <class U, U (*Swap)(U)>
void swap_all(std::uint8_t* p, std::size_t count) {
    for (std::size_t i = 0; i < count; ++i, p += sizeof(U)) {
        U x;
        std::memcpy(&x, p, sizeof(U));
        x = Swap(x);
        std::memcpy(p, &x, sizeof(U));
    }
}
std::uint16_t bswap16(std::uint16_t x) { return __builtin_bswap16(x); }
std::uint32_t bswap32(std::uint32_t x) { return __builtin_bswap32(x); }
std::uint64_t bswap64(std::uint64_t x) { return __builtin_bswap64(x); }
}  // namespace

void swap_bytes(void* data, std::size_t count, std::size_t esize) {
    auto* p = static_cast<std::uint8_t*>(data);
    switch (esize) {
        case 1: return;
        case 2: return swap_all<std::uint16_t, bswap16>(p, count);
        case 4: return swap_all<std::uint32_t, bswap32>(p, count);
        case 8: return swap_all<std::uint64_t, bswap64>(p, count);
        default: throw Error("swap_bytes: unsupported element size");
    }
}

std::string data_subject(const DataLocation& loc) {
    return loc.detached ? loc.header + " (data file " + loc.src->name() + ")" : loc.header;
}

Volume read_raw_voxels(const DataLocation& loc, const Grid& g, DType t, bool big_endian) {
    const std::uint64_t need = static_cast<std::uint64_t>(g.voxel_count()) * dtype_size(t);
    const std::uint64_t size = loc.src->size();
    const std::uint64_t have = loc.offset <= size ? size - loc.offset : 0;
    if (need > have) {
        std::string where = loc.detached ? "data file " + loc.src->name() : std::string("the file");
        std::string msg = std::string(loc.claimant) + " says " + describe(g.dims, t) + " = " + with_commas(need) +
                          " bytes but " + where + " holds " + with_commas(have);
        if (loc.offset > size)
            msg += " (data offset " + with_commas(loc.offset) + " is past its end of " + with_commas(size) +
                   " bytes)";
        fail(loc.header, msg);
    }
    Volume v = allocate(g, t);
    loc.src->read(loc.offset, v.data.data(), v.data.size());
    if (big_endian != host_is_big_endian()) swap_bytes(v.data.data(), v.data.size() / dtype_size(t), dtype_size(t));
    return v;
}

Volume read_compressed_voxels(const DataLocation& loc, std::uint64_t compressed, std::uint64_t skip, const Grid& g,
                              DType t, bool big_endian) {
    const std::uint64_t need = static_cast<std::uint64_t>(g.voxel_count()) * dtype_size(t);
    const std::uint64_t size = loc.src->size();
    const std::string subject = data_subject(loc);
    if (loc.offset > size || compressed > size - loc.offset)
        fail(subject, "header declares " + with_commas(compressed) + " compressed bytes but the file holds " +
                          with_commas(loc.offset > size ? 0 : size - loc.offset));
    const std::uint64_t total = need + skip < need ? std::numeric_limits<std::uint64_t>::max() : need + skip;
    check_inflate_bound(subject, total, compressed);
    Volume v = allocate(g, t);
    Inflater inf(*loc.src, loc.offset, compressed, subject, total);
    inf.skip(skip);
    inf.read(v.data.data(), v.data.size());
    inf.finish();
    if (big_endian != host_is_big_endian()) swap_bytes(v.data.data(), v.data.size() / dtype_size(t), dtype_size(t));
    return v;
}

// ---- text voxels ---------------------------------------------------------------------------------------------

namespace {

bool is_text_separator(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f' || c == ',';
}

template <class T>
bool parse_text_value(std::string_view tok, T& out) {
    if (!tok.empty() && tok[0] == '+') tok.remove_prefix(1);
    if (tok.empty()) return false;
    const char* b = tok.data();
    const char* e = tok.data() + tok.size();
    if constexpr (std::is_integral_v<T>) {
        using Wide = std::conditional_t<std::is_signed_v<T>, std::int64_t, std::uint64_t>;
        Wide w{};
        auto [end, ec] = std::from_chars(b, e, w);
        if (ec == std::errc() && end == e) {
            if (w < static_cast<Wide>(std::numeric_limits<T>::min()) ||
                w > static_cast<Wide>(std::numeric_limits<T>::max()))
                return false;
            out = static_cast<T>(w);
            return true;
        }
        // Integral values written as reals ("3.0", "1e3").
        double d = 0;
        auto [end2, ec2] = std::from_chars(b, e, d);
        if (ec2 != std::errc() || end2 != e || !std::isfinite(d) || d != std::floor(d)) return false;
        const double lo = static_cast<double>(std::numeric_limits<T>::min());
        const double hi = std::ldexp(1.0, std::numeric_limits<T>::digits);  // exclusive upper bound
        if (d < lo || d >= hi) return false;
        out = static_cast<T>(d);
        return true;
    } else {
        auto [end, ec] = std::from_chars(b, e, out);
        return ec == std::errc() && end == e;
    }
}

template <class T>
void parse_text(const DataLocation& loc, Volume& v) {
    const std::uint64_t count = v.data.size() / sizeof(T);
    const std::uint64_t size = loc.src->size();
    std::uint64_t pos = loc.offset, done = 0;
    std::vector<char> buf(std::size_t(1) << 20);
    std::string carry;
    auto* out = reinterpret_cast<std::uint8_t*>(v.data.data());
    auto emit = [&](std::string_view tok) {
        T value{};
        if (!parse_text_value(tok, value))
            fail(data_subject(loc), "text value #" + with_commas(done + 1) + " " + quoted(tok) + " is not a valid " +
                                        dtype_name(v.dtype));
        std::memcpy(out + done * sizeof(T), &value, sizeof(T));
        ++done;
    };
    while (done < count && pos < size) {
        const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(buf.size(), size - pos));
        loc.src->read(pos, buf.data(), n);
        pos += n;
        std::size_t i = 0;
        while (i < n && done < count) {
            if (is_text_separator(buf[i])) {
                if (!carry.empty()) {
                    emit(carry);
                    carry.clear();
                }
                ++i;
                continue;
            }
            std::size_t j = i;
            while (j < n && !is_text_separator(buf[j])) ++j;
            if (carry.empty() && j < n) {
                emit(std::string_view(buf.data() + i, j - i));
            } else {
                carry.append(buf.data() + i, j - i);
                if (carry.size() > 256) fail(data_subject(loc), "text value #" + with_commas(done + 1) + " is too long");
                if (j < n) {
                    emit(carry);
                    carry.clear();
                }
            }
            i = j;
        }
    }
    if (done < count && !carry.empty()) emit(carry);
    if (done < count)
        fail(data_subject(loc), "text data is truncated: " + with_commas(done) + " of " + with_commas(count) + " values");
}

}  // namespace

Volume read_ascii_voxels(const DataLocation& loc, const Grid& g, DType t) {
    const auto count = static_cast<std::uint64_t>(g.voxel_count());
    const std::uint64_t size = loc.src->size();
    const std::uint64_t have = loc.offset <= size ? size - loc.offset : 0;
    const std::uint64_t most = have / 2 + (have % 2);  // one character and one separator per value
    if (count > most)
        fail(loc.header, std::string(loc.claimant) + " says " + describe(g.dims, t) + " = " + with_commas(count) +
                             " values but " + (loc.detached ? "data file " + loc.src->name() : std::string("the file")) +
                             " holds " + with_commas(have) + " bytes of text (at most " + with_commas(most) +
                             " values)");
    Volume v = allocate(g, t);
    switch (t) {
        case DType::UInt8: parse_text<std::uint8_t>(loc, v); break;
        case DType::Int8: parse_text<std::int8_t>(loc, v); break;
        case DType::UInt16: parse_text<std::uint16_t>(loc, v); break;
        case DType::Int16: parse_text<std::int16_t>(loc, v); break;
        case DType::UInt32: parse_text<std::uint32_t>(loc, v); break;
        case DType::Int32: parse_text<std::int32_t>(loc, v); break;
        case DType::UInt64: parse_text<std::uint64_t>(loc, v); break;
        case DType::Int64: parse_text<std::int64_t>(loc, v); break;
        case DType::Float32: parse_text<float>(loc, v); break;
        case DType::Float64: parse_text<double>(loc, v); break;
    }
    return v;
}

std::uint64_t skip_lines(const ByteSource& src, const std::string& header, std::uint64_t offset, std::int64_t lines) {
    if (lines < 0) fail(header, "line skip " + std::to_string(lines) + " must not be negative");
    const std::uint64_t size = src.size();
    std::vector<char> buf(std::size_t(1) << 16);
    std::int64_t left = lines;
    std::uint64_t pos = offset;
    while (left > 0) {
        if (pos >= size)
            fail(header, "line skip " + std::to_string(lines) + " runs past the end of " + src.name() + " (" +
                             std::to_string(lines - left) + " lines found)");
        const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(buf.size(), size - pos));
        src.read(pos, buf.data(), n);
        for (std::size_t i = 0; i < n; ++i)
            if (buf[i] == '\n' && --left == 0) return pos + i + 1;
        pos += n;
    }
    return pos;
}

bool names_several_files(std::string_view value) {
    const auto words = split_words(value);
    if (words.empty()) return false;
    if (iequals(words[0], "LIST")) return true;
    std::int64_t a = 0, b = 0;
    return words.size() >= 3 && parse_int(words[1], a) && parse_int(words[2], b);
}

// ---- writing -------------------------------------------------------------------------------------------------

FileWriter::FileWriter(const std::string& path, const std::string& shown_as)
    : path_(shown_as.empty() ? path : shown_as) {
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd_ < 0) {
        const int e = errno;
        if (e == ENOENT || e == ENOTDIR) throw FileNotFound(path_ + ": cannot create the file: " + errno_text(e));
        throw Error(path_ + ": cannot create the file: " + errno_text(e));
    }
}

FileWriter::~FileWriter() {
    if (fd_ >= 0) ::close(fd_);
}

void FileWriter::write(const void* data, std::size_t n) {
    write_at(pos_, data, n);
    pos_ += n;
}

void FileWriter::write_at(std::uint64_t offset, const void* data, std::size_t n) {
    const auto* p = static_cast<const char*>(data);
    while (n > 0) {
        const ssize_t r = ::pwrite(fd_, p, std::min<std::size_t>(n, std::size_t(1) << 30), static_cast<off_t>(offset));
        if (r < 0) {
            if (errno == EINTR) continue;
            throw Error(path_ + ": write failed: " + errno_text(errno));
        }
        p += r;
        n -= static_cast<std::size_t>(r);
        offset += static_cast<std::uint64_t>(r);
    }
}

void FileWriter::close() {
    const int fd = fd_;
    fd_ = -1;
    if (fd >= 0 && ::close(fd) != 0) throw Error(path_ + ": write failed on close: " + errno_text(errno));
}

void check_view(const std::string& path, const VolumeView& v) {
    check_grid(v.grid, dtype_size(v.dtype), std::numeric_limits<std::uint64_t>::max(), path);
    if (!v.data) throw Error(path + ": no voxel data to write");
}

void little_endian_chunks(const VolumeView& v, const std::function<void(const void*, std::size_t)>& sink) {
    const std::size_t esize = dtype_size(v.dtype);
    const std::size_t total = static_cast<std::size_t>(v.grid.voxel_count()) * esize;
    const auto* p = static_cast<const std::uint8_t*>(v.data);
    if (esize == 1 || !host_is_big_endian()) {
        for (std::size_t done = 0; done < total;) {
            const std::size_t step = std::min<std::size_t>(total - done, std::size_t(64) << 20);
            sink(p + done, step);
            done += step;
        }
        return;
    }
    std::vector<std::uint8_t> buf(std::size_t(1) << 20);
    for (std::size_t done = 0; done < total;) {
        const std::size_t step = std::min(total - done, buf.size());
        std::memcpy(buf.data(), p + done, step);
        swap_bytes(buf.data(), step / esize, esize);
        sink(buf.data(), step);
        done += step;
    }
}

}  // namespace detail
}  // namespace volrig

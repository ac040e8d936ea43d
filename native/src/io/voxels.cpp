// io/voxels.cpp: reading the voxels of a header-described volume (io/io_detail.hpp): grid checks, byte order, raw,
// compressed and text voxel data, and the NRRD/MetaImage data-file helpers.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <type_traits>

#include "io/zlib_inflate.hpp"
#include "io/io_detail.hpp"

namespace volrig::io_detail {

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

namespace {

// Whether the file budget applies: the caller chose no max_bytes, and $VOLRIG_MAX_BYTES chose none for the process.
bool budget_applies(const ReadOptions& opt) {
    const char* env = std::getenv("VOLRIG_MAX_BYTES");
    return !opt.max_bytes_given && !(env && *env);
}

// ratio_allowance, at least kBudgetFloor.
std::uint64_t file_allowance(std::uint64_t file_bytes) { return std::max(kBudgetFloor, ratio_allowance(file_bytes)); }

}  // namespace

std::uint64_t ratio_allowance(std::uint64_t file_bytes) {
    const bool huge = file_bytes > std::numeric_limits<std::uint64_t>::max() / kBudgetRatio;
    return huge ? std::numeric_limits<std::uint64_t>::max() : file_bytes * kBudgetRatio;
}

std::uint64_t budget_of(std::uint64_t file_bytes, const ReadOptions& opt) {
    return budget_applies(opt) ? std::min(opt.max_bytes, file_allowance(file_bytes)) : opt.max_bytes;
}

void check_budget(const std::string& name, std::uint64_t demand, std::uint64_t file_bytes, const ReadOptions& opt,
                  const std::string& what, const std::string& or_else) {
    if (demand <= file_allowance(file_bytes) || !budget_applies(opt)) return;
    fail(name, what + " need " + with_commas(demand) + " bytes from a file of " + with_commas(file_bytes) +
                   " bytes: more than 1 GB and more than " + with_commas(kBudgetRatio) +
                   " times the file, so it is refused as broken or hostile; if the file is right, allow it with "
                   "max_bytes=" + std::to_string(demand) + " (Python) or VOLRIG_MAX_BYTES=" + std::to_string(demand) +
                   " in the environment" + (or_else.empty() ? "" : "; or " + or_else));
}

namespace {

template <class T>
void finite_range_of(const std::uint8_t* p, std::size_t n, double& lo, double& hi) {
    for (std::size_t i = 0; i < n; ++i) {
        T x;
        std::memcpy(&x, p + i * sizeof(T), sizeof(T));
        const auto d = static_cast<double>(x);
        if (!std::isfinite(d)) continue;
        lo = std::min(lo, d);
        hi = std::max(hi, d);
    }
}

}  // namespace

void finite_range(DType t, const std::uint8_t* p, std::size_t n, double& lo, double& hi) {
    switch (t) {
        case DType::UInt8: return finite_range_of<std::uint8_t>(p, n, lo, hi);
        case DType::Int8: return finite_range_of<std::int8_t>(p, n, lo, hi);
        case DType::UInt16: return finite_range_of<std::uint16_t>(p, n, lo, hi);
        case DType::Int16: return finite_range_of<std::int16_t>(p, n, lo, hi);
        case DType::UInt32: return finite_range_of<std::uint32_t>(p, n, lo, hi);
        case DType::Int32: return finite_range_of<std::int32_t>(p, n, lo, hi);
        case DType::UInt64: return finite_range_of<std::uint64_t>(p, n, lo, hi);
        case DType::Int64: return finite_range_of<std::int64_t>(p, n, lo, hi);
        case DType::Float32: return finite_range_of<float>(p, n, lo, hi);
        case DType::Float64: return finite_range_of<double>(p, n, lo, hi);
    }
}

DType rescaled_type(const std::string& name, const std::string& what, double lo, double hi, double slope,
                    double inter, DType stored) {
    if (lo > hi) return stored == DType::Float64 ? DType::Float64 : DType::Float32;  // no finite values
    const double a = lo * slope + inter, b = hi * slope + inter;
    if (!std::isfinite(a) || !std::isfinite(b))
        fail(name, what + " " + format_double(slope) + "/" + format_double(inter) + " take the stored values " +
                       format_double(lo) + " to " + format_double(hi) + " beyond the range of a double");
    const double most = std::max(std::fabs(a), std::fabs(b));
    return stored == DType::Float64 || most > static_cast<double>(std::numeric_limits<float>::max()) ? DType::Float64
                                                                                                      : DType::Float32;
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

void skip_to_data(DataLocation& loc, std::int64_t skip, const char* label, const Grid& g, DType t) {
    const std::uint64_t file_size = loc.src->size();
    const std::uint64_t available = file_size - std::min(loc.offset, file_size);
    if (skip == -1) {
        const std::uint64_t data_bytes = static_cast<std::uint64_t>(g.voxel_count()) * dtype_size(t);
        if (data_bytes <= available) loc.offset = file_size - data_bytes;
        return;
    }
    const auto bytes = static_cast<std::uint64_t>(skip);
    if (bytes > available)
        fail(data_subject(loc), std::string(label) + " " + with_commas(bytes) + " runs past the end of the data (" +
                                    with_commas(file_size) + " bytes)");
    loc.offset += bytes;
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

}  // namespace volrig::io_detail

// io/metaimage.cpp: MetaImage reader and writer (ITK/VTK MetaIO .mha/.mhd).
//
// Reads "Key = Value" headers (keys case-insensitive) ending with ElementDataFile: LOCAL data right after that
// line (.mha) or one data file beside the header (.mhd); raw, zlib/gzip-compressed (CompressedData) or text
// (BinaryData = False) voxels in either byte order; NDims 1..3 (or more when the extra sizes are 1).
// Element sizes follow MetaIO's own table: MET_LONG/MET_ULONG are 4 bytes (int32/uint32), MET_LONG_LONG/
// MET_ULONG_LONG 8. Spacing = ElementSpacing (else ElementSize), origin = Offset (or Origin/Position);
// orientation = TransformMatrix (ITK's layout: the direction of axis a is numbers 3a..3a+2, in LPS), else
// AnatomicalOrientation (ITK's letters: where each axis comes from, RAI = identity); the writer writes both. Refused: other ObjectTypes, ElementNumberOfChannels > 1, array
// element types, several data files (LIST or patterns).
#include <cmath>
#include <cstring>
#include <map>

#include "io/zlib_inflate.hpp"
#include "io/io_detail.hpp"
#include "volrig/io.hpp"

namespace volrig {

namespace {

using namespace io_detail;  // the shared reader helpers (fail, quoted, with_commas, kMaxHeader, ...)
using Field = HeaderField;

struct Header {
    io_detail::HeaderFields fields;  // lowercase keys
    std::string data_file;
    int data_file_line = 0;
    std::uint64_t data_start = 0;  // first byte after the ElementDataFile line
};

Header read_header(const ByteSource& src) {
    const std::string& name = src.name();
    const std::uint64_t size = src.size();
    if (size == 0) fail(name, "empty file: not a MetaImage header");
    Header h;
    std::string text;
    std::size_t scanned = 0;
    int line_no = 0;
    for (;;) {
        const std::size_t before = text.size();
        if (before >= size) fail(name, "no ElementDataFile field: not a complete MetaImage header");
        if (before >= kMaxHeader)
            fail(name, "header is longer than 1 MiB without an ElementDataFile field: not a MetaImage file?");
        const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(64 * 1024, size - before));
        text.resize(before + n);
        src.read(before, &text[before], n);
        for (;;) {
            const std::size_t nl = text.find('\n', scanned);
            const bool last = nl == std::string::npos;
            if (last && text.size() < size) break;  // need more bytes
            std::string_view line(text.data() + scanned, (last ? text.size() : nl) - scanned);
            ++line_no;
            const std::string here = "line " + std::to_string(line_no) + ": ";
            if (!io_detail::trim(line).empty()) {
                const std::size_t eq = line.find('=');
                if (eq == std::string_view::npos)
                    fail(name, here + "expected 'Key = Value', got " + quoted(io_detail::trim(line)) +
                                   (line_no == 1 ? " (not a MetaImage header?)" : ""));
                const std::string key = io_detail::lower(io_detail::trim(line.substr(0, eq)));
                if (key.empty()) fail(name, here + "expected 'Key = Value', got " + quoted(io_detail::trim(line)));
                const std::string value(io_detail::trim(line.substr(eq + 1)));
                if (key == "elementdatafile") {
                    h.data_file = value;
                    h.data_file_line = line_no;
                    h.data_start = last ? size : nl + 1;
                    return h;
                }
                h.fields[key] = Field{value, line_no};
            }
            if (last) fail(name, "no ElementDataFile field: not a complete MetaImage header");
            scanned = nl + 1;
        }
    }
}

bool met_type(std::string_view s, DType& t) {
    static const std::map<std::string, DType> types = {
        {"MET_UCHAR", DType::UInt8},     {"MET_CHAR", DType::Int8},         {"MET_USHORT", DType::UInt16},
        {"MET_SHORT", DType::Int16},     {"MET_UINT", DType::UInt32},       {"MET_INT", DType::Int32},
        {"MET_ULONG", DType::UInt32},    {"MET_LONG", DType::Int32},        {"MET_ULONG_LONG", DType::UInt64},
        {"MET_LONG_LONG", DType::Int64}, {"MET_FLOAT", DType::Float32},     {"MET_DOUBLE", DType::Float64},
    };
    std::string u(s);
    for (char& c : u) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    auto it = types.find(u);
    if (it == types.end()) return false;
    t = it->second;
    return true;
}

const char* met_type_name(DType t) {
    switch (t) {
        case DType::UInt8: return "MET_UCHAR";
        case DType::Int8: return "MET_CHAR";
        case DType::UInt16: return "MET_USHORT";
        case DType::Int16: return "MET_SHORT";
        case DType::UInt32: return "MET_UINT";
        case DType::Int32: return "MET_INT";
        case DType::UInt64: return "MET_ULONG_LONG";
        case DType::Int64: return "MET_LONG_LONG";
        case DType::Float32: return "MET_FLOAT";
        case DType::Float64: return "MET_DOUBLE";
    }
    return "?";
}

// Fails with "<file>: line N: <label> = '<value>' <why>".
[[noreturn]] void bad(const std::string& name, const Field& f, const char* label, const std::string& why) {
    fail(name, "line " + std::to_string(f.line) + ": " + label + " = " + quoted(f.value) + " " + why);
}

// A True/False field (also 1/0); `fallback` when absent.
bool flag(const std::string& name, const Header& h, const char* key, const char* label, bool fallback) {
    const Field* f = h.fields.get(key);
    if (!f) return fallback;
    if (io_detail::iequals(f->value, "true") || f->value == "1") return true;
    if (io_detail::iequals(f->value, "false") || f->value == "0") return false;
    bad(name, *f, label, "must be True or False");
}

// NDims, checked (ObjectType, when given, must be Image).
std::size_t met_ndims(const std::string& name, const Header& h) {
    if (const Field* f = h.fields.get("objecttype"))
        if (!io_detail::iequals(f->value, "image")) bad(name, *f, "ObjectType", "is not supported (only Image)");
    const Field& fnd = h.fields.need(name, "ndims", "NDims");
    std::int64_t ndims = 0;
    if (!io_detail::parse_int(fnd.value, ndims) || ndims < 1 || ndims > 16) bad(name, fnd, "NDims", "must be 1 to 16");
    return static_cast<std::size_t>(ndims);
}

// DimSize: n positive sizes, those beyond the third equal to 1.
std::array<std::int64_t, 3> met_dims(const std::string& name, const Header& h, std::size_t n) {
    const Field& fsize = h.fields.need(name, "dimsize", "DimSize");
    const auto size_words = io_detail::split_words(fsize.value);
    if (size_words.size() < n) bad(name, fsize, "DimSize", "must give " + std::to_string(n) + " sizes (NDims)");
    std::array<std::int64_t, 3> dims{1, 1, 1};
    for (std::size_t a = 0; a < n; ++a) {
        std::int64_t d = 0;
        if (!io_detail::parse_int(size_words[a], d) || d <= 0) bad(name, fsize, "DimSize", "must be positive integers");
        if (a < 3) {
            dims[a] = d;
        } else if (d != 1) {
            fail(name, std::to_string(n) + "-D image (DimSize " + quoted(fsize.value) +
                           ") is not supported: only 2-D and 3-D volumes");
        }
    }
    return dims;
}

// ElementType, with at most one channel.
DType met_dtype(const std::string& name, const Header& h) {
    const Field& ftype = h.fields.need(name, "elementtype", "ElementType");
    DType dtype{};
    if (!met_type(ftype.value, dtype)) bad(name, ftype, "ElementType", "is not supported");
    if (const Field* f = h.fields.get("elementnumberofchannels")) {
        std::int64_t c = 0;
        if (!io_detail::parse_int(f->value, c) || c < 1)
            bad(name, *f, "ElementNumberOfChannels", "must be a positive integer");
        if (c > 1) bad(name, *f, "ElementNumberOfChannels", "is not supported: multi-channel images cannot be read");
    }
    return dtype;
}

// The first min(n, 3) numbers of a field into `out`: finite, and non-zero (taken as magnitudes) when `positive`.
void met_vector(const std::string& name, const Field& f, const char* label, std::size_t n, bool positive,
                std::array<double, 3>& out) {
    const auto words = io_detail::split_words(f.value);
    if (words.size() < n) bad(name, f, label, "must give " + std::to_string(n) + " numbers (NDims)");
    for (std::size_t a = 0; a < n && a < 3; ++a) {
        double d = 0;
        if (!io_detail::parse_double(words[a], d)) bad(name, f, label, "must be numbers");
        if (positive) {
            d = std::fabs(d);
            if (!std::isfinite(d) || d == 0) bad(name, f, label, "must be finite and non-zero");
        } else if (!std::isfinite(d)) {
            bad(name, f, label, "must be finite");
        }
        out[a] = d;
    }
}

// Spacing (ElementSpacing, else ElementSize) and origin (Offset, else Origin, else Position) into g.
void met_spacing_and_origin(const std::string& name, const Header& h, std::size_t n, Grid& g) {
    if (const Field* f = h.fields.get("elementspacing"))
        met_vector(name, *f, "ElementSpacing", n, true, g.spacing);
    else if (const Field* fs = h.fields.get("elementsize"))
        met_vector(name, *fs, "ElementSize", n, true, g.spacing);
    if (const Field* f = h.fields.get("offset"))
        met_vector(name, *f, "Offset", n, false, g.origin);
    else if (const Field* fo = h.fields.get("origin"))
        met_vector(name, *fo, "Origin", n, false, g.origin);
    else if (const Field* fp = h.fields.get("position"))
        met_vector(name, *fp, "Position", n, false, g.origin);
}

// The LPS direction an axis points to when it comes from anatomical letter c (R->L is +x): false when unknown.
bool from_letter(char c, std::array<double, 3>& dir) {
    static const char* const letters = "RLAPIS";  // from R: +x, from L: -x, from A: +y, ...
    const char* at = std::strchr(letters, std::toupper(static_cast<unsigned char>(c)));
    if (!at || !c) return false;
    const auto i = static_cast<std::size_t>(at - letters);
    dir = {0, 0, 0};
    dir[i / 2] = i % 2 == 0 ? 1 : -1;
    return true;
}

// AnatomicalOrientation ("RAI") as a direction matrix; false when the value is not three letters of distinct axes.
bool anatomical_direction(std::string_view value, Matrix3& d) {
    value = io_detail::trim(value);
    if (value.size() != 3) return false;
    d = Matrix3{};
    std::array<double, 3> dir{};
    for (std::size_t a = 0; a < 3; ++a) {
        if (!from_letter(value[a], dir)) return false;
        for (std::size_t r = 0; r < 3; ++r) d[3 * r + a] = dir[r];
    }
    return normalize_direction(d).empty();
}

// The letters of the axes' nearest anatomical directions (ITK's convention): "RAI" for the identity.
std::string anatomical_letters(const Matrix3& d) {
    std::string out;
    for (std::size_t a = 0; a < 3; ++a) {
        std::size_t best = 0;
        for (std::size_t r = 1; r < 3; ++r)
            if (std::fabs(d[3 * r + a]) > std::fabs(d[3 * best + a])) best = r;
        out += "RLAPIS"[2 * best + (d[3 * best + a] < 0 ? 1 : 0)];
    }
    return out;
}

// The direction matrix from TransformMatrix (column a = numbers 3a..3a+2, as ITK writes it), else from
// AnatomicalOrientation; identity for 2-D images and when neither is given.
void met_direction(const std::string& name, const Header& h, std::size_t n, Grid& g) {
    if (n != 3) return;
    if (const Field* f = h.fields.get("transformmatrix")) {
        const auto words = io_detail::split_words(f->value);
        if (words.size() != 9) bad(name, *f, "TransformMatrix", "must give 9 numbers (NDims 3)");
        Matrix3 d{};
        for (std::size_t i = 0; i < 9; ++i)
            if (!io_detail::parse_double(words[i], d[3 * (i % 3) + i / 3])) bad(name, *f, "TransformMatrix", "must be numbers");
        const std::string problem = normalize_direction(d);
        if (!problem.empty()) bad(name, *f, "TransformMatrix", problem);
        g.direction = d;
    } else if (const Field* fa = h.fields.get("anatomicalorientation")) {
        Matrix3 d{};
        if (anatomical_direction(fa->value, d)) g.direction = d;
    }
}

// How the voxels are stored.
struct Encoding {
    bool big_endian = false;
    bool binary = true;
    bool compressed = false;
    std::int64_t header_size = 0;  // bytes before the data; -1: the data are the last bytes of the file
};

Encoding met_encoding(const std::string& name, const Header& h) {
    Encoding e;
    e.big_endian = h.fields.get("binarydatabyteordermsb")
                       ? flag(name, h, "binarydatabyteordermsb", "BinaryDataByteOrderMSB", false)
                       : flag(name, h, "elementbyteordermsb", "ElementByteOrderMSB", false);
    e.binary = flag(name, h, "binarydata", "BinaryData", true);
    e.compressed = flag(name, h, "compresseddata", "CompressedData", false);
    if (const Field* f = h.fields.get("headersize")) {
        if (!io_detail::parse_int(f->value, e.header_size) || e.header_size < -1)
            bad(name, *f, "HeaderSize", "must be -1 or more");
        if (e.header_size == -1 && (e.compressed || !e.binary))
            bad(name, *f, "HeaderSize", "(data at the end of the file) is only valid for uncompressed binary data");
    }
    return e;
}

// Where the data starts: after the ElementDataFile line (LOCAL) or in the data file (opened into `detached`).
io_detail::DataLocation met_data_location(const ByteSource& src, const Header& h, std::unique_ptr<ByteSource>& detached) {
    const std::string& name = src.name();
    io_detail::DataLocation loc(src);
    const Field fdata{h.data_file, h.data_file_line};
    if (h.data_file.empty()) bad(name, fdata, "ElementDataFile", "is empty");
    if (io_detail::iequals(h.data_file, "LOCAL")) {
        loc.offset = h.data_start;
    } else {
        if (io_detail::names_several_files(h.data_file))
            bad(name, fdata, "ElementDataFile", "names several files: multi-file MetaImage data is not supported");
        detached = src.open_sibling(h.data_file);
        loc.src = detached.get();
        loc.detached = true;
    }
    return loc;
}

// The stream runs from the data offset to its own end marker. CompressedDataSize is checked against the file but
// not trusted as the stream's length: real files understate it (VTK's frogtissue.mhd says 260,020 for a
// 262,087-byte stream), and MetaIO readers decode them anyway.
Volume read_compressed(const Header& h, const io_detail::DataLocation& loc, const Grid& g, DType dtype, bool big_endian) {
    const std::uint64_t file_size = loc.src->size();
    const std::uint64_t available = file_size - std::min(loc.offset, file_size);
    if (const Field* f = h.fields.get("compresseddatasize")) {
        std::int64_t c = 0;
        if (!io_detail::parse_int(f->value, c) || c <= 0)
            bad(loc.header, *f, "CompressedDataSize", "must be a positive integer");
        if (static_cast<std::uint64_t>(c) > available)
            fail(io_detail::data_subject(loc), "header declares CompressedDataSize " +
                                                with_commas(static_cast<std::uint64_t>(c)) + " but the file holds " +
                                                with_commas(available) + " bytes of data");
    }
    return io_detail::read_compressed_voxels(loc, available, 0, g, dtype, big_endian);
}

}  // namespace

Volume read_metaimage(const ByteSource& src, const ReadOptions& opt) {
    const std::string& name = src.name();
    const Header h = read_header(src);
    const std::size_t n = met_ndims(name, h);
    Grid g;
    g.dims = met_dims(name, h, n);
    const DType dtype = met_dtype(name, h);
    met_spacing_and_origin(name, h, n, g);
    met_direction(name, h, n, g);
    io_detail::check_volume(name, g, dtype, opt.max_bytes);
    const Encoding e = met_encoding(name, h);
    std::unique_ptr<ByteSource> detached;
    io_detail::DataLocation loc = met_data_location(src, h, detached);
    io_detail::skip_to_data(loc, e.header_size, "HeaderSize", g, dtype);
    if (!e.binary) return io_detail::read_ascii_voxels(loc, g, dtype);
    if (!e.compressed) return io_detail::read_raw_voxels(loc, g, dtype, e.big_endian);
    return read_compressed(h, loc, g, dtype, e.big_endian);
}

void write_metaimage(const std::string& path, const VolumeView& v, bool compress) {
    io_detail::check_view(path, v);
    const Grid& g = v.grid;
    const auto f = io_detail::format_double;
    std::string head = "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n";
    head += std::string("CompressedData = ") + (compress ? "True" : "False") + "\n";
    std::string size_line = "CompressedDataSize = ";
    const std::size_t size_field = 20;  // room for any uint64, padded with spaces and filled in afterwards
    std::string tail = "TransformMatrix =";
    for (std::size_t a = 0; a < 3; ++a)
        for (std::size_t r = 0; r < 3; ++r) tail += " " + f(g.direction[3 * r + a] + 0.0);  // + 0.0: no -0
    tail += "\n";
    tail += "Offset = " + f(g.origin[0]) + " " + f(g.origin[1]) + " " + f(g.origin[2]) + "\n";
    tail += "CenterOfRotation = 0 0 0\n";
    tail += "AnatomicalOrientation = " + anatomical_letters(g.direction) + "\n";
    tail += "ElementSpacing = " + f(g.spacing[0]) + " " + f(g.spacing[1]) + " " + f(g.spacing[2]) + "\n";
    tail += "DimSize = " + std::to_string(g.dims[0]) + " " + std::to_string(g.dims[1]) + " " +
            std::to_string(g.dims[2]) + "\n";
    tail += std::string("ElementType = ") + met_type_name(v.dtype) + "\n";
    tail += "ElementDataFile = LOCAL\n";
    write_atomically(path, [&](const std::string& tmp) {
        io_detail::FileWriter out(tmp, path);
        out.write(head);
        std::uint64_t size_at = 0;
        if (compress) {
            out.write(size_line);
            size_at = out.position();
            out.write(std::string(size_field, ' ') + "\n");
        }
        out.write(tail);
        if (compress) {
            io_detail::Deflater z(out, false);
            io_detail::little_endian_chunks(v, [&](const void* p, std::size_t n) { z.write(p, n); });
            const std::string csize = std::to_string(z.finish());
            out.write_at(size_at, csize.data(), csize.size());
        } else {
            io_detail::little_endian_chunks(v, [&](const void* p, std::size_t n) { out.write(p, n); });
        }
        out.close();
    });
}

}  // namespace volrig

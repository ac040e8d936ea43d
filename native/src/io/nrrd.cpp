// io/nrrd.cpp: NRRD reader and writer (http://teem.sourceforge.net/nrrd/format.html).
//
// Reads NRRD0001..NRRD0005 with attached (.nrrd) or single detached (.nhdr + data file) data in raw, gzip or
// ascii encoding, either endianness, dimension 1..3 (or more when the extra axes have size 1). Spacing comes from
// "space directions" (vector norms) or "spacings"; origin from "space origin" (else "axis mins"). Orientation: the
// unit space directions become the grid's direction matrix, converted with the origin from the file's "space"
// (RAS, LAS, LPS, scanner-xyz, ...) to LPS; the writer writes LPS. Refused with a clear message: bzip2/hex encodings, type "block", several data
// files (LIST or patterns), multi-component axes, 4-D data.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>

#include "io/zlib_inflate.hpp"
#include "io/io_detail.hpp"
#include "volrig/io.hpp"

namespace volrig {

namespace {

using namespace io_detail;  // the shared reader helpers (fail, quoted, with_commas, kMaxHeader, ...)
using Field = HeaderField;

// Field names compare lowercase with spaces removed ("data file" = "datafile").
std::string field_key(std::string_view s) {
    std::string out;
    for (char c : s)
        if (c != ' ' && c != '\t') out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

bool nrrd_type(std::string_view name, DType& t) {
    // Lowercase with runs of spaces collapsed.
    std::string n;
    for (auto w : io_detail::split_words(name)) {
        if (!n.empty()) n += ' ';
        n += io_detail::lower(w);
    }
    static const std::map<std::string, DType> types = {
        {"uchar", DType::UInt8}, {"unsigned char", DType::UInt8}, {"uint8", DType::UInt8}, {"uint8_t", DType::UInt8},
        {"signed char", DType::Int8}, {"int8", DType::Int8}, {"int8_t", DType::Int8},
        {"short", DType::Int16}, {"short int", DType::Int16}, {"signed short", DType::Int16},
        {"signed short int", DType::Int16}, {"int16", DType::Int16}, {"int16_t", DType::Int16},
        {"ushort", DType::UInt16}, {"unsigned short", DType::UInt16}, {"unsigned short int", DType::UInt16},
        {"uint16", DType::UInt16}, {"uint16_t", DType::UInt16},
        {"int", DType::Int32}, {"signed int", DType::Int32}, {"int32", DType::Int32}, {"int32_t", DType::Int32},
        {"uint", DType::UInt32}, {"unsigned int", DType::UInt32}, {"uint32", DType::UInt32},
        {"uint32_t", DType::UInt32},
        {"longlong", DType::Int64}, {"long long", DType::Int64}, {"long long int", DType::Int64},
        {"signed long long", DType::Int64}, {"signed long long int", DType::Int64}, {"int64", DType::Int64},
        {"int64_t", DType::Int64},
        {"ulonglong", DType::UInt64}, {"unsigned long long", DType::UInt64},
        {"unsigned long long int", DType::UInt64}, {"uint64", DType::UInt64}, {"uint64_t", DType::UInt64},
        {"float", DType::Float32}, {"double", DType::Float64},
    };
    auto it = types.find(n);
    if (it == types.end()) return false;
    t = it->second;
    return true;
}

const char* nrrd_type_name(DType t) {
    // NRRD accepts the numpy-style integer names; floats are "float" and "double".
    if (t == DType::Float32) return "float";
    if (t == DType::Float64) return "double";
    return dtype_name(t);
}

// Kinds that describe positions along the grid (anything else is a per-sample component axis).
bool domain_kind(std::string_view k) {
    const std::string l = io_detail::lower(k);
    return l == "domain" || l == "space" || l == "time" || l == "none" || l == "???";
}

// Parses "(a,b,c)" into numbers; false when malformed.
bool parse_vector(std::string_view s, std::vector<double>& out) {
    s = io_detail::trim(s);
    if (s.size() < 2 || s.front() != '(' || s.back() != ')') return false;
    s = s.substr(1, s.size() - 2);
    out.clear();
    std::size_t start = 0;
    for (;;) {
        const std::size_t comma = s.find(',', start);
        double d = 0;
        if (!io_detail::parse_double(s.substr(start, comma == std::string_view::npos ? s.npos : comma - start), d))
            return false;
        out.push_back(d);
        if (comma == std::string_view::npos) break;
        start = comma + 1;
    }
    return !out.empty() && out.size() <= 16;
}

// Splits a "space directions" value into per-axis items: "(1,0,0)", "none".
std::vector<std::string_view> vector_items(std::string_view s) {
    std::vector<std::string_view> out;
    std::size_t i = 0;
    while (i < s.size()) {
        while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
        if (i >= s.size()) break;
        std::size_t j = i;
        if (s[i] == '(') {
            j = s.find(')', i);
            j = j == std::string_view::npos ? s.size() : j + 1;
        } else {
            while (j < s.size() && s[j] != ' ' && s[j] != '\t') ++j;
        }
        out.push_back(s.substr(i, j - i));
        i = j;
    }
    return out;
}

struct Header {
    io_detail::HeaderFields fields;
    bool has_blank_line = false;
    std::uint64_t data_start = 0;  // first byte after the blank line
};

Header read_header(const ByteSource& src) {
    const std::string& name = src.name();
    const std::uint64_t size = src.size();
    std::string text;
    Header h;
    std::size_t scanned = 0;  // start of the first line not yet examined
    int line_no = 0;
    bool done = false;
    while (!done) {
        const std::size_t before = text.size();
        if (before >= size) break;
        if (before >= kMaxHeader) fail(name, "header is longer than 1 MiB (no blank line ends it): not a NRRD file?");
        const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(64 * 1024, size - before));
        text.resize(before + n);
        src.read(before, &text[before], n);
        if (before == 0 && text.compare(0, std::min<std::size_t>(text.size(), 7), std::string("NRRD000"), 0,
                                        std::min<std::size_t>(text.size(), 7)) != 0)
            fail(name, "not a NRRD file (it does not start with NRRD000x)");
        // Examine each complete line.
        for (;;) {
            const std::size_t nl = text.find('\n', scanned);
            const bool last = nl == std::string::npos;
            if (last && text.size() < size) break;  // need more bytes
            std::string_view line(text.data() + scanned, (last ? text.size() : nl) - scanned);
            if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
            ++line_no;
            const std::string here = "line " + std::to_string(line_no) + ": ";
            if (line_no == 1) {
                if (line.size() < 8 || line.substr(0, 7) != "NRRD000" || line[7] < '1' || line[7] > '9')
                    fail(name, "not a NRRD file (it does not start with NRRD000x)");
            } else if (line.empty() && !last) {
                h.has_blank_line = true;
                h.data_start = nl + 1;
                done = true;
                break;
            } else if (!line.empty() && line[0] != '#') {
                const std::size_t kv = line.find(":=");
                const std::size_t fd = line.find(": ");
                if (kv != std::string_view::npos && (fd == std::string_view::npos || kv < fd)) {
                    // key:=value pair: ignored
                } else if (fd == std::string_view::npos) {
                    if (!io_detail::trim(line).empty())
                        fail(name, here + "expected 'field: value', got " + quoted(line));
                } else {
                    const std::string key = field_key(line.substr(0, fd));
                    h.fields[key] = Field{std::string(io_detail::trim(line.substr(fd + 2))), line_no};
                }
            }
            if (last) {
                done = true;
                break;
            }
            scanned = nl + 1;
        }
    }
    if (text.empty()) fail(name, "empty file: not a NRRD file");
    return h;
}

// Fails with "<file>: line N: <label> '<value>' <why>".
[[noreturn]] void bad(const std::string& name, const Field& f, const char* label, const std::string& why) {
    fail(name, "line " + std::to_string(f.line) + ": " + label + " " + quoted(f.value) + " " + why);
}

DType nrrd_dtype(const std::string& name, const Header& h) {
    const Field& ftype = h.fields.need(name, "type", "type");
    DType dtype{};
    if (io_detail::iequals(io_detail::trim(ftype.value), "block"))
        bad(name, ftype, "type", "is not supported (opaque blocks are not voxels)");
    if (!nrrd_type(ftype.value, dtype)) bad(name, ftype, "type", "is not a NRRD scalar type");
    return dtype;
}

struct Axis {
    std::int64_t size = 1;
    bool has_spacing = false;
    double spacing = 1.0;
    double min = 0.0;
    std::string kind = "domain";
    std::vector<double> direction;  // the space direction vector (empty for 'none')
};

// The axes "dimension" and "sizes" declare.
std::vector<Axis> nrrd_sizes(const std::string& name, const Header& h) {
    const Field& fdim = h.fields.need(name, "dimension", "dimension");
    std::int64_t dim = 0;
    if (!io_detail::parse_int(fdim.value, dim) || dim < 1 || dim > 16)
        bad(name, fdim, "dimension", "must be an integer from 1 to 16");
    const Field& fsizes = h.fields.need(name, "sizes", "sizes");
    const auto size_words = io_detail::split_words(fsizes.value);
    if (static_cast<std::int64_t>(size_words.size()) != dim)
        bad(name, fsizes, "sizes",
            "must list " + std::to_string(dim) + " sizes (dimension " + std::to_string(dim) + ")");
    std::vector<Axis> axes(static_cast<std::size_t>(dim));
    for (std::size_t a = 0; a < axes.size(); ++a)
        if (!io_detail::parse_int(size_words[a], axes[a].size) || axes[a].size <= 0)
            bad(name, fsizes, "sizes", "must be positive integers");
    return axes;
}

// The words of a per-axis field; fails unless there is one per axis.
std::vector<std::string_view> per_axis(const std::string& name, const Field& f, const char* label, const char* what,
                                       std::size_t axes) {
    auto words = io_detail::split_words(f.value);
    if (words.size() != axes)
        bad(name, f, label, std::string("must give ") + what + " per axis (" + std::to_string(axes) + ")");
    return words;
}

// Spacing from "space directions" (vector norms), else from "spacings".
void nrrd_spacings(const std::string& name, const Header& h, std::vector<Axis>& axes) {
    if (const Field* f = h.fields.get("spacedirections")) {
        const auto items = vector_items(f->value);
        if (items.size() != axes.size())
            bad(name, *f, "space directions",
                "must give one vector or 'none' per axis (" + std::to_string(axes.size()) + ")");
        std::vector<double> v;
        for (std::size_t a = 0; a < axes.size(); ++a) {
            if (io_detail::iequals(items[a], "none")) continue;
            if (!parse_vector(items[a], v))
                bad(name, *f, "space directions", "must be vectors like (1,0,0) or 'none'");
            double n2 = 0;
            for (double c : v) n2 += c * c;
            axes[a].has_spacing = true;
            axes[a].spacing = std::sqrt(n2);
            axes[a].direction = v;
        }
    } else if (const Field* fs = h.fields.get("spacings")) {
        const auto words = per_axis(name, *fs, "spacings", "one number", axes.size());
        for (std::size_t a = 0; a < axes.size(); ++a) {
            if (!io_detail::parse_double(words[a], axes[a].spacing)) bad(name, *fs, "spacings", "must be numbers");
            axes[a].spacing = std::fabs(axes[a].spacing);
            axes[a].has_spacing = true;
        }
    }
}

// Reads "axis mins" (true when given) and "kinds" into the axes.
bool nrrd_mins_and_kinds(const std::string& name, const Header& h, std::vector<Axis>& axes) {
    bool have_mins = false;
    if (const Field* f = h.fields.get("axismins")) {
        const auto words = per_axis(name, *f, "axis mins", "one number", axes.size());
        for (std::size_t a = 0; a < axes.size(); ++a)
            if (!io_detail::parse_double(words[a], axes[a].min)) bad(name, *f, "axis mins", "must be numbers");
        have_mins = true;
    }
    if (const Field* f = h.fields.get("kinds")) {
        const auto words = per_axis(name, *f, "kinds", "one kind", axes.size());
        for (std::size_t a = 0; a < axes.size(); ++a) axes[a].kind = std::string(words[a]);
    }
    return have_mins;
}

// Drops component axes of size 1, refuses larger ones; then drops size-1 axes beyond the third.
std::vector<Axis> spatial_axes(const std::string& name, const std::vector<Axis>& axes) {
    std::vector<Axis> kept;
    for (std::size_t a = 0; a < axes.size(); ++a) {
        if (domain_kind(axes[a].kind)) {
            kept.push_back(axes[a]);
        } else if (axes[a].size > 1) {
            fail(name, "axis " + std::to_string(a) + " has kind " + quoted(axes[a].kind) + " of size " +
                           std::to_string(axes[a].size) + ": multi-component volumes are not supported");
        }
    }
    while (kept.size() > 3) {
        auto it = std::find_if(kept.begin(), kept.end(), [](const Axis& x) { return x.size == 1; });
        if (it == kept.end()) {
            std::string sizes;
            for (const Axis& x : kept) sizes += (sizes.empty() ? "" : "x") + std::to_string(x.size);
            fail(name, std::to_string(kept.size()) + "-D data (" + sizes +
                           ") is not supported: multi-component/4-D volumes are not supported");
        }
        kept.erase(it);
    }
    if (kept.empty()) fail(name, "no spatial axes (every axis is a component axis)");
    return kept;
}

// The signs that take the file's "space" to LPS: RAS and LAS flip axes; LPS, scanner-xyz, 3D-*-handed and no
// "space" keep them.
std::array<double, 3> lps_signs(const std::string& name, const Header& h) {
    const Field* f = h.fields.get("space");
    if (!f) return {1, 1, 1};
    std::string s;
    for (char c : io_detail::lower(f->value))
        if (c != '-' && c != ' ') s += c;
    if (s == "rightanteriorsuperior" || s == "ras") return {-1, -1, 1};
    if (s == "leftanteriorsuperior" || s == "las") return {1, -1, 1};
    if (s == "leftposteriorsuperior" || s == "lps" || s == "scannerxyz" || s == "3drighthanded" ||
        s == "3dlefthanded")
        return {1, 1, 1};
    bad(name, *f, "space", "is not supported (3-D spaces: RAS, LAS, LPS, scanner-xyz, 3D-right-handed)");
}

// The unit space directions of the kept axes as the columns of g.direction (in LPS), and the origin in LPS. Two
// given directions get the third as their cross product; with fewer, the grid stays axis-aligned.
void nrrd_direction(const std::string& name, const Header& h, const std::vector<Axis>& kept, Grid& g) {
    const std::array<double, 3> sign = lps_signs(name, h);
    for (int r = 0; r < 3; ++r) g.origin[r] *= sign[r];
    std::size_t given = 0;
    while (given < kept.size() && given < 3 && kept[given].direction.size() == 3) ++given;
    if (given < 2 || given < std::min<std::size_t>(kept.size(), 3)) return;
    Matrix3 d{};
    for (std::size_t a = 0; a < given; ++a)
        for (int r = 0; r < 3; ++r) d[3 * r + a] = sign[r] * kept[a].direction[r] / kept[a].spacing;
    if (given == 2) {
        d[2] = d[3] * d[7] - d[6] * d[4];
        d[5] = d[6] * d[1] - d[0] * d[7];
        d[8] = d[0] * d[4] - d[3] * d[1];
    }
    const std::string problem = normalize_direction(d);
    if (!problem.empty()) bad(name, *h.fields.get("spacedirections"), "space directions", problem);
    g.direction = d;
}

// The grid of the (at most three) spatial axes; the origin from "space origin", else "axis mins".
Grid nrrd_grid(const std::string& name, const Header& h, const std::vector<Axis>& kept, bool have_mins) {
    Grid g;
    for (std::size_t a = 0; a < 3; ++a) {
        if (a >= kept.size()) {
            g.dims[a] = 1;
            continue;
        }
        g.dims[a] = kept[a].size;
        if (kept[a].has_spacing) {
            if (!std::isfinite(kept[a].spacing) || kept[a].spacing <= 0)
                fail(name, std::string("spacing along ") + "xyz"[a] + " is " + io_detail::format_double(kept[a].spacing) +
                               ": must be finite and non-zero");
            g.spacing[a] = kept[a].spacing;
        }
        if (have_mins && std::isfinite(kept[a].min)) g.origin[a] = kept[a].min;
    }
    if (const Field* f = h.fields.get("spaceorigin")) {
        std::vector<double> v;
        if (!io_detail::iequals(f->value, "none")) {
            if (!parse_vector(f->value, v)) bad(name, *f, "space origin", "must be a vector like (0,0,0)");
            g.origin = {0, 0, 0};
            for (std::size_t a = 0; a < 3 && a < v.size(); ++a) g.origin[a] = v[a];
            for (std::size_t a = 0; a < 3 && a < v.size(); ++a)
                if (!std::isfinite(v[a])) bad(name, *f, "space origin", "must be finite");
        }
    }
    nrrd_direction(name, h, kept, g);
    return g;
}

enum class Enc { Raw, Gzip, Ascii };

Enc nrrd_encoding(const std::string& name, const Header& h) {
    const Field& fenc = h.fields.need(name, "encoding", "encoding");
    const std::string enc = io_detail::lower(fenc.value);
    if (enc == "raw") return Enc::Raw;
    if (enc == "gzip" || enc == "gz") return Enc::Gzip;
    if (enc == "ascii" || enc == "text" || enc == "txt") return Enc::Ascii;
    if (enc == "bzip2" || enc == "bz2" || enc == "hex")
        bad(name, fenc, "encoding", "is not supported: re-save the file with gzip or raw encoding");
    bad(name, fenc, "encoding", "is not a known NRRD encoding (raw, gzip, ascii)");
}

bool nrrd_big_endian(const std::string& name, const Header& h, DType dtype, Enc encoding) {
    if (const Field* f = h.fields.get("endian")) {
        const std::string e = io_detail::lower(f->value);
        if (e == "big") return true;
        if (e != "little") bad(name, *f, "endian", "must be 'little' or 'big'");
    } else if (dtype_size(dtype) > 1 && encoding != Enc::Ascii) {
        fail(name, std::string("missing field 'endian' (required for ") + dtype_name(dtype) + " data)");
    }
    return false;
}

// Where the data starts: after the header's blank line or at the start of the "data file" (opened into
// `detached`), after "line skip" lines; "byte skip" is left to read_data.
io_detail::DataLocation nrrd_data_location(const ByteSource& src, const Header& h, std::unique_ptr<ByteSource>& detached) {
    const std::string& name = src.name();
    io_detail::DataLocation loc(src);
    if (const Field* f = h.fields.get("datafile")) {
        if (io_detail::names_several_files(f->value))
            bad(name, *f, "data file", "names several files: multi-file NRRD data is not supported");
        detached = src.open_sibling(f->value);
        loc.src = detached.get();
        loc.detached = true;
        loc.offset = 0;
    } else {
        if (!h.has_blank_line)
            fail(name, "no data: the header has neither a blank line followed by data nor a 'data file' field");
        loc.offset = h.data_start;
    }
    if (const Field* f = h.fields.get("lineskip")) {
        std::int64_t lines = 0;
        if (!io_detail::parse_int(f->value, lines) || lines < 0)
            bad(name, *f, "line skip", "must be a non-negative integer");
        loc.offset = io_detail::skip_lines(*loc.src, name, loc.offset, lines);
    }
    return loc;
}

// "byte skip": 0 when absent; -1 (raw data only) means the data are the last bytes of the file.
std::int64_t nrrd_byte_skip(const std::string& name, const Header& h, Enc encoding) {
    std::int64_t byte_skip = 0;
    if (const Field* f = h.fields.get("byteskip")) {
        if (!io_detail::parse_int(f->value, byte_skip) || byte_skip < -1) bad(name, *f, "byte skip", "must be -1 or more");
        if (byte_skip == -1 && encoding != Enc::Raw)
            bad(name, *f, "byte skip", "(data at the end of the file) is only valid with raw encoding");
    }
    return byte_skip;
}

Volume read_data(io_detail::DataLocation loc, Enc encoding, std::int64_t byte_skip, const Grid& g, DType dtype,
                 bool big_endian) {
    switch (encoding) {
        case Enc::Raw:
            io_detail::skip_to_data(loc, byte_skip, "byte skip", g, dtype);
            return io_detail::read_raw_voxels(loc, g, dtype, big_endian);
        case Enc::Gzip: {
            const std::uint64_t file_size = loc.src->size();
            if (loc.offset > file_size) fail(io_detail::data_subject(loc), "no compressed data after the header");
            return io_detail::read_compressed_voxels(loc, file_size - loc.offset, static_cast<std::uint64_t>(byte_skip), g,
                                                  dtype, big_endian);
        }
        case Enc::Ascii:
            io_detail::skip_to_data(loc, byte_skip, "byte skip", g, dtype);
            return io_detail::read_ascii_voxels(loc, g, dtype);
    }
    fail(loc.header, "unreachable encoding");
}

}  // namespace

Volume read_nrrd(const ByteSource& src, const ReadOptions& opt) {
    const std::string& name = src.name();
    const Header h = read_header(src);
    const DType dtype = nrrd_dtype(name, h);
    std::vector<Axis> axes = nrrd_sizes(name, h);
    nrrd_spacings(name, h, axes);
    const bool have_mins = nrrd_mins_and_kinds(name, h, axes);
    const Grid g = nrrd_grid(name, h, spatial_axes(name, axes), have_mins);
    io_detail::check_volume(name, g, dtype, opt.max_bytes);
    const Enc encoding = nrrd_encoding(name, h);
    const bool big_endian = nrrd_big_endian(name, h, dtype, encoding);
    std::unique_ptr<ByteSource> detached;
    const io_detail::DataLocation loc = nrrd_data_location(src, h, detached);
    return read_data(loc, encoding, nrrd_byte_skip(name, h, encoding), g, dtype, big_endian);
}

void write_nrrd(const std::string& path, const VolumeView& v, bool gzip) {
    io_detail::check_view(path, v);
    const Grid& g = v.grid;
    std::string h = "NRRD0004\n# Complete NRRD file format specification at:\n"
                    "# http://teem.sourceforge.net/nrrd/format.html\n# written by volrig\n";
    h += std::string("type: ") + nrrd_type_name(v.dtype) + "\n";
    h += "dimension: 3\nspace: left-posterior-superior\n";
    h += "sizes: " + std::to_string(g.dims[0]) + " " + std::to_string(g.dims[1]) + " " + std::to_string(g.dims[2]) +
         "\n";
    const auto f = io_detail::format_double;
    h += "space directions:";
    for (int a = 0; a < 3; ++a) {
        const Matrix3& d = g.direction;
        // + 0.0 writes -0 as 0
        h += " (" + f(d[a] * g.spacing[a] + 0.0) + "," + f(d[3 + a] * g.spacing[a] + 0.0) + "," +
             f(d[6 + a] * g.spacing[a] + 0.0) + ")";
    }
    h += "\n";
    h += "kinds: domain domain domain\n";
    if (dtype_size(v.dtype) > 1) h += "endian: little\n";
    h += std::string("encoding: ") + (gzip ? "gzip" : "raw") + "\n";
    h += "space origin: (" + f(g.origin[0]) + "," + f(g.origin[1]) + "," + f(g.origin[2]) + ")\n\n";
    write_atomically(path, [&](const std::string& tmp) {
        io_detail::FileWriter out(tmp, path);
        out.write(h);
        if (gzip) {
            io_detail::Deflater z(out, true);
            io_detail::little_endian_chunks(v, [&](const void* p, std::size_t n) { z.write(p, n); });
            z.finish();
        } else {
            io_detail::little_endian_chunks(v, [&](const void* p, std::size_t n) { out.write(p, n); });
        }
        out.close();
    });
}

}  // namespace volrig

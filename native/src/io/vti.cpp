// io/vti.cpp: VTK XML image data (.vti), the "VTK" section of volrig/io.hpp.
//
// Read: one piece covering the whole extent, one scalar point-data array (the PointData's active Scalars, else its
// first array) stored appended and raw (VTK's writers' default: `<AppendedData encoding="raw">_` then the bytes),
// uncompressed or zlib-compressed (vtkZLibDataCompressor: a block table, then one zlib stream per block), with
// UInt32 or UInt64 headers, either byte order. The XML before the appended data is parsed here (a few elements and
// their attributes): an XML library would choke on the raw bytes that follow, as VTK's own reader avoids too.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "io/io_detail.hpp"
#include "io/zlib_inflate.hpp"
#include "volrig/io.hpp"

namespace volrig {

namespace {

using namespace io_detail;

/// The XML of a .vti up to its appended data, and where the appended bytes start (after the '_' marker).
struct VtiText {
    std::string xml;
    std::uint64_t data_start = 0;
};

VtiText read_text(const ByteSource& src) {
    const std::string& name = src.name();
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(src.size(), kMaxHeader));
    std::string head(n, '\0');
    if (n) src.read(0, &head[0], n);
    if (head.compare(0, 5, "<?xml") != 0 && head.find("<VTKFile") == std::string::npos)
        fail(name, "not a VTK XML file (no <VTKFile> element in its first bytes)");
    const std::size_t appended = head.find("<AppendedData");
    if (appended == std::string::npos)
        fail(name, "no <AppendedData> within the first " + with_commas(kMaxHeader) +
                       " bytes: only appended data is read (inline \"binary\" and \"ascii\" arrays are not)");
    const std::size_t close = head.find('>', appended);
    const std::size_t mark = close == std::string::npos ? close : head.find('_', close);
    if (mark == std::string::npos) fail(name, "the <AppendedData> element has no '_' marker before its data");
    for (std::size_t i = close + 1; i < mark; ++i)
        if (head[i] != ' ' && head[i] != '\n' && head[i] != '\r' && head[i] != '\t')
            fail(name, "text between <AppendedData> and its '_' marker");
    return {head.substr(0, close + 1), mark + 1};
}

/// One element's start tag: its name's position and its attributes' text.
struct Tag {
    std::size_t at = std::string::npos;
    std::string_view attributes;
    bool found() const { return at != std::string::npos; }
};

/// The first start tag <name ...> at or after `from` (before `until`).
Tag find_tag(const std::string& xml, std::string_view name, std::size_t from = 0,
             std::size_t until = std::string::npos) {
    const std::string open = "<" + std::string(name);
    for (std::size_t at = xml.find(open, from); at != std::string::npos && at < until; at = xml.find(open, at + 1)) {
        const char c = at + open.size() < xml.size() ? xml[at + open.size()] : '\0';
        if (c != ' ' && c != '\t' && c != '\n' && c != '\r' && c != '>' && c != '/') continue;  // <PointDataX
        const std::size_t end = xml.find('>', at);
        if (end == std::string::npos) return {};
        const std::size_t from_attr = at + open.size();
        return {at, std::string_view(xml).substr(from_attr, end - from_attr)};
    }
    return {};
}

/// The value of attribute `key` ("" when absent); `present` says whether it was there.
std::string attribute(std::string_view attrs, std::string_view key, bool* present = nullptr) {
    for (std::size_t i = 0; i < attrs.size();) {
        while (i < attrs.size() && (attrs[i] == ' ' || attrs[i] == '\t' || attrs[i] == '\n' || attrs[i] == '\r')) ++i;
        const std::size_t eq = attrs.find('=', i);
        if (eq == std::string_view::npos) break;
        const std::string_view k = trim(attrs.substr(i, eq - i));
        std::size_t q = eq + 1;
        while (q < attrs.size() && (attrs[q] == ' ' || attrs[q] == '\t' || attrs[q] == '\n' || attrs[q] == '\r')) ++q;
        if (q >= attrs.size() || (attrs[q] != '"' && attrs[q] != '\'')) break;
        const std::size_t end = attrs.find(attrs[q], q + 1);
        if (end == std::string_view::npos) break;
        if (k == key) {
            if (present) *present = true;
            return std::string(attrs.substr(q + 1, end - q - 1));
        }
        i = end + 1;
    }
    if (present) *present = false;
    return {};
}

std::vector<double> numbers(const std::string& name, const std::string& what, const std::string& text,
                            std::size_t count) {
    std::vector<double> out;
    for (std::string_view w : split_words(text)) {
        double v = 0;
        if (!parse_double(w, v) || !std::isfinite(v)) fail(name, what + " " + quoted(text) + " is not " +
                                                                      std::to_string(count) + " finite numbers");
        out.push_back(v);
    }
    if (out.size() != count)
        fail(name, what + " " + quoted(text) + " is not " + std::to_string(count) + " finite numbers");
    return out;
}

DType vtk_type(const std::string& name, const std::string& t) {
    static const std::pair<const char*, DType> types[] = {
        {"Int8", DType::Int8},     {"UInt8", DType::UInt8},   {"Int16", DType::Int16},   {"UInt16", DType::UInt16},
        {"Int32", DType::Int32},   {"UInt32", DType::UInt32}, {"Int64", DType::Int64},   {"UInt64", DType::UInt64},
        {"Float32", DType::Float32}, {"Float64", DType::Float64}, {"Char", DType::Int8}, {"UChar", DType::UInt8}};
    for (const auto& [n, d] : types)
        if (t == n) return d;
    fail(name, "DataArray type " + quoted(t) + " is not a number type volrig reads");
}

/// The file-wide settings of <VTKFile>.
struct Layout {
    bool big_endian = false;
    std::size_t header_bytes = 4;  // UInt32 (VTK's default) or UInt64
    bool zlib = false;
};

Layout file_layout(const std::string& name, const std::string& xml) {
    const Tag f = find_tag(xml, "VTKFile");
    if (!f.found()) fail(name, "no <VTKFile> element");
    if (attribute(f.attributes, "type") != "ImageData")
        fail(name, "VTKFile type " + quoted(attribute(f.attributes, "type")) + ": only ImageData (.vti) is read");
    Layout l;
    const std::string order = attribute(f.attributes, "byte_order");
    if (order == "BigEndian") l.big_endian = true;
    else if (!order.empty() && order != "LittleEndian") fail(name, "byte_order " + quoted(order) + " is not known");
    const std::string header = attribute(f.attributes, "header_type");
    if (header == "UInt64") l.header_bytes = 8;
    else if (!header.empty() && header != "UInt32") fail(name, "header_type " + quoted(header) + " is not known");
    const std::string comp = attribute(f.attributes, "compressor");
    if (comp == "vtkZLibDataCompressor") l.zlib = true;
    else if (!comp.empty()) fail(name, "compressor " + quoted(comp) + " is not read (only vtkZLibDataCompressor)");
    return l;
}

/// The grid from <ImageData> and its one <Piece>.
Grid image_grid(const std::string& name, const std::string& xml) {
    const Tag im = find_tag(xml, "ImageData");
    if (!im.found()) fail(name, "no <ImageData> element");
    const std::vector<double> ext = numbers(name, "WholeExtent", attribute(im.attributes, "WholeExtent"), 6);
    const Tag piece = find_tag(xml, "Piece", im.at);
    if (!piece.found()) fail(name, "no <Piece> element");
    if (find_tag(xml, "Piece", piece.at + 1).found()) fail(name, "several pieces: only single-piece files are read");
    if (numbers(name, "the Piece's Extent", attribute(piece.attributes, "Extent"), 6) != ext)
        fail(name, "the piece's Extent differs from the WholeExtent: only whole single pieces are read");
    Grid g;
    bool has = false;
    const std::string sp = attribute(im.attributes, "Spacing", &has);
    const std::vector<double> s = has ? numbers(name, "Spacing", sp, 3) : std::vector<double>{1, 1, 1};
    const std::string og = attribute(im.attributes, "Origin", &has);
    const std::vector<double> o = has ? numbers(name, "Origin", og, 3) : std::vector<double>{0, 0, 0};
    const std::string dir = attribute(im.attributes, "Direction", &has);
    if (has) {
        const std::vector<double> d = numbers(name, "Direction", dir, 9);
        std::copy(d.begin(), d.end(), g.direction.begin());
    }
    for (int a = 0; a < 3; ++a) {
        const double lo = ext[2 * a], hi = ext[2 * a + 1];
        if (lo != std::floor(lo) || hi != std::floor(hi) || hi < lo || hi - lo >= double(1 << 30))
            fail(name, "WholeExtent " + quoted(attribute(im.attributes, "WholeExtent")) +
                           " is not three whole ranges lo <= hi");
        g.dims[a] = static_cast<std::int64_t>(hi - lo) + 1;
        g.spacing[a] = s[a];
    }
    // VTK: the world position of extent index i is Origin + Direction * (Spacing * i); voxel 0 is the extent's min.
    const std::array<double, 3> first{ext[0] * s[0], ext[2] * s[1], ext[4] * s[2]};
    for (int r = 0; r < 3; ++r) {
        g.origin[r] = o[r];
        for (int c = 0; c < 3; ++c) g.origin[r] += g.direction[3 * r + c] * first[c];
    }
    return g;
}

/// The array to read: the PointData's active Scalars, else its first DataArray.
struct Array {
    std::string name;
    DType type = DType::Float32;
    std::uint64_t offset = 0;
};

Array point_array(const std::string& name, const std::string& xml) {
    const Tag pd = find_tag(xml, "PointData");
    const std::size_t end = pd.found() ? xml.find("</PointData", pd.at) : std::string::npos;
    const bool empty_tag = pd.found() && !pd.attributes.empty() && pd.attributes.back() == '/';
    Tag chosen;
    if (pd.found() && !empty_tag) {
        const std::string active = attribute(pd.attributes, "Scalars");
        for (Tag t = find_tag(xml, "DataArray", pd.at, end); t.found(); t = find_tag(xml, "DataArray", t.at + 1, end))
            if (!chosen.found() || (!active.empty() && attribute(t.attributes, "Name") == active)) {
                chosen = t;
                if (!active.empty() && attribute(t.attributes, "Name") == active) break;
            }
    }
    if (!chosen.found())
        fail(name, find_tag(xml, "DataArray").found() ? "no point data array (cell data is not read)"
                                                      : "no DataArray");
    Array a;
    a.name = attribute(chosen.attributes, "Name");
    const std::string what = "DataArray " + quoted(a.name);
    a.type = vtk_type(name, attribute(chosen.attributes, "type"));
    const std::string comps = attribute(chosen.attributes, "NumberOfComponents");
    if (!comps.empty() && comps != "1")
        fail(name, what + " has " + quoted(comps) + " components: only scalars are read");
    if (attribute(chosen.attributes, "format") != "appended")
        fail(name, what + " is stored " + quoted(attribute(chosen.attributes, "format")) +
                       ": only appended data is read");
    std::int64_t off = -1;
    if (!parse_int(trim(attribute(chosen.attributes, "offset")), off) || off < 0)
        fail(name, what + "'s offset " + quoted(attribute(chosen.attributes, "offset")) + " is not a byte offset");
    a.offset = static_cast<std::uint64_t>(off);
    return a;
}

/// An unsigned header word (4 or 8 bytes, in the file's byte order) at `at`.
std::uint64_t header_word(const ByteSource& src, std::uint64_t at, const Layout& l) {
    std::uint8_t b[8] = {};
    src.read(at, b, l.header_bytes);
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < l.header_bytes; ++i) {
        const std::size_t k = l.big_endian ? i : l.header_bytes - 1 - i;
        v = v << 8 | b[k];
    }
    return v;
}

/// The zlib block table at `at`: block count, block size, last block's size, each block's compressed size.
Volume read_blocks(const ByteSource& src, std::uint64_t at, const Layout& l, const Grid& g, DType t,
                   const std::string& what) {
    const std::string& name = src.name();
    const std::uint64_t need = static_cast<std::uint64_t>(g.voxel_count()) * dtype_size(t);
    const std::uint64_t blocks = header_word(src, at, l), size = header_word(src, at + l.header_bytes, l);
    std::uint64_t last = header_word(src, at + 2 * l.header_bytes, l);
    if (last == 0) last = size;
    if (blocks == 0 || size == 0 || last > size || blocks > need / size + 1 ||
        (blocks - 1) * size + last != need)
        fail(name, what + "'s block table (" + with_commas(blocks) + " blocks of " + with_commas(size) +
                       " bytes, the last " + with_commas(last) + ") does not make the " + with_commas(need) +
                       " bytes of " + describe(g.dims, t));
    std::uint64_t pos = at + (3 + blocks) * l.header_bytes;
    if (pos > src.size()) fail(name, what + "'s block table runs past the end of the file");
    std::vector<std::uint64_t> packed(static_cast<std::size_t>(blocks));
    std::uint64_t total = 0;
    for (std::uint64_t k = 0; k < blocks; ++k) {
        packed[k] = header_word(src, at + (3 + k) * l.header_bytes, l);
        if (packed[k] > src.size() - pos - total)
            fail(name, what + "'s compressed blocks run past the end of the file");
        total += packed[k];
    }
    check_inflate_bound(name, need, total);
    Volume v = allocate(g, t);
    for (std::uint64_t k = 0; k < blocks; ++k) {
        const std::uint64_t n = k + 1 == blocks ? last : size;
        Inflater inf(src, pos, packed[k], name + ": " + what + " block " + std::to_string(k + 1), n);
        inf.read(v.data.data() + k * size, static_cast<std::size_t>(n));
        inf.finish();
        pos += packed[k];
    }
    if (l.big_endian != host_is_big_endian()) swap_bytes(v.data.data(), v.data.size() / dtype_size(t), dtype_size(t));
    return v;
}

}  // namespace

Volume read_vti(const ByteSource& src, const ReadOptions& opt) {
    const std::string& name = src.name();
    const VtiText text = read_text(src);
    const Layout l = file_layout(name, text.xml);
    const Grid g = image_grid(name, text.xml);
    const Array a = point_array(name, text.xml);
    const std::uint64_t bytes = check_volume(name, g, a.type, opt.max_bytes);
    check_budget(name, bytes, src.size(), opt, "the " + describe(g.dims, a.type) + " voxels");
    const std::string what = "DataArray " + quoted(a.name);
    if (a.offset > src.size() - text.data_start) fail(name, what + "'s offset runs past the end of the file");
    const std::uint64_t at = text.data_start + a.offset;
    const std::uint64_t words = l.zlib ? 3 : 1;  // the block table's first three words, or the byte count
    if (words * l.header_bytes > src.size() - at) fail(name, what + "'s header runs past the end of the file");
    if (l.zlib) return read_blocks(src, at, l, g, a.type, what);
    const std::uint64_t n = header_word(src, at, l);
    if (n != bytes)
        fail(name, what + " holds " + with_commas(n) + " bytes but " + describe(g.dims, a.type) + " needs " +
                       with_commas(bytes));
    DataLocation loc(src);
    loc.offset = at + l.header_bytes;
    return read_raw_voxels(loc, g, a.type, l.big_endian);
}

}  // namespace volrig

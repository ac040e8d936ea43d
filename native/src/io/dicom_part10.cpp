// io/dicom_part10.cpp: a structural check of a DICOM Part-10 file before GDCM sees it (io/io_detail.hpp).
//
// Why hand-written: Debian's GDCM aborts the process (failed internal assertions) on some malformed files, e.g.
// a meta element whose length runs past the end of the file. So every file is walked first: the 128-byte
// preamble and "DICM", the file meta group (explicit VR little endian), then the data set in the transfer syntax
// the meta group names (implicit or explicit VR, either byte order), every explicit VR one DICOM knows, every
// element's length bounded by the bytes left, sequences and items (defined or undefined length, nested at most
// kMaxDepth deep) and encapsulated pixel data walked item by item. Values are skipped, not read: only element
// headers are. Deflated data sets cannot be walked and are refused. Then the image pixel module values GDCM
// asserts on (samples per pixel, bits allocated/stored, high bit, ...) are checked, and RLE frames (headers,
// segment offsets, every run within its segment and frame), which GDCM's RLE decoder overruns on, and native
// pixel data of the size the image module declares (GDCM's raw decoder copies past a shorter one). The caller may
// check each explicit VR against the tag's (GDCM's dictionary: GDCM asserts on a VR its attribute does not allow). GDCM still does all the parsing and decoding; this only refuses what it cannot survive.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include "io/io_detail.hpp"

namespace volrig::io_detail {

namespace {

constexpr int kMaxDepth = 16;
constexpr std::uint32_t kUndefined = 0xffffffffu;
constexpr std::uint16_t kItemGroup = 0xfffe;
constexpr std::uint16_t kItem = 0xe000, kItemEnd = 0xe00d, kSequenceEnd = 0xe0dd;

struct Walker {
    const ByteSource& src;
    std::uint64_t size;
    bool explicit_vr = true;
    bool big = false;  // byte order of the data set (the meta group is always little endian)
    std::map<std::uint16_t, std::string> image;  // top-level (0028,xxxx) values of at most 64 bytes
    std::string syntax;                           // the transfer syntax UID
    std::int64_t pixel_bytes = -1;                // length of the top-level native pixel data (-1: none)
    std::vector<std::pair<std::uint64_t, std::uint32_t>> fragments;  // encapsulated pixel data: offset, length
    std::function<bool(std::uint16_t, std::uint16_t, const char*)> vr_ok;  // the VR suits the tag (may be empty)

    [[noreturn]] void bad(std::uint64_t at, const std::string& what) const {
        fail(src.name(), "broken DICOM structure at byte " + with_commas(at) + ": " + what);
    }
    std::uint16_t u16(const std::uint8_t* p, bool be) const {
        return static_cast<std::uint16_t>(be ? (p[0] << 8) | p[1] : (p[1] << 8) | p[0]);
    }
    std::uint32_t u32(const std::uint8_t* p, bool be) const {
        return be ? (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | p[3]
                  : (std::uint32_t(p[3]) << 24) | (std::uint32_t(p[2]) << 16) | (std::uint32_t(p[1]) << 8) | p[0];
    }
    void need(std::uint64_t at, std::uint64_t n, const char* what) const {
        if (at > size || n > size - at) bad(at, std::string(what) + " runs past the end of the file");
    }
};

struct Element {
    std::uint16_t group = 0, elem = 0;
    char vr[3] = {0, 0, 0};
    std::uint32_t length = 0;
    std::uint64_t value_at = 0;  // first value byte
};

// The value representations of DICOM PS3.5 (GDCM aborts on others in explicit VR files).
bool known_vr(const char* vr) {
    static const char* const all[] = {"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FL", "FD", "IS", "LO", "LT", "OB",
                                      "OD", "OF", "OL", "OV", "OW", "PN", "SH", "SL", "SQ", "SS", "ST", "SV", "TM",
                                      "UC", "UI", "UL", "UN", "UR", "US", "UT", "UV"};
    for (const char* k : all)
        if (vr[0] == k[0] && vr[1] == k[1]) return true;
    return false;
}

bool long_vr(const char* vr) {
    static const char* const longs[] = {"OB", "OW", "OF", "SQ", "UT", "UN", "UC", "UR", "OD", "OL", "OV", "SV", "UV"};
    for (const char* l : longs)
        if (vr[0] == l[0] && vr[1] == l[1]) return true;
    return false;
}

// Reads the element header at `at` (explicit or implicit VR; item tags have no VR).
Element header_at(const Walker& w, std::uint64_t at, bool explicit_vr, bool be) {
    std::uint8_t h[12];
    w.need(at, 8, "an element header");
    w.src.read(at, h, 8);
    Element e;
    e.group = w.u16(h, be);
    e.elem = w.u16(h + 2, be);
    if (e.group == kItemGroup || !explicit_vr) {
        e.length = w.u32(h + 4, be);
        e.value_at = at + 8;
        return e;
    }
    e.vr[0] = static_cast<char>(h[4]);
    e.vr[1] = static_cast<char>(h[5]);
    if (!known_vr(e.vr))
        w.bad(at, "value representation " + quoted(std::string_view(e.vr, 2)) + " is not a DICOM VR");
    if (!long_vr(e.vr)) {
        e.length = w.u16(h + 6, be);
        e.value_at = at + 8;
        return e;
    }
    w.need(at, 12, "an element header");
    w.src.read(at + 8, h + 8, 4);
    e.length = w.u32(h + 8, be);
    e.value_at = at + 12;
    return e;
}

std::uint64_t walk_items(Walker& w, std::uint64_t at, std::uint64_t end, int depth, bool fragments);

std::string hex4(std::uint16_t v) {
    char buf[8];
    std::snprintf(buf, sizeof buf, "%04X", v);
    return buf;
}

// Keeps a short image pixel module value (0028,xxxx) for check_image_module.
void keep_image_value(Walker& w, const Element& e) {
    std::string v(e.length, '\0');
    w.need(e.value_at, e.length, "an element's value");
    if (e.length) w.src.read(e.value_at, &v[0], e.length);
    w.image[e.elem] = v;
}

// A kept US value (binary), or -1 when absent or not two bytes.
int us_value(const Walker& w, std::uint16_t elem) {
    auto it = w.image.find(elem);
    if (it == w.image.end() || it->second.size() != 2) return -1;
    return w.u16(reinterpret_cast<const std::uint8_t*>(it->second.data()), w.big);
}

// The image pixel module values GDCM asserts on (it aborts the process on samples per pixel above 4, bits stored
// above bits allocated, ...), checked before it sees them; what volrig cannot read (colour) is refused here too.
void check_image_module(const Walker& w) {
    const int spp = us_value(w, 0x0002), rows = us_value(w, 0x0010), cols = us_value(w, 0x0011);
    const int ba = us_value(w, 0x0100), bs = us_value(w, 0x0101), hb = us_value(w, 0x0102), pr = us_value(w, 0x0103);
    const std::string name = w.src.name();
    if (rows <= 0 || cols <= 0) fail(name, "no valid Rows/Columns: not a DICOM image");
    if (spp != 1) fail(name, "samples per pixel " + std::to_string(spp) + ": only single-channel (grey) images are supported");
    if (ba != 8 && ba != 16 && ba != 32 && ba != 64)
        fail(name, "bits allocated " + std::to_string(ba) + " is not supported (8, 16, 32 or 64)");
    if (bs != -1 && (bs < 1 || bs > ba)) fail(name, "bits stored " + std::to_string(bs) + " is not 1 to bits allocated");
    if (hb != -1 && (hb < 0 || hb >= (bs == -1 ? ba : bs))) fail(name, "high bit " + std::to_string(hb) + " is out of range");
    if (pr != -1 && pr != 0 && pr != 1) fail(name, "pixel representation " + std::to_string(pr) + " is not 0 or 1");
    // GDCM asserts on a zero slope, which it also takes when an intercept comes without a (non-empty) slope.
    const auto slope = w.image.find(0x1053);
    if (slope != w.image.end() || w.image.count(0x1052)) {
        double v = 0;
        const std::string text = slope == w.image.end() ? "" : std::string(trim(slope->second.c_str()));
        if (!parse_double(text.substr(0, text.find('\\')), v) || !std::isfinite(v) || v == 0)
            fail(name, "RescaleSlope " + quoted(text) + " is not a finite non-zero number (with a RescaleIntercept)");
    }
    auto it = w.image.find(0x0004);
    std::string pi = it == w.image.end() ? "" : std::string(trim(it->second.c_str()));
    if (pi != "MONOCHROME1" && pi != "MONOCHROME2")
        fail(name, "photometric interpretation " + quoted(pi) + ": only MONOCHROME1/2 images are supported");
}

// Where a walk from `at` stops (`end`, or the file's end when 0); refuses nesting deeper than kMaxDepth.
std::uint64_t walk_stop(Walker& w, std::uint64_t at, std::uint64_t end, int depth) {
    if (depth > kMaxDepth) w.bad(at, "sequences nested more than " + std::to_string(kMaxDepth) + " deep");
    return end ? end : w.size;
}

// The element at `at`, refused when its tag already appeared in the data set (`seen`): GDCM keeps the first, the
// checks below the last.
Element element_once(Walker& w, std::uint64_t at, std::set<std::uint32_t>& seen) {
    const Element e = header_at(w, at, w.explicit_vr, w.big);
    if (e.group != kItemGroup && !seen.insert((std::uint32_t(e.group) << 16) | e.elem).second)
        w.bad(at, "element (" + hex4(e.group) + "," + hex4(e.elem) + ") appears twice in one data set");
    return e;
}

// Walks the elements from `at` to `end` (or to an item delimiter when `end` is 0: returns just past it).
std::uint64_t walk_elements(Walker& w, std::uint64_t at, std::uint64_t end, int depth) {
    const std::uint64_t stop = walk_stop(w, at, end, depth);
    std::set<std::uint32_t> seen;
    while (at < stop) {
        const Element e = element_once(w, at, seen);
        if (e.group == kItemGroup) {
            if (!end && e.elem == kItemEnd) {
                if (e.length != 0) w.bad(at, "an item delimiter with a non-zero length");
                return e.value_at;
            }
            w.bad(at, "an item tag where an element was expected");
        }
        if (w.explicit_vr && w.vr_ok && !w.vr_ok(e.group, e.elem, e.vr))
            w.bad(at, "element (" + hex4(e.group) + "," + hex4(e.elem) + ") has VR " + std::string(e.vr, 2) +
                          ", which its tag does not allow");
        if (depth == 0 && e.group == 0x0028 && e.length != kUndefined && e.length <= 64) keep_image_value(w, e);
        const bool pixels = e.group == 0x7fe0 && e.elem == 0x0010;
        if (pixels && depth == 0 && e.length != kUndefined) w.pixel_bytes = e.length;
        const bool sequence = std::strncmp(e.vr, "SQ", 2) == 0 || (!w.explicit_vr && e.length == kUndefined);
        if (e.length == kUndefined) {
            if (!sequence && !pixels && std::strncmp(e.vr, "UN", 2) != 0)
                w.bad(at, "undefined length on a " + quoted(std::string_view(e.vr, 2)) + " element");
            at = walk_items(w, e.value_at, 0, depth + 1, pixels);
        } else {
            w.need(e.value_at, e.length, "an element's value");
            if (std::strncmp(e.vr, "SQ", 2) == 0 && e.length > 0) walk_items(w, e.value_at, e.value_at + e.length, depth + 1, false);
            at = e.value_at + e.length;
        }
        if (end && at > end) w.bad(at, "an element runs past the end of its item");
    }
    if (!end) w.bad(at, "an item without its delimiter");
    return at;
}

// Walks sequence items from `at` to `end` (or to a sequence delimiter when `end` is 0: returns just past it).
// `fragments`: encapsulated pixel data (items hold bytes, not data sets).
std::uint64_t walk_items(Walker& w, std::uint64_t at, std::uint64_t end, int depth, bool fragments) {
    const std::uint64_t stop = walk_stop(w, at, end, depth);
    std::set<std::uint32_t> seen;
    while (at < stop) {
        const Element e = element_once(w, at, seen);
        if (e.group != kItemGroup) w.bad(at, "an element where a sequence item was expected");
        if (e.elem == kSequenceEnd) {
            if (end) w.bad(at, "a sequence delimiter in a sequence of defined length");
            if (e.length != 0) w.bad(at, "a sequence delimiter with a non-zero length");
            return e.value_at;
        }
        if (e.elem != kItem) w.bad(at, "an unknown item tag");
        if (e.length == kUndefined) {
            if (fragments) w.bad(at, "a pixel data fragment of undefined length");
            at = walk_elements(w, e.value_at, 0, depth + 1);
        } else {
            w.need(e.value_at, e.length, "a sequence item");
            if (!fragments && e.length > 0) walk_elements(w, e.value_at, e.value_at + e.length, depth + 1);
            if (fragments && depth == 1) w.fragments.emplace_back(e.value_at, e.length);
            at = e.value_at + e.length;
        }
    }
    if (!end) w.bad(at, "a sequence without its delimiter");
    if (at != end) w.bad(at, "an item runs past the end of its sequence");
    return at;
}

// The file meta group (explicit VR little endian); sets how the data set is encoded and returns where it starts.
std::uint64_t walk_meta(Walker& w) {
    std::uint64_t at = 132;
    std::string syntax;
    std::set<std::uint16_t> seen;  // GDCM keeps the first of a repeated element, the checks below would the last
    while (at < w.size) {
        const Element e = header_at(w, at, true, false);
        if (e.group != 0x0002) break;
        if (!seen.insert(e.elem).second) w.bad(at, "element (0002," + hex4(e.elem) + ") appears twice in the file meta group");
        if (e.length == kUndefined) w.bad(at, "undefined length in the file meta group");
        if (std::strncmp(e.vr, "SQ", 2) == 0 || std::strncmp(e.vr, "UN", 2) == 0)  // GDCM asserts on these here
            w.bad(at, "a " + std::string(e.vr, 2) + " element in the file meta group");
        w.need(e.value_at, e.length, "a file meta element");
        if (e.elem == 0x0010) {
            if (e.length > 64) w.bad(at, "a transfer syntax UID longer than 64 bytes");
            syntax.resize(e.length);
            if (e.length) w.src.read(e.value_at, &syntax[0], e.length);
            syntax.resize(std::strlen(syntax.c_str()));  // up to the first NUL, as GDCM reads it
            while (!syntax.empty() && syntax.back() == ' ') syntax.pop_back();
        }
        at = e.value_at + e.length;
    }
    if (syntax.empty()) w.bad(at, "no transfer syntax UID (0002,0010) in the file meta group");
    if (syntax == "1.2.840.10008.1.2.1.99")
        fail(w.src.name(), "deflated DICOM (transfer syntax 1.2.840.10008.1.2.1.99) is not supported");
    w.syntax = syntax;
    w.explicit_vr = syntax != "1.2.840.10008.1.2";
    w.big = syntax == "1.2.840.10008.1.2.2";
    return at;
}

// One RLE segment (PackBits) from `at` to `end` may write at most `room` bytes and must not read past `end`.
void check_rle_segment(const Walker& w, std::uint64_t at, std::uint64_t end, std::uint64_t room) {
    std::vector<std::uint8_t> in(static_cast<std::size_t>(end - at));
    if (!in.empty()) w.src.read(at, in.data(), in.size());
    std::uint64_t out = 0;
    for (std::size_t i = 0; i < in.size() && out < room;) {
        const auto n = static_cast<std::int8_t>(in[i++]);
        if (n == -128) continue;
        const std::uint64_t run = n >= 0 ? std::uint64_t(n) + 1 : std::uint64_t(1 - n);
        const std::size_t take = n >= 0 ? static_cast<std::size_t>(run) : 1;
        if (in.size() - i < take) w.bad(at + i, "an RLE run reads past the end of its segment");
        if (out + run > room) w.bad(at + i, "an RLE run writes past the end of the frame");
        i += take;
        out += run;
    }
}

// RLE Lossless pixel data (GDCM's decoder overruns on broken headers): per frame fragment, a 64-byte header with
// as many segments as bytes per pixel, ascending offsets inside the fragment, and segments that stay in bounds.
void check_rle(const Walker& w) {
    const std::uint64_t room = std::uint64_t(us_value(w, 0x0010)) * static_cast<std::uint64_t>(us_value(w, 0x0011));
    const int segments = us_value(w, 0x0100) / 8;
    if (w.fragments.size() < 2) fail(w.src.name(), "RLE pixel data without frames");
    for (std::size_t f = 1; f < w.fragments.size(); ++f) {  // fragment 0 is the basic offset table
        const auto [at, len] = w.fragments[f];
        std::uint8_t h[64];
        if (len < 64) w.bad(at, "an RLE frame shorter than its 64-byte header");
        w.src.read(at, h, 64);
        if (static_cast<int>(w.u32(h, false)) != segments)
            w.bad(at, "an RLE frame with " + std::to_string(w.u32(h, false)) + " segments where " +
                          std::to_string(segments) + " were expected");
        for (int k = 0; k < segments; ++k) {
            const std::uint32_t start = w.u32(h + 4 + 4 * k, false);
            const std::uint32_t stop = k + 1 < segments ? w.u32(h + 8 + 4 * k, false) : len;
            if (start < 64 || start >= stop || stop > len)  // GDCM asserts on an empty segment too
                w.bad(at, "RLE segment offsets out of order or range");
            check_rle_segment(w, at + start, at + stop, room);
        }
    }
}

// Native (uncompressed) pixel data must hold rows x columns x frames samples (an odd byte of padding allowed):
// GDCM's raw decoder copies past a shorter element.
void check_native_pixels(const Walker& w) {
    std::int64_t frames = 1;
    if (auto f = w.image.find(0x0008); f != w.image.end()) {
        const std::string text(trim(f->second.c_str()));
        if (!text.empty() && (!parse_int(text, frames) || frames < 1 || frames > 1000000))
            fail(w.src.name(), "NumberOfFrames " + quoted(text) + " is not a positive integer");
    }
    const std::int64_t want = std::int64_t(us_value(w, 0x0010)) * us_value(w, 0x0011) * frames * (us_value(w, 0x0100) / 8);
    if (w.pixel_bytes < want || w.pixel_bytes > want + 1)
        fail(w.src.name(), "pixel data holds " + with_commas(static_cast<std::uint64_t>(w.pixel_bytes)) +
                               " bytes where rows x columns x frames need " + with_commas(static_cast<std::uint64_t>(want)));
}

}  // namespace

std::string check_dicom_part10(const ByteSource& src,
                               const std::function<bool(std::uint16_t, std::uint16_t, const char*)>& vr_ok) {
    Walker w{src, src.size(), true, false, {}, {}, -1, {}, vr_ok};
    char magic[4] = {0, 0, 0, 0};
    if (w.size >= 132) src.read(128, magic, 4);
    if (std::memcmp(magic, "DICM", 4) != 0)
        fail(src.name(), "not a DICOM Part-10 file (no 'DICM' after the 128-byte preamble)");
    walk_elements(w, walk_meta(w), w.size, 0);
    check_image_module(w);
    if (w.syntax == "1.2.840.10008.1.2.5") check_rle(w);
    if (w.pixel_bytes >= 0) check_native_pixels(w);
    return w.syntax;
}

bool dicom_needs_isolation(const std::string& syntax) {
    return syntax != "1.2.840.10008.1.2" && syntax != "1.2.840.10008.1.2.1" && syntax != "1.2.840.10008.1.2.2" &&
           syntax != "1.2.840.10008.1.2.5";
}

}  // namespace volrig::io_detail

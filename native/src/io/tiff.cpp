// io/tiff.cpp: TIFF stacks through libtiff (io.hpp says what is read and refused).
//
// libtiff does the TIFF (every compression it was built with, strips and tiles, either byte order); it reads
// through a ByteSource (TIFFClientOpenExt), so files and memory go the same way, and its errors and warnings are
// caught per file (never printed, never the process-wide handlers). This file checks that every page is a
// single-channel image of one size and type, sizes the stack against max_bytes before allocating, and copies
// the pages into it.
#include <tiffio.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>

#include "io/io_detail.hpp"
#include "volrig/io.hpp"

namespace volrig {

namespace {

using io_detail::fail;

// ---- libtiff on a ByteSource ---------------------------------------------------------------------------------

struct Client {
    const ByteSource* src = nullptr;
    std::uint64_t pos = 0;
    std::string error;  // libtiff's first error message
};

tmsize_t client_read(thandle_t h, void* buf, tmsize_t n) {
    auto* c = static_cast<Client*>(h);
    const std::uint64_t size = c->src->size();
    if (n <= 0 || c->pos >= size) return 0;
    const auto take = static_cast<std::size_t>(std::min<std::uint64_t>(static_cast<std::uint64_t>(n), size - c->pos));
    try {
        c->src->read(c->pos, buf, take);
    } catch (const std::exception& e) {
        if (c->error.empty()) c->error = e.what();
        return -1;
    }
    c->pos += take;
    return static_cast<tmsize_t>(take);
}
tmsize_t client_write(thandle_t, void*, tmsize_t) { return -1; }
toff_t client_seek(thandle_t h, toff_t off, int whence) {
    auto* c = static_cast<Client*>(h);
    const std::uint64_t base = whence == SEEK_CUR ? c->pos : whence == SEEK_END ? c->src->size() : 0;
    c->pos = base + off;
    return c->pos;
}
int client_close(thandle_t) { return 0; }
toff_t client_size(thandle_t h) { return static_cast<Client*>(h)->src->size(); }
int client_map(thandle_t, void**, toff_t*) { return 0; }
void client_unmap(thandle_t, void*, toff_t) {}

int on_error(TIFF*, void* user, const char* module, const char* fmt, va_list ap) {
    auto* c = static_cast<Client*>(user);
    if (c->error.empty()) {
        char buf[512];
        std::vsnprintf(buf, sizeof buf, fmt, ap);
        c->error = (module ? std::string(module) + ": " : std::string()) + buf;
    }
    return 1;  // handled: libtiff's process-wide handler is not called
}
int on_warning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

// An open TIFF file; closes itself.
class TiffFile {
public:
    explicit TiffFile(const ByteSource& src) {
        client_.src = &src;
        TIFFOpenOptions* o = TIFFOpenOptionsAlloc();
        TIFFOpenOptionsSetErrorHandlerExtR(o, on_error, &client_);
        TIFFOpenOptionsSetWarningHandlerExtR(o, on_warning, &client_);
        tif_ = TIFFClientOpenExt(src.name().c_str(), "rm", &client_, client_read, client_write, client_seek,
                                 client_close, client_size, client_map, client_unmap, o);
        TIFFOpenOptionsFree(o);
        if (!tif_) fail(src.name(), "not a TIFF file libtiff can read" + because());
    }
    ~TiffFile() {
        if (tif_) TIFFClose(tif_);
    }
    TiffFile(const TiffFile&) = delete;
    TiffFile& operator=(const TiffFile&) = delete;

    TIFF* get() const { return tif_; }
    const std::string& name() const { return client_.src->name(); }
    /// " (libtiff: <message>)" when libtiff said why, else "".
    std::string because() const { return client_.error.empty() ? "" : " (libtiff: " + client_.error + ")"; }
    /// Fails "<name>: <where>: <libtiff's message>" when libtiff reported an error (e.g. a broken next page).
    void check(const std::string& where) const {
        if (!client_.error.empty()) fail(name(), where + ": " + client_.error);
    }

private:
    Client client_;
    TIFF* tif_ = nullptr;
};

// ---- pages ---------------------------------------------------------------------------------------------------

struct Page {
    std::uint32_t width = 0, height = 0;
    DType dtype = DType::UInt8;
};

bool dtype_for(std::uint16_t format, std::uint16_t bits, DType& t) {
    // key: SampleFormat * 100 + BitsPerSample
    static constexpr std::array<std::pair<int, DType>, 8> kTypes{{{108, DType::UInt8}, {116, DType::UInt16},
        {132, DType::UInt32}, {208, DType::Int8}, {216, DType::Int16}, {232, DType::Int32}, {332, DType::Float32},
        {364, DType::Float64}}};
    return io_detail::dtype_from_table(kTypes, format * 100 + bits, t);
}

// The current page's size and type; fails for colour, palette, bilevel and unsupported samples.
Page page_of(const TiffFile& f, int index) {
    TIFF* t = f.get();
    const std::string where = f.name() + ": page " + std::to_string(index + 1);
    Page p;
    std::uint16_t spp = 1, bits = 1, format = SAMPLEFORMAT_UINT, photometric = PHOTOMETRIC_MINISBLACK;
    if (!TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &p.width) || !TIFFGetField(t, TIFFTAG_IMAGELENGTH, &p.height) ||
        p.width == 0 || p.height == 0)
        throw FileFormatError(where + ": no image size");
    TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLESPERPIXEL, &spp);
    TIFFGetFieldDefaulted(t, TIFFTAG_BITSPERSAMPLE, &bits);
    TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLEFORMAT, &format);
    TIFFGetFieldDefaulted(t, TIFFTAG_PHOTOMETRIC, &photometric);
    if (spp != 1)
        throw FileFormatError(where + ": " + std::to_string(spp) +
                              " samples per pixel: only single-channel (grey) images are supported");
    if (photometric == PHOTOMETRIC_PALETTE)
        throw FileFormatError(where + ": a palette (indexed colour) image is not supported");
    if (!dtype_for(format, bits, p.dtype))
        throw FileFormatError(where + ": " + std::to_string(bits) + "-bit samples of format " + std::to_string(format) +
                              " are not supported (8/16/32-bit integers, 32/64-bit floats)");
    return p;
}

// Copies the current page (stripped or tiled) into dst, rows of width * esize bytes.
void read_page(const TiffFile& f, const Page& p, std::uint8_t* dst, int index) {
    TIFF* t = f.get();
    const std::size_t esize = dtype_size(p.dtype), row = static_cast<std::size_t>(p.width) * esize;
    const std::string where = f.name() + ": page " + std::to_string(index + 1);
    if (!TIFFIsTiled(t)) {
        if (static_cast<std::size_t>(TIFFScanlineSize64(t)) != row) throw FileFormatError(where + ": unexpected row size");
        for (std::uint32_t y = 0; y < p.height; ++y)
            if (TIFFReadScanline(t, dst + y * row, y, 0) < 0)
                throw FileFormatError(where + ": cannot read row " + std::to_string(y) + f.because());
        return;
    }
    std::uint32_t tw = 0, th = 0;
    TIFFGetField(t, TIFFTAG_TILEWIDTH, &tw);
    TIFFGetField(t, TIFFTAG_TILELENGTH, &th);
    const std::uint64_t tile_bytes = std::uint64_t(tw) * th * esize;
    if (tw == 0 || th == 0 || static_cast<std::uint64_t>(TIFFTileSize64(t)) != tile_bytes ||
        tile_bytes > (std::uint64_t(1) << 28))
        throw FileFormatError(where + ": unexpected tile size " + std::to_string(tw) + "x" + std::to_string(th));
    std::vector<std::uint8_t> tile(std::size_t(tw) * th * esize);
    for (std::uint32_t y0 = 0; y0 < p.height; y0 += th)
        for (std::uint32_t x0 = 0; x0 < p.width; x0 += tw) {
            if (TIFFReadTile(t, tile.data(), x0, y0, 0, 0) < 0)
                throw FileFormatError(where + ": cannot read the tile at " + std::to_string(x0) + ", " +
                                      std::to_string(y0) + f.because());
            const std::size_t w = std::min(tw, p.width - x0) * esize;
            const std::uint32_t rows = std::min<std::uint64_t>(th, p.height - y0);
            for (std::uint32_t y = 0; y < rows; ++y)
                std::memcpy(dst + (std::size_t(y0) + y) * row + std::size_t(x0) * esize,
                            tile.data() + std::size_t(y) * tw * esize, w);
        }
}

// Spacing (x, y) in mm from XResolution/YResolution and ResolutionUnit (1 when absent or unit-less).
std::array<double, 2> resolution_spacing(const TiffFile& f) {
    float xr = 0, yr = 0;
    std::uint16_t unit = RESUNIT_INCH;
    TIFFGetFieldDefaulted(f.get(), TIFFTAG_RESOLUTIONUNIT, &unit);
    const double per = unit == RESUNIT_INCH ? 25.4 : unit == RESUNIT_CENTIMETER ? 10.0 : 0.0;
    std::array<double, 2> out{1.0, 1.0};
    if (per > 0 && TIFFGetField(f.get(), TIFFTAG_XRESOLUTION, &xr) && std::isfinite(xr) && xr > 0) out[0] = per / xr;
    if (per > 0 && TIFFGetField(f.get(), TIFFTAG_YRESOLUTION, &yr) && std::isfinite(yr) && yr > 0) out[1] = per / yr;
    return out;
}

// Fails unless page p matches the first page.
void check_same(const std::string& name, int index, const Page& first, const Page& p) {
    if (p.width != first.width || p.height != first.height || p.dtype != first.dtype)
        fail(name, "page " + std::to_string(index + 1) + " is " + std::to_string(p.width) + "x" +
                       std::to_string(p.height) + " " + dtype_name(p.dtype) + " where the first page is " +
                       std::to_string(first.width) + "x" + std::to_string(first.height) + " " + dtype_name(first.dtype) +
                       ": every slice must have one size and type");
}

// The pages of each file: their shape (checked alike) and count.
struct Stack {
    Page first;
    std::array<double, 2> spacing{1, 1};
    std::int64_t pages = 0;
    std::uint64_t file_bytes = 0;  // of every file
};

void add_file(Stack& s, const ByteSource& src, const ReadOptions& opt) {
    TiffFile f(src);
    s.file_bytes += src.size();
    int index = 0;
    do {
        const Page p = page_of(f, index);
        io_detail::check_budget(src.name(), std::uint64_t(p.width) * p.height * dtype_size(p.dtype), src.size(), opt,
                                "page " + std::to_string(index + 1) + "'s " + std::to_string(p.width) + " x " +
                                    std::to_string(p.height) + " " + dtype_name(p.dtype) + " pixels");
        if (s.pages == 0) {
            s.first = p;
            s.spacing = resolution_spacing(f);
        } else {
            check_same(src.name(), index, s.first, p);
        }
        ++s.pages;
        ++index;
    } while (TIFFReadDirectory(f.get()));
    f.check("after page " + std::to_string(index));
}

// Reads every page of the file into dst (room for `room` bytes); returns the bytes written.
std::size_t copy_file(const ByteSource& src, const Page& first, std::uint8_t* dst, std::size_t room) {
    TiffFile f(src);
    const std::size_t bytes = std::size_t(first.width) * first.height * dtype_size(first.dtype);
    std::size_t done = 0;
    int index = 0;
    do {
        check_same(src.name(), index, first, page_of(f, index));
        if (room - done < bytes) fail(src.name(), "the file changed while it was being read");
        read_page(f, first, dst + done, index);
        done += bytes;
        ++index;
    } while (TIFFReadDirectory(f.get()));
    f.check("after page " + std::to_string(index));
    return done;
}

Grid grid_of(const Stack& s, const ReadOptions& opt) {
    Grid g;
    g.dims = {s.first.width, s.first.height, s.pages};
    g.spacing = {s.spacing[0], s.spacing[1], s.spacing[0]};
    for (int a = 0; a < 3; ++a)
        if (opt.spacing[a] > 0) g.spacing[a] = opt.spacing[a];
    if (!(opt.spacing[2] > 0)) g.spacing[2] = g.spacing[0];
    return g;
}

// Calls its argument with each source of a stack in order (opening files one at a time).
using EachSource = std::function<void(const std::function<void(const ByteSource&)>&)>;

// Two passes over the sources: the pages' shape and count, then (sized against max_bytes) their pixels.
Volume read_sources(const std::string& name, const EachSource& each, const ReadOptions& opt) {
    Stack s;
    each([&](const ByteSource& src) { add_file(s, src, opt); });
    const Grid g = grid_of(s, opt);
    const std::uint64_t bytes = io_detail::check_volume(name, g, s.first.dtype, opt.max_bytes);
    io_detail::check_budget(name, bytes, s.file_bytes, opt, "the " + std::to_string(s.pages) + " pages");
    Volume v = io_detail::allocate(g, s.first.dtype);
    std::size_t done = 0;
    each([&](const ByteSource& src) { done += copy_file(src, s.first, v.data.data() + done, v.data.size() - done); });
    if (done != v.data.size()) fail(name, "the files changed while they were being read");
    return v;
}

// "slice2" < "slice10": digit runs compare as numbers.
bool natural_less(const std::string& a, const std::string& b) {
    std::size_t i = 0, j = 0;
    while (i < a.size() && j < b.size()) {
        if (std::isdigit(static_cast<unsigned char>(a[i])) && std::isdigit(static_cast<unsigned char>(b[j]))) {
            std::size_t ie = i, je = j;
            while (ie < a.size() && std::isdigit(static_cast<unsigned char>(a[ie]))) ++ie;
            while (je < b.size() && std::isdigit(static_cast<unsigned char>(b[je]))) ++je;
            std::string_view da(a.data() + i, ie - i), db(b.data() + j, je - j);
            while (da.size() > 1 && da[0] == '0') da.remove_prefix(1);
            while (db.size() > 1 && db[0] == '0') db.remove_prefix(1);
            if (da.size() != db.size()) return da.size() < db.size();
            if (da != db) return da < db;
            i = ie, j = je;
        } else {
            if (a[i] != b[j]) return a[i] < b[j];
            ++i, ++j;
        }
    }
    return a.size() - i < b.size() - j;
}

bool tiff_name(const std::string& file) {
    const std::string low = io_detail::lower(file);
    return (low.size() > 4 && low.compare(low.size() - 4, 4, ".tif") == 0) ||
           (low.size() > 5 && low.compare(low.size() - 5, 5, ".tiff") == 0);
}

// The folder's .tif/.tiff files in natural order.
std::vector<std::string> tiff_files(const std::string& folder) {
    std::vector<std::string> files;
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(folder, ec))
        if (e.is_regular_file(ec) && tiff_name(e.path().filename().string())) files.push_back(e.path().string());
    std::sort(files.begin(), files.end(), natural_less);
    return files;
}

}  // namespace

Volume read_tiff_file(const ByteSource& src, const ReadOptions& opt) {
    return read_sources(src.name(), [&](const std::function<void(const ByteSource&)>& f) { f(src); }, opt);
}

Volume read_tiff(const std::string& path, const ReadOptions& opt) {
    io_detail::check_input_path(path);
    std::error_code ec;
    if (!std::filesystem::is_directory(path, ec)) return read_tiff_file(*open_file(path), opt);
    const std::vector<std::string> files = tiff_files(path);
    if (files.empty()) fail(path, "no .tif or .tiff files in the folder");
    const auto each = [&](const std::function<void(const ByteSource&)>& f) {
        for (const std::string& file : files) f(*open_file(file));
    };
    return read_sources(path, each, opt);
}

}  // namespace volrig

// io/dicom.cpp: DICOM series through GDCM (io.hpp says what is read and refused).
//
// GDCM does the DICOM: its Scanner reads the few header tags that group and sort slices, its ImageReader decodes
// each slice's pixels (every transfer syntax GDCM supports: raw, RLE, JPEG lossless/lossy, JPEG-LS, JPEG 2000).
// This file only groups, sorts, checks the geometry and rescales. Errors name the folder or file and say what is
// wrong; nothing is allocated before the series' size is checked against max_bytes. Every file passes
// check_dicom_part10 (io/dicom_part10.cpp) before GDCM reads it: Debian's GDCM aborts on some broken files.
#include <gdcmDicts.h>
#include <gdcmGlobal.h>
#include <gdcmImage.h>
#include <gdcmImageReader.h>
#include <gdcmScanner.h>

#include <dirent.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "io/io_detail.hpp"
#include "volrig/io.hpp"

namespace volrig {

namespace {

using io_detail::fail;
using Vec3 = std::array<double, 3>;

const gdcm::Tag kSeriesUid(0x0020, 0x000e), kDescription(0x0008, 0x103e), kModality(0x0008, 0x0060),
    kPosition(0x0020, 0x0032), kOrientation(0x0020, 0x0037), kRows(0x0028, 0x0010), kColumns(0x0028, 0x0011),
    kPixelSpacing(0x0028, 0x0030), kFrames(0x0028, 0x0008);

// Runs a GDCM call, turning the exceptions GDCM throws on broken input into a FileFormatError naming `name`.
template <class F>
auto guarded(const std::string& name, F&& f) -> decltype(f()) {
    try {
        return f();
    } catch (const Error&) {
        throw;
    } catch (const std::bad_alloc&) {
        fail(name, "GDCM ran out of memory reading it (broken lengths?)");
    } catch (const std::exception& e) {
        fail(name, std::string("GDCM: ") + e.what());
    }
}

// ---- header values -------------------------------------------------------------------------------------------

// A scanned value without its padding (spaces, NULs); "" when absent.
std::string text_of(const gdcm::Scanner& s, const std::string& file, const gdcm::Tag& t) {
    const char* v = s.GetValue(file.c_str(), t);
    if (!v) return {};
    std::string out(v);
    while (!out.empty() && (out.back() == ' ' || out.back() == '\0')) out.pop_back();
    return std::string(io_detail::trim(out));
}

// The numbers of a multi-valued DICOM string "a\b\c"; empty when any is malformed.
std::vector<double> numbers_of(const std::string& s) {
    std::vector<double> out;
    std::size_t start = 0;
    while (!s.empty()) {
        const std::size_t end = s.find('\\', start);
        double d = 0;
        if (!io_detail::parse_double(std::string_view(s).substr(start, end - start), d) || !std::isfinite(d)) return {};
        out.push_back(d);
        if (end == std::string::npos) break;
        start = end + 1;
    }
    return out;
}

Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

std::string base_name(const std::string& path) { return std::filesystem::path(path).filename().string(); }

// ---- finding the slices --------------------------------------------------------------------------------------

struct Slice {
    std::string file;
    std::vector<double> position, orientation;  // ImagePositionPatient (3), ImageOrientationPatient (6)
    std::string pixel_spacing;
    std::int64_t rows = 0, columns = 0, frames = 1;
    double along = 0;      // position along the slice normal
    bool isolate = false;  // compressed (JPEG family): decoded in a child process (io/isolate.cpp)
    std::uint64_t file_bytes = 0;
};

struct Series {
    std::string uid, description, modality;
    std::vector<Slice> slices;
};

// Whether an explicit VR suits the tag in GDCM's dictionary (unknown and private tags: any VR).
bool vr_suits_tag(std::uint16_t group, std::uint16_t element, const char* vr) {
    if (group % 2) return true;  // private
    const gdcm::VR dict = gdcm::Global::GetInstance().GetDicts().GetDictEntry(gdcm::Tag(group, element)).GetVR();
    if (dict == gdcm::VR::INVALID || dict == gdcm::VR::UN) return true;
    const char two[3] = {vr[0], vr[1], 0};
    return dict.Compatible(gdcm::VR(gdcm::VR::GetVRType(two)));
}

// The Part-10 structure check with GDCM's dictionary VRs; returns the transfer syntax UID.
std::string check_part10(const ByteSource& src) { return io_detail::check_dicom_part10(src, vr_suits_tag); }

// The files to read: each passed the Part-10 check; those in `isolate` are decoded in a child process.
struct Candidates {
    std::vector<std::string> files;
    std::set<std::string> isolate;
};

// Adds the file when it passes the Part-10 structure check (other files in a folder are not DICOM, or too broken
// for GDCM, and are left out).
void add_if_well_formed(Candidates& c, const std::string& file) {
    try {
        if (io_detail::dicom_needs_isolation(check_part10(*open_file(file)))) c.isolate.insert(file);
        c.files.push_back(file);
    } catch (const Error&) {
    }
}

using Warn = std::function<void(const std::string&)>;

// Adds the regular files under `folder` (recursively) to `files`. volrig walks the folder, not GDCM (which stopped
// at a FIFO, a socket or a dangling link, and looped forever on a link to a parent): symbolic links are followed,
// each folder is entered once (a second way into one, e.g. a link loop, is skipped with a warning), and entries
// that are neither regular files nor folders are skipped with a warning naming them.
void walk_folder(const std::string& folder, std::set<std::pair<dev_t, ino_t>>& entered, std::vector<std::string>& files,
                 const Warn& warn, int depth) {
    const auto say = [&](const std::string& what) {
        if (warn) warn(what);
    };
    if (depth > 64) return say(folder + ": folders nested more than 64 deep; not scanned further");
    DIR* d = ::opendir(folder.c_str());
    if (!d) return say(folder + ": cannot be read (" + io_detail::errno_text(errno) + "); skipped");
    std::vector<std::string> names;
    while (const dirent* e = ::readdir(d))
        if (std::strcmp(e->d_name, ".") != 0 && std::strcmp(e->d_name, "..") != 0) names.emplace_back(e->d_name);
    ::closedir(d);
    std::sort(names.begin(), names.end());
    for (const std::string& name : names) {
        const std::string full = folder + (folder.back() == '/' ? "" : "/") + name;
        struct stat st {};
        if (::stat(full.c_str(), &st) != 0) {
            say(full + ": " + (errno == ENOENT ? std::string("a dangling link") : io_detail::errno_text(errno)) +
                "; skipped");
        } else if (S_ISDIR(st.st_mode)) {
            if (entered.insert({st.st_dev, st.st_ino}).second)
                walk_folder(full, entered, files, warn, depth + 1);
            else
                say(full + ": a folder already scanned (a link loop?); skipped");
        } else if (S_ISREG(st.st_mode)) {
            files.push_back(full);
        } else {
            say(full + ": " + io_detail::file_kind(st.st_mode) + ", not a file; skipped");
        }
    }
}

// The files to scan (each passed check_dicom_part10 or, for a single file, is checked when read): a folder's
// (recursively), those under a DICOMDIR's folder, or the file itself.
Candidates candidate_files(const std::string& path, const Warn& warn) {
    namespace fs = std::filesystem;
    io_detail::check_input_path(path);
    std::error_code ec;
    const bool dicomdir = io_detail::iequals(base_name(path), "DICOMDIR");
    Candidates c;
    if (!fs::is_directory(path, ec) && !dicomdir) {
        if (io_detail::dicom_needs_isolation(check_part10(*open_file(path)))) c.isolate.insert(path);
        c.files.push_back(path);
        return c;
    }
    const std::string folder = dicomdir ? fs::path(path).parent_path().string() : path;
    std::vector<std::string> files;
    std::set<std::pair<dev_t, ino_t>> entered;
    struct stat st {};
    if (::stat(folder.empty() ? "." : folder.c_str(), &st) == 0) entered.insert({st.st_dev, st.st_ino});
    walk_folder(folder.empty() ? "." : folder, entered, files, warn, 0);
    std::sort(files.begin(), files.end());
    for (const std::string& f : files)
        if (!io_detail::iequals(base_name(f), "DICOMDIR")) add_if_well_formed(c, f);
    return c;
}

gdcm::Scanner scan(const std::string& path, const std::vector<std::string>& files) {
    gdcm::Scanner s;
    for (const gdcm::Tag& t : {kSeriesUid, kDescription, kModality, kPosition, kOrientation, kRows, kColumns,
                               kPixelSpacing, kFrames})
        s.AddTag(t);
    if (!guarded(path, [&] { return s.Scan(files); })) fail(path, "GDCM could not scan the DICOM files");
    return s;
}

// The slice a scanned file holds; false for files that are no DICOM image (no rows/columns).
bool slice_of(const gdcm::Scanner& s, const std::string& file, Slice& out) {
    if (!s.IsKey(file.c_str())) return false;
    std::int64_t rows = 0, columns = 0, frames = 1;
    if (!io_detail::parse_int(text_of(s, file, kRows), rows) || !io_detail::parse_int(text_of(s, file, kColumns), columns) ||
        rows <= 0 || columns <= 0)
        return false;
    const std::string f = text_of(s, file, kFrames);
    if (!f.empty() && (!io_detail::parse_int(f, frames) || frames < 1)) fail(file, "NumberOfFrames " + io_detail::quoted(f) + " is not a positive integer");
    out.file = file;
    out.rows = rows;
    out.columns = columns;
    out.frames = frames;
    out.position = numbers_of(text_of(s, file, kPosition));
    out.orientation = numbers_of(text_of(s, file, kOrientation));
    out.pixel_spacing = text_of(s, file, kPixelSpacing);
    return true;
}

// Image slices grouped by SeriesInstanceUID, the series with the most slices first.
std::vector<Series> find_series(const std::string& path, const Warn& warn) {
    const Candidates found = candidate_files(path, warn);
    const std::vector<std::string>& files = found.files;
    const gdcm::Scanner s = scan(path, files);
    std::map<std::string, Series> by_uid;
    for (const std::string& file : files) {
        Slice slice;
        if (!slice_of(s, file, slice)) continue;
        slice.isolate = found.isolate.count(file) > 0;
        std::error_code ec;
        slice.file_bytes = std::filesystem::file_size(file, ec);
        if (ec) slice.file_bytes = 0;
        const std::string uid = text_of(s, file, kSeriesUid);
        Series& series = by_uid[uid];
        if (series.slices.empty()) {
            series.uid = uid;
            series.description = text_of(s, file, kDescription);
            series.modality = text_of(s, file, kModality);
        }
        series.slices.push_back(std::move(slice));
    }
    std::vector<Series> out;
    for (auto& [uid, series] : by_uid) out.push_back(std::move(series));
    std::stable_sort(out.begin(), out.end(),
                     [](const Series& a, const Series& b) { return a.slices.size() > b.slices.size(); });
    if (out.empty()) fail(path, "no DICOM images found (" + std::to_string(files.size()) + " well-formed DICOM files)");
    return out;
}

const Series& choose_series(const std::string& path, const std::vector<Series>& all, const std::string& uid) {
    if (uid.empty()) return all.front();
    for (const Series& s : all)
        if (s.uid == uid) return s;
    std::string known;
    for (const Series& s : all) known += (known.empty() ? "" : ", ") + s.uid;
    fail(path, "no series with SeriesInstanceUID " + io_detail::quoted(uid) + " (found: " + known + ")");
}

// PixelSpacing (0028,0030) must be two finite positive numbers when present (GDCM would take 0, NaN or a
// negative value as 1), as the NRRD, MetaImage and NIfTI readers require of their spacings.
void check_pixel_spacing(const std::string& file, const std::string& text) {
    const std::vector<double> ps = numbers_of(text);
    if (!text.empty() && (ps.size() != 2 || !(ps[0] > 0) || !(ps[1] > 0)))
        fail(file, "PixelSpacing " + io_detail::quoted(text) + " is not two finite positive numbers");
}

// The PixelSpacing text of a data set without its padding ("" when absent).
std::string pixel_spacing_text(const gdcm::DataSet& ds) {
    if (!ds.FindDataElement(kPixelSpacing)) return {};
    const gdcm::ByteValue* bv = ds.GetDataElement(kPixelSpacing).GetByteValue();
    if (!bv || !bv->GetPointer()) return {};
    std::string out(bv->GetPointer(), bv->GetLength());
    while (!out.empty() && (out.back() == ' ' || out.back() == '\0')) out.pop_back();
    return std::string(io_detail::trim(out));
}

// ---- geometry of a stack of slices ---------------------------------------------------------------------------

// Checks that every slice has the first one's size, orientation, pixel spacing and a position.
void check_alike(const std::string& path, const std::vector<Slice>& slices) {
    const Slice& a = slices.front();
    for (const Slice& b : slices) {
        if (b.rows != a.rows || b.columns != a.columns || b.frames != 1)
            fail(path, "mixed slice sizes: " + base_name(a.file) + " is " + std::to_string(a.columns) + "x" +
                           std::to_string(a.rows) + ", " + base_name(b.file) + " is " + std::to_string(b.columns) +
                           "x" + std::to_string(b.rows) + (b.frames != 1 ? " with several frames" : ""));
        if (b.position.size() != 3 || b.orientation.size() != 6)
            fail(b.file, "no valid ImagePositionPatient/ImageOrientationPatient: the slices cannot be stacked");
        for (std::size_t i = 0; i < 6; ++i)
            if (std::fabs(b.orientation[i] - a.orientation[i]) > 1e-4)
                fail(path, "mixed orientations: " + base_name(a.file) + " and " + base_name(b.file) +
                               " have different ImageOrientationPatient");
        if (b.pixel_spacing != a.pixel_spacing)
            fail(path, "mixed pixel spacings: " + base_name(a.file) + " " + io_detail::quoted(a.pixel_spacing) + ", " +
                           base_name(b.file) + " " + io_detail::quoted(b.pixel_spacing));
    }
}

// The direction matrix (row, column, normal) of ImageOrientationPatient.
Matrix3 direction_of(const std::string& file, const std::vector<double>& iop) {
    const Vec3 row{iop[0], iop[1], iop[2]}, col{iop[3], iop[4], iop[5]};
    const Vec3 n = cross(row, col);
    Matrix3 d{row[0], col[0], n[0], row[1], col[1], n[1], row[2], col[2], n[2]};
    const std::string problem = normalize_direction(d);
    if (!problem.empty()) fail(file, "ImageOrientationPatient: " + problem);
    return d;
}

// When every gap is a whole number of the smallest (within 10 %), the series has slices missing from a regular
// spacing: fails naming each missing position (along the normal from the first slice, and in patient
// coordinates), at most 10 of them.
void refuse_missing(const std::string& path, const std::vector<Slice>& slices, const Vec3& n, double lo) {
    std::vector<double> missing;  // along the normal
    for (std::size_t i = 1; i < slices.size(); ++i) {
        const double steps = (slices[i].along - slices[i - 1].along) / lo;
        const double whole = std::round(steps);
        if (std::fabs(steps - whole) > 0.1) return;  // not a regular spacing with gaps
        for (int j = 1; j < static_cast<int>(whole) && missing.size() <= 10; ++j)
            missing.push_back(slices[i - 1].along + j * (slices[i].along - slices[i - 1].along) / whole);
    }
    if (missing.empty()) return;
    const auto num = [](double v) { return io_detail::format_double(std::round(v * 1e3) / 1e3); };
    std::string list;
    for (std::size_t k = 0; k < missing.size() && k < 10; ++k) {
        const double d = missing[k] - slices[0].along;
        list += (k ? "; " : "") + num(d) + " mm (" + num(slices[0].position[0] + d * n[0]) + ", " +
                num(slices[0].position[1] + d * n[1]) + ", " + num(slices[0].position[2] + d * n[2]) + ")";
    }
    fail(path, "incomplete series: no slice at " + list + (missing.size() > 10 ? "; ..." : "") +
                   " (along the slice normal from " + base_name(slices[0].file) + ", and in patient coordinates)"
                   " where the others are " + num(lo) + " mm apart");
}

// Sorts the slices along the normal (column 2 of d) and returns the mean gap; fails on repeated positions,
// uneven gaps or slices off the normal, warns about small jitter.
double sort_and_space(const std::string& path, std::vector<Slice>& slices, const Matrix3& d, const ReadOptions& opt) {
    const Vec3 n{d[2], d[5], d[8]};
    for (Slice& s : slices) s.along = dot({s.position[0], s.position[1], s.position[2]}, n);
    std::sort(slices.begin(), slices.end(), [](const Slice& a, const Slice& b) { return a.along < b.along; });
    const double mean = (slices.back().along - slices.front().along) / static_cast<double>(slices.size() - 1);
    double lo = std::numeric_limits<double>::max(), hi = 0;
    std::size_t at_hi = 1;
    for (std::size_t i = 1; i < slices.size(); ++i) {
        const double gap = slices[i].along - slices[i - 1].along;
        if (gap < 1e-4)
            fail(path, base_name(slices[i - 1].file) + " and " + base_name(slices[i].file) +
                           " lie at the same position: two stacks in one series?");
        lo = std::min(lo, gap);
        if (gap > hi) hi = gap, at_hi = i;
    }
    const auto mm = [](double v) { return io_detail::format_double(std::round(v * 1e4) / 1e4) + " mm"; };
    if (hi - lo > 0.1 * mean) {
        refuse_missing(path, slices, n, lo);
        fail(path, "uneven slice gaps: " + mm(hi) + " between " + base_name(slices[at_hi - 1].file) + " and " +
                       base_name(slices[at_hi].file) + " where the smallest is " + mm(lo));
    }
    for (const Slice& s : slices) {  // each position on the line through the first along the normal
        Vec3 off{};
        for (int r = 0; r < 3; ++r) off[r] = s.position[r] - slices[0].position[r] - (s.along - slices[0].along) * n[r];
        if (std::sqrt(dot(off, off)) > 0.01 * mean + 1e-3)
            fail(path, base_name(s.file) + " is not on the slice normal through the first slice (gantry tilt or "
                                           "sheared stack): not supported");
    }
    if (hi - lo > 1e-3 * mean && opt.warn)
        opt.warn(path + ": slice gaps vary from " + mm(lo) + " to " + mm(hi) + "; assumed the mean " + mm(mean));
    return mean;
}

// ---- pixels --------------------------------------------------------------------------------------------------

bool dtype_of(const gdcm::PixelFormat& pf, DType& t) {
    switch (pf.GetScalarType()) {
        case gdcm::PixelFormat::UINT8: t = DType::UInt8; return true;
        case gdcm::PixelFormat::INT8: t = DType::Int8; return true;
        case gdcm::PixelFormat::UINT16: t = DType::UInt16; return true;
        case gdcm::PixelFormat::INT16: t = DType::Int16; return true;
        case gdcm::PixelFormat::UINT32: t = DType::UInt32; return true;
        case gdcm::PixelFormat::INT32: t = DType::Int32; return true;
        case gdcm::PixelFormat::FLOAT32: t = DType::Float32; return true;
        case gdcm::PixelFormat::FLOAT64: t = DType::Float64; return true;
        default: return false;
    }
}

// The decoded image's element type; fails for colour and unsupported pixel formats.
DType image_dtype(const std::string& name, const gdcm::Image& im) {
    const gdcm::PixelFormat& pf = im.GetPixelFormat();
    if (pf.GetSamplesPerPixel() != 1)
        fail(name, std::to_string(pf.GetSamplesPerPixel()) + " samples per pixel: colour images are not supported");
    DType t{};
    if (!dtype_of(pf, t)) fail(name, std::string("pixel format ") + pf.GetScalarTypeAsString() + " is not supported");
    return t;
}

struct Scale {
    double slope = 1, inter = 0;
};

// Decodes an image's pixels into dst (n bytes expected).
void decode(const std::string& name, const gdcm::Image& im, std::uint8_t* dst, std::size_t n) {
    const unsigned long len = im.GetBufferLength();
    if (len != n)
        fail(name, "GDCM decodes " + io_detail::with_commas(len) + " bytes of pixels where the header declares " +
                       io_detail::with_commas(n));
    if (!guarded(name, [&] { return im.GetBuffer(reinterpret_cast<char*>(dst)); }))
        fail(name, "GDCM could not decode the pixel data");
}

Scale scale_of(const std::string& name, const gdcm::Image& im) {
    Scale s{im.GetSlope(), im.GetIntercept()};
    if (!std::isfinite(s.slope) || !std::isfinite(s.inter) || s.slope == 0)
        fail(name, "RescaleSlope/RescaleIntercept " + io_detail::format_double(s.slope) + "/" +
                       io_detail::format_double(s.inter) + " are not usable");
    return s;
}

template <class In, class Out>
void rescale_slice(const std::uint8_t* in, std::uint8_t* out, std::size_t n, const Scale& s) {
    for (std::size_t i = 0; i < n; ++i) {
        In x;
        std::memcpy(&x, in + i * sizeof(In), sizeof(In));
        const Out y = static_cast<Out>(static_cast<double>(x) * s.slope + s.inter);
        std::memcpy(out + i * sizeof(Out), &y, sizeof(Out));
    }
}

template <class In>
void rescale_as(DType out_type, const std::uint8_t* in, std::uint8_t* out, std::size_t n, const Scale& s) {
    if (out_type == DType::Int16)
        rescale_slice<In, std::int16_t>(in, out, n, s);
    else if (out_type == DType::Float64)
        rescale_slice<In, double>(in, out, n, s);
    else
        rescale_slice<In, float>(in, out, n, s);
}

void rescale_any(DType in_type, DType out_type, const std::uint8_t* in, std::uint8_t* out, std::size_t n,
                 const Scale& s) {
    switch (in_type) {
        case DType::UInt8: return rescale_as<std::uint8_t>(out_type, in, out, n, s);
        case DType::Int8: return rescale_as<std::int8_t>(out_type, in, out, n, s);
        case DType::UInt16: return rescale_as<std::uint16_t>(out_type, in, out, n, s);
        case DType::Int16: return rescale_as<std::int16_t>(out_type, in, out, n, s);
        case DType::UInt32: return rescale_as<std::uint32_t>(out_type, in, out, n, s);
        case DType::Int32: return rescale_as<std::int32_t>(out_type, in, out, n, s);
        case DType::UInt64: return rescale_as<std::uint64_t>(out_type, in, out, n, s);
        case DType::Int64: return rescale_as<std::int64_t>(out_type, in, out, n, s);
        case DType::Float32: return rescale_as<float>(out_type, in, out, n, s);
        case DType::Float64: return rescale_as<double>(out_type, in, out, n, s);
    }
}

bool integral(double v) { return std::floor(v) == v; }

// Applies each slice's rescale: the stored values when every slice has (1, 0); int16 when the slopes and
// intercepts are integral and the values fit; else float32, or float64 when the values do not fit float32 (a
// slope of 3e38); refused when they overflow a double.
Volume rescale(const std::string& name, Volume&& raw, const std::vector<Scale>& scales, std::uint64_t max_bytes) {
    const bool identity = std::all_of(scales.begin(), scales.end(), [](const Scale& s) { return s.slope == 1 && s.inter == 0; });
    if (identity) return std::move(raw);
    const auto slice = static_cast<std::size_t>(raw.grid.dims[0] * raw.grid.dims[1]);
    const std::size_t esize = dtype_size(raw.dtype);
    bool fits = raw.dtype != DType::Float32 && raw.dtype != DType::Float64;
    DType wide = DType::Float32;
    for (std::size_t k = 0; k < scales.size(); ++k) {
        double lo = std::numeric_limits<double>::max(), hi = std::numeric_limits<double>::lowest();
        io_detail::finite_range(raw.dtype, raw.data.data() + k * slice * esize, slice, lo, hi);
        if (io_detail::rescaled_type(name, "RescaleSlope/RescaleIntercept", lo, hi, scales[k].slope, scales[k].inter,
                                     raw.dtype) == DType::Float64)
            wide = DType::Float64;
        const double a = lo * scales[k].slope + scales[k].inter, b = hi * scales[k].slope + scales[k].inter;
        fits = fits && integral(scales[k].slope) && integral(scales[k].inter) && std::min(a, b) >= -32768 &&
               std::max(a, b) <= 32767;
    }
    const DType out_type = fits ? DType::Int16 : wide;
    io_detail::check_volume(name, raw.grid, out_type, max_bytes);
    Volume out = io_detail::allocate(raw.grid, out_type);
    for (std::size_t k = 0; k < scales.size(); ++k)
        rescale_any(raw.dtype, out_type, raw.data.data() + k * slice * esize,
                    out.data.data() + k * slice * dtype_size(out_type), slice, scales[k]);
    return out;
}

// Reads a series of single-frame slices (sorted) into one volume.
Volume read_stack(const std::string& path, const std::vector<Slice>& slices, Grid g, const ReadOptions& opt) {
    Volume raw;
    std::vector<Scale> scales;
    std::size_t slice_bytes = 0;
    for (std::size_t k = 0; k < slices.size(); ++k) {
        const std::string& file = slices[k].file;
        if (opt.reading) opt.reading(file);
        gdcm::ImageReader r;
        r.SetFileName(file.c_str());
        if (!guarded(file, [&] { return r.Read(); })) fail(file, "GDCM could not read the image");
        const gdcm::Image& im = r.GetImage();
        const DType t = image_dtype(file, im);
        if (k == 0) {
            const std::uint64_t bytes = io_detail::check_volume(path, g, t, opt.max_bytes);
            std::uint64_t files = 0;
            for (const Slice& s : slices) files += s.file_bytes;
            io_detail::check_budget(path, bytes, files, opt, "the " + io_detail::describe(g.dims, t) + " voxels");
            raw = io_detail::allocate(g, t);
            slice_bytes = static_cast<std::size_t>(g.dims[0] * g.dims[1]) * dtype_size(t);
        } else if (t != raw.dtype) {
            fail(path, std::string("mixed pixel types: ") + dtype_name(raw.dtype) + " and " + dtype_name(t) + " in " +
                           base_name(file));
        }
        decode(file, im, raw.data.data() + k * slice_bytes, slice_bytes);
        scales.push_back(scale_of(file, im));
    }
    return rescale(path, std::move(raw), scales, opt.max_bytes);
}

Volume read_series(const std::string& path, Series series, const ReadOptions& opt) {
    std::vector<Slice>& slices = series.slices;
    if (slices.size() == 1) return read_dicom_file(*open_file(slices[0].file), opt);
    check_alike(path, slices);
    Grid g;
    g.direction = direction_of(slices[0].file, slices[0].orientation);
    g.spacing[2] = sort_and_space(path, slices, g.direction, opt);
    g.dims = {slices[0].columns, slices[0].rows, static_cast<std::int64_t>(slices.size())};
    g.origin = {slices[0].position[0], slices[0].position[1], slices[0].position[2]};
    check_pixel_spacing(slices[0].file, slices[0].pixel_spacing);
    const std::vector<double> ps = numbers_of(slices[0].pixel_spacing);  // absent: 1 mm
    if (ps.size() == 2) g.spacing[0] = ps[1], g.spacing[1] = ps[0];  // row\column spacing
    if (std::none_of(slices.begin(), slices.end(), [](const Slice& s) { return s.isolate; }))
        return read_stack(path, slices, g, opt);
    return io_detail::isolated_volume(path, "GDCM's decoder", opt,
                                      [&](const ReadOptions& o) { return read_stack(path, slices, g, o); });
}

// Reads the whole byte source (DICOM files are read whole by GDCM anyway).
std::string all_bytes(const ByteSource& src, const ReadOptions& opt) {
    if (src.size() > opt.max_bytes + (std::uint64_t(64) << 20))
        fail(src.name(), "the file holds " + io_detail::with_commas(src.size()) + " bytes, more than the size limit");
    std::string bytes(static_cast<std::size_t>(src.size()), '\0');
    if (!bytes.empty()) src.read(0, &bytes[0], bytes.size());
    return bytes;
}

// The geometry GDCM gives a single image: spacing, origin and direction cosines.
Grid single_grid(const std::string& name, const gdcm::Image& im) {
    const unsigned int* dims = im.GetDimensions();
    Grid g;
    g.dims = {dims[0], dims[1], im.GetNumberOfDimensions() > 2 ? dims[2] : 1};
    for (int a = 0; a < 3; ++a) {
        const double s = im.GetSpacing(static_cast<unsigned>(a)), o = im.GetOrigin(static_cast<unsigned>(a));
        if (!std::isfinite(s) || !(s > 0))  // GDCM gives 1 when the file has none
            fail(name, "pixel spacing " + io_detail::format_double(s) + " is not a finite positive number");
        g.spacing[a] = s;
        if (!std::isfinite(o)) fail(name, "the image position is not finite");
        g.origin[a] = o;
    }
    const double* c = im.GetDirectionCosines();
    g.direction = direction_of(name, std::vector<double>(c, c + 6));
    return g;
}

// A checked single file (check_part10), decoded.
Volume decode_file(const ByteSource& src, const ReadOptions& opt) {
    const std::string& name = src.name();
    std::istringstream in(all_bytes(src, opt));
    gdcm::ImageReader r;
    r.SetStream(in);
    if (!guarded(name, [&] { return r.Read(); })) fail(name, "not a DICOM image GDCM can read");
    const gdcm::Image& im = r.GetImage();
    const DType t = image_dtype(name, im);
    check_pixel_spacing(name, pixel_spacing_text(r.GetFile().GetDataSet()));
    const Grid g = single_grid(name, im);
    const std::uint64_t bytes = io_detail::check_volume(name, g, t, opt.max_bytes);
    io_detail::check_budget(name, bytes, src.size(), opt, "the " + io_detail::describe(g.dims, t) + " voxels");
    Volume raw = io_detail::allocate(g, t);
    decode(name, im, raw.data.data(), raw.data.size());
    const std::vector<Scale> scales(static_cast<std::size_t>(g.dims[2]), scale_of(name, im));
    return rescale(name, std::move(raw), scales, opt.max_bytes);
}

}  // namespace

Volume read_dicom_file(const ByteSource& src, const ReadOptions& opt) {
    if (!io_detail::dicom_needs_isolation(check_part10(src))) return decode_file(src, opt);
    return io_detail::isolated_volume(src.name(), "GDCM's decoder", opt,
                                      [&](const ReadOptions& o) { return decode_file(src, o); });
}

Volume read_dicom(const std::string& path, const ReadOptions& opt) {
    std::vector<Series> all = find_series(path, opt.warn);
    return read_series(path, choose_series(path, all, opt.series), opt);
}

std::vector<DicomSeriesInfo> dicom_series(const std::string& path, const std::function<void(const std::string&)>& warn) {
    std::vector<DicomSeriesInfo> out;
    for (const Series& s : find_series(path, warn)) {
        DicomSeriesInfo i;
        i.uid = s.uid;
        i.description = s.description;
        i.modality = s.modality;
        const Slice& first = s.slices.front();
        i.dims = {first.columns, first.rows,
                  s.slices.size() == 1 ? first.frames : static_cast<std::int64_t>(s.slices.size())};
        for (const Slice& sl : s.slices) i.files.push_back(sl.file);
        out.push_back(std::move(i));
    }
    return out;
}

}  // namespace volrig

// io/nifti.cpp: NIfTI-1 reader (.nii, .nii.gz, .hdr/.img pairs), either byte order.
//
// The 348-byte header's sizeof_hdr gives the byte order. dim[0] 1..7 with dims 4..7 equal to 1 (a single 3-D
// volume); datatypes uint8/int8/int16/uint16/int32/uint32/int64/uint64/float32/float64 with a matching bitpix.
// Spacing = |pixdim[1..3]|; orientation from the sform (sform_code > 0: origin srow_x/y/z[3], directions the
// unit columns of its 3x3 part), else the qform (qform_code > 0: the quaternion with qfac = pixdim[0], origin
// qoffset_x/y/z), both converted from NIfTI's RAS to LPS (x and y negated); with neither code, the qoffsets as
// given and no rotation (NIfTI's "method 1"). scl_slope/scl_inter are applied as io.hpp says. A .nii.gz is one gzip stream:
// the header is inflated first, then the voxels straight into the output buffer.
// Refused with a clear message: NIfTI-2, Analyze 7.5 (no magic), 4-D and higher, complex/RGB/binary/float128.
#include <cfloat>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

#include "io/zlib_inflate.hpp"
#include "io/io_detail.hpp"
#include "volrig/io.hpp"

namespace volrig {

namespace {

using io_detail::fail;
using io_detail::with_commas;

constexpr std::size_t kHeaderSize = 348;

class HeaderFields {
public:
    HeaderFields(const std::uint8_t* h, bool swap) : h_(h), swap_(swap) {}
    std::int16_t i16(std::size_t at) const { return get<std::int16_t>(at); }
    std::int32_t i32(std::size_t at) const { return get<std::int32_t>(at); }
    float f32(std::size_t at) const { return get<float>(at); }

private:
    template <class T>
    T get(std::size_t at) const {
        std::uint8_t b[sizeof(T)];
        std::memcpy(b, h_ + at, sizeof(T));
        if (swap_) io_detail::swap_bytes(b, 1, sizeof(T));
        T v;
        std::memcpy(&v, b, sizeof(T));
        return v;
    }
    const std::uint8_t* h_;
    bool swap_;
};

bool nifti_type(int code, DType& t) {
    static constexpr std::array<std::pair<int, DType>, 10> kTypes{{{2, DType::UInt8}, {4, DType::Int16},
        {8, DType::Int32}, {16, DType::Float32}, {64, DType::Float64}, {256, DType::Int8}, {512, DType::UInt16},
        {768, DType::UInt32}, {1024, DType::Int64}, {1280, DType::UInt64}}};
    return io_detail::dtype_from_table(kTypes, code, t);
}

const char* unsupported_type_name(int code) {
    switch (code) {
        case 0: return "unknown (DT_UNKNOWN)";
        case 1: return "binary (DT_BINARY)";
        case 32: return "complex64";
        case 128: return "RGB24";
        case 1536: return "float128";
        case 1792: return "complex128";
        case 2048: return "complex256";
        case 2304: return "RGBA32";
        default: return nullptr;
    }
}

template <class In, class Out>
void scale_all(const std::uint8_t* in, std::uint8_t* out, std::size_t n, double slope, double inter) {
    for (std::size_t i = 0; i < n; ++i) {
        In x;
        std::memcpy(&x, in + i * sizeof(In), sizeof(In));
        double y = static_cast<double>(x) * slope + inter;
        if constexpr (std::is_same_v<Out, float>) {
            if (std::isfinite(y) && std::fabs(y) > static_cast<double>(FLT_MAX))
                y = std::copysign(std::numeric_limits<double>::infinity(), y);
        }
        const auto z = static_cast<Out>(y);
        std::memcpy(out + i * sizeof(Out), &z, sizeof(Out));
    }
}

template <class Out>
void scale_from(DType in_type, const std::uint8_t* in, std::uint8_t* out, std::size_t n, double slope, double inter) {
    switch (in_type) {
        case DType::UInt8: return scale_all<std::uint8_t, Out>(in, out, n, slope, inter);
        case DType::Int8: return scale_all<std::int8_t, Out>(in, out, n, slope, inter);
        case DType::UInt16: return scale_all<std::uint16_t, Out>(in, out, n, slope, inter);
        case DType::Int16: return scale_all<std::int16_t, Out>(in, out, n, slope, inter);
        case DType::UInt32: return scale_all<std::uint32_t, Out>(in, out, n, slope, inter);
        case DType::Int32: return scale_all<std::int32_t, Out>(in, out, n, slope, inter);
        case DType::UInt64: return scale_all<std::uint64_t, Out>(in, out, n, slope, inter);
        case DType::Int64: return scale_all<std::int64_t, Out>(in, out, n, slope, inter);
        case DType::Float32: return scale_all<float, Out>(in, out, n, slope, inter);
        case DType::Float64: return scale_all<double, Out>(in, out, n, slope, inter);
    }
}

// Applies value * slope + inter, giving out_type (io_detail::rescaled_type: float32, or float64 when the values
// need it).
Volume apply_scaling(Volume&& in, double slope, double inter, DType out_type) {
    const std::size_t n = in.data.size() / dtype_size(in.dtype);
    if (dtype_size(out_type) <= dtype_size(in.dtype)) {
        // Same or smaller elements: convert in place front to back (each write lands at or before its read).
        std::uint8_t* p = in.data.data();
        const std::size_t isz = dtype_size(in.dtype), osz = dtype_size(out_type);
        for (std::size_t i = 0; i < n; ++i) {
            std::uint8_t tmp[8];
            std::memcpy(tmp, p + i * isz, isz);
            if (out_type == DType::Float64)
                scale_from<double>(in.dtype, tmp, p + i * osz, 1, slope, inter);
            else
                scale_from<float>(in.dtype, tmp, p + i * osz, 1, slope, inter);
        }
        in.data.resize(n * osz);
        in.dtype = out_type;
        return std::move(in);
    }
    Volume out = io_detail::allocate(in.grid, out_type);
    if (out_type == DType::Float64)
        scale_from<double>(in.dtype, in.data.data(), out.data.data(), n, slope, inter);
    else
        scale_from<float>(in.dtype, in.data.data(), out.data.data(), n, slope, inter);
    return out;
}

std::string image_name_for(const std::string& header_name) {
    const std::string base = std::filesystem::path(header_name).filename().string();
    if (base.size() < 4) return {};
    const std::string ext = base.substr(base.size() - 4);
    if (ext == ".hdr") return base.substr(0, base.size() - 4) + ".img";
    if (ext == ".HDR") return base.substr(0, base.size() - 4) + ".IMG";
    if (io_detail::iequals(ext, ".hdr")) return base.substr(0, base.size() - 4) + ".img";
    return {};
}

// Reads the 348 header bytes into hdr; a .nii.gz is inflated, and `inf` stays open for the voxels. True for gzip.
bool read_header_bytes(const ByteSource& src, std::uint8_t* hdr, std::unique_ptr<io_detail::Inflater>& inf) {
    const std::string& name = src.name();
    const std::uint64_t size = src.size();
    std::uint8_t magic2[2] = {0, 0};
    if (size >= 2) src.read(0, magic2, 2);
    const bool gz = magic2[0] == 0x1f && magic2[1] == 0x8b;
    if (gz) {
        inf = std::make_unique<io_detail::Inflater>(src, 0, size, name, kHeaderSize);
        inf->read(hdr, kHeaderSize);
    } else {
        if (size < kHeaderSize)
            fail(name, "the file holds " + with_commas(size) + " bytes, less than the 348-byte NIfTI-1 header");
        src.read(0, hdr, kHeaderSize);
    }
    return gz;
}

// Whether the header's byte order differs from the host's, from sizeof_hdr.
bool needs_swap(const std::string& name, const std::uint8_t* hdr) {
    std::int32_t sizeof_hdr = 0;
    std::memcpy(&sizeof_hdr, hdr, 4);
    const std::int32_t swapped = static_cast<std::int32_t>(__builtin_bswap32(static_cast<std::uint32_t>(sizeof_hdr)));
    if (sizeof_hdr == 348) return false;
    if (swapped == 348) return true;
    if (sizeof_hdr == 540 || swapped == 540) fail(name, "NIfTI-2 files are not supported (convert to NIfTI-1)");
    fail(name, "not a NIfTI-1 file (sizeof_hdr is " + std::to_string(sizeof_hdr) + ", not 348)");
}

// dim[1..3] into g.dims (1 beyond dim[0]); dims 4..7 must be 1. Returns dim[0].
int nifti_dims(const std::string& name, const HeaderFields& f, Grid& g) {
    std::int16_t dim[8];
    for (int i = 0; i < 8; ++i) dim[i] = f.i16(40 + 2 * static_cast<std::size_t>(i));
    if (dim[0] < 1 || dim[0] > 7) fail(name, "dim[0] = " + std::to_string(dim[0]) + " must be 1 to 7");
    std::int64_t volumes = 1;
    for (int i = 1; i <= dim[0]; ++i) {
        if (dim[i] < 1) fail(name, "dim[" + std::to_string(i) + "] = " + std::to_string(dim[i]) + " must be positive");
        if (i >= 4) volumes *= dim[i];
    }
    if (volumes > 1)
        fail(name, std::to_string(dim[0]) + "-D NIfTI (" + std::to_string(volumes) +
                       " volumes) not supported: only single 3-D volumes");
    for (int a = 0; a < 3; ++a) g.dims[a] = a + 1 <= dim[0] ? dim[a + 1] : 1;
    return dim[0];
}

// datatype, with a matching bitpix.
DType nifti_dtype(const std::string& name, const HeaderFields& f) {
    const int code = f.i16(70);
    const int bitpix = f.i16(72);
    DType dtype{};
    if (!nifti_type(code, dtype)) {
        if (const char* what = unsupported_type_name(code))
            fail(name, std::string("datatype ") + std::to_string(code) + " (" + what + ") is not supported");
        fail(name, "unknown datatype " + std::to_string(code));
    }
    if (bitpix != static_cast<int>(8 * dtype_size(dtype)))
        fail(name, "bitpix " + std::to_string(bitpix) + " disagrees with datatype " + std::to_string(code) + " (" +
                       dtype_name(dtype) + ", " + std::to_string(8 * dtype_size(dtype)) + " bits)");
    return dtype;
}

// The 3x3 part of the sform (rows srow_x, srow_y, srow_z).
Matrix3 sform_matrix(const HeaderFields& f) {
    Matrix3 m{};
    for (std::size_t r = 0; r < 3; ++r)
        for (std::size_t c = 0; c < 3; ++c) m[3 * r + c] = f.f32(280 + 16 * r + 4 * c);
    return m;
}

// The qform's rotation (quatern_b/c/d, a = sqrt(1 - b^2 - c^2 - d^2)) with the third column times qfac.
Matrix3 qform_matrix(const HeaderFields& f) {
    double b = f.f32(256), c = f.f32(260), d = f.f32(264);
    double a = 1 - (b * b + c * c + d * d);
    if (a < 1e-7) {  // 180-degree rotation: renormalise (b, c, d) as nifti1_io does
        const double n = std::sqrt(b * b + c * c + d * d);
        if (n > 0) b /= n, c /= n, d /= n;
        a = 0;
    } else {
        a = std::sqrt(a);
    }
    const double qfac = f.f32(76) < 0 ? -1 : 1;
    return Matrix3{a * a + b * b - c * c - d * d, 2 * (b * c - a * d),         qfac * 2 * (b * d + a * c),
                   2 * (b * c + a * d),         a * a + c * c - b * b - d * d, qfac * 2 * (c * d - a * b),
                   2 * (b * d - a * c),         2 * (c * d + a * b),         qfac * (a * a + d * d - c * c - b * b)};
}

// The sform (sform_code > 0) or qform (qform_code > 0) rotation into g.direction, converted from RAS to LPS with
// the origin.
void nifti_direction(const std::string& name, const HeaderFields& f, Grid& g) {
    const bool sform = f.i16(254) > 0;
    if (!sform && f.i16(252) <= 0) return;
    Matrix3 d = sform ? sform_matrix(f) : qform_matrix(f);
    const std::string problem = normalize_direction(d);
    if (!problem.empty()) fail(name, std::string(sform ? "sform" : "qform") + ": " + problem);
    for (std::size_t c = 0; c < 3; ++c) d[c] = -d[c], d[3 + c] = -d[3 + c];
    g.direction = d;
    g.origin[0] = -g.origin[0];
    g.origin[1] = -g.origin[1];
}

// Spacing = |pixdim[1..3]| (1 for unused axes); origin from the sform (sform_code > 0), else the qform offsets;
// the direction as nifti_direction says.
void nifti_geometry(const std::string& name, const HeaderFields& f, int ndim, Grid& g) {
    for (int a = 0; a < 3; ++a) {
        const double p = std::fabs(static_cast<double>(f.f32(76 + 4 * static_cast<std::size_t>(a + 1))));
        const bool ok = std::isfinite(p) && p > 0;
        if (a + 1 <= ndim && !ok)
            fail(name, "pixdim[" + std::to_string(a + 1) + "] = " + io_detail::format_double(p) +
                           ": voxel spacing must be finite and non-zero");
        g.spacing[a] = ok ? p : 1.0;
    }
    const int sform_code = f.i16(254);
    for (int a = 0; a < 3; ++a)
        g.origin[a] = sform_code > 0 ? f.f32(280 + 16 * static_cast<std::size_t>(a) + 12)
                                     : f.f32(268 + 4 * static_cast<std::size_t>(a));
    for (int a = 0; a < 3; ++a)
        if (!std::isfinite(g.origin[a]))
            fail(name, std::string(sform_code > 0 ? "srow_" : "qoffset_") + "xyz"[a] + " is " +
                           io_detail::format_double(g.origin[a]) + ": the origin must be finite");
    nifti_direction(name, f, g);
}

struct Scaling {
    double slope = 1, inter = 0;
    bool on = false;  // false when the slope is 0 or (slope, inter) = (1, 0)
};

// scl_slope/scl_inter, checked; a scaled result (float32, or float64) must fit max_bytes too.
Scaling nifti_scaling(const std::string& name, const HeaderFields& f, const Grid& g, DType dtype,
                      std::uint64_t max_bytes) {
    Scaling s;
    s.slope = f.f32(112);
    s.inter = f.f32(116);
    s.on = s.slope != 0 && !(s.slope == 1 && s.inter == 0);
    if (s.on) {
        if (!std::isfinite(s.slope))
            fail(name, "scl_slope is " + io_detail::format_double(s.slope) + ": must be finite (or 0 for no scaling)");
        if (!std::isfinite(s.inter)) fail(name, "scl_inter is " + io_detail::format_double(s.inter) + ": must be finite");
        io_detail::check_volume(name, g, dtype == DType::Float64 ? DType::Float64 : DType::Float32, max_bytes);
    }
    return s;
}

// vox_offset: where the voxels start (past the header and its extensions in a single file).
std::uint64_t nifti_data_offset(const std::string& name, const HeaderFields& f, bool single) {
    const double vox = f.f32(108);
    if (!std::isfinite(vox) || vox < 0 || vox > 1e15)
        fail(name, "vox_offset " + io_detail::format_double(vox) + " is not a valid byte offset");
    const auto offset = static_cast<std::uint64_t>(vox);
    if (single && offset < 352)
        fail(name, "vox_offset " + io_detail::format_double(vox) + " is inside the header (must be at least 352)");
    return offset;
}

// The voxels of a .nii.gz, inflated straight into the volume after the header.
Volume read_gzip_voxels(const ByteSource& src, io_detail::Inflater& inf, std::uint64_t offset, const Grid& g, DType dtype,
                        bool big_endian) {
    const std::uint64_t total = offset + static_cast<std::uint64_t>(g.voxel_count()) * dtype_size(dtype);
    io_detail::check_inflate_bound(src.name(), total, src.size());
    Volume v = io_detail::allocate(g, dtype);
    inf.expect(total);
    inf.skip(offset - kHeaderSize);
    inf.read(v.data.data(), v.data.size());
    inf.finish();
    if (big_endian != io_detail::host_is_big_endian())
        io_detail::swap_bytes(v.data.data(), v.data.size() / dtype_size(dtype), dtype_size(dtype));
    return v;
}

// Uncompressed voxels at `offset` of this file ('n+1') or of the .img beside this .hdr ('ni1').
Volume read_file_voxels(const ByteSource& src, bool pair, std::uint64_t offset, const Grid& g, DType dtype,
                        bool big_endian) {
    const std::string& name = src.name();
    io_detail::DataLocation loc(src);
    loc.offset = offset;
    std::unique_ptr<ByteSource> image;
    if (pair) {
        const std::string img = image_name_for(name);
        if (img.empty())
            fail(name, "header has the 'ni1' magic (separate .img file) but its name does not end in .hdr");
        image = src.open_sibling(img);
        loc.src = image.get();
        loc.detached = true;
    }
    return io_detail::read_raw_voxels(loc, g, dtype, big_endian);
}

}  // namespace

Volume read_nifti(const ByteSource& src, const ReadOptions& opt) {
    const std::string& name = src.name();
    std::uint8_t hdr[kHeaderSize];
    std::unique_ptr<io_detail::Inflater> inf;
    const bool gz = read_header_bytes(src, hdr, inf);
    const bool swap = needs_swap(name, hdr);
    const bool big_endian = swap != io_detail::host_is_big_endian();
    const HeaderFields f(hdr, swap);
    const bool single = std::memcmp(hdr + 344, "n+1", 3) == 0 && hdr[347] == 0;
    const bool pair = std::memcmp(hdr + 344, "ni1", 3) == 0 && hdr[347] == 0;
    if (!single && !pair) fail(name, "no NIfTI-1 magic ('n+1' or 'ni1'): Analyze 7.5 files are not supported");

    Grid g;
    const int ndim = nifti_dims(name, f, g);
    const DType dtype = nifti_dtype(name, f);
    nifti_geometry(name, f, ndim, g);
    io_detail::check_volume(name, g, dtype, opt.max_bytes);
    const Scaling scaling = nifti_scaling(name, f, g, dtype, opt.max_bytes);
    const std::uint64_t offset = nifti_data_offset(name, f, single);
    if (gz && pair) fail(name, "a gzip-compressed 'ni1' header (.hdr.gz) is not supported");
    Volume v = gz ? read_gzip_voxels(src, *inf, offset, g, dtype, big_endian)
                  : read_file_voxels(src, pair, offset, g, dtype, big_endian);
    if (scaling.on) {
        double lo = std::numeric_limits<double>::max(), hi = std::numeric_limits<double>::lowest();
        io_detail::finite_range(v.dtype, v.data.data(), v.data.size() / dtype_size(v.dtype), lo, hi);
        const DType out = io_detail::rescaled_type(name, "scl_slope/scl_inter", lo, hi, scaling.slope, scaling.inter,
                                                   v.dtype);
        io_detail::check_volume(name, g, out, opt.max_bytes);
        v = apply_scaling(std::move(v), scaling.slope, scaling.inter, out);
    }
    return v;
}

}  // namespace volrig

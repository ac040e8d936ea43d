// io/io.cpp: the volume I/O entry points that are no single format: the size limit, raw voxels, and the dispatcher
// that picks a reader from the file name (folders and unnamed DICOM files by content). The readers live in
// io_<format>.cpp, the helpers they share in io/io_detail.cpp, io/voxels.cpp, io/source.cpp and io/write.cpp (all
// declared in io/io_detail.hpp).
#include <cctype>
#include <charconv>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string_view>

#include "io/io_detail.hpp"
#include "volrig/io.hpp"

namespace volrig {

namespace {
constexpr std::uint64_t kDefaultMaxBytes = std::uint64_t(16) << 30;
}  // namespace

std::uint64_t default_max_bytes() {
    const char* env = std::getenv("VOLRIG_MAX_BYTES");
    if (!env || !*env) return kDefaultMaxBytes;
    // Digits with an optional binary suffix K, M, G or T; anything else falls back to the default.
    std::string_view s = io_detail::trim(env);
    std::uint64_t value = 0;
    auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
    if (ec != std::errc() || end == s.data()) return kDefaultMaxBytes;
    std::string_view rest = io_detail::trim(std::string_view(end, static_cast<std::size_t>(s.data() + s.size() - end)));
    int shift = 0;
    if (!rest.empty()) {
        const char c = static_cast<char>(std::toupper(static_cast<unsigned char>(rest[0])));
        shift = c == 'K' ? 10 : c == 'M' ? 20 : c == 'G' ? 30 : c == 'T' ? 40 : -1;
        if (shift < 0 || !(rest.size() == 1 || io_detail::iequals(rest.substr(1), "B") || io_detail::iequals(rest.substr(1), "iB")))
            return kDefaultMaxBytes;
    }
    if (shift && value > (std::numeric_limits<std::uint64_t>::max() >> shift)) return kDefaultMaxBytes;
    return value << shift;
}

Volume read_raw(const ByteSource& src, const RawLayout& layout, const ReadOptions& opt) {
    Grid g;
    g.dims = layout.dims;
    g.spacing = layout.spacing;
    g.origin = layout.origin;
    io_detail::check_volume(src.name(), g, layout.dtype, opt.max_bytes);
    io_detail::DataLocation loc(src);
    loc.offset = layout.offset;
    loc.claimant = "the layout";
    return io_detail::read_raw_voxels(loc, g, layout.dtype, layout.big_endian);
}

namespace {

// True when the file starts with the DICOM Part-10 preamble (128 bytes, then "DICM").
bool has_dicom_preamble(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    char head[132] = {};
    return f.read(head, sizeof head) && std::memcmp(head + 128, "DICM", 4) == 0;
}

// True when a regular file under the folder (recursively) is a DICOM Part-10 file.
bool has_dicom_file(const std::string& folder) {
    std::error_code ec;
    for (auto it = std::filesystem::recursive_directory_iterator(folder, ec);
         !ec && it != std::filesystem::recursive_directory_iterator(); it.increment(ec))
        if (it->is_regular_file(ec) && has_dicom_preamble(it->path().string())) return true;
    return false;
}

// True when the folder itself holds a .tif or .tiff file.
bool has_tiff_file(const std::string& folder) {
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(folder, ec)) {
        const std::string low = io_detail::lower(e.path().filename().string());
        const auto n = low.size();
        if ((n > 4 && low.compare(n - 4, 4, ".tif") == 0) || (n > 5 && low.compare(n - 5, 5, ".tiff") == 0))
            return true;
    }
    return false;
}

// Folders: DICOM when any file under them is DICOM, else a TIFF stack when they hold TIFF files (else read_dicom
// says that no DICOM images were found).
Volume read_folder(const std::string& path, const ReadOptions& opt) {
    if (!has_dicom_file(path) && has_tiff_file(path)) return read_tiff(path, opt);
    return read_dicom(path, opt);
}

}  // namespace

Volume read_volume(const std::string& path, const ReadOptions& opt) {
    io_detail::check_input_path(path);
    const std::string low = io_detail::lower(path);
    auto ends = [&](const char* e) {
        const std::size_t n = std::strlen(e);
        return low.size() >= n && low.compare(low.size() - n, n, e) == 0;
    };
    if (ends(".vdb")) return read_vdb(path, "", opt);
    if (ends(".tif") || ends(".tiff")) return read_tiff(path, opt);
    if (ends(".dcm") || ends(".dicom") || ends("dicomdir") || has_dicom_preamble(path)) return read_dicom(path, opt);
    enum class Kind { Nrrd, Meta, Nifti, Vti } kind;
    if (ends(".nrrd") || ends(".nhdr"))
        kind = Kind::Nrrd;
    else if (ends(".mhd") || ends(".mha"))
        kind = Kind::Meta;
    else if (ends(".nii") || ends(".nii.gz") || ends(".hdr"))
        kind = Kind::Nifti;
    else if (ends(".vti"))
        kind = Kind::Vti;
    else if (std::error_code ec; std::filesystem::is_directory(path, ec))  // a folder by another name
        return read_folder(path, opt);
    else
        throw FileFormatError(path + ": unknown volume format (known endings: .nrrd .nhdr .mhd .mha .nii .nii.gz "
                                     ".hdr .vti .vdb .tif .tiff .dcm, DICOMDIR, folders of DICOM or TIFF files; raw "
                                     "files need read_raw)");
    auto src = open_file(path);
    switch (kind) {
        case Kind::Nrrd: return read_nrrd(*src, opt);
        case Kind::Meta: return read_metaimage(*src, opt);
        case Kind::Vti: return read_vti(*src, opt);
        case Kind::Nifti: break;
    }
    return read_nifti(*src, opt);
}

}  // namespace volrig

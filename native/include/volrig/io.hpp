// volrig/io.hpp: reading and writing sampled volumes.
//
// Readers validate every header against the file before allocating: declared sizes are compared with the
// bytes present (or, for compressed data, with the largest size the compressed bytes could inflate to), absurd
// dimensions are refused, and decompression never writes past the declared size. Every error is a
// FileFormatError (or FileNotFound) whose message starts with the file name and says what is wrong.
// Writers write to a temporary name beside the target and rename it into place.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "volrig/volume.hpp"

namespace volrig {

/// Default limit on the decoded size of one volume (bytes): 16 GiB, or $VOLRIG_MAX_BYTES when set.
std::uint64_t default_max_bytes();

struct ReadOptions {
    std::uint64_t max_bytes = default_max_bytes();
    /// The caller chose max_bytes: then the file budget does not apply. Otherwise a file may not demand (decode
    /// to, or need as working memory) more than 1 GB (10^9 bytes) when that is also more than 1000 times its own
    /// size: a small file that declares a huge image is far more often broken or hostile than sparse. The error
    /// names the file, the demand and how to allow it (pass max_bytes, or set $VOLRIG_MAX_BYTES, which lifts the
    /// budget too).
    bool max_bytes_given = false;
    /// DICOM: the SeriesInstanceUID to read from a folder holding several series (empty: the one with most slices).
    std::string series;
    /// TIFF: spacing (x, y, z) to use instead of the file's resolution (a component <= 0: from the file; z,
    /// which TIFF does not store, then equals x).
    std::array<double, 3> spacing{0.0, 0.0, 0.0};
    /// Told what a reader assumed about a doubtful file (e.g. DICOM slice spacing that jitters); may be empty.
    std::function<void(const std::string&)> warn;
    /// Told the file a reader is about to decode when it reads several (a DICOM folder's slices); may be empty.
    /// A decoder that crashes in its child process is reported as crashing on the last file named so.
    std::function<void(const std::string&)> reading;
    /// VDB: read only the voxels of this box (the grid's index coordinates, inclusive), met with its active
    /// voxels' bounding box; the read is refused when they do not meet. Unused by the other formats.
    struct IndexBox {
        std::array<std::int64_t, 3> min, max;
    };
    std::optional<IndexBox> crop;
};

/// A random-access byte source: a file on disk or a block of memory (fuzzing, tests).
class ByteSource {
public:
    virtual ~ByteSource() = default;
    virtual std::uint64_t size() const = 0;
    /// Reads exactly n bytes at offset; throws FileFormatError naming the source when they are not there.
    virtual void read(std::uint64_t offset, void* dst, std::size_t n) const = 0;
    /// Name used in error messages (the path for files).
    virtual const std::string& name() const = 0;
    /// Opens a file named in this source's header (a detached data file), relative to this source's folder.
    /// Memory sources refuse with FileFormatError.
    virtual std::unique_ptr<ByteSource> open_sibling(const std::string& relative_name) const = 0;
};

std::unique_ptr<ByteSource> open_file(const std::string& path);
std::unique_ptr<ByteSource> memory_source(const std::uint8_t* data, std::size_t n, std::string name);

/// Raw voxels: the caller says what the file holds.
struct RawLayout {
    std::array<std::int64_t, 3> dims{0, 0, 0};  ///< x, y, z
    DType dtype = DType::UInt8;
    std::array<double, 3> spacing{1.0, 1.0, 1.0};
    std::array<double, 3> origin{0.0, 0.0, 0.0};
    bool big_endian = false;
    std::uint64_t offset = 0;  ///< bytes to skip before the voxels
};
Volume read_raw(const ByteSource& src, const RawLayout& layout, const ReadOptions& opt = {});

/// NRRD (.nrrd attached header, .nhdr detached header; raw and gzip encodings; either endianness).
Volume read_nrrd(const ByteSource& src, const ReadOptions& opt = {});
/// MetaImage (.mhd with a separate data file, .mha with LOCAL data; zlib CompressedData).
Volume read_metaimage(const ByteSource& src, const ReadOptions& opt = {});
/// VTK XML image data (.vti): one whole piece, the point data's active scalars (else its first array), appended
/// raw, uncompressed or zlib-compressed (vtkZLibDataCompressor), UInt32/UInt64 headers, either byte order.
Volume read_vti(const ByteSource& src, const ReadOptions& opt = {});
/// NIfTI-1 (.nii, .nii.gz, .hdr/.img pair). scl_slope/scl_inter are applied (result float32, or float64 for
/// float64 data) unless the slope is 0 or (slope, inter) = (1, 0). Spacing = |pixdim[1..3]|; origin from the
/// sform (sform_code > 0) or else the qform offsets.
Volume read_nifti(const ByteSource& src, const ReadOptions& opt = {});

/// DICOM (through GDCM). A folder (searched recursively), a DICOMDIR (the files under its folder are searched; its
/// records are not read) or a single file. Slices are grouped by SeriesInstanceUID and sorted along the slice
/// normal (ImagePositionPatient . (row x column direction)); the slice spacing comes from the positions; origin =
/// the first slice's position, direction = (row, column, normal) in LPS. RescaleSlope/Intercept are applied:
/// int16 when they are integral and the values fit, else float32 (no rescale: the stored type). Refused with a
/// FileFormatError: mixed sizes, orientations or pixel spacings, two slices at one position, uneven gaps (missing
/// slices), slices not stacked along their normal (gantry tilt), colour images. Spacing that jitters a little is
/// averaged and reported through opt.warn. Compressed transfer syntaxes are decoded by GDCM.
Volume read_dicom(const std::string& path, const ReadOptions& opt = {});
/// One DICOM file (single or multi-frame) from a byte source (fuzzing, tests).
Volume read_dicom_file(const ByteSource& src, const ReadOptions& opt = {});

struct DicomSeriesInfo {
    std::string uid, description, modality;
    std::array<std::int64_t, 3> dims{0, 0, 0};  ///< columns, rows, slices (frames of a single multi-frame file)
    std::vector<std::string> files;
};
/// The image series under a folder / DICOMDIR / file, the largest first. `warn` hears what the folder walk skipped
/// (dangling links, FIFOs, sockets, link loops, unreadable folders), as read_dicom's opt.warn does.
std::vector<DicomSeriesInfo> dicom_series(const std::string& path,
                                          const std::function<void(const std::string&)>& warn = {});

/// A TIFF stack (through libtiff): a multi-page TIFF file or a folder of TIFF files in natural order (slice2 before
/// slice10), one page per slice. Single-channel 8/16/32-bit unsigned or signed integers or 32/64-bit floats;
/// every page the same size and type. Spacing: opt.spacing where given, else x and y from XResolution/
/// YResolution with ResolutionUnit (inch or cm -> mm), z = x. Origin 0, axis-aligned.
Volume read_tiff(const std::string& path, const ReadOptions& opt = {});
/// One (multi-page) TIFF file from a byte source (fuzzing, tests).
Volume read_tiff_file(const ByteSource& src, const ReadOptions& opt = {});

/// Picks the reader from the file name: .nrrd .nhdr .mhd .mha .nii .nii.gz .hdr .vdb .tif .tiff .dcm DICOMDIR,
/// else by content (a folder of DICOM or TIFF files; a file with the DICOM preamble) (raw needs read_raw).
Volume read_volume(const std::string& path, const ReadOptions& opt = {});

/// Writers. gzip/compress select the compressed encodings.
void write_nrrd(const std::string& path, const VolumeView& v, bool gzip = true);
void write_metaimage(const std::string& path, const VolumeView& v, bool compress = true);

/// Writes a file atomically: `write(tmp)` writes a temporary file beside `path`, which is then renamed onto
/// `path`. On any exception the temporary file is removed and `path` is left untouched.
void write_atomically(const std::string& path, const std::function<void(const std::string& tmp_path)>& write);

// ---- OpenVDB -------------------------------------------------------------------------------------------------

struct VdbGridInfo {
    std::string name;
    std::string type;  ///< OpenVDB value type name, e.g. "float", "int32"
    std::array<std::int64_t, 3> bbox_min{0, 0, 0}, bbox_max{0, 0, 0};  ///< active voxel bounding box (index)
    std::int64_t active_voxels = 0;
};
std::vector<VdbGridInfo> vdb_grids(const std::string& path);

/// Reads one grid (by name; empty = "density" if present, else the first scalar grid) densely over its active
/// voxel bounding box. Spacing = the transform's voxel size (linear, axis-aligned transforms only), origin =
/// world position of the bbox minimum. float/double grids give float32/float64, int32/int64 grids int32/int64,
/// bool grids uint8.
Volume read_vdb(const std::string& path, const std::string& grid = "", const ReadOptions& opt = {});

/// Writes named grids on one voxel lattice (one spacing, origins a whole number of voxels apart; each grid's
/// spacing and origin go into its transform). Floating and uint8 volumes (masks, 8-bit scans) become FloatGrids
/// (stored as half floats when `half`); other integer volumes (e.g. int16/int32 bone labels), and uint8 ones marked
/// as labels (VolumeView::labels), become Int32Grids. Only non-zero voxels are active; the background is 0.
/// `metadata`: the file's string metadata (name, value), e.g. a bake's tissue classes (read back by volrig.vdb_metadata).
using VdbMetadata = std::vector<std::pair<std::string, std::string>>;
void write_vdb(const std::string& path, const std::vector<std::pair<std::string, VolumeView>>& grids, bool half = false,
               const VdbMetadata& metadata = {});

/// write_vdb in two steps: the grids built while the samples are at hand (build_vdb, checked as write_vdb checks
/// them; `path` names the file in errors), written later, say on another thread once the samples are gone (a
/// bake's frame goes back to its Deformer as soon as its grids are built). Built grids hold their topology (about
/// 100 bytes per 8³ block holding an active voxel, per grid) and their leaf values compressed as the file stores them
/// (a bake's frame of the phantom at scale 1: 11 MB for its 10 M covered voxels, density and bone grids together),
/// not OpenVDB's in-memory values.
class VdbGrids {
public:
    VdbGrids();
    ~VdbGrids();
    VdbGrids(VdbGrids&&) noexcept;
    VdbGrids& operator=(VdbGrids&&) noexcept;
    /// Writes the grids to `path` atomically and frees them (once: a second call, or one on a moved-from
    /// VdbGrids, throws).
    void write(const std::string& path);
    bool written() const;  ///< true once written (or moved from)

private:
    friend VdbGrids build_vdb(const std::string&, const std::vector<std::pair<std::string, VolumeView>>&, bool,
                              const VdbMetadata&);
    struct Impl;
    std::unique_ptr<Impl> impl_;
};
VdbGrids build_vdb(const std::string& path, const std::vector<std::pair<std::string, VolumeView>>& grids, bool half = false,
                   const VdbMetadata& metadata = {});

}  // namespace volrig

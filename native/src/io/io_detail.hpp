// io/io_detail.hpp: internals shared by the file readers and writers (io.cpp, io/nrrd.cpp, io/metaimage.cpp,
// io/nifti.cpp; the text readers of mesh_io.cpp and mocap/bvh.cpp). Not installed; not part of the public API.
// Defined in io/io_detail.cpp (messages, text, LineReader), io/voxels.cpp (grids and voxels) and io/write.cpp
// (writing); none of them depends on a format reader.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "volrig/io.hpp"

namespace volrig::io_detail {

// ---- messages ------------------------------------------------------------------------------------------------

/// Throws FileFormatError("<name>: <what>").
[[noreturn]] void fail(const std::string& name, const std::string& what);
/// 1558802 -> "1,558,802".
std::string with_commas(std::uint64_t n);
/// A header value quoted for an error message: non-printable bytes shown as '?', long values cut.
std::string quoted(std::string_view s);
/// "103x94x161 uint8".
std::string describe(const std::array<std::int64_t, 3>& dims, DType t);
/// The system's text for an errno value.
std::string errno_text(int e);

// ---- paths ---------------------------------------------------------------------------------------------------

/// Fails with Error (ValueError in Python) when the path holds a NUL byte (the OS would cut the name there).
void check_path(const std::string& path);
/// "a FIFO", "a socket", ... for a stat st_mode that is not a regular file.
std::string file_kind(unsigned mode);
/// check_path, then refuses (without opening it) a path that is neither a regular file nor a folder: a FIFO would
/// block open() and read() forever. FileNotFound when it does not exist.
void check_input_path(const std::string& path);
/// check_input_path, and refuses folders too.
void check_regular_file(const std::string& path);

// ---- text ----------------------------------------------------------------------------------------------------

std::string_view trim(std::string_view s);
std::string lower(std::string_view s);
bool iequals(std::string_view a, std::string_view b);
/// Splits on spaces/tabs (and, when `commas`, on commas).
std::vector<std::string_view> split_words(std::string_view s, bool commas = false);
/// Strict whole-token parses (locale independent); false on junk or overflow.
bool parse_int(std::string_view s, std::int64_t& out);
bool parse_double(std::string_view s, double& out);
/// Shortest text that reads back as exactly `v`.
std::string format_double(double v);

// ---- text files read line by line (OBJ, PLY headers, TGF, BVH) -------------------------------------------------

/// Bytes read from the source at a time, and the longest line accepted.
constexpr std::size_t kTextChunk = std::size_t(1) << 20;
constexpr std::size_t kMaxLine = std::size_t(64) << 20;

/// "line 12: ", the prefix of messages about one line.
std::string at_line(std::int64_t line);
/// Fails with "<name>: line N: binary data (a NUL byte) where <format> text was expected" when the line holds a NUL.
void refuse_binary(const std::string& name, std::int64_t line_no, std::string_view line, const char* format);

/// Lines of a text file read in chunks of kTextChunk (never the whole file at once); each line comes without its
/// '\n' (and a '\r' before it). A line longer than kMaxLine fails naming the source and the line.
class LineReader {
public:
    explicit LineReader(const ByteSource& src) : src_(src), size_(src.size()) {}

    /// The next line; false at the end of the file. The view is valid until the next call.
    bool next(std::string_view& line);
    /// Number of the line last returned (1-based).
    std::int64_t line_number() const { return line_; }
    /// File offset of the first byte after the line last returned.
    std::uint64_t offset() const { return base_ + pos_; }
    /// Bytes of the file after the line last returned.
    std::uint64_t remaining() const { return size_ - offset(); }

private:
    bool take(std::string_view& line, std::size_t end, std::size_t next);

    const ByteSource& src_;
    std::uint64_t size_;
    std::string buf_;
    std::uint64_t base_ = 0;  // file offset of buf_[0]
    std::size_t pos_ = 0;     // start of the unread part of buf_
    std::int64_t line_ = 0;
};

// ---- text headers (NRRD, MetaImage) ---------------------------------------------------------------------------

/// The longest text header (NRRD, MetaImage) read before the file is taken for something else.
constexpr std::size_t kMaxHeader = std::size_t(1) << 20;

struct HeaderField {
    std::string value;
    int line = 0;  ///< line number in the header, for messages
};

/// The key/value fields of a text header, keyed as the reader normalises them.
struct HeaderFields : std::map<std::string, HeaderField> {
    /// The field, or null when absent.
    const HeaderField* get(const std::string& key) const {
        auto it = std::map<std::string, HeaderField>::find(key);
        return it == end() ? nullptr : &it->second;
    }
    /// The field; fails with "<file>: missing field '<label>'" when absent.
    const HeaderField& need(const std::string& file, const std::string& key, const char* label) const {
        const HeaderField* f = get(key);
        if (!f) fail(file, std::string("missing field '") + label + "'");
        return *f;
    }
};

// ---- grids and voxels ----------------------------------------------------------------------------------------

/// Validates dims/spacing/origin and the decoded size against opt.max_bytes (check_grid), rethrowing as a
/// FileFormatError naming `name`. Returns the byte count.
std::uint64_t check_volume(const std::string& name, const Grid& g, DType t, std::uint64_t max_bytes);
/// The file budget (ReadOptions::max_bytes_given): fails naming `name` when `demand` bytes are more than
/// kBudgetFloor and more than kBudgetRatio times `file_bytes`, unless the caller gave max_bytes. `what` says what
/// the demand is for ("the pixels", "the dense grid"); `or_else`, when given, another way out the message offers.
constexpr std::uint64_t kBudgetFloor = 1000000000;  // 1 GB
constexpr std::uint64_t kBudgetRatio = 1000;
void check_budget(const std::string& name, std::uint64_t demand, std::uint64_t file_bytes, const ReadOptions& opt,
                  const std::string& what, const std::string& or_else = "");
/// kBudgetRatio times `file_bytes`, saturating: what the file may hold at that ratio.
std::uint64_t ratio_allowance(std::uint64_t file_bytes);
/// The most a file of `file_bytes` may demand: opt.max_bytes, and while the file budget applies (no max_bytes given,
/// no $VOLRIG_MAX_BYTES) at most the larger of kBudgetFloor and kBudgetRatio times the file.
std::uint64_t budget_of(std::uint64_t file_bytes, const ReadOptions& opt);
/// The smallest and largest finite values among n elements of type t (lo > hi when there are none).
void finite_range(DType t, const std::uint8_t* p, std::size_t n, double& lo, double& hi);
/// The element type a rescaled volume (value * slope + inter) needs: float32 when every result fits it, else
/// float64 (so a slope of 3e38 gives its true values, not inf); fails naming `name` when results overflow double
/// too. `lo`/`hi`: finite_range of the stored values.
DType rescaled_type(const std::string& name, const std::string& what, double lo, double hi, double slope,
                    double inter, DType stored);
/// A volume of the grid's size (zero-filled).
Volume allocate(const Grid& g, DType t);

bool host_is_big_endian();
/// Reverses the bytes of each of `count` elements of `esize` bytes, in place.
void swap_bytes(void* data, std::size_t count, std::size_t esize);

/// Where the voxels of a header-described volume live.
struct DataLocation {
    DataLocation() = default;
    /// Data in `s` itself, which names the errors.
    explicit DataLocation(const ByteSource& s) : src(&s), header(s.name()) {}
    const ByteSource* src = nullptr;  ///< the file holding the voxels
    std::string header;               ///< name of the header file (subject of error messages)
    std::uint64_t offset = 0;         ///< first data byte in *src
    bool detached = false;            ///< data file differs from the header file
    const char* claimant = "header";  ///< who declared the layout ("header says ...")
};

/// The readers below check the bytes present against the grid before allocating, then read straight into the
/// returned volume's buffer. The grid must have passed check_volume.

/// Uncompressed voxels at loc, byte-swapped in place when the file's order differs from the host's.
/// "<hdr>: header says 3x3x3 uint8 = 27 bytes but the file holds 20".
Volume read_raw_voxels(const DataLocation& loc, const Grid& g, DType t, bool big_endian);
/// A zlib/gzip stream of `compressed` bytes at loc, of which the first `skip` decompressed bytes are dropped.
Volume read_compressed_voxels(const DataLocation& loc, std::uint64_t compressed, std::uint64_t skip,
                              const Grid& g, DType t, bool big_endian);
/// Whitespace- (or comma-) separated numbers at loc.
Volume read_ascii_voxels(const DataLocation& loc, const Grid& g, DType t);

/// Subject for messages about the data: "<hdr>" or "<hdr> (data file <data>)".
std::string data_subject(const DataLocation& loc);

/// Moves loc.offset past `skip` bytes, failing "<subject>: <label> N runs past the end of the data (S bytes)" when
/// they are not there; skip -1 moves it to the last bytes of the file that hold the grid's voxels (when the file
/// is too short for them, the read that follows reports it). NRRD "byte skip", MetaImage HeaderSize.
void skip_to_data(DataLocation& loc, std::int64_t skip, const char* label, const Grid& g, DType t);

/// Offset of the first byte after `lines` newlines starting at `offset` (NRRD "line skip").
std::uint64_t skip_lines(const ByteSource& src, const std::string& header, std::uint64_t offset, std::int64_t lines);

/// True when a data-file value names several files (LIST, or a printf pattern followed by numbers).
bool names_several_files(std::string_view value);

// ---- DICOM ---------------------------------------------------------------------------------------------------

/// Walks a DICOM Part-10 file's structure (preamble, meta group, every element and item length within the file)
/// and checks its image pixel module; fails naming the source unless GDCM can safely be handed it and it is a
/// grey image (io/dicom_part10.cpp says why).
/// `vr_ok(group, element, vr)`, when given, says whether an explicit VR suits the tag (GDCM's dictionary).
/// Returns the transfer syntax UID.
std::string check_dicom_part10(const ByteSource& src,
                               const std::function<bool(std::uint16_t, std::uint16_t, const char*)>& vr_ok = {});
/// True unless the transfer syntax is native (implicit/explicit VR, either byte order) or RLE, which
/// check_dicom_part10 validates completely: the JPEG family (JPEG, JPEG-LS, JPEG 2000, ...) is decoded in a child
/// process (run_isolated).
bool dicom_needs_isolation(const std::string& syntax);

// ---- decoders that may crash (io/isolate.cpp) -------------------------------------------------------------------

/// What a child process sends its parent (run_isolated): warnings, then one result.
class IsolatedOutput {
public:
    explicit IsolatedOutput(int fd);
    void warn(const std::string& text);
    /// Names the file the child decodes next (a crash is then reported on it).
    void reading(const std::string& file);
    /// Starts the result with its first bytes; more() sends the rest.
    void result(const void* data, std::size_t n);
    void more(const void* data, std::size_t n);

private:
    int fd_;
};

/// The parent's end: the result's bytes, in the order the child sent them.
class IsolatedInput {
public:
    explicit IsolatedInput(int fd) : fd_(fd) {}
    /// False when the child stopped before sending n more bytes.
    bool read(void* data, std::size_t n);

private:
    int fd_;
};

/// Runs `work` in a fork()ed child (on one thread) and `receive` in the caller on what it sent. The child's
/// volrig errors are rethrown here as the same class; a child that dies (a failed assertion, a segfault) becomes
/// FileFormatError("<name>: <doing> crashed on this file (killed by signal 6 (Aborted)): ..."). `warn` gets the
/// child's warnings (may be empty). For decoders that abort or corrupt memory on broken input (GDCM's JPEG
/// family, OpenVDB). The child is held to `limits` (decoder_limits): a decoder that needs more memory fails at once
/// (FileFormatError when it throws std::bad_alloc), one that runs longer is stopped ("killed by signal 24 (CPU time
/// limit exceeded)").
struct ChildLimits {
    std::uint64_t memory = 0;       ///< bytes of data the child may map beyond what it holds at the fork (0: no cap)
    std::uint64_t cpu_seconds = 0;  ///< CPU seconds it may use (0: no cap)
};
void run_isolated(const std::string& name, const std::string& doing, const ChildLimits& limits,
                  const std::function<void(IsolatedOutput&)>& work,
                  const std::function<void(IsolatedInput&)>& receive,
                  const std::function<void(const std::string&)>& warn = {});
/// What a decoder may use: three times the file's budget (budget_of) in memory (the result, the decoder's own copy,
/// slack) plus 256 MiB; kDecodeSecondsFloor CPU seconds plus one per kDecodeBytesPerSecond of `work` (decoders run
/// at 100 MB/s or more of output, about 5 times slower under sanitizers, and `work`, what the file may hold at
/// 1000:1, is far more than any real file's output: a looping decoder on a file under 500 KB stops within 10 s).
/// A 0 (no cap) for values too large to triple.
constexpr std::uint64_t kDecodeSecondsFloor = 5;
constexpr std::uint64_t kDecodeBytesPerSecond = 100000000;
ChildLimits decoder_limits(std::uint64_t budget, std::uint64_t work);
/// decoder_limits for the file or folder `path` read with `opt`. A regular file: its budget_of, and as work what it
/// may hold at kBudgetRatio to 1 (not the 1 GB floor: a 10 KB file gets 5.5 s, so a decoder looping on a tiny
/// hostile file stops within 10 s). A folder: max_bytes for both.
ChildLimits decoder_limits(const std::string& path, const ReadOptions& opt);
/// A volume decoded by `decode` in a child process (run_isolated); its warnings go to opt.warn.
Volume isolated_volume(const std::string& name, const std::string& doing, const ReadOptions& opt,
                       const std::function<Volume(const ReadOptions&)>& decode);

// ---- writing -------------------------------------------------------------------------------------------------

/// An output file opened for writing (created or truncated); every failure throws naming `shown_as` (the
/// final name when writing a temporary file), or the path itself.
class FileWriter {
public:
    explicit FileWriter(const std::string& path, const std::string& shown_as = "");
    ~FileWriter();
    FileWriter(const FileWriter&) = delete;
    FileWriter& operator=(const FileWriter&) = delete;
    void write(const void* data, std::size_t n);
    void write(std::string_view s) { write(s.data(), s.size()); }
    /// Overwrites bytes already written at `offset`.
    void write_at(std::uint64_t offset, const void* data, std::size_t n);
    std::uint64_t position() const { return pos_; }
    void close();

private:
    int fd_ = -1;
    std::string path_;
    std::uint64_t pos_ = 0;
};

/// Checks a view before writing it: positive dims, finite positive spacing, finite origin, data present.
void check_view(const std::string& path, const VolumeView& v);
/// Hands the voxels to `sink` in little-endian byte order, in chunks (no copy on little-endian hosts).
void little_endian_chunks(const VolumeView& v, const std::function<void(const void*, std::size_t)>& sink);

/// A format's type code to DType through a table of (code, type) pairs: false for a code not in it.
template <std::size_t N>
bool dtype_from_table(const std::array<std::pair<int, DType>, N>& table, int code, DType& t) {
    for (const auto& [c, type] : table)
        if (c == code) {
            t = type;
            return true;
        }
    return false;
}

}  // namespace volrig::io_detail

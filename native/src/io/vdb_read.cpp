// io/vdb_read.cpp: OpenVDB reading, the "OpenVDB" section of volrig/io.hpp (writing: io/vdb_write.cpp).
//
// Reading (read_vdb, vdb_grids): the grid is copied densely over its active voxel bounding box. Only linear transforms
// with an axis-aligned positive scale are accepted (rotated, sheared, mirrored and frustum transforms are refused);
// spacing = the scale, origin = the world position of the bounding box minimum. Files are read through OpenVDB's
// archive code from a stream owned here (see VdbReader), so truncated files are refused with a FileFormatError.
// Known limit: OpenVDB 10 itself can overrun a buffer on some deliberately corrupted leaf data (bloscFromStream
// copies a length read from the file before checking it), so .vdb files are trusted more than the other formats.
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/io/io.h>
#include <openvdb/tools/Dense.h>

#include <tbb/blocked_range.h>
#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <ctime>
#include <fstream>
#include <limits>
#include <memory>
#include <random>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include "volrig/io.hpp"
#include "io/io_detail.hpp"
#include "io/vdb_detail.hpp"

namespace volrig {

using io_detail::initialize_openvdb;

namespace {

bool is_scalar_type(const std::string& t) {
    return t == "float" || t == "double" || t == "int32" || t == "int64" || t == "bool";
}

/// Runs f() and turns OpenVDB's (and the standard library's) exceptions into a FileFormatError naming the file.
template <class F>
auto guarded_read(const std::string& path, const std::string& doing, F&& f) -> decltype(f()) {
    try {
        return f();
    } catch (const Error&) {
        throw;
    } catch (const openvdb::Exception& e) {
        throw FileFormatError(path + ": not a valid OpenVDB file: failed " + doing + " (" + e.what() + ")");
    } catch (const std::bad_alloc&) {
        throw FileFormatError(path + ": corrupt OpenVDB file: failed " + doing + " (out of memory)");
    } catch (const std::exception& e) {
        throw FileFormatError(path + ": corrupt OpenVDB file: failed " + doing + " (" + e.what() + ")");
    }
}

/// Reads VDB files through OpenVDB's own archive code, as io::File does (header, file metadata, then one grid
/// descriptor per grid with the grid's byte range), but from a stream it owns: io::File reads a truncated last
/// grid without complaint (its stream state is not checked), whereas here every grid's byte range is checked
/// against the file size when the file is opened and the stream state after each read.
class VdbReader : public openvdb::io::Archive {
public:
    explicit VdbReader(const std::string& path) : path_(path) {
        initialize_openvdb();
        is_.open(path, std::ios::binary);
        if (!is_) throw FileNotFound(path + ": no such file or it cannot be opened");
        is_.seekg(0, std::ios::end);
        size_ = static_cast<std::int64_t>(is_.tellg());
        is_.seekg(0, std::ios::beg);
        if (!is_ || size_ < 16)
            throw FileFormatError(path + ": not an OpenVDB file (" + std::to_string(std::max<std::int64_t>(size_, 0)) +
                                  " bytes is too short for a VDB header)");
        guarded_read(path_, "reading the file header", [&] {
            readHeader(is_);  // throws IoError when the magic number is wrong
            check_stream("the file header");
            const std::uint32_t oldest = openvdb::OPENVDB_FILE_VERSION_ROOTNODE_MAP,
                                newest = openvdb::OPENVDB_FILE_VERSION;
            if (fileVersion() < oldest || fileVersion() > newest)
                throw FileFormatError(path_ + ": unsupported OpenVDB file format version " +
                                      std::to_string(fileVersion()) + " (this build reads " + std::to_string(oldest) +
                                      " to " + std::to_string(newest) + ")");
            if (!inputHasGridOffsets())
                throw FileFormatError(path_ + ": VDB stream without grid offsets (not a seekable .vdb file)");
            meta_ = std::make_shared<openvdb::io::StreamMetadata>();
            meta_->setSeekable(true);
            openvdb::io::setStreamMetadataPtr(is_, meta_, /*transfer=*/false);
            setFormatVersion(is_);
            setLibraryVersion(is_);
            setDataCompression(is_);
            openvdb::MetaMap file_meta;
            check_meta("the file metadata");
            file_meta.readMeta(is_);
            check_stream("the file metadata");
            const std::int32_t count = readGridCount(is_);
            check_stream("the grid count");
            if (count < 0) throw FileFormatError(path_ + ": negative grid count " + std::to_string(count));
            for (std::int32_t i = 0; i < count; ++i) {
                openvdb::io::GridDescriptor gd;
                // The descriptor's names: unique name, type name, and (since instancing) the parent's name.
                check_blocks(fileVersion() >= openvdb::OPENVDB_FILE_VERSION_GRID_INSTANCING ? 3 : 2,
                             "grid descriptor " + std::to_string(i));
                gd.read(is_);
                check_stream("grid descriptor " + std::to_string(i));
                const std::int64_t here = static_cast<std::int64_t>(is_.tellg());
                if (gd.getGridPos() < here || gd.getEndPos() < gd.getGridPos() || gd.getEndPos() > size_) {
                    std::ostringstream s;
                    s << path_ << ": truncated or corrupt OpenVDB file: grid '" << gd.gridName() << "' spans bytes "
                      << gd.getGridPos() << " to " << gd.getEndPos() << " but the file holds " << size_ << " bytes";
                    throw FileFormatError(s.str());
                }
                descriptors_.push_back(gd);
                gd.seekToEnd(is_);
            }
            return 0;
        });
    }
    VdbReader(const VdbReader&) = delete;
    VdbReader& operator=(const VdbReader&) = delete;

    const std::vector<openvdb::io::GridDescriptor>& descriptors() const { return descriptors_; }
    std::uint64_t size() const { return static_cast<std::uint64_t>(size_); }

    /// The descriptor of the first grid named `name`, or nullptr.
    const openvdb::io::GridDescriptor* find(const std::string& name) const {
        for (const auto& gd : descriptors_)
            if (gd.gridName() == name) return &gd;
        return nullptr;
    }

    /// Value type name of a grid ("float", "int32", "vec3s", ...) without reading it.
    static std::string value_type(const openvdb::io::GridDescriptor& gd) {
        return openvdb::GridBase::createGrid(gd.gridType())->valueType();
    }

    /// A grid's metadata and transform (no tree).
    openvdb::GridBase::Ptr read_metadata(const openvdb::io::GridDescriptor& gd) {
        return guarded_read(path_, "reading the metadata of grid '" + gd.gridName() + "'", [&] {
            auto grid = openvdb::GridBase::createGrid(gd.gridType());
            grid->setSaveFloatAsHalf(gd.saveFloatAsHalf());
            is_.clear();
            gd.seekToGrid(is_);
            readGridCompression(is_);
            check_meta("grid '" + gd.gridName() + "' metadata");
            grid->readMeta(is_);
            grid->readTransform(is_);
            check_stream("grid '" + gd.gridName() + "' metadata");
            if (grid->getName().empty()) grid->setName(gd.gridName());
            return grid;
        });
    }

    /// A whole grid (instances share their parent's tree).
    openvdb::GridBase::Ptr read_grid(const openvdb::io::GridDescriptor& gd, int depth = 0) {
        if (gd.isInstance()) {
            const openvdb::io::GridDescriptor* parent = nullptr;
            for (const auto& other : descriptors_)
                if (other.uniqueName() == gd.instanceParentName()) parent = &other;
            if (!parent || parent == &gd || depth > static_cast<int>(descriptors_.size()))
                throw FileFormatError(path_ + ": grid '" + gd.gridName() + "' is an instance of a missing grid");
            auto tree_owner = read_grid(*parent, depth + 1);
            auto grid = read_metadata(gd);
            guarded_read(path_, "sharing the tree of grid '" + gd.gridName() + "'", [&] {
                grid->setTree(tree_owner->baseTreePtr());
                return 0;
            });
            return grid;
        }
        return guarded_read(path_, "reading grid '" + gd.gridName() + "'", [&] {
            auto grid = openvdb::GridBase::createGrid(gd.gridType());
            grid->setSaveFloatAsHalf(gd.saveFloatAsHalf());
            is_.clear();
            gd.seekToGrid(is_);
            openvdb::io::Archive::readGrid(grid, gd, is_);
            check_stream("grid '" + gd.gridName() + "'");
            if (static_cast<std::int64_t>(is_.tellg()) > gd.getEndPos())
                throw FileFormatError(path_ + ": corrupt OpenVDB file: grid '" + gd.gridName() +
                                      "' reads past its end");
            if (grid->getName().empty()) grid->setName(gd.gridName());
            return grid;
        });
    }

    /// "'a' (float), 'b' (int32)" for error messages.
    std::string grid_list() const {
        std::string s;
        for (const auto& gd : descriptors_) {
            if (!s.empty()) s += ", ";
            s += "'" + gd.gridName() + "' (" + value_type(gd) + ")";
        }
        return s.empty() ? std::string("none") : s;
    }

private:
    /// Walks the metadata map at the stream's position without reading it (a count, then per entry three blocks
    /// of a 32-bit length and that many bytes: name, type name, value) and fails unless every length fits in the
    /// file: OpenVDB allocates (and zero-fills) a string of whatever length the file declares before reading it.
    void check_meta(const std::string& what) {
        const std::streampos start = is_.tellg();
        std::uint32_t count = 0;
        is_.read(reinterpret_cast<char*>(&count), sizeof count);
        check_stream(what);
        if (std::int64_t(count) * 12 > size_ - static_cast<std::int64_t>(is_.tellg()))
            throw FileFormatError(path_ + ": corrupt OpenVDB file: " + what + " declares " + std::to_string(count) +
                                  " entries, more than the file holds");
        check_blocks(std::int64_t(count) * 3, what);
        is_.seekg(start);
    }

    /// Walks `blocks` blocks of a 32-bit length and that many bytes from the stream's position (then returns to
    /// it), failing unless each fits in the file.
    void check_blocks(std::int64_t blocks, const std::string& what) {
        const std::streampos start = is_.tellg();
        const auto left = [&] { return size_ - static_cast<std::int64_t>(is_.tellg()); };
        for (std::int64_t i = 0; i < blocks; ++i) {
            std::uint32_t n = 0;
            is_.read(reinterpret_cast<char*>(&n), sizeof n);
            check_stream(what);
            if (std::int64_t(n) > left())
                throw FileFormatError(path_ + ": corrupt OpenVDB file: " + what + " declares a " + std::to_string(n) +
                                      "-byte value, more than the file holds");
            is_.seekg(n, std::ios::cur);
        }
        check_stream(what);
        is_.seekg(start);
    }

    void check_stream(const std::string& what) const {
        if (!is_.good())
            throw FileFormatError(path_ + ": truncated or corrupt OpenVDB file (reading " + what +
                                  " ran past the end of the file)");
    }

    std::string path_;
    std::ifstream is_;
    std::int64_t size_ = 0;
    openvdb::io::StreamMetadata::Ptr meta_;
    std::vector<openvdb::io::GridDescriptor> descriptors_;
};

/// Index bounding box from the file's stats metadata, if it has them (written by OpenVDB's writer by default).
bool stats_bbox(const openvdb::GridBase& g, openvdb::CoordBBox& bbox, std::int64_t& count) {
    using openvdb::GridBase;
    auto lo = g.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MIN);
    auto hi = g.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MAX);
    auto n = g.getMetadata<openvdb::Int64Metadata>(GridBase::META_FILE_VOXEL_COUNT);
    if (!lo || !hi || !n) return false;
    bbox = openvdb::CoordBBox(openvdb::Coord(lo->value()), openvdb::Coord(hi->value()));
    count = n->value();
    return true;
}

/// Grid geometry of `bbox` under `xf`, refusing transforms that are not an axis-aligned positive scale.
Grid geometry_of(const openvdb::math::Transform& xf, const openvdb::CoordBBox& bbox, const std::string& path,
                 const std::string& name) {
    const std::string subject = path + ": grid '" + name + "'";
    if (!xf.isLinear())
        throw FileFormatError(subject + " has a nonlinear (" + xf.mapType() +
                              ") transform; only axis-aligned linear transforms are supported");
    const openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();  // row vectors: world = index * m
    double scale = 0;
    for (int a = 0; a < 3; ++a) scale = std::max(scale, std::abs(m[a][a]));
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            if (r != c && !(std::abs(m[r][c]) <= 1e-9 * scale))
                throw FileFormatError(subject + " has a rotated or sheared transform (" + xf.mapType() +
                                      "); only axis-aligned linear transforms are supported");
    for (int a = 0; a < 3; ++a)
        if (!(m[a][a] > 0) || !std::isfinite(m[a][a]))
            throw FileFormatError(subject + " has a mirrored or degenerate transform (scale " +
                                  std::to_string(m[0][0]) + ", " + std::to_string(m[1][1]) + ", " +
                                  std::to_string(m[2][2]) + "); only positive axis-aligned scales are supported");
    Grid g;
    for (int a = 0; a < 3; ++a) {
        g.dims[a] = static_cast<std::int64_t>(bbox.max()[a]) - static_cast<std::int64_t>(bbox.min()[a]) + 1;
        g.spacing[a] = m[a][a];
    }
    const openvdb::Vec3d o = xf.indexToWorld(bbox.min());
    g.origin = {o[0], o[1], o[2]};
    return g;
}

DType dtype_of_grid(const std::string& type) {
    if (type == "float") return DType::Float32;
    if (type == "double") return DType::Float64;
    if (type == "int32") return DType::Int32;
    if (type == "int64") return DType::Int64;
    return DType::UInt8;  // bool
}

/// Copies the grid over bbox into out (x fastest, z slowest), in slabs of z on plain threads: read_vdb runs in a
/// child process (io/isolate.cpp) where TBB has a single thread.
template <class T, class GridT>
void copy_dense(const GridT& grid, const openvdb::CoordBBox& bbox, void* out) {
    const int z0 = bbox.min().z(), depth = bbox.max().z() - z0 + 1;
    const std::size_t slab = std::size_t(bbox.dim().x()) * std::size_t(bbox.dim().y());
    const int n = static_cast<int>(std::max(1u, std::min(std::thread::hardware_concurrency(), 16u)));
    std::vector<std::thread> threads;
    std::exception_ptr error;
    std::mutex error_mutex;
    for (int i = 0; i < n; ++i) {
        const int a = z0 + static_cast<int>(std::int64_t(depth) * i / n);
        const int b = z0 + static_cast<int>(std::int64_t(depth) * (i + 1) / n) - 1;
        if (a > b) continue;
        threads.emplace_back([&, a, b] {
            try {
                const openvdb::CoordBBox part(openvdb::Coord(bbox.min().x(), bbox.min().y(), a),
                                              openvdb::Coord(bbox.max().x(), bbox.max().y(), b));
                openvdb::tools::Dense<T, openvdb::tools::LayoutXYZ> dense(part, static_cast<T*>(out) +
                                                                                     std::size_t(a - z0) * slab);
                openvdb::tools::copyToDense(grid, dense, /*serial=*/true);
            } catch (...) {
                const std::lock_guard<std::mutex> lock(error_mutex);
                if (!error) error = std::current_exception();
            }
        });
    }
    for (std::thread& t : threads) t.join();
    if (error) std::rethrow_exception(error);
}

}  // namespace

// ---- public API ----------------------------------------------------------------------------------------------

// ---- public API ----------------------------------------------------------------------------------------------

namespace {

std::vector<VdbGridInfo> grids_here(const std::string& path) {
    VdbReader file(path);
    std::vector<VdbGridInfo> out;
    for (const auto& gd : file.descriptors()) {
        auto grid = file.read_metadata(gd);
        VdbGridInfo info;
        info.name = gd.gridName();
        info.type = grid->valueType();
        openvdb::CoordBBox bbox;
        std::int64_t count = 0;
        if (!stats_bbox(*grid, bbox, count)) {
            auto full = file.read_grid(gd);
            bbox = full->evalActiveVoxelBoundingBox();
            count = static_cast<std::int64_t>(full->activeVoxelCount());
        }
        if (count > 0 && !bbox.empty()) {
            for (int a = 0; a < 3; ++a) {
                info.bbox_min[a] = bbox.min()[a];
                info.bbox_max[a] = bbox.max()[a];
            }
        }
        info.active_voxels = count;
        out.push_back(std::move(info));
    }
    return out;
}

std::string box_text(const openvdb::CoordBBox& b) {
    const auto c = [](const openvdb::Coord& p) {
        return "(" + std::to_string(p.x()) + ", " + std::to_string(p.y()) + ", " + std::to_string(p.z()) + ")";
    };
    return c(b.min()) + " .. " + c(b.max());
}

/// Refuses (in the caller's process, before OpenVDB's) a crop box whose min exceeds its max or that leaves
/// OpenVDB's 32-bit index coordinates.
void check_crop(const std::string& path, const ReadOptions& opt) {
    if (!opt.crop) return;
    constexpr std::int64_t lo = std::numeric_limits<std::int32_t>::min(), hi = std::numeric_limits<std::int32_t>::max();
    for (std::size_t i = 0; i < 3; ++i)
        if (opt.crop->min[i] > opt.crop->max[i] || opt.crop->min[i] < lo || opt.crop->max[i] > hi)
            throw Error(path + ": the crop box's min must not exceed its max, within 32-bit index coordinates");
}

/// `active` met with opt.crop (checked by check_crop, when given); refused when they do not meet.
openvdb::CoordBBox cropped(const openvdb::CoordBBox& active, const ReadOptions& opt, const std::string& subject) {
    if (!opt.crop) return active;
    openvdb::Coord a, b;
    for (int k = 0; k < 3; ++k) {
        a[k] = static_cast<openvdb::Int32>(opt.crop->min[static_cast<std::size_t>(k)]);
        b[k] = static_cast<openvdb::Int32>(opt.crop->max[static_cast<std::size_t>(k)]);
    }
    openvdb::CoordBBox out = active;
    out.intersect(openvdb::CoordBBox(a, b));
    if (out.empty())
        throw FileFormatError(subject + ": the crop box " + box_text(openvdb::CoordBBox(a, b)) +
                              " holds none of the active voxels, which lie in " + box_text(active));
    return out;
}

Volume read_here(const std::string& path, const std::string& grid_name, const ReadOptions& opt) {
    VdbReader file(path);
    const openvdb::io::GridDescriptor* gd = nullptr;
    if (grid_name.empty()) {
        gd = file.find("density");
        for (const auto& d : file.descriptors())
            if (!gd && is_scalar_type(VdbReader::value_type(d))) gd = &d;
        if (!gd) throw FileFormatError(path + ": no scalar grid to read (grids present: " + file.grid_list() + ")");
    } else {
        gd = file.find(grid_name);
        if (!gd)
            throw FileFormatError(path + ": no grid named '" + grid_name + "' (grids present: " + file.grid_list() +
                                  ")");
    }
    const std::string name = gd->gridName();
    const std::string subject = path + ": grid '" + name + "'";
    const std::string type = VdbReader::value_type(*gd);
    if (!is_scalar_type(type))
        throw FileFormatError(subject + " holds " + type +
                              " values; only scalar grids (float, double, int32, int64, bool) can be read");
    const std::size_t esize = dtype_size(dtype_of_grid(type));
    auto checked = [&](const Grid& g, const openvdb::CoordBBox& active) {
        try {
            check_grid(g, esize, opt.max_bytes, subject);
        } catch (const FileFormatError&) {
            throw;
        } catch (const Error& e) {
            throw FileFormatError(e.what());
        }
        const std::uint64_t dense = static_cast<std::uint64_t>(g.voxel_count()) * esize;
        io_detail::check_budget(path, dense, file.size(), opt,
                                "grid '" + name + "' as a dense " + std::to_string(g.dims[0]) + " x " +
                                    std::to_string(g.dims[1]) + " x " + std::to_string(g.dims[2]) + " box (" +
                                    (opt.crop ? "the crop box met with the active voxels' bounding box"
                                              : "the active voxels' bounding box") + ")",
                                "read part of it with crop=(min, max) in the grid's index coordinates (its active "
                                "voxels lie in " + box_text(active) + ")");
    };

    // Check the size the stats metadata declare (when present) before reading the tree.
    {
        auto meta = file.read_metadata(*gd);
        openvdb::CoordBBox bbox;
        std::int64_t count = 0;
        if (stats_bbox(*meta, bbox, count) && count > 0 && !bbox.empty()) {
            const openvdb::CoordBBox part = cropped(bbox, opt, subject);
            checked(geometry_of(meta->transform(), part, path, name), bbox);
        }
    }

    auto base = file.read_grid(*gd);
    const openvdb::CoordBBox active = base->evalActiveVoxelBoundingBox();
    if (active.empty() || base->activeVoxelCount() == 0) throw FileFormatError(subject + " has no active voxels");
    const openvdb::CoordBBox bbox = cropped(active, opt, subject);
    Volume vol;
    vol.grid = geometry_of(base->transform(), bbox, path, name);
    vol.dtype = dtype_of_grid(type);
    checked(vol.grid, active);
    vol.data.resize(static_cast<std::size_t>(vol.grid.voxel_count()) * esize);
    void* out = vol.data.data();
    guarded_read(path, "copying grid '" + name + "'", [&] {
        if (type == "float") copy_dense<float>(*openvdb::gridPtrCast<openvdb::FloatGrid>(base), bbox, out);
        else if (type == "double") copy_dense<double>(*openvdb::gridPtrCast<openvdb::DoubleGrid>(base), bbox, out);
        else if (type == "int32") copy_dense<std::int32_t>(*openvdb::gridPtrCast<openvdb::Int32Grid>(base), bbox, out);
        else if (type == "int64") copy_dense<std::int64_t>(*openvdb::gridPtrCast<openvdb::Int64Grid>(base), bbox, out);
        else copy_dense<std::uint8_t>(*openvdb::gridPtrCast<openvdb::BoolGrid>(base), bbox, out);
        return 0;
    });
    return vol;
}

}  // namespace

// OpenVDB reads in a child process (io/isolate.cpp): a corrupt leaf can make it overrun a buffer.
Volume read_vdb(const std::string& path, const std::string& grid_name, const ReadOptions& opt) {
    io_detail::check_regular_file(path);
    check_crop(path, opt);
    return io_detail::isolated_volume(path, "OpenVDB's reader", opt,
                                      [&](const ReadOptions& o) { return read_here(path, grid_name, o); });
}

std::vector<VdbGridInfo> vdb_grids(const std::string& path) {
    io_detail::check_regular_file(path);
    std::vector<VdbGridInfo> out;
    const auto send_text = [](io_detail::IsolatedOutput& o, const std::string& t) {
        const std::uint64_t n = t.size();
        o.more(&n, sizeof n);
        o.more(t.data(), t.size());
    };
    const auto take_text = [&](io_detail::IsolatedInput& in, std::string& t) {
        std::uint64_t n = 0;
        if (!in.read(&n, sizeof n) || n > (std::uint64_t(1) << 20)) io_detail::fail(path, "OpenVDB's reader stopped");
        t.resize(static_cast<std::size_t>(n));
        if (n && !in.read(&t[0], t.size())) io_detail::fail(path, "OpenVDB's reader stopped");
    };
    io_detail::run_isolated(
        path, "OpenVDB's reader", io_detail::decoder_limits(path, ReadOptions{}),
        [&](io_detail::IsolatedOutput& o) {
            const std::vector<VdbGridInfo> all = grids_here(path);
            const std::uint64_t n = all.size();
            o.result(&n, sizeof n);
            for (const VdbGridInfo& g : all) {
                send_text(o, g.name);
                send_text(o, g.type);
                o.more(g.bbox_min.data(), sizeof g.bbox_min);
                o.more(g.bbox_max.data(), sizeof g.bbox_max);
                o.more(&g.active_voxels, sizeof g.active_voxels);
            }
        },
        [&](io_detail::IsolatedInput& in) {
            std::uint64_t n = 0;
            if (!in.read(&n, sizeof n) || n > (std::uint64_t(1) << 24)) io_detail::fail(path, "OpenVDB's reader stopped");
            out.resize(static_cast<std::size_t>(n));
            for (VdbGridInfo& g : out) {
                take_text(in, g.name);
                take_text(in, g.type);
                if (!in.read(g.bbox_min.data(), sizeof g.bbox_min) || !in.read(g.bbox_max.data(), sizeof g.bbox_max) ||
                    !in.read(&g.active_voxels, sizeof g.active_voxels))
                    io_detail::fail(path, "OpenVDB's reader stopped");
            }
        });
    return out;
}

}  // namespace volrig

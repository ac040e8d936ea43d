// io/vdb_write.cpp: OpenVDB writing, the "OpenVDB" section of volrig/io.hpp (reading: io/vdb_read.cpp).
//
// Grid types written (write_vdb):
//   float32, float64       -> FloatGrid, class FOG_VOLUME, stored as half floats when `half`; so are views of half
//                             floats (VolumeView::half).
//   uint8                  -> FloatGrid too, class FOG_VOLUME (values unchanged: a mask becomes 0/1, an 8-bit scan
//                             keeps 0..255). uint8 is what masks and 8-bit scans are; as float grids they render
//                             directly as density in Blender/Cycles and in Blender's viewport.
//   int8, int16, int32, uint16, uint32, int64, uint64
//                          -> Int32Grid (labels such as the `bone` grid); a value outside int32 is refused.
//   any integer type marked as labels (VolumeView::labels), uint8 included
//                          -> Int32Grid as well (a bake's frames hold their bone labels as bytes).
// Reading back therefore gives float32 for uint8 volumes written here (same values).
//
// Transform: a linear transform whose index (i, j, k) maps to origin + spacing * (i, j, k) (createLinearTransform
// with the per-axis scale, then postTranslate(origin)). OpenVDB (and Blender's volume import) put voxel centres at
// integer index coordinates, so voxel (x, y, z) of the array is centred at the world position docs/DESIGN.md gives it.
// Background 0; exactly the non-zero voxels are active; a leaf-sized 8^3 block whose 512 voxels are all non-zero and
// equal is stored as an active tile (as openvdb::tools::copyFromDense does).
//
// Built grids (build_vdb) hold their leaves' active masks only, with the leaf buffers already compressed (in parallel,
// straight from the samples, by OpenVDB's own io::writeCompressedValues), and the file is written by write_archive
// here rather than io::File: io::File needs every leaf's values in memory (4 bytes per voxel of each non-constant
// 8^3 block, per grid), which while a bake's next frame computed beside them was what held a bake above 3 bytes per
// source voxel. write_archive follows io::Archive::write of OpenVDB 10 step by step, through OpenVDB's classes for
// everything but the buffers (GridDescriptor, metadata, transform, topology) and with the delayed-load metadata
// OpenVDB's reader seeks by; the bytes equal what io::File writes for the same whole grids but the random UUID
// (Catch2: "a bake's grids are written as OpenVDB writes them ..." compares them and reads the file back with
// delayed loading, as Blender does). It is the hand-written part of the writer, tied to OpenVDB 10's file format
// (OPENVDB_FILE_VERSION 224), which that test checks against the installed library.
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
#include <type_traits>
#include <vector>

#include "volrig/io.hpp"
#include "io/vdb_detail.hpp"

namespace volrig {

using io_detail::initialize_openvdb;

namespace {

// ---- writing -------------------------------------------------------------------------------------------------

/// First offending voxel while building a grid (values that do not fit the grid type).
struct Overflow {
    std::atomic<bool> seen{false};
    std::mutex mutex;
    std::int64_t index = std::numeric_limits<std::int64_t>::max();
    std::string value;
    void note(std::int64_t i, const std::string& v) {
        std::lock_guard<std::mutex> lock(mutex);
        if (i < index) {
            index = i;
            value = v;
        }
        seen = true;
    }
};

template <class Out, class In>
bool fits(In v) {
    if constexpr (std::is_floating_point_v<Out>) {
        return true;
    } else if constexpr (std::is_signed_v<In>) {
        return static_cast<std::int64_t>(v) >= std::numeric_limits<Out>::min() &&
               static_cast<std::int64_t>(v) <= std::numeric_limits<Out>::max();
    } else {
        return static_cast<std::uint64_t>(v) <= static_cast<std::uint64_t>(std::numeric_limits<Out>::max());
    }
}

/// Whether the n values at p are all bytes zero (a quick test before a block's voxels are looked at one by one).
template <class In>
bool all_zero_bytes(const In* p, std::int64_t n) {
    const auto* b = reinterpret_cast<const unsigned char*>(p);
    const auto bytes = static_cast<std::size_t>(n) * sizeof(In);
    std::uint64_t acc = 0;
    for (std::size_t i = 0; i + 8 <= bytes; i += 8) {
        std::uint64_t w;
        std::memcpy(&w, b + i, 8);
        acc |= w;
    }
    for (std::size_t i = bytes / 8 * 8; i < bytes; ++i) acc |= b[i];
    return acc == 0;
}

/// Whether every value of type In fits the grid type Out (no overflow check needed).
template <class Out, class In>
constexpr bool always_fits() {
    if constexpr (std::is_floating_point_v<Out>) return true;
    else if constexpr (!std::is_integral_v<In>) return false;
    else if constexpr (std::is_signed_v<In> == std::is_signed_v<Out>) return sizeof(In) <= sizeof(Out);
    else return !std::is_signed_v<In> && sizeof(In) < sizeof(Out);
}

template <class In>
bool nonzero(const In& v) {
    if constexpr (std::is_same_v<In, openvdb::math::half>) return (v.bits() & 0x7fff) != 0;  // (NaNs are non-zero)
    else return v != In(0);
}

/// The active mask of one leaf-sized block of `ex` x `ey` x `ez` voxels (the non-zero ones that fit ValueT),
/// `row(y, z)` pointing at its row of voxels along x; `same` and `first` tell whether all of them hold one value
/// (`first`). Values that do not fit go to `overflow(x, y, z, v)` and stay inactive. A mask word per x holds bit
/// (y << 3) + z: OpenVDB's leaf order (x << 6) + (y << 3) + z.
template <class ValueT, class Row, class OnOverflow>
typename openvdb::tree::LeafNode<ValueT, 3>::NodeMaskType block_mask(Row&& row, std::int64_t ex, std::int64_t ey,
                                                                     std::int64_t ez, bool& same, ValueT& first,
                                                                     OnOverflow&& overflow) {
    using In = std::remove_cv_t<std::remove_reference_t<decltype(*row(0, 0))>>;
    typename openvdb::tree::LeafNode<ValueT, 3>::NodeMaskType mask;
    std::uint64_t words[8] = {};
    for (std::int64_t z = 0; z < ez; ++z) {
        for (std::int64_t y = 0; y < ey; ++y) {
            const In* p = row(y, z);
            const int bit = static_cast<int>((y << 3) + z);
            for (std::int64_t x = 0; x < ex; ++x) {
                bool on = nonzero(p[x]);
                if constexpr (!always_fits<ValueT, In>()) {
                    if (on && !fits<ValueT>(p[x])) {
                        overflow(x, y, z, p[x]);
                        on = false;
                    }
                }
                words[x] |= std::uint64_t(on) << bit;
            }
        }
    }
    for (int x = 0; x < 8; ++x) mask.template getWord<std::uint64_t>(static_cast<openvdb::Index>(x)) = words[x];
    same = mask.isOn();  // a constant block is a tile only when full
    if (same) {
        first = static_cast<ValueT>(*row(0, 0));
        for (std::int64_t z = 0; z < ez && same; ++z)
            for (std::int64_t y = 0; y < ey && same; ++y)
                for (std::int64_t x = 0; x < ex && same; ++x) same = static_cast<ValueT>(row(y, z)[x]) == first;
    }
    return mask;
}

/// A built grid with its leaf buffers compressed as OpenVDB writes them (LeafNode::writeBuffers: the value mask,
/// then io::writeCompressedValues), in Tree::writeBuffers order, in runs of leaves compressed in parallel; with the
/// delayed-load metadata OpenVDB's reader seeks by (each leaf's mask-compression byte and compressed size) and the
/// whole grid's memory (file_mem_bytes). Its leaves hold their active masks only (OpenVDB's PartialCreate leaves,
/// about 100 bytes against 2 KB with values): write_archive writes it as OpenVDB would write the whole grid, at a
/// fraction of the memory (a bake's next frame computes while the file is written).
struct BuiltGrid {
    openvdb::GridBase::Ptr grid;
    std::uint32_t compression = 0;  ///< the stream flags the runs were compressed with (Archive::setGridCompression's)
    std::vector<std::string> runs;
    openvdb::io::DelayedLoadMetadata delayed;
    std::int64_t mem_bytes = 0;
};

/// The file-level compression VdbGrids writes with (io::File's default: Blosc and active values), and what
/// io::File applies to a grid of class `cls` (Archive::setGridCompression: no ZIP on fog volumes and level sets).
std::uint32_t file_compression() { return openvdb::io::Archive::DEFAULT_COMPRESSION_FLAGS; }
bool records_sizes() { return file_compression() & (openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ZIP); }
std::uint32_t compression_for(openvdb::GridClass cls) {
    std::uint32_t c = file_compression();
    if (cls == openvdb::GRID_FOG_VOLUME || cls == openvdb::GRID_LEVEL_SET) c &= ~std::uint32_t(openvdb::io::COMPRESS_ZIP);
    return c;
}

/// The tree's leaves in the order Tree::writeBuffers writes them (root table order, then children in index order),
/// which is also the order of the delayed-load metadata.
template <class TreeT>
std::vector<const typename TreeT::LeafNodeType*> leaves_in_write_order(const TreeT& tree) {
    std::vector<const typename TreeT::LeafNodeType*> out;
    for (auto upper = tree.root().cbeginChildOn(); upper; ++upper)
        for (auto lower = upper->cbeginChildOn(); lower; ++lower)
            for (auto leaf = lower->cbeginChildOn(); leaf; ++leaf) out.push_back(&*leaf);
    return out;
}

/// Compresses the buffers of `grid`'s leaves, which hold their masks only: `values_of(leaf, out)` writes the leaf's
/// active values to `out` in mask order (the order of the mask's on-iterator) and returns how many it wrote.
///
/// Each leaf's record is what LeafNode::writeBuffers writes through io::writeCompressedValues with active-mask
/// compression: the value mask, the mask-compression byte, then the active values (as half floats when the grid
/// saves floats as halves) through OpenVDB's own HalfWriter/writeData. The byte is always NO_MASK_OR_INACTIVE_VALS,
/// the one MaskCompress finds for these leaves (every inactive value is the background), so it is not recomputed
/// from a full 512-value buffer per leaf; the Catch2 byte comparison against io::File guards this.
///
/// `Stored` is the type values_of writes: the grid's value type, or, for half floats written as half floats (a
/// bake's frames), the halves themselves, written as they are: HalfWriter would convert their floats back to the
/// very same halves (half -> float -> half is exact), one conversion each way per voxel.
template <class GridT, class Stored = typename GridT::ValueType, class ValuesOf>
BuiltGrid compress_buffers(typename GridT::Ptr grid, ValuesOf&& values_of) {
    using ValueT = typename GridT::ValueType;
    constexpr bool kHalves = std::is_same_v<Stored, openvdb::math::half>;
    static_assert(kHalves || std::is_same_v<Stored, ValueT>, "values as the grid's type, or as half floats");
    using LeafT = typename GridT::TreeType::LeafNodeType;
    namespace io = openvdb::io;
    constexpr std::size_t kRun = 256;  // leaves per task
    constexpr std::int8_t kMetadata = io::NO_MASK_OR_INACTIVE_VALS;
    const auto leaves = leaves_in_write_order(grid->tree());
    BuiltGrid out;
    out.compression = compression_for(grid->getGridClass());
    if (!(out.compression & io::COMPRESS_ACTIVE_MASK)) throw Error("the VDB writer writes active-mask compression only");
    out.runs.assign((leaves.size() + kRun - 1) / kRun, std::string());
    if (!leaves.empty()) {
        out.delayed.resizeMask(leaves.size());
        if (records_sizes()) out.delayed.resizeCompressedSize(leaves.size());
    }
    const bool half = grid->saveFloatAsHalf();
    if (kHalves && !half) throw Error("half floats are written as such only to a grid saving half floats");
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, out.runs.size()), [&](const auto& r) {
        std::vector<Stored> active(LeafT::SIZE);
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            std::ostringstream s;
            for (std::size_t i = k * kRun; i < std::min(leaves.size(), (k + 1) * kRun); ++i) {
                const LeafT& leaf = *leaves[i];
                const auto count = static_cast<openvdb::Index>(values_of(leaf, active.data()));
                leaf.getValueMask().save(s);
                s.put(static_cast<char>(kMetadata));
                out.delayed.setMask(i, kMetadata);
                const auto data = static_cast<std::int64_t>(s.tellp());
                if constexpr (kHalves) io::writeData<Stored>(s, active.data(), count, out.compression);
                else if (half) io::HalfWriter<io::RealToHalf<ValueT>::isReal, ValueT>::write(s, active.data(), count,
                                                                                                  out.compression);
                else io::writeData<ValueT>(s, active.data(), count, out.compression);
                if (records_sizes()) out.delayed.setCompressedSize(i, static_cast<std::int64_t>(s.tellp()) - data);
            }
            out.runs[k] = s.str();
        }
    });
    // what the whole grid would hold, its leaves' values too (file_mem_bytes, as OpenVDB writes it)
    out.mem_bytes = static_cast<std::int64_t>(grid->memUsage() + leaves.size() * LeafT::SIZE * sizeof(ValueT));
    out.grid = std::move(grid);
    return out;
}

/// Builds a grid holding the non-zero voxels of `src` (C-order [z, y, x], dims of `g`; or 8³ bricks when
/// `bricked`) at index coordinates (x, y, z), its leaves holding their active masks only: leaf-sized blocks are
/// scanned in parallel, one task per (z, y) row of blocks, and inserted serially; then the leaves' buffers are
/// compressed from `src` (BuiltGrid; `half`: floats stored as half floats).
template <class GridT, class In>
BuiltGrid build_grid(const In* src, const Grid& g, bool bricked, bool half, openvdb::GridClass cls,
                     Overflow& overflow) {
    using ValueT = typename GridT::ValueType;
    using TreeT = typename GridT::TreeType;
    using LeafT = typename TreeT::LeafNodeType;
    constexpr int D = static_cast<int>(LeafT::DIM);
    static_assert(D == 8, "bricked views are 8³ bricks: leaf-sized");
    const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    const std::int64_t bx = (nx + D - 1) / D, by = (ny + D - 1) / D, bz = (nz + D - 1) / D;
    const ValueT zero = openvdb::zeroVal<ValueT>();
    const auto sample = [&](std::int64_t x, std::int64_t y, std::int64_t z) {  // the element of voxel (x, y, z)
        return bricked ? static_cast<std::int64_t>(brick_index(x, y, z, g.dims)) : (z * ny + y) * nx + x;
    };

    struct Block {
        LeafT* leaf = nullptr;   // a partly active or non-constant block
        bool tile = false;       // a fully active constant block
        ValueT value{};
    };
    std::vector<Block> blocks(static_cast<std::size_t>(bx * by * bz));

    tbb::parallel_for(tbb::blocked_range2d<std::int64_t>(0, bz, 1, 0, by, 4), [&](const auto& r) {
        for (std::int64_t kz = r.rows().begin(); kz != r.rows().end(); ++kz) {
            for (std::int64_t ky = r.cols().begin(); ky != r.cols().end(); ++ky) {
                for (std::int64_t kx = 0; kx < bx; ++kx) {
                    const std::int64_t x0 = kx * D, y0 = ky * D, z0 = kz * D;
                    const std::int64_t ex = std::min<std::int64_t>(D, nx - x0), ey = std::min<std::int64_t>(D, ny - y0),
                                       ez = std::min<std::int64_t>(D, nz - z0);
                    if (bricked && all_zero_bytes(src + brick_index(x0, y0, z0, g.dims), D * D * D))
                        continue;  // (most bricks of a frame's box: never written, shared zero pages)
                    const auto row = [&](std::int64_t y, std::int64_t z) { return src + sample(x0, y0 + y, z0 + z); };
                    bool same = true;
                    ValueT first{};
                    const auto mask = block_mask<ValueT>(row, ex, ey, ez, same, first, [&](std::int64_t x,
                                                         std::int64_t y, std::int64_t z, const In& v) {
                        std::ostringstream s;
                        s << +v;
                        overflow.note(((z0 + z) * ny + (y0 + y)) * nx + x0 + x, s.str());
                    });
                    if (mask.isOff()) continue;
                    Block& b = blocks[static_cast<std::size_t>((kz * by + ky) * bx + kx)];
                    if (same) {
                        b.tile = true;
                        b.value = first;
                    } else {
                        const openvdb::Coord origin(static_cast<int>(x0), static_cast<int>(y0), static_cast<int>(z0));
                        b.leaf = new LeafT(openvdb::PartialCreate(), origin, zero, false);
                        b.leaf->setValueMask(mask);
                    }
                }
            }
        }
    });

    auto grid = GridT::create(zero);
    if (cls != openvdb::GRID_UNKNOWN) grid->setGridClass(cls);
    grid->setSaveFloatAsHalf(half);
    openvdb::tree::ValueAccessor<TreeT> acc(grid->tree());
    for (Block& b : blocks) {
        if (b.leaf) acc.addLeaf(b.leaf);  // the tree takes ownership
        else if (b.tile) {
            // Recompute the origin from the block index.
            const std::size_t i = static_cast<std::size_t>(&b - blocks.data());
            const std::int64_t kx = static_cast<std::int64_t>(i) % bx, ky = (static_cast<std::int64_t>(i) / bx) % by,
                               kz = static_cast<std::int64_t>(i) / (bx * by);
            acc.addTile(1, openvdb::Coord(static_cast<int>(kx * D), static_cast<int>(ky * D), static_cast<int>(kz * D)),
                        b.value, true);
        }
    }
    if (overflow.seen) return {};
    const auto values_of = [&](const LeafT& leaf, auto* out) {
        using Stored = std::remove_pointer_t<decltype(out)>;
        const openvdb::Coord o = leaf.origin();
        const In* p = src + sample(o.x(), o.y(), o.z());
        const std::int64_t sy = bricked ? D : nx, sz = bricked ? D * D : nx * ny;  // (x steps by 1 in both)
        std::size_t count = 0;
        for (auto it = leaf.getValueMask().beginOn(); it; ++it) {  // leaf order: (x << 6) + (y << 3) + z
            const openvdb::Index n = it.pos();
            out[count++] = static_cast<Stored>(p[(n & 7) * sz + ((n >> 3) & 7) * sy + (n >> 6)]);
        }
        return count;
    };
    if constexpr (std::is_same_v<In, openvdb::math::half> && std::is_same_v<ValueT, float>)
        if (half) return compress_buffers<GridT, openvdb::math::half>(grid, values_of);
    return compress_buffers<GridT>(grid, values_of);
}

template <class GridT>
BuiltGrid build_from_view(const VolumeView& v, bool half, openvdb::GridClass cls, Overflow& overflow) {
    const auto build = [&](const auto* p) { return build_grid<GridT>(p, v.grid, v.bricked, half, cls, overflow); };
    if (v.half) return build(static_cast<const openvdb::math::half*>(v.data));
    switch (v.dtype) {
        case DType::UInt8: return build(static_cast<const std::uint8_t*>(v.data));
        case DType::Int8: return build(static_cast<const std::int8_t*>(v.data));
        case DType::UInt16: return build(static_cast<const std::uint16_t*>(v.data));
        case DType::Int16: return build(static_cast<const std::int16_t*>(v.data));
        case DType::UInt32: return build(static_cast<const std::uint32_t*>(v.data));
        case DType::Int32: return build(static_cast<const std::int32_t*>(v.data));
        case DType::UInt64: return build(static_cast<const std::uint64_t*>(v.data));
        case DType::Int64: return build(static_cast<const std::int64_t*>(v.data));
        case DType::Float32: return build(static_cast<const float*>(v.data));
        case DType::Float64: return build(static_cast<const double*>(v.data));
    }
    throw Error("unknown dtype");
}

bool same(double a, double b) { return std::abs(a - b) <= 1e-12 * std::max({1.0, std::abs(a), std::abs(b)}); }

/// Same spacing, and an origin a whole number of voxels from g0's: the voxels of both grids coincide.
bool on_lattice_of(const Grid& g, const Grid& g0) {
    for (int a = 0; a < 3; ++a) {
        if (!same(g.spacing[a], g0.spacing[a])) return false;
        const double steps = (g.origin[a] - g0.origin[a]) / g0.spacing[a];
        if (std::abs(steps - std::round(steps)) > 1e-6) return false;
    }
    return true;
}

/// index (i, j, k) -> origin + spacing * (i, j, k)
openvdb::math::Transform::Ptr index_to_world(const Grid& g) {
    openvdb::Mat4d scale = openvdb::Mat4d::identity();
    for (int a = 0; a < 3; ++a) scale[a][a] = g.spacing[a];
    auto xf = openvdb::math::Transform::createLinearTransform(scale);
    xf->postTranslate(openvdb::Vec3d(g.origin[0], g.origin[1], g.origin[2]));
    return xf;
}

std::string dims_string(const Grid& g) {
    std::ostringstream s;
    s << g.dims[0] << " x " << g.dims[1] << " x " << g.dims[2] << " spacing (" << g.spacing[0] << ", " << g.spacing[1]
      << ", " << g.spacing[2] << ") origin (" << g.origin[0] << ", " << g.origin[1] << ", " << g.origin[2] << ")";
    return s.str();
}

}  // namespace

namespace {

/// A random version-4 UUID as 36 characters, as boost::uuids writes it (the archive header's file identity).
std::string random_uuid() {
    std::random_device device;
    std::mt19937_64 gen((std::uint64_t(device()) << 32) ^ device() ^ std::uint64_t(std::time(nullptr)));
    unsigned char b[16];
    for (int i = 0; i < 16; i += 8) {
        const std::uint64_t w = gen();
        std::memcpy(b + i, &w, 8);
    }
    b[6] = static_cast<unsigned char>((b[6] & 0x0f) | 0x40);
    b[8] = static_cast<unsigned char>((b[8] & 0x3f) | 0x80);
    static const char* hex = "0123456789abcdef";
    std::string s;
    for (int i = 0; i < 16; ++i) {
        if (i == 4 || i == 6 || i == 8 || i == 10) s += '-';
        s += hex[b[i] >> 4];
        s += hex[b[i] & 15];
    }
    return s;
}

template <class T>
void put(std::ostream& os, T v) {
    os.write(reinterpret_cast<const char*>(&v), sizeof(T));
}

/// One grid as io::Archive::writeGrid writes it (OpenVDB 10, seekable): descriptor, offsets, compression flags,
/// metadata with the delayed-load and statistics entries, transform, topology (OpenVDB's), then the precompressed
/// leaf buffers, and the offsets filled in.
void write_grid(std::ostream& os, const BuiltGrid& b) {
    const openvdb::GridBase& grid = *b.grid;
    openvdb::io::GridDescriptor gd(grid.getName(), grid.type(), grid.saveFloatAsHalf());
    gd.writeHeader(os);
    const std::streamoff offsets = os.tellp();
    gd.writeStreamPos(os);
    gd.setGridPos(os.tellp());
    openvdb::io::setDataCompression(os, b.compression);
    put(os, b.compression);
    const auto copy = openvdb::ConstPtrCast<openvdb::GridBase>(grid.copyGrid());  // shallow: metadata only
    copy->insertMeta(openvdb::GridBase::META_FILE_DELAYED_LOAD, b.delayed);
    copy->addStatsMetadata();
    copy->insertMeta(openvdb::GridBase::META_FILE_MEM_BYTES, openvdb::Int64Metadata(b.mem_bytes));
    copy->insertMeta(openvdb::GridBase::META_FILE_COMPRESSION,
                     openvdb::StringMetadata(openvdb::io::compressionToString(b.compression)));
    copy->writeMeta(os);
    grid.writeTransform(os);
    grid.writeTopology(os);
    gd.setBlockPos(os.tellp());
    for (const std::string& run : b.runs) os.write(run.data(), static_cast<std::streamsize>(run.size()));
    gd.setEndPos(os.tellp());
    os.seekp(offsets, std::ios_base::beg);
    gd.writeStreamPos(os);
    gd.seekToEnd(os);
}

/// What io::File::write(grids) writes (Archive::write: header, the file metadata `meta`, the grids), for grids whose
/// leaf buffers are precompressed. The bytes equal OpenVDB's for the same whole grids but the header's random UUID (the
/// Catch2 case "a bake's grids are written as OpenVDB writes them" compares them).
void write_archive(std::ostream& os, const std::vector<BuiltGrid>& grids, const openvdb::MetaMap& meta) {
    openvdb::io::setDataCompression(os, file_compression());
    openvdb::io::setWriteGridStatsMetadata(os, true);
    put<std::int64_t>(os, openvdb::OPENVDB_MAGIC);
    put<std::uint32_t>(os, openvdb::OPENVDB_FILE_VERSION);
    put<std::uint32_t>(os, openvdb::OPENVDB_LIBRARY_MAJOR_VERSION);
    put<std::uint32_t>(os, openvdb::OPENVDB_LIBRARY_MINOR_VERSION);
    put<char>(os, 1);  // seekable: grid offsets present
    os << random_uuid();
    meta.writeMeta(os);
    put(os, static_cast<std::int32_t>(grids.size()));
    for (const BuiltGrid& b : grids) {
        write_grid(os, b);
        openvdb::io::setDataCompression(os, file_compression());
    }
}

}  // namespace

struct VdbGrids::Impl {
    std::vector<BuiltGrid> grids;
    openvdb::MetaMap meta;
    bool written = false;
};

VdbGrids::VdbGrids() : impl_(std::make_unique<Impl>()) {}
VdbGrids::~VdbGrids() = default;
VdbGrids::VdbGrids(VdbGrids&&) noexcept = default;
VdbGrids& VdbGrids::operator=(VdbGrids&&) noexcept = default;
bool VdbGrids::written() const { return !impl_ || impl_->written; }

void VdbGrids::write(const std::string& path) {
    if (!impl_) throw Error(path + ": these grids were moved elsewhere");
    if (impl_->written) throw Error(path + ": these grids were written already");
    try {
        write_atomically(path, [&](const std::string& tmp) {
            std::ofstream file(tmp, std::ios_base::out | std::ios_base::binary | std::ios_base::trunc);
            if (!file) throw Error(path + ": cannot create the file " + tmp);
            write_archive(file, impl_->grids, impl_->meta);
            file.close();
            if (!file) throw Error(path + ": cannot write the OpenVDB file (the disk may be full)");
        });
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        throw Error(path + ": cannot write the OpenVDB file (" + e.what() + ")");
    }
    impl_->written = true;
    impl_->grids.clear();
}

void write_vdb(const std::string& path, const std::vector<std::pair<std::string, VolumeView>>& grids, bool half,
               const VdbMetadata& metadata) {
    build_vdb(path, grids, half, metadata).write(path);
}

VdbGrids build_vdb(const std::string& path, const std::vector<std::pair<std::string, VolumeView>>& grids, bool half,
                   const VdbMetadata& metadata) {
    initialize_openvdb();
    if (grids.empty()) throw Error(path + ": no grids to write");
    const Grid& g0 = grids.front().second.grid;
    for (const auto& entry : metadata)
        if (entry.first.empty()) throw Error(path + ": a metadata entry needs a non-empty name");
    std::set<std::string> names;
    for (const auto& [name, view] : grids) {
        const std::string subject = path + ": grid '" + name + "'";
        if (name.empty()) throw Error(path + ": a grid needs a non-empty name");
        if (!names.insert(name).second) throw Error(path + ": grid name '" + name + "' is used twice");
        if (!view.data) throw Error(subject + " has no data");
        check_grid(view.grid, dtype_size(view.dtype), std::numeric_limits<std::uint64_t>::max(), subject);
        for (int a = 0; a < 3; ++a)
            if (view.grid.dims[a] > std::numeric_limits<std::int32_t>::max())
                throw Error(subject + ": dimensions exceed OpenVDB's 32-bit index range");
        if (view.half && view.dtype != DType::UInt16) throw Error(subject + ": half floats are 16-bit samples");
        if (view.labels && (view.half || view.dtype == DType::Float32 || view.dtype == DType::Float64))
            throw Error(subject + ": labels are integers");
        if (view.bricked && (view.grid.dims[0] % 8 || view.grid.dims[1] % 8 || view.grid.dims[2] % 8))
            throw Error(subject + ": a grid in 8³ bricks needs dimensions that are multiples of 8");
        if (!on_lattice_of(view.grid, g0))
            throw Error(subject + " has geometry " + dims_string(view.grid) + " but grid '" + grids.front().first +
                        "' has " + dims_string(g0) + "; all grids of one file must share one voxel lattice");
    }

    std::vector<BuiltGrid> out;
    for (const auto& [name, view] : grids) {
        Overflow overflow;
        const bool as_float = view.half || view.dtype == DType::Float32 || view.dtype == DType::Float64 ||
                              (view.dtype == DType::UInt8 && !view.labels);
        BuiltGrid b = as_float ? build_from_view<openvdb::FloatGrid>(view, half, openvdb::GRID_FOG_VOLUME, overflow)
                               : build_from_view<openvdb::Int32Grid>(view, false, openvdb::GRID_UNKNOWN, overflow);
        if (overflow.seen) {
            const Grid& g = view.grid;
            const std::int64_t i = overflow.index;
            std::ostringstream s;
            s << path << ": grid '" << name << "': value " << overflow.value << " at voxel (" << i % g.dims[0] << ", "
              << (i / g.dims[0]) % g.dims[1] << ", " << i / (g.dims[0] * g.dims[1])
              << ") does not fit in an int32 grid";
            throw Error(s.str());
        }
        b.grid->setName(name);
        b.grid->setTransform(index_to_world(view.grid));
        out.push_back(std::move(b));
    }
    VdbGrids built;
    built.impl_->grids = std::move(out);
    for (const auto& [name, value] : metadata) built.impl_->meta.insertMeta(name, openvdb::StringMetadata(value));
    return built;
}

}  // namespace volrig

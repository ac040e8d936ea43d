// volrig/deform.hpp: per-frame sampled reconstruction from moved spheres (docs/ALGORITHMS.md §7; the stages are
// in native/src/deform/, outlined in docs/ARCHITECTURE.md).
//
// Each skeleton point i is a sphere: centre cᵢ (a voxel of the source grid), radius rᵢ (world units), bound to one
// or more bones. A frame gives one rest-to-pose matrix per bone (world coordinates of the source grid:
// posed = M · rest). Every output voxel q covered by a moved sphere (|q − Tᵢcᵢ|² < rᵢ², open balls as in
// reconstruct.hpp) takes the source value at Tᵢ⁻¹q from the covering sphere that wins the proximity buffer:
//   * Proximity::Nearest: the nearest centre, |q − Tᵢcᵢ| (the thesis);
//   * Proximity::Power:   the smallest power distance |q − Tᵢcᵢ|² − rᵢ² (the sphere q is deepest inside).
// Ties go to the lowest sphere index (the brute-force scatter in index order with a strict comparison).
//
// Modes: Rigid (the thesis: every sphere moves with its owning bone), Linear and DualQuaternion (each sphere's
// transform is the blend of its bones' transforms by the binding weights, rounded to 16ths; linear blends are
// projected onto the nearest rotation, dual quaternions are rigid by construction; the value still comes from the
// inverse of that sphere's own transform). Bone matrices must be rigid (rotation + translation).
//
// Speed. Within one bone all spheres share one transform and rigid motions keep distances, so the winner among a
// bone's spheres at an output voxel q is the winner at its rest position p = T⁻¹q. For each bone the rest-space
// power diagram of its spheres is sampled once per rig on the lattice (a lower envelope of parabolas, linear
// time: F_b(v) = minᵢ |v − cᵢ|² − rᵢ² and its argmin). The power function is |p|² plus a concave function, so on
// the lattice cube around p the trilinear interpolation of F_b minus Σ s²u(1−u) is a lower bound of the exact
// value and the argmins of the cube's corners give an upper bound; both are equal wherever the corners agree.
// These bounds decide coverage and the winning bone almost everywhere; the rest is settled exactly by a k-d tree
// over the bone's spheres. Per frame the work is close to one gather per output voxel. In smooth modes the spheres
// whose rounded weights agree form a blend group with the blended transform (no lattice tables: groups are small
// and overlap). Every blend is rigid, so all blended spheres' powers at q are |q − yᵢ|² − rᵢ² with yᵢ their posed
// centres, and any two differ by an affine function of q: per frame they are pruned together in output space (per
// region, tile, block and sub-block, the spheres no other one beats all over it) and gathered as one candidate
// whose exact per-voxel power comes from each sphere through its own group's map.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "volrig/memory.hpp"
#include "volrig/progress.hpp"
#include "volrig/volume.hpp"

namespace volrig {

enum class DeformMode { Rigid, Linear, DualQuaternion };
enum class Proximity { Power, Nearest };
enum class Sampling { Nearest, Trilinear };

/// The names of the options, in enum order: the one place they are spelled (the bindings hand them to Python).
inline constexpr std::array<const char*, 3> kDeformModeNames = {"rigid", "linear", "dual_quaternion"};
inline constexpr std::array<const char*, 2> kProximityNames = {"power", "nearest"};
inline constexpr std::array<const char*, 2> kSamplingNames = {"nearest", "trilinear"};

DeformMode deform_mode_from_name(const std::string& name);  ///< "rigid" | "linear" | "dual_quaternion" (or "dq")
Proximity proximity_from_name(const std::string& name);     ///< "power" | "nearest"
Sampling sampling_from_name(const std::string& name);       ///< "nearest" | "trilinear"

/// The bound reconstruction spheres (views; the Deformer copies what it keeps).
struct BoundSpheres {
    const std::int32_t* ijk = nullptr;    ///< n rows [z, y, x]: centre voxels of the source grid
    const float* radius = nullptr;        ///< n radii, world units
    std::size_t n = 0;
    const std::int32_t* bone = nullptr;   ///< n owning bones (0 <= bone < bone_count)
    std::size_t bone_count = 0;
    /// Smooth weights as CSR rows (may be null: every sphere then has weight 1 on its owning bone).
    const std::int64_t* weight_offsets = nullptr;  ///< n + 1
    const std::int32_t* weight_bones = nullptr;
    const float* weights = nullptr;
};

struct DeformOptions {
    DeformMode mode = DeformMode::Rigid;
    Proximity proximity = Proximity::Power;
    Sampling sampling = Sampling::Trilinear;
    std::vector<float> radius_scale;  ///< empty, or n factors (>= 0) for bulge and pinch
    bool values = true;               ///< false: binary reconstruction (bone labels only, values left empty)
    /// Smooth modes: each blend group's radii take a factor from its pose that keeps the limb's volume at bends
    /// (docs/ALGORITHMS.md §7, "Volume at bends"; issue 18). Weight-1 spheres and the rigid mode never change.
    bool keep_volume = true;
    /// The output in 8³ bricks (DeformedVolume::bricks) instead of cropped C-order arrays: a frame then costs
    /// memory only in the bricks it covers (a bake's frames; issue 17). Not with an imposed box.
    bool bricks = false;
    /// With bricks: the values as IEEE half floats (DeformedVolume::half_values), rounded as OpenVDB rounds the
    /// floats it stores as half, and the bone labels as bytes when the rig has fewer than 255 bones
    /// (DeformedVolume::bone8): half the memory of a bake's frame, and the same file.
    bool half = false;
};

struct DeformStats {
    std::int64_t covered = 0;        ///< output voxels covered by a sphere
    std::int64_t exact_queries = 0;  ///< per-bone exact (k-d tree) queries the bounds did not settle
    std::int64_t blended_spheres = 0;  ///< spheres moved by a blend of bones (smooth modes)
    /// How the covered voxels were decided (they sum to `covered`): by whole 8³ blocks one bone covers alone, by the
    /// per-cube power ranges, by the power of the sphere labelling the cube, or by the full per-voxel search.
    std::int64_t by_block = 0, by_cube = 0, by_sphere = 0, by_search = 0;
    /// (candidate field, 4³ output sub-block) pairs looked up voxel by voxel whose powers came straight from the one
    /// sphere that is the field's nearest over the whole sub-block's preimage (no per-voxel table lookups).
    std::int64_t exact_sub_blocks = 0;
    /// Piece voxels the rigid layer drew (Deformer::set_rigid_layer), over or beside the spheres' (an output voxel
    /// two pieces land on counts twice).
    std::int64_t rigid_layer = 0;
    /// Covered voxels a limb gave up to the other limb of its bent joint past their contact plane (keep_volume's
    /// sliding contact, smooth modes).
    std::int64_t contact = 0;
};

/// One deformed frame. The output grid has the source spacing and lies on the source lattice: output voxel
/// (x, y, z) is source lattice index offset + (x, y, z), so grid.origin = source origin + spacing * offset.
/// Unless a box is imposed, it is the bounding box of the covered voxels. The Deformer's frames live in memory it
/// recycles (ZeroedPool): whoever writes into their arrays must mark_written what they write.
///
/// With DeformOptions::bricks the frame is not cropped: its box is the posed spheres' grown to multiples of 8 (offset
/// and dims), and the arrays hold it brick by brick: voxel (x, y, z) at brick_index (volume.hpp), so that only the
/// bricks a frame covers become resident. `extent` is the
/// covered voxels' box inside it {x, y, z, dims x, y, z} (all of it for a cropped frame; dims 0 when none is).
struct DeformedVolume {
    Grid grid;
    std::array<std::int64_t, 3> offset{0, 0, 0};
    ZeroedArray<float> values;       ///< source samples (0 where empty); empty when options.values is false
    ZeroedArray<std::uint16_t> half_values;  ///< the same as IEEE half floats' bits, instead (options.half)
    ZeroedArray<std::int16_t> bone;  ///< owning bone + 1 of the winning sphere, 0 = empty
    ZeroedArray<std::uint8_t> bone8;  ///< the same as bytes, instead (options.half with fewer than 255 bones)
    DeformStats stats;
    bool bricks = false;
    std::array<std::int64_t, 6> extent{0, 0, 0, 0, 0, 0};
};

/// Rest-to-pose matrices: bone_count 4x4 matrices, row-major, 16 doubles each.
using BoneMatrices = const double*;

/// One bone's piece of rigid tissue (issue 18's rigid layer): one bit a voxel of the box {offset x, y, z, dims x, y,
/// z} of the source lattice, C order [z, y, x], bit k of the flat index in byte k / 8 at bit k % 8 (numpy's
/// packbits with bitorder "little"); 1 = the piece's.
struct RigidPiece {
    std::int32_t bone = 0;
    std::array<std::int64_t, 6> box{0, 0, 0, 0, 0, 0};
    const std::uint8_t* bits = nullptr;
    bool at(std::int64_t i, std::int64_t j, std::int64_t k) const {
        const std::int64_t n = (k * box[4] + j) * box[3] + i;
        return (bits[n >> 3] >> (n & 7)) & 1;
    }
};

/// Per-rig precomputation (per-bone rest-space power diagrams and k-d trees) and per-frame reconstruction.
/// Keeps a copy of the spheres and a view of the source samples (which must outlive the Deformer).
class Deformer {
public:
    Deformer(const VolumeView& source, const BoundSpheres& spheres);
    ~Deformer();
    Deformer(const Deformer&) = delete;
    Deformer& operator=(const Deformer&) = delete;

    /// Reconstructs one frame. `box`, when given as {offset x, y, z, dims x, y, z}, fixes the output grid
    /// (otherwise it grows to fit the posed spheres).
    DeformedVolume frame(BoneMatrices matrices, const DeformOptions& options, const Progress& progress = {},
                         const std::array<std::int64_t, 6>* box = nullptr);

    /// Replaces the binding of the same spheres (same count, centres and radii; bones and weights may change). The
    /// next frame rebuilds only the fields whose spheres changed: repainting one bone's weights rebuilds the fields
    /// of the bones (and blend groups) whose spheres moved, not the whole rig.
    void rebind(const BoundSpheres& spheres);
    /// How many fields the last build took over from the build before (the rest were built anew).
    std::size_t reused_fields() const;

    /// When the bones' fields get their lattice tables (per-cube power ranges and power-diagram labels: what lets a
    /// frame settle most voxels from a table; about 4 rigid frames' time to build): at the first frame drawn after
    /// `frames` frames without a change of the per-rig data (a new Deformer, rebind, another mode family or
    /// radius_scale). Until then a bone's field takes its powers from the balls meeting each preimage, as the blend
    /// groups always do: a rig change then costs the spheres' k-d trees only and a frame somewhat more
    /// (benchmarks/RESULTS.md, Bake throughput). 0: at the first frame; -1: never. A rebind rebuilds the fields it
    /// changes without tables; those it keeps keep theirs.
    static constexpr int kLatticeAfter = 8;
    void set_lattice_after(int frames);
    int lattice_after() const;
    /// Whether every bone's field has its lattice tables (false before the first frame).
    bool lattice_tables() const;

    /// The rigid layer (issue 18): from the next frame on, each piece moved by its bone alone is drawn over the
    /// spheres' reconstruction (as paint_rigid_pieces draws it), sampled from `source` (the scan itself, while the
    /// spheres may sample a copy whose rigid voxels hold soft tissue); the output box grows to hold the pieces.
    /// The pieces' voxels and `source` must outlive the Deformer (or the next call). No pieces: no layer.
    void set_rigid_layer(const VolumeView& source, std::vector<RigidPiece> pieces);
    /// Replaces the samples the spheres take (same grid; any element type), e.g. by the rigid layer's soft copy;
    /// must outlive the Deformer (or the next call).
    void set_source(const VolumeView& source);

    std::size_t bone_count() const;
    std::size_t sphere_count() const;
    /// Bytes held by the per-rig data currently built (per-cube power ranges, labels and corner powers, k-d trees,
    /// sphere copies).
    std::size_t memory_bytes() const;
    /// Output memory of earlier frames kept for the next ones (mapped; resident where those frames wrote), and its
    /// release.
    std::size_t kept_frame_bytes() const;
    void release_frame_memory();

    struct Impl;

private:
    std::unique_ptr<Impl> impl_;
};

/// Crops a frame, in place, to the bounding box of its covered voxels (one voxel at its offset when none is covered).
/// Deformer::frame returns frames already cropped unless a box was imposed.
void crop_to_covered(DeformedVolume& frame);

/// The box of the source lattice ({offset, dims}) that holds every piece moved by its bone's matrix (empty dims
/// when there are no pieces).
std::array<std::int64_t, 6> rigid_pieces_box(const Grid& grid, const std::vector<RigidPiece>& pieces,
                                             BoneMatrices matrices, std::size_t bone_count);

/// Draws the pieces, each moved rigidly by its bone, over a frame's arrays on `box` (C order, dims of the box):
/// every output voxel whose rest position (through the bone's posed-to-rest map, rounded to the nearest lattice
/// point) is one of the piece's voxels takes bone + 1 and the source sampled at that rest position; pieces later
/// in the list win where two land on one voxel. `values` may be null (binary frames). Returns the voxels drawn.
std::int64_t paint_rigid_pieces(const VolumeView& source, const std::vector<RigidPiece>& pieces,
                                BoneMatrices matrices, std::size_t bone_count, Sampling sampling,
                                const std::array<std::int64_t, 6>& box, float* values, std::int16_t* bone);

/// The literal thesis algorithm, for tests and benchmarks: every sphere is transformed and scattered over the
/// bounding box of its ball into an output buffer with a proximity buffer, in sphere index order. Same output
/// conventions as Deformer::frame; `box` as there.
DeformedVolume deform_reference(const VolumeView& source, const BoundSpheres& spheres, BoneMatrices matrices,
                                const DeformOptions& options, const Progress& progress = {},
                                const std::array<std::int64_t, 6>* box = nullptr);

/// A plain inverse warp of the source by one rest-to-pose matrix (one gather per output voxel): the speed
/// reference for deform. The output grid is the source grid, or `box` as in Deformer::frame.
std::vector<float> inverse_warp(const VolumeView& source, const double* matrix, Sampling sampling,
                                const Progress& progress = {}, const std::array<std::int64_t, 6>* box = nullptr);

}  // namespace volrig

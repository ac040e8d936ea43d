// deform/deformer.cpp: the Deformer: per-rig fields built once, and per frame the outline of the algorithm
// (docs/ALGORITHMS.md §7): motions, output box, gather, crop.
#include <algorithm>
#include <limits>
#include <map>
#include <string>

#include "deform/bend.hpp"
#include "deform/bone_field.hpp"
#include "deform/frame_box.hpp"
#include "deform/gather.hpp"
#include "deform/motion.hpp"
#include "deform/rigid_layer.hpp"
#include "deform/spheres.hpp"
#include "volrig/deform.hpp"
#include "volrig/reconstruct.hpp"

namespace volrig {

using namespace deform_detail;

namespace {

/// What a field stands for: a bone (weights empty), or a blend group (its owner and rounded weights).
using FieldKey = std::pair<std::int32_t, Weights>;

/// The enum value whose name (in `names`, enum order) is `name`; throws listing the names otherwise.
template <class E, std::size_t N>
E from_name(const std::string& name, const std::array<const char*, N>& names, const char* what) {
    std::string list;
    for (std::size_t k = 0; k < N; ++k) {
        if (name == names[k]) return static_cast<E>(k);
        list += std::string(k ? (k + 1 == N ? " or " : ", ") : "") + "\"" + names[k] + "\"";
    }
    throw Error("unknown " + std::string(what) + " '" + name + "' (use " + list + ")");
}

/// A key for a frame's box (never 0, which names no layout): the output pool's layout of a frame in bricks.
std::uint64_t box_key(const Box& bx) {
    std::uint64_t h = 1469598103934665603ull;
    for (const std::int64_t v : bx) h = (h ^ static_cast<std::uint64_t>(v)) * 1099511628211ull;
    return h | 1;
}

}  // namespace

DeformMode deform_mode_from_name(const std::string& name) {
    return from_name<DeformMode>(name == "dq" ? "dual_quaternion" : name, kDeformModeNames, "deform mode");
}
Proximity proximity_from_name(const std::string& name) { return from_name<Proximity>(name, kProximityNames, "proximity"); }
Sampling sampling_from_name(const std::string& name) { return from_name<Sampling>(name, kSamplingNames, "sampling"); }

struct Deformer::Impl : SphereStore {
    VolumeView source;
    Grid grid;
    std::shared_ptr<ZeroedPool> pool = ZeroedPool::create();  // frames' output memory, recycled

    // per-rig data for one (partition, radii) key
    bool built = false, built_smooth = false;
    std::vector<float> built_scale;
    // Fields: one per bone (its rigid spheres, with lattice tables), then, in smooth modes, one per group of
    // spheres whose rounded weights agree (they share one blended transform; spheres and k-d tree only). A field is identified by its key (its bone, or its group's
    // owner and weights) and its members; a rebuild takes over every field whose key and members are unchanged.
    std::vector<BoneField> fields;
    std::vector<FieldKey> field_keys;
    std::vector<std::vector<std::uint32_t>> field_members;
    std::size_t reused = 0;
    std::vector<std::int32_t> field_owner;  // the bone each field's voxels are labelled with
    SmoothGroups groups;                    // fields from bone_count on are its groups, in order
    std::int64_t blended_spheres = 0;
    std::vector<double> radii;              // scaled radii
    VolumeView layer_source;                // the rigid layer: what its pieces sample, and the pieces
    std::vector<RigidPiece> pieces;
    BendModel bend;                         // the blend groups' bend model (volume kept at bends)
    double bound_step = 1;                  // the quantum of the fields' power bounds
    int lattice_after = Deformer::kLatticeAfter;  // Deformer::set_lattice_after
    std::int64_t frames_since_change = 0;   // frames drawn since the fields last changed

    /// A quarter of the lattice cell's squared diagonal (with a margin): no sphere covers where its power is above.
    double threshold() const {
        const auto& sp = grid.spacing;
        return 0.25 * (sp[0] * sp[0] + sp[1] * sp[1] + sp[2] * sp[2]) * (1 + 1e-9);
    }
    std::vector<std::vector<std::uint32_t>> partition(bool smooth);
    void build(bool smooth, const DeformOptions& o, const Progress& progress);
    void rebuild(bool smooth, const DeformOptions& o, const Progress& progress);
    bool lattice_due() const { return lattice_after >= 0 && frames_since_change >= lattice_after; }
    void add_lattice_tables(const Progress& progress);
    std::vector<BoneField> take_reusable(const std::vector<double>& new_radii, std::map<FieldKey, std::size_t>& index);
    void add_group_motions(std::vector<Motion>& m, DeformMode mode) const;
    Box frame_reach(const std::vector<Motion>& motions) const;
    void bend_groups(const std::vector<Motion>& m, const DeformOptions& o);
    DeformedVolume frame(BoneMatrices matrices, const DeformOptions& o, const Progress& progress, const Box* fixed_box);
};

/// The spheres of each field: per bone its rigid spheres, then (smooth) per group its blended ones.
std::vector<std::vector<std::uint32_t>> Deformer::Impl::partition(bool smooth) {
    std::vector<std::vector<std::uint32_t>> members(bone_count);
    field_owner.clear();
    for (std::size_t b = 0; b < bone_count; ++b) field_owner.push_back(static_cast<std::int32_t>(b));
    groups = smooth ? smooth_groups(view(), grid) : SmoothGroups{};
    for (std::size_t k = 0; k < groups.weights.size(); ++k) {
        members.emplace_back();
        field_owner.push_back(groups.owner[k]);
    }
    blended_spheres = 0;
    for (std::size_t i = 0; i < n; ++i) {
        std::size_t f = static_cast<std::size_t>(bone[i]);
        if (smooth) {
            f = groups.group_of[i] >= 0 ? bone_count + static_cast<std::size_t>(groups.group_of[i])
                                        : static_cast<std::size_t>(groups.bone_of[i]);
            blended_spheres += groups.group_of[i] >= 0;
        }
        members[f].push_back(static_cast<std::uint32_t>(i));
    }
    return members;
}

/// The fields of the last build when the radii are unchanged (their data stays valid), indexed by key; else none.
std::vector<BoneField> Deformer::Impl::take_reusable(const std::vector<double>& new_radii,
                                                     std::map<FieldKey, std::size_t>& index) {
    std::vector<BoneField> old;
    if (fields.empty() || new_radii != radii) return old;
    old = std::move(fields);
    for (std::size_t j = 0; j < field_keys.size(); ++j) index.emplace(field_keys[j], j);
    return old;
}

/// The fields for this mode family and radius_scale (kept when they are the last build's), then the bones' lattice
/// tables when they are due.
void Deformer::Impl::build(bool smooth, const DeformOptions& o, const Progress& progress) {
    if (!(built && built_smooth == smooth && built_scale == o.radius_scale)) rebuild(smooth, o, progress);
    if (lattice_due()) add_lattice_tables(progress);
}

/// Every field anew, but those whose key and spheres are the last build's (taken over with or without their
/// tables); a bone's new field gets its tables only when they are due at once (lattice_after 0).
void Deformer::Impl::rebuild(bool smooth, const DeformOptions& o, const Progress& progress) {
    built = false;
    frames_since_change = 0;
    std::vector<double> new_radii = scaled_radii(view(), o);
    std::map<FieldKey, std::size_t> old_index;
    std::vector<BoneField> old = take_reusable(new_radii, old_index);
    std::vector<std::vector<std::uint32_t>> old_members = std::move(field_members);
    fields.clear();
    radii = std::move(new_radii);
    field_members = partition(smooth);
    field_keys.clear();
    for (std::size_t b = 0; b < bone_count; ++b) field_keys.push_back({static_cast<std::int32_t>(b), {}});
    for (std::size_t k = 0; k < groups.weights.size(); ++k) field_keys.push_back({groups.owner[k], groups.weights[k]});
    const double T = threshold();
    // One quantum for every field's power bounds (they are compared across fields as integers).
    double maxlim = 0;
    for (double r : radii) maxlim = std::max(maxlim, open_ball_limit_sq(r));
    bound_step = (maxlim + 4 * T) / 30000.0;
    fields.reserve(field_members.size());
    reused = 0;
    DiagramScratch diagram;
    try {
        for (std::size_t f = 0; f < field_members.size(); ++f) {
            const auto it = old_index.find(field_keys[f]);
            if (it != old_index.end() && old_members[it->second] == field_members[f]) {
                fields.push_back(std::move(old[it->second]));  // (with or without its lattice tables)
                ++reused;
            } else {
                fields.push_back(f < bone_count && lattice_due()
                                     ? build_bone_field(grid, view(), field_members[f], radii, T, bound_step, &diagram)
                                     : build_ball_field(grid, view(), field_members[f], radii, T, bound_step));
            }
            report(progress, 0.5 * static_cast<double>(f + 1) / static_cast<double>(field_members.size()));
        }
    } catch (...) {  // cancelled or failed part-way: nothing of this build may be taken over by the next one
        fields.clear();
        field_keys.clear();
        field_members.clear();
        throw;
    }
    bend = smooth ? bend_model(view(), groups, radii, grid) : BendModel{};
    built = true;
    built_smooth = smooth;
    built_scale = o.radius_scale;
}

/// Builds the lattice tables of the bones' fields that have none yet (the blend groups' never have them), in place:
/// each field is whole with or without them, so a cancelled pass leaves the fields it did not reach as they were.
void Deformer::Impl::add_lattice_tables(const Progress& progress) {
    std::vector<std::size_t> todo;
    for (std::size_t f = 0; f < bone_count; ++f)
        if (!fields[f].lattice) todo.push_back(f);
    const double T = threshold();
    DiagramScratch diagram;
    for (std::size_t k = 0; k < todo.size(); ++k) {
        const std::size_t f = todo[k];
        fields[f] = build_bone_field(grid, view(), field_members[f], radii, T, bound_step, &diagram);
        report(progress, 0.5 * static_cast<double>(k + 1) / static_cast<double>(todo.size()));
    }
}

/// The output box: the moved spheres', grown to hold the rigid layer's pieces.
Box Deformer::Impl::frame_reach(const std::vector<Motion>& motions) const {
    Box bx = posed_box(fields, motions, grid);
    if (pieces.empty()) return bx;
    const Box p = pieces_reach(pieces, motions);
    Box u;
    for (int a = 0; a < 3; ++a) {
        u[a] = std::min(bx[a], p[a]);
        u[3 + a] = std::max(bx[a] + bx[3 + a], p[a] + p[3 + a]) - u[a];
    }
    return u;
}

/// After the bones' motions, each group's blend: every field's motion.
void Deformer::Impl::add_group_motions(std::vector<Motion>& m, DeformMode mode) const {
    for (std::size_t k = 0; k < groups.weights.size(); ++k)
        m.push_back(blended_motion(m, groups.weights[k], groups.owner[k], mode, grid, groups.pivot[k]));
}

/// The blend groups' radii in this pose: their factors from the bend model (all 1 without keep_volume), set on
/// their fields (lattice-free, so that this costs a pass over their spheres, not a rebuild).
void Deformer::Impl::bend_groups(const std::vector<Motion>& m, const DeformOptions& o) {
    if (groups.weights.empty()) return;
    const std::vector<double> f =
        o.keep_volume ? bend_factors(bend, groups, m, o.mode) : std::vector<double>(groups.weights.size(), 1.0);
    for (std::size_t k = 0; k < f.size(); ++k) scale_ball_field(fields[bone_count + k], radii, f[k], grid);
}

DeformedVolume Deformer::Impl::frame(BoneMatrices matrices, const DeformOptions& o, const Progress& progress,
                                     const Box* fixed_box) {
    check_options(o, n);
    std::vector<Motion> motions = bone_motions(matrices, bone_count, grid);
    build(o.mode != DeformMode::Rigid && has_weights, o, progress);
    bend_groups(motions, o);
    const bool contact = o.keep_volume && !groups.weights.empty() && o.mode != DeformMode::Rigid;
    const FieldContacts planes = contact ? contacts(bend, groups, motions, o.mode, bone_count, grid) : FieldContacts{};
    add_group_motions(motions, o.mode);
    if (o.bricks && fixed_box) throw Error("deform: bricks and an imposed box do not go together");
    if (o.half && !o.bricks) throw Error("deform: half-float values are for frames in bricks");
    const Box bx = o.bricks ? brick_aligned(frame_reach(motions)) : fixed_box ? *fixed_box : frame_reach(motions);
    check_box_reach(bx);
    DeformedVolume out = frame_on(grid, bx);
    const auto total = static_cast<std::size_t>(bx[3] * bx[4] * bx[5]);
    // Recycled output memory: only what earlier frames wrote is zeroed again (marked as it is written). A frame in
    // bricks names its box as the layout: a voxel's place in the bricks moves with the box, so memory a frame on
    // another box wrote goes back to the kernel rather than staying resident beside this frame's.
    const std::uint64_t layout = o.bricks ? box_key(bx) : 0;
    if (o.values && o.half) out.half_values = pool->take<std::uint16_t>(total, layout);
    else if (o.values) out.values = pool->take<float>(total, layout);
    if (o.half && bone_count < 255) out.bone8 = pool->take<std::uint8_t>(total, layout);
    else out.bone = pool->take<std::int16_t>(total, layout);
    report(progress, 0.55);
    const auto& sp = grid.spacing;
    const FieldSet set{fields, motions, sp.data(), {sp[0] * sp[0], sp[1] * sp[1], sp[2] * sp[2]}, threshold(),
                       bound_step, o.proximity == Proximity::Nearest, contact ? &planes : nullptr};
    GatherResult r = gather(set, field_owner, source, bx, o, out, progress);
    Drawn layer;
    if (!pieces.empty()) {
        layer = paint_layer_pooled(layer_source, pieces, motions, o.sampling, bx, out, o.bricks);
        for (int a = 0; a < 3; ++a) r.lo[a] = std::min(r.lo[a], layer.lo[a]), r.hi[a] = std::max(r.hi[a], layer.hi[a]);
    }
    if (o.bricks) set_extent(out, r.lo, r.hi);
    else if (!fixed_box) crop_to_extent(out, r.lo, r.hi, &grid);
    report(progress, 1.0);
    out.stats = {r.covered, r.queries, blended_spheres, r.by_block, r.by_cube, r.by_sphere, r.by_search,
                 r.exact_sub_blocks, layer.count, r.contact};
    ++frames_since_change;
    return out;
}

Deformer::Deformer(const VolumeView& source, const BoundSpheres& spheres) : impl_(std::make_unique<Impl>()) {
    check_grid(source.grid, dtype_size(source.dtype), std::numeric_limits<std::uint64_t>::max(), "deform source");
    check_source(source, "deform");
    check_spheres(source.grid, spheres);
    Impl& m = *impl_;
    m.source = source;
    m.grid = source.grid;
    advise_huge_pages(source.data, static_cast<std::size_t>(source.grid.voxel_count()) * dtype_size(source.dtype));
    m.assign(spheres);
}

Deformer::~Deformer() = default;

void Deformer::rebind(const BoundSpheres& spheres) {
    Impl& m = *impl_;
    check_spheres(m.grid, spheres);
    if (spheres.n != m.n || spheres.bone_count != m.bone_count || !std::equal(m.ijk.begin(), m.ijk.end(), spheres.ijk) ||
        !std::equal(m.radius.begin(), m.radius.end(), spheres.radius))
        throw Error("rebind: the spheres or the bone count differ from the Deformer's (only bones and weights may "
                    "change): make a new Deformer");
    m.set_binding(spheres);
    m.built = false;  // the next frame rebuilds what changed
}

std::size_t Deformer::reused_fields() const { return impl_->reused; }

void Deformer::set_lattice_after(int frames) {
    if (frames < -1) throw Error("set_lattice_after: give a number of frames, 0 (at once) or -1 (never)");
    impl_->lattice_after = frames;
}

int Deformer::lattice_after() const { return impl_->lattice_after; }

bool Deformer::lattice_tables() const {
    const Impl& m = *impl_;
    if (!m.built) return false;
    for (std::size_t f = 0; f < m.bone_count; ++f)
        if (!m.fields[f].lattice) return false;
    return true;
}

void Deformer::set_source(const VolumeView& source) {
    if (source.grid.dims != impl_->grid.dims) throw Error("set_source: the samples do not have the Deformer's grid");
    check_source(source, "deform");
    impl_->source = source;
}

void Deformer::set_rigid_layer(const VolumeView& source, std::vector<RigidPiece> pieces) {
    Impl& m = *impl_;
    if (source.grid.dims != m.grid.dims) throw Error("rigid layer: its source does not have the Deformer's grid");
    check_source(source, "rigid layer");
    check_pieces(m.grid, pieces, m.bone_count);
    m.layer_source = source;
    m.pieces = std::move(pieces);
}

std::size_t Deformer::bone_count() const { return impl_->bone_count; }
std::size_t Deformer::sphere_count() const { return impl_->n; }

std::size_t Deformer::memory_bytes() const {
    std::size_t b = impl_->SphereStore::memory_bytes() + impl_->radii.size() * 8 +
                    impl_->groups.group_of.size() * 8 + impl_->groups.weights.size() * 64;
    for (const auto& f : impl_->fields) b += f.bytes();
    return b;
}

std::size_t Deformer::kept_frame_bytes() const { return impl_->pool->kept_bytes(); }
void Deformer::release_frame_memory() { impl_->pool->trim(); }

DeformedVolume Deformer::frame(BoneMatrices matrices, const DeformOptions& options, const Progress& progress,
                               const std::array<std::int64_t, 6>* box) {
    return impl_->frame(matrices, options, progress, box);
}

}  // namespace volrig

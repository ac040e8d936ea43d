// volrig/rig.hpp: the articulated skeleton (docs/ALGORITHMS.md §6): automatic rigging from a skeleton-tree, Blender's
// rest-matrix convention, and binding skeleton points to bones.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "volrig/progress.hpp"
#include "volrig/tree.hpp"
#include "volrig/volume.hpp"

namespace volrig {

/// Joints (world positions) and bones between them. A bone runs from joint bones[b][0] (head) to bones[b][1]
/// (tail); parents[b] is the parent bone or -1.
struct Rig {
    std::vector<std::array<double, 3>> joints;
    std::vector<std::array<std::int32_t, 2>> bones;
    std::vector<std::string> names;
    std::vector<std::int32_t> parents;
    std::string kind = "custom";  ///< one of kAutorigKinds (autorig) or "custom"
    /// Per joint: the skeleton point it sits on, or -1 (an end joint extended to the surface, a user joint).
    std::vector<std::int64_t> joint_points;
    // What autorig found (left at their defaults for other rigs):
    double fit = 0;                          ///< how well the template fits, 0..1
    std::array<double, 3> up{0, 0, 0};       ///< the up direction used or inferred (unit; zero when unknown)
    double up_confidence = 0;                ///< 1 when given, else how clearly the shape shows it (0..1)
    std::string runner_up;                   ///< the second-best template's kind ("" when there was none)
    double runner_up_fit = 0;
    /// What the user should know about the result ("" when nothing): e.g. that no body plan fits.
    std::string note;
};

/// Checks a rig's consistency (indices in range, finite joints, no zero-length bones, parents acyclic, names
/// unique and non-empty); throws Error saying what is wrong.
void check_rig(const Rig& rig);

/// Blender's rest matrix of a bone (roll 0): column-major 4x4 (16 doubles), Y axis along head -> tail, X and Z
/// from the smallest rotation taking +Y to the bone direction (vec_roll_to_mat3), translation = head.
std::array<double, 16> rest_matrix(const std::array<double, 3>& head, const std::array<double, 3>& tail);

/// The templates autorig fits (AutorigOptions::kind, Rig::kind): body plans, then neutral chains.
inline constexpr std::array<const char*, 5> kAutorigKinds = {"humanoid", "quadruped", "winged", "hand", "chains"};

/// Marker names autorig accepts (AutorigOptions::markers): joints of the humanoid and quadruped templates (a
/// quadruped's front legs are its arms).
inline constexpr std::array<const char*, 20> kMarkerNames = {
    "chin",    "neck",    "head_top", "groin",      "shoulder.L", "shoulder.R", "elbow.L", "elbow.R", "wrist.L", "wrist.R",
    "hand_tip.L", "hand_tip.R", "hip.L", "hip.R", "knee.L",     "knee.R",     "ankle.L", "ankle.R", "toe.L",   "toe.R"};

struct AutorigOptions {
    /// Bone count target. Role-named rigs (humanoid, quadruped) use their 21 role bones when this allows;
    /// other shapes get at most this many bones along their chains. 0 selects 24.
    int bones = 0;
    /// Spur pruning: a leaf branch goes when its tip's ball lies inside the ball of a node nearer the root scaled
    /// by this factor.
    double prune_scale = 1.5;
    /// Chains are split at bends until every point lies within tolerance * its radius of its bone (4-D: position
    /// and radius), for shapes without a role template.
    double tolerance = 0.35;
    /// Try the humanoid / quadruped body plans; false gives neutral chains whatever the shape.
    bool roles = true;
    /// Force a template, one of kAutorigKinds ("" = the best fit). A forced body plan is built whatever its score
    /// (an error when the shape has no extremities for it: five for a humanoid or quadruped, six for a hand).
    std::string kind;
    /// The world's up direction in the volume's frame, when known: a humanoid's spine must point up, a quadruped's
    /// limbs down. Without it, up is inferred from the winning template.
    std::optional<std::array<double, 3>> up;
    /// Rig the object's own skeleton at autorig's scale (resampled to about 400 voxels along its longest extent
    /// when finer) instead of the given points: any point count gives the same rig; the given points only carry
    /// the joints. False always rigs the given points and tree, its joints on those points (end joints aside).
    bool own_scale = true;
    /// Points the user marked on the object (world positions), by name (kMarkerNames; any subset). They are hard
    /// constraints of the body-plan embedding (the extremity a marker lies nearest has the role its name gives),
    /// then the marked joints move to them. Only for the humanoid and quadruped plans (an error with kind "hand"
    /// or "chains"); with markers, the best body plan that meets them wins over neutral chains.
    std::vector<std::pair<std::string, std::array<double, 3>>> markers;
    /// The body-plan penalties' weights (kPlanTerms, then neutral chains' score; empty = the fitted ones). For
    /// fitting and cross-validating them; users leave it empty.
    std::vector<double> plan_weights;
};

/// The names of the body-plan features (the order of AutorigOptions::plan_weights, which adds the chains' score).
std::vector<std::string> autorig_plan_terms();

/// The fitted body-plan weights (autorig_plan_terms' order, then the chains' score): AutorigOptions::plan_weights'
/// default.
std::vector<double> autorig_fitted_weights();

/// What autorig kept, for pictures and diagnostics.
struct AutorigDetail {
    std::vector<std::uint8_t> kept;  ///< per point: 1 when it survived spur pruning
    std::int64_t root = -1;          ///< the point the pruned tree was rooted at
    /// The level-set tree: node centroids, radii, edges, and whether each node survived pruning.
    std::vector<std::array<double, 3>> nodes;
    std::vector<double> node_radius;
    std::vector<std::array<std::uint32_t, 2>> node_edges;
    std::vector<std::uint8_t> node_kept;
    /// Every body-plan reading the search scored: its kind and features (autorig_plan_terms), for fitting weights.
    std::vector<std::string> reading_kind;
    std::vector<std::vector<double>> reading_features;
    /// ... and its extremities (indices into nodes): head, legs, arms; a hand's wrist only.
    std::vector<std::vector<std::uint32_t>> reading_leaves;
    /// Neutral chains' fit (1 - worst deviation; -1 when chains were not built).
    double chains_fit = -1;
};

/// Reduces a skeleton-tree (edges over the points) of the object in `mask` to an articulated skeleton (the stages
/// are described in native/src/autorig/autorig.cpp): the points' scale axis and its level-set tree, spurs pruned,
/// then every template (humanoid, quadruped, hand: role-named bones; neutral chains) fitted and scored; the best wins
/// (rig.kind, rig.fit, rig.runner_up). Uses the part with the largest ball volume.
Rig autorig(const Grid& grid, const std::uint8_t* mask, const PointSet& pts,
            const std::vector<std::array<std::uint32_t, 2>>& tree_edges, const AutorigOptions& opt = {},
            const Progress& progress = {}, AutorigDetail* detail = nullptr);

enum class BindMode { Rigid, Smooth };

/// Skeleton points bound to bones. Rigid: bone[i] only. Smooth: up to 3 (bone, weight) pairs per point in
/// weight_bones / weights (n x 3, unused slots bone -1 weight 0), weights summing to 1; bone[i] is the heaviest.
struct Binding {
    std::vector<std::int32_t> bone;
    std::vector<std::array<std::int32_t, 3>> weight_bones;
    std::vector<std::array<float, 3>> weights;
    /// Per point: 1 when no bone could be reached inside the object and the nearest bone in a straight line
    /// was used instead.
    std::vector<std::uint8_t> unreachable;
};

/// Binds each point to the bone nearest to it by geodesic distance inside the object: distance along a contained
/// straight line to the closest point of a bone, or along the contained neighbour graph (skeleton_graph) from
/// points that have one. Smooth mode adds a falloff across each joint: within one radius of the joint plane the
/// neighbouring bone takes up to half the weight.
/// `rigid` (optional, on the same grid): tissue that must not bend (bone). Points on it take weight 1 on one bone;
/// a 26-connected rigid component goes wholly to the bone that holds at least 90% of its points' ball volume,
/// unless it spans joints (bones touching in the label map: other bones' points lying past the joint region, more
/// than two ball radii or a quarter of their bone beyond the joint's plane, hold 1% of its ball volume); then each
/// point keeps its own bone.
Binding bind(const Grid& grid, const std::uint8_t* mask, const PointSet& pts, const Rig& rig, BindMode mode,
             const Progress& progress = {}, const std::uint8_t* rigid = nullptr);

// ---- rigs from a scan's bones (native/src/rig/bones/, docs/rig.md "Rigs from the bones") --------------------------

struct BoneRigOptions {
    /// Bones touching across an articulation are parted by an opening of this radius (mm; 0 = 4 mm or a
    /// twentieth of the skeleton's size, the cube root of its bone's volume, whichever is smaller; at least one
    /// voxel): the bone is eroded (6-neighbour steps), its 26-connected components labelled, and every bone voxel
    /// given the component reached in fewest steps.
    double opening = 0;
    /// Components of the eroded bone smaller than this (mm^3; 0 = 1000, a 10 mm cube, or 1/600 of the bone's
    /// volume, whichever is smaller) are no segments of their own: their voxels go to the nearest segment.
    double min_volume = 0;
    /// How far (mm) two segments may lie apart and still meet at a joint (0 = 20 mm or a quarter of the skeleton's
    /// size, whichever is smaller).
    double reach = 0;
};

/// The bone tissue split into rigid segments at its articulations.
struct BoneSegments {
    std::vector<std::int32_t> labels;  ///< per voxel: 0 = no segment, 1..count, largest first
    std::vector<std::int64_t> sizes;   ///< sizes[s - 1] = voxels in segment s
};

/// Splits `bone` (non-zero = bone, on `grid`) into segments (BoneRigOptions::opening). Throws Error for an empty
/// bone mask.
BoneSegments bone_segments(const Grid& grid, const std::uint8_t* bone, const BoneRigOptions& opt = {});

/// One limb joint rig_to_bones placed: which (joint index, its name such as "knee.L"), from where to where, how
/// ("contact": the centre of the contact between two segments; "ball": a sphere fitted to a head at its socket;
/// "section": the narrowest section of one segment spanning the joint, split there; "bulge": a knee, elbow or ankle
/// inside one segment with no narrower section, at its widest bone along the limb, split there; "kept": not moved, `why` says
/// why), and the segments either side (0 = none).
struct BoneJoint {
    std::int32_t joint = -1;
    std::string name;
    std::array<double, 3> from{0, 0, 0}, to{0, 0, 0};
    std::string how;
    std::string why;
    std::int32_t parent_segment = 0, child_segment = 0;
};

struct BoneRig {
    Rig rig;                              ///< the input rig, limb joints moved; topology and names unchanged
    std::vector<BoneJoint> joints;        ///< one per limb joint found in the rig (moved or kept)
    BoneSegments segments;                ///< the segments, after splits at merged joints
    std::vector<std::int32_t> bone_segment;  ///< per rig bone: the segment it runs through (0 = none)
};

/// Moves a role-named rig's limb joints (shoulders, elbows, wrists, hips, knees, ankles; .L and .R) to the
/// articulations the bone tissue shows: each limb bone is matched to the segment its middle runs through, a joint
/// between two segments goes to their contact's centre (hips and shoulders: the centre of a sphere fitted to the
/// head's surface facing its socket), a joint inside one segment to its narrowest section, where the segment is
/// split. End joints move with their bone's head (directions kept). A rig without role names is returned as is.
/// On slices at least twice as far apart as the pixels the bone is interpolated between them first and fitted on
/// that (native/src/rig/bones/slices.cpp); the segments come back on `grid`.
BoneRig rig_to_bones(const Grid& grid, const std::uint8_t* bone, const Rig& rig, const BoneRigOptions& opt = {});

// ---- when the flesh is missing (native/src/rig/bones/body.cpp) ---------------------------------------------------

/// The share of `body`'s surface voxels (a 6-neighbour outside it, inside the grid) that are bone: about 0 for a
/// scan with skin (bone lies under flesh), large for organs and bones without skin or the bone alone.
double bare_bone_share(const Grid& grid, const std::uint8_t* body, const std::uint8_t* bone);

/// autorig(bone=) reads the body plan from the bone when at least this share of the surface is bare bone.
inline constexpr double kBareBoneShare = 0.1;

/// The bone grown into a body: every voxel within `radius` of the bone, the largest 26-connected component. The
/// radius starts at twice the bone's median depth (at least kBoneBodyMinVoxels voxels) and grows by
/// kBoneBodyGrowth, at most kBoneBodySteps times, until that component holds kBoneBodyJoined of the bone (joint
/// spaces and girdles apart from the spine bridged; thin bones thick enough for autorig's own scale).
struct BoneBody {
    std::vector<std::uint8_t> mask;  ///< per voxel 0/1
    double radius = 0;               ///< the radius used (mm)
    double joined = 0;               ///< the share of the bone in the body
};
inline constexpr double kBoneBodyMinVoxels = 1.5, kBoneBodyGrowth = 1.5, kBoneBodyJoined = 0.95;
inline constexpr int kBoneBodySteps = 5;
/// Throws Error for an empty bone mask.
BoneBody bone_body(const Grid& grid, const std::uint8_t* bone);

}  // namespace volrig

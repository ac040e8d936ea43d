// rig/autorig/templates.hpp: body plans fitted to the node tree, each scored (internal to the core; tested alone in
// tests/native/test_rig_autorig.cpp).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "rig/autorig/plan_score.hpp"
#include "rig/autorig/rig_builder.hpp"

namespace volrig::rig_detail {

/// A template's embedding: the rig (no bones when it could not be built), how well it fits (0..1), the up
/// direction it implies and how sure that is (0..1; 0 when it implies none).
struct Candidate {
    Rig rig;
    double fit = 0;
    Vec up = Vec::Zero();
    double up_confidence = 0;
    double score = std::numeric_limits<double>::infinity();  ///< plan_score's (a body plan's or the hand's)
    bool up_overruled = false;  ///< read without the given up, along which no body plan stood (autorig.cpp)
};

/// The five extremities of a body plan: head, two legs (meeting at the pelvis), two arms (meeting at the chest).
struct Plan {
    std::uint32_t head = kNone, legs[2] = {kNone, kNone}, arms[2] = {kNone, kNone};
    double score = std::numeric_limits<double>::infinity();  ///< plan_score; kept when below the chains' score
    int broken = std::numeric_limits<int>::max();  ///< markers the reading breaks (the search minimises them first)
};
/// A reading under way: a Plan's extremities and where its legs and arms meet the spine.
struct Reading {
    std::uint32_t head, legs[2], arms[2], pelvis, chest;
};

/// A marker (AutorigOptions::markers) as a constraint on which extremity has which role: its point (in the node
/// tree's frame) and the role its name gives.
struct RoleMarker {
    enum Role { Head, Arm, Leg, Pelvis } role = Head;
    Vec at = Vec::Zero();
};
/// The role of a marker name (kMarkerNames), or throws Error for an unknown one.
RoleMarker::Role marker_role(const std::string& name);

/// What the body-plan search reads besides the tree: the up direction when given, the weights (plan_weights) and
/// the markers every reading must meet.
struct SearchInput {
    std::optional<Vec> up;
    const std::vector<double>& weights;
    std::vector<RoleMarker> markers;
};
/// A humanoid's upper arm or thigh shorter than this share of its proportional length (from the forearm or shin)
/// has its proximal end hidden in the trunk: it is moved out (build_plan).
constexpr double kHiddenEnd = 0.8;
/// A humanoid's hand tips lie at least this fraction of its legs' length above its foot tips along the spine (a
/// shortfall is added to the score: four feet on the ground are no humanoid's hands and feet).
constexpr double kHandsAboveFeet = 0.25;
/// The head's tip lies ahead of the chest along the spine: the cosine between chest -> head tip and pelvis -> chest
/// is at least this (a camel's neck rises at about 45 degrees; a limb hangs across the spine); a shortfall is added.
constexpr double kHeadAhead = 0.25;

/// The body plans read from five extremities: the same head, legs and arms, told apart by their features (a winged
/// reading's arms are wings).
enum class PlanKind { Humanoid, Quadruped, Winged };
inline const char* plan_kind_name(PlanKind k) {
    return k == PlanKind::Humanoid ? "humanoid" : k == PlanKind::Quadruped ? "quadruped" : "winged";
}

struct PlanSearch {
    Plan humanoid, quadruped, winged;
    Plan& of(PlanKind k) { return k == PlanKind::Humanoid ? humanoid : k == PlanKind::Quadruped ? quadruped : winged; }
    const Plan& of(PlanKind k) const { return const_cast<PlanSearch&>(*this).of(k); }
};

/// Discrete search over the assignments of five of the seven most significant extremities to head, legs and arms,
/// each read as a humanoid, a quadruped and a winged body and scored by plan_score over its
/// features (plan_score.hpp). The best reading of each kind: the fewest markers broken, then the lowest score;
/// every reading appended to `all` when given (for fitting the weights).
PlanSearch search_plans(const NodeTree& t, const SearchInput& in, std::vector<PlanReading>* all = nullptr);
/// The score below which a body plan beats neutral chains, with the fitted weights.
inline double plan_limit() { return chains_score(fitted_plan_weights()); }
/// How far below chains' score, and below every reading under the given up, a body plan read without that up must
/// score to overrule it, when no reading under it is that clear of chains (a character modelled lying down): the
/// margin the weights were fitted to (fit_plan_weights.py: each subject's own plan 1 below every other reading), so
/// only a reading as clear as training asks of the right plan.
constexpr double kUpOverruleMargin = 1.0;
/// ... and that reading must show its own up clearly (Candidate::up_confidence: a humanoid's legs within 18 degrees
/// of opposite its spine). A guard against overruling up for a shape that only happens to score: of the development
/// subjects' right humanoid and quadruped readings without up, 33 of 39 show their up at 0.9 or more; the shapes
/// with no plan that read as a plan without up (a lone arm, a statue) at 0.47-0.54.
constexpr double kUpOverruleClarity = 0.9;

/// The trunk from the pelvis to the chest cut into hips, spine and chest at these shares of its chord (a trunk's
/// medial axis wiggles: cuts at its bends, or shares of its arc, wander between resolutions), or by fit_chain when
/// it has too few samples.
inline const std::vector<double> kSpineProportions{1.0, 1.0, 1.0};
Fit trunk_fit(const Chain4& spine);

/// Per node of the tree (kept ones; 1 elsewhere): RigContext::cross_section_ratio across the tree's direction there
/// (from its parent), within kSectionRadii of its radius: a wing's or a fin's width over its thickness, 1 for a round
/// limb (NodeTree::sheet).
constexpr double kSectionRadii = 3.0;
std::vector<double> node_sheets(const RigContext& c);

/// Whether the extremities' bounding box is at least half the object's (a body plan spans the object).
bool spans_object(const NodeTree& t, const std::vector<std::uint32_t>& leaves);

/// The role-named rig of a plan (Rigify's names: hips, spine, chest, neck, head, shoulder / upper_arm / forearm /
/// hand and pelvis / thigh / shin / foot with .L/.R; a wing's bones are its arm's: humerus, radius and ulna, hand)
/// and its extra parts (add_extra_chains), or a candidate without bones when its chains are too short to cut.
Candidate build_plan(const RigContext& c, const Plan& plan, PlanKind kind, double tolerance,
                     const std::optional<Vec>& up = std::nullopt);

/// A limb whose proximal bone (upper arm, thigh) comes out shorter than kHiddenEnd times `ratio` times the next
/// one (forearm, shin) had its proximal end hidden in the trunk: where an arm lies against the trunk, its medial
/// axis leaves the trunk at the armpit, not at the humeral head. That end moves out along the bone's line (away
/// from the distal joint) to the proportional length, as far as the object reaches; it is a free joint then
/// (joint_points -1). Nothing changes when either bone is missing.
void restore_proximal(const RigContext& c, Rig& rig, const std::string& proximal, const std::string& distal,
                      double ratio);

/// A limb chain's samples from the trunk out: a sample more than kTrunkJump times as thick as every sample beyond
/// it is trunk (a limb lying against the trunk joins it through the trunk's medial sheet, not at its own radius).
constexpr double kTrunkJump = 1.5;
/// The index of the first sample after the last trunk sample (the root counts; only in the first half of the
/// chain's length: a hand thickens from its finger tip too), or 0 when there is none.
std::size_t own_start(const Chain4& chain);

/// How much of an arm's visible top gives its line (arc length, in radii of its first own sample).
constexpr double kFusedTopRadii = 2.0;
/// A fused upper arm runs along the body: |cos| between its line and the body's up (the given up, else the spine)
/// at least this.
constexpr double kFusedAlongSpine = 0.7;
/// An arm fused with the trunk (arms at the sides of a scan): the medial axis of its upper arm starts mid-arm
/// (own), below the humeral head. The shoulder joint goes up the line of its visible top (kFusedTopRadii) to the
/// shoulder's surface and one radius back in; `cuts` (into the chain: the chest, own, elbow, wrist, tip) come from
/// proportional_fit of upper arm, forearm and hand over the shoulder joint and the own samples.
struct FusedArm {
    std::size_t own = 0;
    Vec shoulder = Vec::Zero();
    std::vector<std::size_t> cuts;
};
/// The fused reading of an arm chain (from the chest), or none: no trunk samples beyond its root, a top across the
/// body (a shoulder girdle, a raised arm), too few samples.
std::optional<FusedArm> fused_arm(const RigContext& c, const Chain4& chain, const Vec& body_up, const Vec& front);
/// A free arm's shoulder joint the same way (the medial axis leaves the shoulder's corner, not the humeral head):
/// from the line of the upper arm's axis (`arm`: the chain from the chest, `top` and `elbow` its upper arm's first
/// and last samples) up to the shoulder's surface and its mean radius back in, centred front to back.
void shoulder_on_top(const RigContext& c, Rig& rig, const Chain4& arm, std::size_t top, std::size_t elbow,
                     const std::string& upper_arm, const Vec& body_up, const Vec& front);
/// Moves the head of bone `upper_arm` to the fused arm's shoulder joint.
void place_fused_shoulder(Rig& rig, const std::string& upper_arm, const Vec& shoulder);

/// The hip: the legs' medial axes fork below the hip joints (at the crotch, thighs pressed together lower still),
/// so the thigh's head moves up its line to the level of the hips bone's head (the fork), when that is higher.
void hip_on_thigh_line(Rig& rig, const std::string& thigh);

/// A leg is straight when no node of its axis between hip and ankle (`leg`: those nodes) lies more than this
/// share of the hip-ankle distance off their line (a knee bent by less than about 45 degrees: 2 atan(2 * 0.2));
/// its knee then goes to the node nearest the thigh's share of hip-ankle (Drillis and Contini), not to a wiggle of
/// the axis (knee pads, boot tops, a calf). Relative to the leg's length, not its radius: a thin leg's axis strays
/// many of its radii where a thick one's does not. The shared reference skeletons (compiled weights): mean CD-J2J
/// 4.75 -> 4.68, better on 5 (the T-pose human 3.00 -> 2.26, its axis bowed forward over the shin), worse on
/// none; flat from 0.12 up (a bend fit then only for sitting and crouching knees).
constexpr double kStraightLegBend = 0.2;
/// ... and then to the narrowest node within kNeckWindow radii of it, when the leg widens from there by kNeckRise
/// on both sides (thigh above, calf below: a human knee).
constexpr double kNeckWindow = 2.0;
constexpr double kNeckRise = 0.05;
/// ... and by this many voxels (the finest spacing of the grid autorig works on) more: the axis's radii are
/// distance-transform values, which step by fractions of a voxel, so a limb a few voxels thick (a character
/// voxelized at 160 to 260 cells) shows 5% dips along a plain cylinder; a dip within that noise is no knee or
/// ankle neck (the wrist's, the narrowest node of its window, keeps kNeckRise alone).
constexpr double kNeckNoise = 0.35;
/// Whether a limb `wide` thick widens from `narrow` enough to be a neck (kNeckRise, kNeckNoise of `voxel`).
inline bool widens(double wide, double narrow, double voxel) {
    return wide >= (1 + kNeckRise) * narrow + kNeckNoise * voxel;
}
/// Between samples lo and hi of a chain: the sample where the radius dips deepest, the least of the widest sample
/// before it and the widest after it being the most above its own radius, by kNeckRise (and kNeckNoise) at least
/// (a knee between thigh and calf, a neck between trunk and head); else none. The deepest dip, not the narrowest sample: a leg
/// narrows towards the ankle.
/// `voxel`: the finest spacing (see widens).
std::optional<std::size_t> deepest_dip(const Chain4& chain, std::size_t lo, std::size_t hi, double voxel);
/// A knee found at its neck lengthens the thigh to this share of the knee's height above the sole (measured down
/// the shin's line to the farthest surface of the leg's axis samples): Drillis and Contini's thigh 0.245 H over
/// knee height 0.285 H.
constexpr double kThighToKneeHeight = 0.245 / 0.285;
/// `leg`: the leg's nodes from the hip to the foot's tip.
void straight_knee(const RigContext& c, Rig& rig, const std::vector<std::uint32_t>& leg, const std::string& sfx);

/// The wrist at its neck: a forearm narrows to the wrist, and a hand resting on something (the pelvis, a thigh)
/// widens again in the mask, so where the arm's axis from the elbow (`arm`: its nodes from the elbow to the hand's
/// tip) has a node narrower than every node within kNeckWindow of its radii and the arm widens by kNeckRise on both
/// sides, the wrist goes to the one nearest the rig's wrist. A free hand, thinner than its wrist, keeps the wrist.
void wrist_at_neck(const RigContext& c, Rig& rig, const std::vector<std::uint32_t>& arm, const std::string& sfx);

/// The ankle above a heel: where the lower leg narrows (its neck, above the malleoli) and then widens into a heel
/// around the rig's ankle (the widest node within kNeckWindow radii of it, by kNeckRise at least), the medial axis
/// turns towards the toes at the heel's centre, below the ankle joint; the ankle goes midway along the axis between
/// the neck and the heel's widest node, where the malleoli are. A leg without that shape keeps its ankle.
/// `leg`: the leg's nodes from the knee to the foot's tip.
void heel_ankle(const RigContext& c, Rig& rig, const std::vector<std::uint32_t>& leg, const std::string& sfx);

/// A bent limb's joint (elbow, knee) at the corner of its bones' axes: the medial axis rounds a bend on its
/// inside, by about a radius, so the joint between `proximal` and `distal` goes to the point where the lines
/// through their axes (the axis samples of `limb` more than kBendRound radii of arc from the joint) come closest,
/// when they meet at more than kBendAngle (radians), at most one radius away and half a radius inside the object.
constexpr double kBendRound = 0.5;
constexpr double kBendAngle = 0.35;
void bend_corner(const RigContext& c, Rig& rig, const std::vector<std::uint32_t>& limb, const std::string& proximal,
                 const std::string& distal);

/// Left and right limbs have the same proportions whatever their pose: when the shares of the bones beyond the
/// root's (thigh, shin, foot of a leg) in their sum differ by more than kLimbMismatch between the sides' fits, the
/// limb whose shares lie farther from `prior`'s (Drillis and Contini's) is fitted again beyond its root's bone with
/// the other's lengths as its proportions, kMatchWeight times as strongly as limb_fit's (`limb[s]`: its nodes from the root out). Legs
/// only: the pair's fits on the shared characters (benchmarks/rig_characters.py) bring the legs' mean CD-J2J 5.35 ->
/// 5.30 (better on 6, worse on 1 by 0.01), the arms' 5.30 -> 5.31 (artists' 4.72 -> 4.81): a hand's fingers and a
/// raised or fused arm make the arms' pieces differ for reasons other than a misfit.
constexpr double kLimbMismatch = 0.1;
constexpr double kMatchWeight = 10.0;
void match_limb_fits(const RigContext& c, const std::vector<std::uint32_t> (&limb)[2], Fit (&fit)[2],
                     const std::vector<double>& prior);

/// Hips no lower than this share of the neck's height above the sole: the least hip-to-neck height ratio of the
/// shared humanoid reference skeletons (artists' and RigNet's, 0.55 to 0.85: cartoon heads and long legs). Legs
/// fused above the knees (thighs pressed together, a coat, a skirt) fork low and would put the hips there.
constexpr double kLeastHipHeight = 0.55;
/// Thigh heads below kLeastHipHeight go straight up to it, and each knee to the node of its leg (`leg[s]`: the
/// nodes from the fork to the foot's tip; `sfx[s]` its side) nearest the thigh's share of hip to ankle: the fork no
/// longer tells where the leg bends.
void raise_low_hips(const RigContext& c, Rig& rig, const std::vector<std::uint32_t> (&leg)[2],
                    const std::string (&sfx)[2], const Vec& body_up);

/// A humanoid's hip joints lie level across its pelvis: each hip's estimate (its thigh's share of the knee
/// height, or the legs' fork) is as good as the other's, so both go to the mean of their heights along `body_up`.
void level_hips(Rig& rig, const Vec& body_up);

/// The chest joint (where neck and shoulders meet) between the shoulder joints, and the hips' head between the
/// hip joints: midway across the body and at their height along `body_up` (shoulder and pelvis bones run across,
/// Rigify's), unchanged front to back. The level-set tree's chest and pelvis nodes lie where the limbs' and the
/// neck's medial axes join the trunk's medial sheet: lower, off the middle, and by how much varies with the
/// resolution.
void centre_chest(Rig& rig, const Vec& body_up);
/// The spine's inner joints cut again (trunk_fit) between the hips' head and the chest's tail where centre_chest
/// put them (`spine`: the trunk's axis samples from the pelvis node to the chest node).
void recut_spine(Rig& rig, Chain4 spine);

/// A humanoid's head bone points up (Rigify's), from the head joint to the top of the head, whichever extremity
/// (the face, the crown) the medial axis reaches: the head joint goes to the head chain's sample (`head`: from the
/// chest out) at kHeadShare of the height from the neck's base to the top of the head below the top (Rigify's
/// metarig: the head 0.6 of the way from the neck's base to the crown), the tail straight up, kHeadTail of the way to
/// the surface.
constexpr double kHeadShare = 0.6;
/// The head bone ends half-way from the head joint to the crown, not at the crown: the reference skeletons end the
/// head at the skull's base (13 of the 15 humanoid references, artists' and RigNet's, have no joint above volrig's
/// head joint), so a tail on the crown was a joint 10-36 (x 100, longest side 1) from any of theirs. Half-way keeps
/// a bone the animator can see and grab inside the head (J2J over the 24 references: 5.26 at the crown, 5.14 at
/// half, 5.09 at a fifth).
constexpr double kHeadTail = 0.5;
void place_head(const RigContext& c, Rig& rig, const Chain4& head, const Vec& body_up);

/// A humanoid's hands end at the knuckles and its feet at the ball of the foot, not at the fingertips and toe tips
/// the fit reaches: where Rigify's metarig ends its hand and foot bones (its fingers and toe bones go on from there)
/// and where the reference skeletons, artists' and RigNet's, end theirs or start their fingers. kHandToKnuckles: the
/// palm's share of the hand's length, wrist to the middle finger's knuckle (about 0.55 in adult anthropometry);
/// kFootToBall: from the ankle to the ball of the foot over the ankle to the toe tip (the ball at about 0.73 of the
/// foot's length from the heel, the ankle at 0.2: 2/3). Over the 24 references (compiled weights), J2J 4.94 -> 4.75;
/// with kHeadTail 5.26 -> 4.75, no character worse (a sweep moving the built ends afterwards: hands and feet at half
/// 4.70, flat from 0.5 to 0.7). A hand holding fingers'
/// chains keeps its end (their roots).
constexpr double kHandToKnuckles = 0.55;
constexpr double kFootToBall = 2.0 / 3.0;
void end_hands_and_feet(Rig& rig);

/// Extra parts (tails, trunks, ears, wings, horns): the most significant branches that no template bone holds
/// (at most kMaxExtraChains) and stick out of the body (their significance, NodeTree::extremities) by at least
/// kExtraReach times their own mean radius, become chains parented to the bone holding the node they hang from,
/// cut at bends like neutral chains (at most 4 bones). Named tail, tail.001, ... when a quadruped's or a winged
/// body's hang from its hips, spine or pelvis with the tip behind the hips, else chain.<parent bone>,
/// chain.<parent bone>.001, ... A winged body's wing keeps none: a sheet's medial axis branches along its edges.
constexpr int kMaxExtraChains = 6;
constexpr double kExtraReach = 2.0;
/// ... and, but for a humanoid's fingers (parts off its forearm or hand, which end_part_reach judges) and a
/// four-legged or winged body's tail (a template's optional part), by kExtraShare of the body's size (the longest side
/// of the box around the tree) at least: artists rig tails, long ears and long hair, not a coat's folds, a cape or a
/// bun. Fitted on the shared reference skeletons (benchmarks/rig_characters.py): mean CD-J2J over 24 characters
/// 5.66 with every part of kExtraReach, 5.43 at 0.15, 5.35 at 0.25, 5.34 with none; better on 14, worse on 3.
constexpr double kExtraShare = 0.25;
void add_extra_chains(const RigContext& c, RigBuilder& b, PlanKind kind, double tolerance);

/// A hand: a wrist stub and five fingers (thumb first, then index, middle, ring, pinky across the palm) meeting
/// on a palm at `palm` (where the first finger leaves the path from the wrist).
struct HandPlan {
    std::uint32_t wrist = kNone, palm = kNone;
    std::array<std::uint32_t, 5> fingers{kNone, kNone, kNone, kNone, kNone};
    double score = std::numeric_limits<double>::infinity();  ///< shape penalty (0 = perfect): kHandShape
};

/// Discrete search over the assignments of six of the eight most significant extremities to a wrist and five
/// fingers. The thumb is the finger whose base lies farthest from where the other four meet. Penalties for the
/// other four: unequal lengths (from the palm centre) and thicknesses, bases away from the palm centre (relative
/// to the finger length), tips pointing back towards the wrist; a wrist thinner than a finger, a wrist stub longer
/// than twice a finger (an arm), a thumb joining beyond the palm centre, a palm centre more than kPalmThickness
/// times as thick as the fingers, significant extremities left out.
HandPlan search_hand(const NodeTree& t);
/// A hand plan's score (plan_score of its bias and shape penalty; infinite when there is none).
double hand_plan_score(const HandPlan& plan, const std::vector<double>& w);
/// A palm is a plate about as thick as its fingers (a human's palm radius is under twice their mean radius); the
/// excess of the ratio over this is added to a hand's score: a body several times thicker than its legs is none.
constexpr double kPalmThickness = 2.5;

/// The hand's rig: "palm" from the wrist end to the palm centre, then per finger three bones parented to it,
/// thumb.01..03 from where the thumb leaves the palm (cut at its bends), f_index / f_middle / f_ring / f_pinky
/// .01..03 from the knuckle (the bend where the path from the palm centre turns into the finger) cut at its
/// bends when clearly bent, else at the phalanges' proportions. Names get .L / .R from the thumb's side of the
/// palm (the thumb lies on the palm's side), none when the thumb lies in the palm's plane. No bones when a chain
/// is too short to cut.
Candidate hand_rig(const RigContext& c, const HandPlan& plan);

/// Markers on a body plan's rig (`markers`: names of kMarkerNames and points in the rig's frame): limbs swap their
/// .L / .R names when the markers say the other side, then each marked joint moves to its marker (a chin: the head
/// joint; a groin: the hips' root), and a knee or elbow marked on one side only sets the other side's at the same
/// share of its limb. The shared humanoids with five markers from their references (compiled weights), each step
/// after the one before: the other knee 3.57 -> 3.56, the groin -> 3.32, then (with legs from their own side) the
/// whole chin -> 3.13.
void apply_markers(Rig& rig, const std::vector<std::pair<std::string, Vec>>& markers);

/// Neutral chains between branch points, cut at bends until every node lies within tolerance * its radius of its
/// bone, at most `target` bones (the least significant branches left out first). Fit: 1 - the worst deviation
/// (relative to the radius), at least 0.
Candidate chain_rig(const RigContext& c, int target, double tolerance);

}  // namespace volrig::rig_detail

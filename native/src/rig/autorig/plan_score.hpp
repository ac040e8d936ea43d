// rig/autorig/plan_score.hpp: a body-plan reading's features and their weights, fitted to data (internal to the
// core). A reading assigns extremities of the node tree to a template's roles (head, legs, arms; or wrist and
// fingers); its score is the weighted sum of its features (penalties, each 0 when the reading is ideal, and one
// bias per template), lower is better. Neutral chains score kChainsScore's weight: a body plan is kept only when it
// scores below it. The weights are fitted by benchmarks/fit_plan_weights.py (a max-margin ranking over the shared
// characters, as Pinocchio fitted its embedding penalties) and written to plan_weights.inc.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace volrig::rig_detail {

/// The features of a reading, in the order of kPlanTermNames. h_ terms only for a humanoid reading, q_ for a
/// quadruped, hand_ for a hand.
enum PlanTerm : int {
    kBiasHumanoid,    ///< 1 for a humanoid reading
    kBiasQuadruped,   ///< 1 for a quadruped reading
    kBiasHand,        ///< 1 for a hand reading
    kBiasWinged,      ///< 1 for a winged reading (two wings, two legs, a head)
    kMirrorLegs,      ///< the legs' tips do not mirror each other across the spine (relative to their length)
    kMirrorArms,      ///< nor the arms' tips
    kLeftOut,         ///< share left out of the seven most significant extremities' weight (significance times end
                      ///< radius: a thin tail weighs less than a head as long)
    kHeadThin,        ///< the head is thinner than an extremity left out (a tail): 0 or 1
    kPairsCross,      ///< the legs' and the arms' left-right directions (tip to tip) disagree (1 - |cos|)
    kRootsCross,      ///< the same a third of the way out along the limbs (tips swing with the pose)
    kHeadBehind,      ///< the head leaves the chest backwards, against the spine's direction (-cos, at least 0)
    kLimbsShort,      ///< the limbs reach less far than the head (1 - mean limb reach / head reach, at least 0)
    kNarrowSpan,      ///< the extremities span less of the object than it spans (1 - extent ratio)
    kLimbRatio,       ///< legs and arms of unequal length (|ln(leg / arm)|, path lengths from pelvis and chest)
    kArmsFlat,        ///< the arms are sheets (wings, fins): their nodes' spread over radius, median, over 4, at most 1
    kLegsFlat,        ///< the same for the legs
    kHLegsThin,       ///< humanoid: legs thinner than arms ((arm radius - leg radius) / arm radius, at least 0)
    kHHandsLow,       ///< humanoid: hands within a quarter of the legs' length above the feet along the spine
    kHLegsNotDown,    ///< humanoid: legs not pointing away from the head along the spine ((1 + cos) / 2)
    kHSpineNotUp,     ///< humanoid: the spine does not point up ((1 - cos) / 2; 0 without up: the spine is up)
    kQLegsAlong,      ///< quadruped: legs along the spine rather than across it (|cos|)
    kQLimbsNotDown,   ///< quadruped: the limbs do not hang down ((1 + cos) / 2; without up, up is against their
                      ///< mean direction)
    kQSpineTilt,      ///< quadruped: the spine is not level (|cos| with up, or that up)
    kHandShape,       ///< hand: search_hand's shape penalty (finger lengths and thicknesses, palm, thumb, stub)
    kWWingsRound,     ///< winged: the wings are not sheets (1 - their flatness, kArmsFlat's measure; kArmsFlat is 0
                      ///< for a winged reading)
    kWLegsNotDown,    ///< winged: the legs do not hang down ((1 + cos) / 2 with up; without up, 0)
    kPlanTerms
};

inline constexpr std::array<const char*, kPlanTerms> kPlanTermNames = {
    "bias_humanoid", "bias_quadruped", "bias_hand", "bias_winged", "mirror_legs", "mirror_arms", "left_out", "head_thin",
    "pairs_cross", "roots_cross", "head_behind", "limbs_short", "narrow_span", "limb_ratio", "arms_flat", "legs_flat", "h_legs_thin", "h_hands_low", "h_legs_not_down",
    "h_spine_not_up", "q_legs_along", "q_limbs_not_down", "q_spine_tilt", "hand_shape", "w_wings_round", "w_legs_not_down"};

using PlanFeatures = std::array<double, kPlanTerms>;

/// Weights: one per term, then the score of neutral chains (kPlanTerms + 1 values).
inline constexpr int kPlanWeights = kPlanTerms + 1;

/// The fitted weights (plan_weights.inc).
const std::vector<double>& fitted_plan_weights();

/// The weights to use: `given` when not empty (checked: kPlanWeights finite values, the penalty terms' at least
/// 0), else the fitted ones. Throws Error otherwise.
const std::vector<double>& plan_weights(const std::vector<double>& given);

/// The score of a reading: weights . features.
double plan_score(const PlanFeatures& f, const std::vector<double>& w);

/// Neutral chains' score.
inline double chains_score(const std::vector<double>& w) { return w[kPlanTerms]; }

/// A reading's fit, 0..1, from its score: 1 / (1 + exp(score - chains' score)); 0.5 at the chains' score.
double plan_fit(double score, const std::vector<double>& w);

/// One reading, for the weight fitting (AutorigDetail::readings).
struct PlanReading {
    std::string kind;
    PlanFeatures features{};
    /// The reading's extremities (the tree's nodes): head, legs, arms; or wrist, thumb, fingers.
    std::vector<std::uint32_t> leaves;
};

}  // namespace volrig::rig_detail

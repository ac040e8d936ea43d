// rig/autorig/chain_fit.hpp: cutting a chain of nodes into bones (internal to the core; tested alone in
// tests/native/test_rig_autorig.cpp). A chain is a sequence of 4-D samples (x, y, z, radius).
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <vector>

namespace volrig::rig_detail {

using Chain4 = std::vector<Eigen::Vector4d>;

struct Fit {
    std::vector<std::size_t> cuts;  ///< indices into the chain, first 0 and last size-1; empty when it failed
    double worst = 0;               ///< largest deviation from a piece's chord / the sample's radius
};

/// Optimal cut of `chain` into k pieces minimising the squared 4-D deviation of its samples from each piece's
/// chord (dynamic programming over at most 64 evenly spread samples of the chain). Fewer pieces when the chain
/// has too few samples.
Fit fit_chain(const Chain4& chain, int k);

/// Weight, per sample, of a bone-length ratio's squared logarithm against the samples' squared deviations.
constexpr double kProportionWeight = 0.05;

/// A chain cut into ratios.size() bones by one optimisation: clear bends, and bone lengths in the given ratios of
/// the whole (the last bone's length counts `extra` beyond the chain's end). Cost: the samples' squared 4-D
/// deviations from their piece's chord relative to the chain's mean radius (a relative measure per sample would let
/// a thin foot's wiggles outweigh a knee), plus kProportionWeight * samples * log(length / expected)^2 per bone;
/// exact over at most 64 samples (dynamic programming). `worst` as for fit_chain. Empty cuts when the chain has
/// fewer samples than bones + 1.
Fit proportional_fit(const Chain4& chain, const std::vector<double>& ratios, double extra,
                     double weight = kProportionWeight);

/// A humanoid limb cut into four bones by proportional_fit with Drillis and Contini's proportions (fractions of the
/// height): half the shoulder breadth 0.13, upper arm 0.186, forearm 0.146, hand 0.108 reaching one tip radius
/// beyond the chain; half the hip breadth 0.095, thigh 0.245, shin 0.246, foot 0.11. Clear bends (the shoulder's
/// corner, an elbow, the ankle) move joints off their proportion.
Fit limb_fit(const Chain4& chain, bool arm);

/// Drillis and Contini's segment lengths (fractions of the height) of a humanoid's arm (half the shoulder breadth,
/// upper arm, forearm, hand) and leg (half the hip breadth, thigh, shin, foot from the ankle to the toe tip).
inline const std::vector<double> kArmProportions{0.13, 0.186, 0.146, 0.108};
inline const std::vector<double> kLegProportions{0.095, 0.245, 0.246, 0.11};

/// Arc length along a chain's positions, from its first sample.
std::vector<double> arc_of(const Chain4& chain);

/// The index of the chain's sample nearest the point q (the first of equals; 0 for an empty chain).
std::size_t nearest_sample(const Chain4& chain, const Eigen::Vector3d& q);

}  // namespace volrig::rig_detail

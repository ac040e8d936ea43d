// autorig/chain_fit.hpp: cutting a chain of nodes into bones (internal to the core; tested alone in
// tests/native/test_autorig.cpp). A chain is a sequence of 4-D samples (x, y, z, radius).
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <vector>

namespace volrig::rigging {

using Chain4 = std::vector<Eigen::Vector4d>;

struct Fit {
    std::vector<std::size_t> cuts;  ///< indices into the chain, first 0 and last size-1; empty when it failed
    double worst = 0;               ///< largest deviation from a piece's chord / the sample's radius
};

/// Optimal cut of `chain` into k pieces minimising the squared 4-D deviation of its samples from each piece's
/// chord (dynamic programming over at most 64 evenly spread samples of the chain). Fewer pieces when the chain
/// has too few samples.
Fit fit_chain(const Chain4& chain, int k);

/// A joint expected at fraction `frac` of the arc from chain index a to b (plus `extra` length beyond b): the
/// sample deviating most from the chord a -> b (in position and radius) within a fifth of that length of the
/// expected place, when it deviates by 0.15 of its radius (a clear bend), else the expected place itself.
std::size_t place_joint(const Chain4& chain, const std::vector<double>& arc, std::size_t a, std::size_t b,
                        double frac, double extra);

/// A humanoid limb cut into four bones: the strong bends by the piecewise-linear fit (an arm leaves the shoulder
/// girdle; a leg leaves the pelvis and turns into the foot), then the weak ones (elbow and wrist; knee) near their
/// Drillis-Contini proportions (upper arm : forearm : hand = 0.186 : 0.146 : 0.108 of the height, thigh and shin
/// equal) and moved to a clear bend nearby. Empty cuts when the chain is too short.
Fit limb_fit(const Chain4& chain, bool arm);

/// Arc length along a chain's positions, from its first sample.
std::vector<double> arc_of(const Chain4& chain);

}  // namespace volrig::rigging

// rig/autorig/plan_score.cpp: a body-plan reading's score from its features and the fitted weights (see
// plan_score.hpp).
#include "rig/autorig/plan_score.hpp"

#include <cmath>
#include <iterator>

#include "volrig/error.hpp"

namespace volrig::rig_detail {

namespace {
constexpr double kFitted[] = {
#include "rig/autorig/plan_weights.inc"
};
static_assert(std::size(kFitted) == kPlanWeights, "plan_weights.inc: one weight per term, then the chains' score");
}  // namespace

const std::vector<double>& fitted_plan_weights() {
    static const std::vector<double> w(std::begin(kFitted), std::end(kFitted));
    return w;
}

const std::vector<double>& plan_weights(const std::vector<double>& given) {
    if (given.empty()) return fitted_plan_weights();
    if (given.size() != static_cast<std::size_t>(kPlanWeights))
        throw Error("autorig: plan_weights must hold " + std::to_string(kPlanWeights) + " values (one per term of "
                    "PLAN_TERMS, then the chains' score), got " + std::to_string(given.size()));
    for (std::size_t k = 0; k < given.size(); ++k) {
        if (!std::isfinite(given[k])) throw Error("autorig: plan_weights must be finite");
        const bool bias = k <= kBiasWinged || k == static_cast<std::size_t>(kPlanTerms);
        if (!bias && given[k] < 0)
            throw Error(std::string("autorig: the weight of penalty '") + kPlanTermNames[k] + "' must be >= 0");
    }
    return given;
}

double plan_score(const PlanFeatures& f, const std::vector<double>& w) {
    double s = 0;
    for (int k = 0; k < kPlanTerms; ++k) s += w[static_cast<std::size_t>(k)] * f[static_cast<std::size_t>(k)];
    return s;
}

double plan_fit(double score, const std::vector<double>& w) {
    return 1.0 / (1.0 + std::exp(std::min(score - chains_score(w), 50.0)));
}

}  // namespace volrig::rig_detail

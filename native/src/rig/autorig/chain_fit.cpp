// rig/autorig/chain_fit.cpp: cutting chains into bones (see chain_fit.hpp).
#include "rig/autorig/chain_fit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace volrig::rig_detail {

namespace {

/// Distance of q from the segment a-b in 4-D.
double deviation(const Eigen::Vector4d& a, const Eigen::Vector4d& b, const Eigen::Vector4d& q) {
    const Eigen::Vector4d d = b - a, p = q - a;
    const double len2 = d.squaredNorm();
    const double t = len2 > 0 ? std::clamp(p.dot(d) / len2, 0.0, 1.0) : 0.0;
    return (p - t * d).norm();
}

}  // namespace

std::vector<double> arc_of(const Chain4& chain) {
    std::vector<double> arc(chain.size(), 0.0);
    for (std::size_t k = 1; k < chain.size(); ++k)
        arc[k] = arc[k - 1] + (chain[k].head<3>() - chain[k - 1].head<3>()).norm();
    return arc;
}

namespace {

/// The chain's samples (at most 64, spread evenly over its indices) and the cost of each piece a -> b: the sum over
/// the samples strictly inside it of (4-D deviation from the chord / the chain's mean radius)^2.
struct PieceCosts {
    const Chain4& chain;
    std::vector<std::size_t> sample;
    std::vector<double> arc, cost;
    std::size_t m = 0;

    explicit PieceCosts(const Chain4& c) : chain(c) {
        const std::size_t n = c.size();
        m = std::min<std::size_t>(n, 64);
        const std::vector<double> full = arc_of(c);
        double mean_r = 0;
        for (std::size_t s = 0; s < m; ++s) {
            sample.push_back(m == 1 ? 0 : s * (n - 1) / (m - 1));
            arc.push_back(full[sample.back()]);
            mean_r += c[sample.back()][3] / static_cast<double>(m);
        }
        cost.assign(m * m, 0.0);
        for (std::size_t a = 0; a < m; ++a)
            for (std::size_t b = a + 2; b < m; ++b) {
                double sum = 0;
                for (std::size_t s = a + 1; s < b; ++s) {
                    const double dv = deviation(at(a), at(b), at(s)) / std::max(mean_r, 1e-12);
                    sum += dv * dv;
                }
                cost[a * m + b] = sum;
            }
    }
    const Eigen::Vector4d& at(std::size_t s) const { return chain[sample[s]]; }
    double of(std::size_t a, std::size_t b) const { return cost[a * m + b]; }

    /// The fit of the sample cuts `from` traced back from the last sample over k pieces: chain indices and the
    /// worst deviation relative to each sample's radius.
    Fit trace(const std::vector<std::size_t>& from, std::size_t k) const {
        std::vector<std::size_t> cuts{m - 1};
        for (std::size_t j = k; j > 0; --j) cuts.push_back(from[j * m + cuts.back()]);
        std::reverse(cuts.begin(), cuts.end());
        Fit f;
        for (std::size_t c = 0; c + 1 < cuts.size(); ++c)
            for (std::size_t s = cuts[c] + 1; s < cuts[c + 1]; ++s)
                f.worst = std::max(f.worst, deviation(at(cuts[c]), at(cuts[c + 1]), at(s)) / std::max(at(s)[3], 1e-9));
        for (std::size_t c : cuts) f.cuts.push_back(sample[c]);
        return f;
    }
};

/// Optimal k pieces from the first sample to the last: piece_cost(j, a, b) for the j-th piece (1-based) from sample
/// a to b is added to the pieces' deviation costs.
template <class Extra>
Fit best_pieces(const PieceCosts& pc, std::size_t k, Extra piece_cost) {
    const std::size_t m = pc.m;
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<double> best((k + 1) * m, inf);
    std::vector<std::size_t> from((k + 1) * m, 0);
    best[0] = 0;
    for (std::size_t j = 1; j <= k; ++j)
        for (std::size_t b = j; b < m; ++b) {
            if (j == k && b != m - 1) continue;
            for (std::size_t a = j - 1; a < b; ++a) {
                if (best[(j - 1) * m + a] == inf) continue;
                const double c = best[(j - 1) * m + a] + pc.of(a, b) + piece_cost(j, a, b);
                if (c < best[j * m + b]) {
                    best[j * m + b] = c;
                    from[j * m + b] = a;
                }
            }
        }
    return pc.trace(from, k);
}

}  // namespace

Fit fit_chain(const Chain4& chain, int k) {
    const PieceCosts pc(chain);
    if (pc.m < 2) return Fit{};
    const auto pieces = static_cast<std::size_t>(std::max(1, std::min<int>(k, static_cast<int>(pc.m) - 1)));
    return best_pieces(pc, pieces, [](std::size_t, std::size_t, std::size_t) { return 0.0; });
}

Fit proportional_fit(const Chain4& chain, const std::vector<double>& ratios, double extra, double weight) {
    const PieceCosts pc(chain);
    const std::size_t m = pc.m, k = ratios.size();
    if (k == 0 || m < k + 1) return Fit{};
    double sum = 0;
    for (double r : ratios) sum += r;
    const double whole = pc.arc[m - 1] + extra;
    return best_pieces(pc, k, [&](std::size_t j, std::size_t a, std::size_t b) {
        const double len = pc.arc[b] - pc.arc[a] + (b == m - 1 ? extra : 0.0);
        const double r = std::log(std::max(len, 1e-12) / std::max(whole * ratios[j - 1] / sum, 1e-12));
        return weight * static_cast<double>(m) * r * r;
    });
}

Fit limb_fit(const Chain4& chain, bool arm) {
    return proportional_fit(chain, arm ? kArmProportions : kLegProportions, arm ? chain.back()[3] : 0.0);
}

std::size_t nearest_sample(const Chain4& chain, const Eigen::Vector3d& q) {
    std::size_t best = 0;
    for (std::size_t k = 1; k < chain.size(); ++k)
        if ((chain[k].head<3>() - q).norm() < (chain[best].head<3>() - q).norm()) best = k;
    return best;
}

}  // namespace volrig::rig_detail

// autorig/chain_fit.cpp: cutting chains into bones (see chain_fit.hpp).
#include "autorig/chain_fit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace volrig::rigging {

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

Fit fit_chain(const Chain4& chain, int k) {
    const std::size_t n = chain.size();
    std::vector<std::size_t> sample;
    const std::size_t m = std::min<std::size_t>(n, 64);
    for (std::size_t s = 0; s < m; ++s) sample.push_back(m == 1 ? 0 : s * (n - 1) / (m - 1));
    Fit f;
    if (m < 2) return f;
    k = std::max(1, std::min<int>(k, static_cast<int>(m) - 1));
    auto at = [&](std::size_t s) -> const Eigen::Vector4d& { return chain[sample[s]]; };
    std::vector<double> cost(m * m, 0.0);
    for (std::size_t a = 0; a < m; ++a)
        for (std::size_t b = a + 1; b < m; ++b) {
            double c = 0;
            for (std::size_t s = a + 1; s < b; ++s) {
                const double dv = deviation(at(a), at(b), at(s));
                c += dv * dv;
            }
            cost[a * m + b] = c;
        }
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<double> best((k + 1) * m, inf);
    std::vector<std::size_t> from((k + 1) * m, 0);
    best[0] = 0;
    for (int j = 1; j <= k; ++j)
        for (std::size_t b = 1; b < m; ++b)
            for (std::size_t a = 0; a < b; ++a) {
                const double c = best[(j - 1) * m + a] + cost[a * m + b];
                if (c < best[j * m + b]) {
                    best[j * m + b] = c;
                    from[j * m + b] = a;
                }
            }
    std::vector<std::size_t> cuts{m - 1};
    for (int j = k; j > 0; --j) cuts.push_back(from[j * m + cuts.back()]);
    std::reverse(cuts.begin(), cuts.end());
    for (std::size_t c = 0; c + 1 < cuts.size(); ++c)
        for (std::size_t s = cuts[c] + 1; s < cuts[c + 1]; ++s)
            f.worst = std::max(f.worst, deviation(at(cuts[c]), at(cuts[c + 1]), at(s)) / std::max(at(s)[3], 1e-9));
    for (std::size_t c : cuts) f.cuts.push_back(sample[c]);
    return f;
}

std::size_t place_joint(const Chain4& chain, const std::vector<double>& arc, std::size_t a, std::size_t b,
                        double frac, double extra) {
    const double len = arc[b] - arc[a] + extra, target = arc[a] + frac * len, w = 0.2 * len;
    auto index_at = [&](double x) {
        const auto it = std::lower_bound(arc.begin() + static_cast<std::ptrdiff_t>(a),
                                         arc.begin() + static_cast<std::ptrdiff_t>(b) + 1, x);
        return std::min<std::size_t>(static_cast<std::size_t>(it - arc.begin()), b);
    };
    std::size_t best = std::clamp(index_at(target), a + 1, b - 1);
    double best_bend = 0.15;
    for (std::size_t c = std::max(a + 1, index_at(target - w)); c <= index_at(target + w) && c < b; ++c) {
        const double bend = deviation(chain[a], chain[b], chain[c]) / std::max(chain[c][3], 1e-9);
        if (bend > best_bend) {
            best_bend = bend;
            best = c;
        }
    }
    return best;
}

Fit limb_fit(const Chain4& chain, bool arm) {
    Fit f = fit_chain(chain, arm ? 2 : 3);
    if (f.cuts.size() != (arm ? 3u : 4u) || chain.size() < 8) return Fit{};
    const std::vector<double> arc = arc_of(chain);
    const std::size_t end = chain.size() - 1;
    if (arm) {
        const std::size_t sh = f.cuts[1];
        if (end - sh < 4) return Fit{};
        const double extra = chain[end][3];
        const std::size_t elbow = std::clamp(place_joint(chain, arc, sh, end, 0.186 / 0.44, extra), sh + 1, end - 2);
        // The wrist at its proportion of the whole arm, measured from the elbow now placed.
        const double whole = arc[end] - arc[sh] + extra;
        const double from_elbow = (0.332 / 0.44 * whole - (arc[elbow] - arc[sh])) / (arc[end] - arc[elbow] + extra);
        const std::size_t wrist = std::clamp(place_joint(chain, arc, elbow, end, from_elbow, extra), elbow + 1, end - 1);
        f.cuts = {0, sh, elbow, wrist, end};
    } else {
        const std::size_t hip = f.cuts[1], ankle = f.cuts[2];
        if (ankle - hip < 3) return Fit{};
        const std::size_t knee = std::clamp(place_joint(chain, arc, hip, ankle, 0.5, 0.0), hip + 1, ankle - 1);
        f.cuts = {0, hip, knee, ankle, end};
    }
    return f;
}

}  // namespace volrig::rigging

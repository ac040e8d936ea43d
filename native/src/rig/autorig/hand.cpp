// rig/autorig/hand.cpp: the hand template: five finger chains on a palm and a wrist stub (see templates.hpp).
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "rig/autorig/templates.hpp"

namespace volrig::rig_detail {

namespace {

constexpr int kHandLeaves = 8;  // the wrist and five fingers are chosen among this many most significant leaves

/// The palm centre of a wrist and some fingers: the node, on the path from the wrist, where the first finger
/// leaves it (the fingers' junction nearest the wrist).
std::uint32_t palm_centre(const NodeTree& t, std::uint32_t wrist, const std::vector<std::uint32_t>& fingers) {
    std::uint32_t c = fingers[0];
    for (std::size_t k = 1; k < fingers.size(); ++k) c = t.median(wrist, c, fingers[k]);
    return c;
}

/// (max - min) / max of positive values: 0 when all are equal.
double spread(const std::vector<double>& v) {
    const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
    return *hi > 0 ? (*hi - *lo) / *hi : 1.0;
}

/// The thumb among five fingers: the one whose base (where it joins the path from the wrist to the others' palm
/// centre) lies farthest from that centre; on a tie, the one pointing farthest from the others' mean direction.
std::size_t find_thumb(const NodeTree& t, std::uint32_t wrist, const std::array<std::uint32_t, 5>& f) {
    std::size_t best = 0;
    double best_key = -1;
    for (std::size_t i = 0; i < 5; ++i) {
        std::vector<std::uint32_t> others;
        for (std::size_t k = 0; k < 5; ++k)
            if (k != i) others.push_back(f[k]);
        const std::uint32_t c = palm_centre(t, wrist, others), base = t.median(wrist, c, f[i]);
        Vec mean = Vec::Zero();
        for (std::uint32_t o : others) mean += (t.at(o) - t.at(c)).normalized();
        const double opposed = 1.0 - mean.normalized().dot((t.at(f[i]) - t.at(c)).normalized());
        const double key = (t.at(base) - t.at(c)).norm() + 1e-3 * opposed * t.radius(c);
        if (key > best_key) {
            best_key = key;
            best = i;
        }
    }
    return best;
}

/// The penalty of a wrist and five fingers (thumb first) read as a hand, 0 = perfect; fills plan's palm and
/// finger order (thumb, then across the palm away from it: index, middle, ring, pinky).
double hand_penalty(const NodeTree& t, std::uint32_t wrist, const std::array<std::uint32_t, 5>& f, HandPlan& plan) {
    const std::vector<std::uint32_t> four(f.begin() + 1, f.end());
    const std::uint32_t c = palm_centre(t, wrist, four), thumb_base = t.median(wrist, c, f[0]);
    const Vec up = (t.at(c) - t.at(wrist)).normalized();
    std::vector<double> len, rad;
    double apart = 0, backwards = 0;
    for (std::uint32_t x : four) {
        const std::vector<std::uint32_t> p = t.path(c, x);
        len.push_back(t.length(p));
        rad.push_back(t.mean_radius(p));
        apart = std::max(apart, (t.at(t.median(wrist, c, x)) - t.at(c)).norm());  // a base off the palm centre
        backwards += std::max(0.0, -(t.at(x) - t.at(c)).normalized().dot(up) + 0.3);  // fingers leave the wrist
    }
    const double finger = std::accumulate(len.begin(), len.end(), 0.0) / 4.0;
    const double stub = t.length(t.path(wrist, c));
    double score = 0.5 * spread(len) + 0.5 * spread(rad) + apart / finger + 0.5 * backwards;
    const double wrist_radius = t.mean_radius(t.path(wrist, c));
    if (wrist_radius < *std::max_element(rad.begin(), rad.end())) score += 0.25;  // a thick wrist
    // A palm is a plate, not a body several times thicker than its legs (a camel's hump, body and legs).
    score += std::max(0.0, t.radius(c) / (0.25 * std::accumulate(rad.begin(), rad.end(), 0.0)) - kPalmThickness);
    // A thumb no longer than one and a half fingers, thinner than the wrist.
    const std::vector<std::uint32_t> thumb = t.path(thumb_base, f[0]);
    score += std::max(0.0, t.length(thumb) / finger - 1.5);
    if (t.mean_radius(thumb) > wrist_radius) score += 0.25;
    if (stub > 2.0 * finger) score += 0.5 * (stub / finger - 2.0);  // a wrist stub, not a whole arm
    // The thumb joins between the wrist and the palm centre.
    if (thumb_base != c && (t.at(thumb_base) - t.at(wrist)).dot(up) > (t.at(c) - t.at(wrist)).dot(up)) score += 0.25;
    const Vec across = perp(t.at(f[0]) - t.at(c), up);
    std::array<std::uint32_t, 4> order{f[1], f[2], f[3], f[4]};
    std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
        return (t.at(a) - t.at(c)).dot(across) > (t.at(b) - t.at(c)).dot(across);
    });
    plan.wrist = wrist;
    plan.palm = c;
    plan.fingers = {f[0], order[0], order[1], order[2], order[3]};
    return score;
}

/// A digit from where it leaves the palm (chain index 0) to its tip cut into three bones: at the bends of a
/// piecewise-linear fit when the digit is clearly bent (a straight bone leaves a node a radius off), else at
/// `joints`, the two inner joints' fractions of the length to the tip (skin included). Empty cuts when the chain
/// is too short.
std::vector<std::size_t> phalanges(const Chain4& chain, const std::array<double, 2>& joints) {
    if (chain.size() < 4) return {};
    if (fit_chain(chain, 1).worst > 1.0) return fit_chain(chain, 3).cuts;
    const std::vector<double> arc = arc_of(chain);
    const std::size_t end = chain.size() - 1;
    const double whole = arc[end] + chain[end][3];  // the skin beyond the last node
    auto at = [&](double frac) {
        return static_cast<std::size_t>(std::lower_bound(arc.begin(), arc.end(), frac * whole) - arc.begin());
    };
    const std::size_t first = std::clamp<std::size_t>(at(joints[0]), 1, end - 2);
    return {0, first, std::clamp<std::size_t>(at(joints[1]), first + 1, end - 1), end};
}

/// A bone-name suffix for the hand's side: the thumb lies on the palm's side of the plane of the wrist, the palm
/// centre and the other fingers' tips; with the fingers up and the palm towards the viewer, a left hand's thumb is
/// on the viewer's left. "" when the thumb's tip lies within its radius of that plane (a flat hand: no side).
std::string side_suffix(const NodeTree& t, const HandPlan& p) {
    const Vec c = t.at(p.palm), up = (c - t.at(p.wrist)).normalized();
    const Vec across = perp(t.at(p.fingers[1]) - t.at(p.fingers[4]), up);  // pinky to index: the thumb's side
    const Vec normal = up.cross(across).normalized();
    const double off = (t.at(p.fingers[0]) - c).dot(normal);
    if (std::abs(off) < t.end_radius(p.fingers[0])) return "";
    return off > 0 ? ".L" : ".R";
}

}  // namespace

HandPlan search_hand(const NodeTree& t) {
    HandPlan best;
    const auto ext = t.extremities();
    if (ext.size() < 6) return best;
    const int m = static_cast<int>(std::min<std::size_t>(ext.size(), kHandLeaves));
    double total = 0;
    for (int i = 0; i < m; ++i) total += std::max(ext[static_cast<std::size_t>(i)].first, 0.0);
    for (int mask = 0; mask < (1 << m); ++mask) {
        if (__builtin_popcount(static_cast<unsigned>(mask)) != 6) continue;
        std::vector<std::uint32_t> six;
        double left_out = 0;
        for (int i = 0; i < m; ++i) {
            const auto& [significance, node] = ext[static_cast<std::size_t>(i)];
            if (mask & (1 << i)) six.push_back(node);
            else left_out += std::max(significance, 0.0);
        }
        if (!spans_object(t, six)) continue;  // a hand at the end of an arm: the arm is no wrist stub
        for (std::size_t w = 0; w < 6; ++w) {
            std::array<std::uint32_t, 5> f{};
            for (std::size_t k = 0, n = 0; k < 6; ++k)
                if (k != w) f[n++] = six[k];
            std::swap(f[0], f[find_thumb(t, six[w], f)]);
            HandPlan plan;
            plan.score = hand_penalty(t, six[w], f, plan) + (total > 0 ? left_out / total : 0.0);
            if (plan.score < best.score) best = plan;
        }
    }
    return best;
}

double hand_plan_score(const HandPlan& plan, const std::vector<double>& w) {
    if (!std::isfinite(plan.score)) return plan.score;
    PlanFeatures f{};
    f[kBiasHand] = 1;
    f[kHandShape] = plan.score;
    return plan_score(f, w);
}

Candidate hand_rig(const RigContext& c, const HandPlan& p) {
    const NodeTree& t = c.tree;
    if (!std::isfinite(p.score)) return Candidate{};
    static const char* const kFingers[5] = {"thumb", "f_index", "f_middle", "f_ring", "f_pinky"};
    const std::string side = side_suffix(t, p);
    RigBuilder b(c);
    const std::vector<std::uint32_t> palm = t.path(p.wrist, p.palm);
    if (palm.size() < 2) return Candidate{};
    b.chain(palm, {0, palm.size() - 1}, {"palm" + side});
    for (int k = 0; k < 5; ++k) {
        // From where the digit leaves the palm (the bend where its path from the palm turns into it): the thumb's
        // metacarpal and two phalanges, a finger's three phalanges. Proportions of the bones' lengths (Buryanov
        // and Kotiuk 2010): thumb 46 : 32 : 24, fingers about 0.5 : 0.29 : 0.21.
        const std::uint32_t from = k == 0 ? t.median(p.wrist, p.palm, p.fingers[0]) : p.palm;
        std::vector<std::uint32_t> path = t.path(from, p.fingers[k]);
        const Fit leaves = fit_chain(c.samples(path), 2);
        if (leaves.cuts.size() != 3) return Candidate{};
        path.erase(path.begin(), path.begin() + static_cast<std::ptrdiff_t>(leaves.cuts[1]));
        const std::vector<std::size_t> cuts =
            phalanges(c.samples(path), k == 0 ? std::array{0.45, 0.76} : std::array{0.5, 0.79});
        if (cuts.size() != 4) return Candidate{};
        const std::string base = std::string(kFingers[k]) + ".0";
        b.chain(path, cuts, {base + "1" + side, base + "2" + side, base + "3" + side}, 0);
    }
    Candidate out;
    out.rig = b.finish("hand");
    return out;
}

}  // namespace volrig::rig_detail

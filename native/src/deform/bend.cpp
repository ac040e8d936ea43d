#include "deform/bend.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <map>

namespace volrig::deform_detail {

namespace {

const double kPi = std::acos(-1.0);

/// The group's two heaviest bones (ties to the lower bone), in bone order, with their weights.
void two_heaviest(const Weights& w, BendGroup& bg) {
    Weights top = w;
    std::stable_sort(top.begin(), top.end(), [](const auto& x, const auto& y) { return x.second > y.second; });
    auto [a, qa] = top[0];
    auto [b, qb] = top[1];
    if (a > b) {
        std::swap(a, b);
        std::swap(qa, qb);
    }
    bg.a = a;
    bg.b = b;
    bg.w = static_cast<double>(qb) / static_cast<double>(qa + qb);
    bg.junction = w.size() > 2;
}

/// The side(s) of the joint a group's slab lies on: 1 = a (w < 1/2), 2 = b (w > 1/2), 3 = both (w = 1/2).
int sides_of(const BendGroup& bg) { return bg.w < 0.5 ? 1 : (bg.w > 0.5 ? 2 : 3); }

/// Per pair and side, the least-squares gradient of w over the centres (world) of the side's blended spheres.
std::vector<std::array<Eigen::Vector3d, 2>> pair_gradients(const BoundSpheres& s, const SmoothGroups& groups,
                                                           const BendModel& m, std::size_t pairs, const Grid& g) {
    auto centre = [&](std::size_t i) {
        return Eigen::Vector3d(g.origin[0] + g.spacing[0] * s.ijk[3 * i + 2], g.origin[1] + g.spacing[1] * s.ijk[3 * i + 1],
                               g.origin[2] + g.spacing[2] * s.ijk[3 * i]);
    };
    auto group = [&](std::size_t i) -> const BendGroup* {
        if (groups.group_of[i] < 0) return nullptr;
        const BendGroup& bg = m.groups[static_cast<std::size_t>(groups.group_of[i])];
        return bg.a < 0 ? nullptr : &bg;
    };
    const std::size_t slots = 2 * pairs;  // slot 2p + side
    std::vector<Eigen::Vector3d> mean(slots, Eigen::Vector3d::Zero()), cw(slots, Eigen::Vector3d::Zero());
    std::vector<double> wmean(slots, 0.0), count(slots, 0.0);
    std::vector<Eigen::Matrix3d> cov(slots, Eigen::Matrix3d::Zero());
    for (int pass = 0; pass < 2; ++pass)
        for (std::size_t i = 0; i < s.n; ++i) {
            const BendGroup* bg = group(i);
            if (!bg) continue;
            for (std::size_t side = 0; side < 2; ++side) {
                if (!(sides_of(*bg) & (1 << side))) continue;
                const std::size_t k = 2 * bg->pair + side;
                if (pass == 0) {
                    mean[k] += centre(i);
                    wmean[k] += bg->w;
                    count[k] += 1;
                    continue;
                }
                const Eigen::Vector3d x = centre(i) - mean[k] / count[k];
                cov[k] += x * x.transpose();
                cw[k] += x * (bg->w - wmean[k] / count[k]);
            }
        }
    std::vector<std::array<Eigen::Vector3d, 2>> grad(pairs, {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()});
    for (std::size_t k = 0; k < slots; ++k) {
        if (count[k] < 2) continue;
        Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov[k], Eigen::ComputeFullU | Eigen::ComputeFullV);
        svd.setThreshold(1e-9);  // collinear centres (a tube's axis alone): the gradient along their line
        grad[k / 2][k % 2] = svd.solve(cw[k]);
    }
    return grad;
}

/// A bisector plane: through `joint`, unit `normal` pointing to b's side; `valid` false where it is not defined.
struct Plane {
    Eigen::Vector3d joint = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::Zero();
    bool valid = false;
};

/// Per pair, the joint's centre by the weights: the mean centre (world) of the blended spheres within 1/16 of w = ½
/// (of all the pair's blended spheres when there are none).
std::vector<Eigen::Vector3d> pair_centres(const BoundSpheres& s, const SmoothGroups& groups, const BendModel& m,
                                          std::size_t pairs, const Grid& g) {
    std::vector<Eigen::Vector3d> near(pairs, Eigen::Vector3d::Zero()), all(pairs, Eigen::Vector3d::Zero());
    std::vector<double> n_near(pairs, 0.0), n_all(pairs, 0.0);
    for (std::size_t i = 0; i < s.n; ++i) {
        if (groups.group_of[i] < 0) continue;
        const BendGroup& bg = m.groups[static_cast<std::size_t>(groups.group_of[i])];
        if (bg.a < 0) continue;
        const Eigen::Vector3d c(g.origin[0] + g.spacing[0] * s.ijk[3 * i + 2], g.origin[1] + g.spacing[1] * s.ijk[3 * i + 1],
                                g.origin[2] + g.spacing[2] * s.ijk[3 * i]);
        all[bg.pair] += c;
        n_all[bg.pair] += 1;
        if (std::abs(bg.w - 0.5) <= 1.0 / 16 + 1e-12) {
            near[bg.pair] += c;
            n_near[bg.pair] += 1;
        }
    }
    for (std::size_t p = 0; p < pairs; ++p) near[p] = n_near[p] > 0 ? near[p] / n_near[p] : all[p] / n_all[p];
    return near;
}

/// The plane through `joint` that mirrors the arms leaving it along `arm_a` and `arm_b` (unit) onto each other, its
/// normal towards arm b; not defined when the arms coincide. A twist of a limb about its own axis leaves it across the
/// limb, so that only a bend makes slabs cross it.
Plane bisector(const Eigen::Vector3d& joint, const Eigen::Vector3d& arm_a, const Eigen::Vector3d& arm_b) {
    Plane p;
    p.joint = joint;
    const Eigen::Vector3d n = arm_b - arm_a;
    if (!(n.norm() > 1e-9)) return p;
    p.normal = n.normalized();
    p.valid = true;
    return p;
}

/// The bend of one bone pair in this pose: per side the limb's rest axis, its rate (|gradient|) and radius, the
/// joint's centre, and the bend's bisector plane posed and at rest.
struct PairPose {
    std::array<Eigen::Vector3d, 2> t{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
    std::array<double, 2> rate{0, 0};
    std::array<double, 2> radius{0, 0};
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // rest
    Plane posed, rest;
    double bend = 0;  // how much the arms' angle closed from rest (radians, >= 0)
};

/// The angle between two unit vectors.
double angle(const Eigen::Vector3d& u, const Eigen::Vector3d& v) { return std::acos(std::clamp(u.dot(v), -1.0, 1.0)); }

PairPose pair_pose(const BendModel& m, std::size_t pair, std::int32_t a, std::int32_t b,
                   const std::vector<Motion>& bones, DeformMode mode) {
    PairPose p;
    p.radius = m.radius[pair];
    p.centre = m.centre[pair];
    for (std::size_t side = 0; side < 2; ++side) {
        p.rate[side] = m.gradient[pair][side].norm();
        if (p.rate[side] > 0) p.t[side] = m.gradient[pair][side] / p.rate[side];
    }
    if (!(p.rate[0] > 0) || !(p.rate[1] > 0)) return p;
    // the arms leave the joint's centre along -t_a and t_b at rest, turned by their bones' rotations in the pose;
    // the centre moves with the half-way blend
    const Rigid half = blend_rigid(bones, {{a, 0.5}, {b, 0.5}}, a, mode, p.centre);
    const Eigen::Matrix3d& Ra = bones[static_cast<std::size_t>(a)].R;
    const Eigen::Matrix3d& Rb = bones[static_cast<std::size_t>(b)].R;
    p.rest = bisector(p.centre, -p.t[0], p.t[1]);
    p.posed = bisector(half.R * p.centre + half.d, -(Ra * p.t[0]), Rb * p.t[1]);
    p.bend = std::max(0.0, angle(-p.t[0], p.t[1]) - angle(-(Ra * p.t[0]), Rb * p.t[1]));
    return p;
}

/// The bisector's signed distance, in radii, from the centre of a disc of radius R centred at P with axis `axis`,
/// measured in the disc (positive: the centre lies on its own side, a's when `side_a`); inf when it does not cut.
double crossing(const Plane& pl, const Eigen::Vector3d& P, const Eigen::Vector3d& axis, bool side_a, double R) {
    if (!pl.valid) return kInf;
    const double own = (side_a ? -1.0 : 1.0) * pl.normal.dot(P - pl.joint);
    const double c = pl.normal.dot(axis), q = std::sqrt(std::max(0.0, 1 - c * c));
    return q > 1e-9 ? own / q / R : (own >= 0 ? kInf : -kInf);
}

/// Whether the bend model cuts a group's slab off at the bisector: a two-bone group on one side of the joint, within
/// two limb radii of the joint's centre and wholly on its own side at rest (a limb straight there, or bent less
/// than its thickness allows); elsewhere (shoulders, hips, limbs bent at rest, the joint's own slab on the bisector)
/// only the slab's stretch counts.
bool cut_by_bisector(const BendGroup& bg, const PairPose& pp, const Eigen::Vector3d& pivot) {
    if (bg.a < 0 || bg.junction || bg.w == 0.5 || !(bg.radius > 0)) return false;
    const auto side = static_cast<std::size_t>(bg.w < 0.5 ? 0 : 1);
    const double R = pp.radius[side];
    if (!(pp.rate[side] > 0) || !((pivot - pp.centre).norm() <= 2 * R)) return false;
    return crossing(pp.rest, pivot, pp.t[side], side == 0, R) >= 1;
}

/// The factor of one group: its slab's stretch along its posed axis (finite differences of the two-bone blend
/// along its side's rest axis) and the posed bisector's distance in its disc.
double group_factor(const BendGroup& bg, const PairPose& pp, const std::vector<Motion>& bones, std::int32_t owner,
                    DeformMode mode, const Eigen::Vector3d& pivot) {
    const int side = bg.w < 0.5 ? 0 : 1;
    Eigen::Vector3d t = pp.t[static_cast<std::size_t>(side)];
    double rate = pp.rate[static_cast<std::size_t>(side)];
    if (bg.w == 0.5) {  // on the joint plane: between the two sides' axes
        t = (pp.t[0] + pp.t[1]).normalized();
        rate = 0.5 * (pp.rate[0] + pp.rate[1]);
    }
    if (bg.a < 0 || bg.junction || !(rate > 0) || !(t.norm() > 0.5) || !(bg.radius > 0)) return 1.0;
    auto blend = [&](double w) { return blend_rigid(bones, {{bg.a, 1 - w}, {bg.b, w}}, owner, mode, pivot); };
    const double eps = std::min({1.0 / 64, 0.5 * bg.w, 0.5 * (1 - bg.w)}), ds = eps / rate;
    const Rigid r0 = blend(bg.w), lo = blend(bg.w - eps), hi = blend(bg.w + eps);
    const Eigen::Vector3d axis = r0.R * t;
    const Eigen::Vector3d dp = (hi.R * (pivot + ds * t) + hi.d - lo.R * (pivot - ds * t) - lo.d) / (2 * ds);
    const double stretch = std::clamp(dp.dot(axis), 0.25, 4.0);
    if (!cut_by_bisector(bg, pp, pivot)) return slab_factor(kInf, stretch);
    const double R = pp.radius[static_cast<std::size_t>(side)];
    return slab_factor(crossing(pp.posed, r0.R * pivot + r0.d, axis, side == 0, R), stretch);
}

/// Whether a limb is straight at its joint at rest: its arms leave the joint's centre more than 120 degrees apart.
bool straight_at_rest(const PairPose& pp) {
    return pp.rest.valid && pp.posed.valid && pp.t[0].dot(pp.t[1]) > 0.5;
}

/// A field's contact plane: the posed bisector, its normal towards b's side when the field is a's (`side_a`). Its
/// zone grows with the bend β from nothing at rest: two tubes of radius R bent by β overlap within R·tan(β/2) of
/// the joint along the limb; the zone reaches twice that, at most four limb radii.
Contact contact_of(const PairPose& pp, bool side_a, const Grid& g) {
    Contact c;
    const double reach = std::min(4.0, 2 * std::tan(std::min(pp.bend, 3.0) / 2)) * std::max(pp.radius[0], pp.radius[1]);
    c.reach2 = reach * reach;
    for (int a = 0; a < 3; ++a) {
        c.joint[a] = (pp.posed.joint[a] - g.origin[static_cast<std::size_t>(a)]) / g.spacing[static_cast<std::size_t>(a)];
        c.normal[a] = (side_a ? 1.0 : -1.0) * pp.posed.normal[a] * g.spacing[static_cast<std::size_t>(a)];
    }
    return c;
}

}  // namespace

double disc_segment(double y) {
    if (!(y < 1)) return 0.0;
    if (!(y > -1)) return kPi;
    return std::acos(y) - y * std::sqrt(1 - y * y);
}

double slab_factor(double x, double stretch) {
    if (x >= kMaxBend && std::abs(stretch - 1) <= 1e-9) return 1.0;
    auto kept = [&](double g) { return stretch * g * g * (kPi - disc_segment(x / g)); };  // grows with g
    if (kept(kMaxBend) <= kPi) return kMaxBend;
    if (kept(kMinBend) >= kPi) return kMinBend;
    double lo = kMinBend, hi = kMaxBend;
    for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        (kept(mid) < kPi ? lo : hi) = mid;
    }
    const double g = 0.5 * (lo + hi);
    return std::abs(g - 1) <= 1e-9 ? 1.0 : g;
}

BendModel bend_model(const BoundSpheres& s, const SmoothGroups& groups, const std::vector<double>& radii,
                     const Grid& g) {
    BendModel m;
    m.groups.resize(groups.weights.size());
    std::map<std::pair<std::int32_t, std::int32_t>, std::size_t> pairs;
    for (std::size_t k = 0; k < groups.weights.size(); ++k) {
        if (groups.weights[k].size() < 2) continue;
        BendGroup& bg = m.groups[k];
        two_heaviest(groups.weights[k], bg);
        bg.pair = pairs.try_emplace({bg.a, bg.b}, pairs.size()).first->second;
    }
    for (std::size_t i = 0; i < s.n; ++i)
        if (groups.group_of[i] >= 0) {
            BendGroup& bg = m.groups[static_cast<std::size_t>(groups.group_of[i])];
            bg.radius = std::max(bg.radius, radii[i]);
        }
    m.gradient = pair_gradients(s, groups, m, pairs.size(), g);
    m.centre = pair_centres(s, groups, m, pairs.size(), g);
    m.radius.assign(pairs.size(), {0.0, 0.0});
    for (const BendGroup& bg : m.groups)
        for (std::size_t side = 0; bg.a >= 0 && side < 2; ++side)
            if (sides_of(bg) & (1 << side)) m.radius[bg.pair][side] = std::max(m.radius[bg.pair][side], bg.radius);
    return m;
}

namespace {

/// Every bone pair's bend in this pose (its two bones from the first two-bone group of the pair).
std::vector<PairPose> pair_poses(const BendModel& m, const std::vector<Motion>& bones, DeformMode mode) {
    std::vector<PairPose> poses(m.gradient.size());
    std::vector<bool> posed(m.gradient.size(), false);
    for (const BendGroup& bg : m.groups)
        if (bg.a >= 0 && !posed[bg.pair]) {
            poses[bg.pair] = pair_pose(m, bg.pair, bg.a, bg.b, bones, mode);
            posed[bg.pair] = true;
        }
    return poses;
}

}  // namespace

std::vector<double> bend_factors(const BendModel& m, const SmoothGroups& groups, const std::vector<Motion>& bones,
                                 DeformMode mode) {
    const std::vector<PairPose> poses = pair_poses(m, bones, mode);
    std::vector<double> f(m.groups.size(), 1.0);
    for (std::size_t k = 0; k < m.groups.size(); ++k) {
        const BendGroup& bg = m.groups[k];
        if (bg.a >= 0) f[k] = group_factor(bg, poses[bg.pair], bones, groups.owner[k], mode, groups.pivot[k]);
    }
    return f;
}

FieldContacts contacts(const BendModel& m, const SmoothGroups& groups, const std::vector<Motion>& bones,
                       DeformMode mode, std::size_t bone_count, const Grid& g) {
    FieldContacts fc(bone_count + m.groups.size());
    const std::vector<PairPose> poses = pair_poses(m, bones, mode);
    auto touching = [&](const BendGroup& bg) {  // a pair whose limb is straight at rest and bent now
        return bg.a >= 0 && straight_at_rest(poses[bg.pair]) && poses[bg.pair].bend > 0;
    };
    std::vector<bool> done(poses.size(), false);
    for (std::size_t k = 0; k < m.groups.size(); ++k) {
        const BendGroup& bg = m.groups[k];
        if (!touching(bg)) continue;
        const PairPose& pp = poses[bg.pair];
        if (!done[bg.pair]) {  // the pair's two bones, once
            done[bg.pair] = true;
            fc[static_cast<std::size_t>(bg.a)].push_back(contact_of(pp, true, g));
            fc[static_cast<std::size_t>(bg.b)].push_back(contact_of(pp, false, g));
        }
        if (cut_by_bisector(bg, pp, groups.pivot[k])) fc[bone_count + k].push_back(contact_of(pp, bg.w < 0.5, g));
    }
    return fc;
}

void bend_radii(const BoundSpheres& s, const SmoothGroups& groups, const std::vector<Motion>& bones, DeformMode mode,
                const Grid& g, std::vector<double>& radii) {
    bend_radii(bend_model(s, groups, radii, g), s, groups, bones, mode, radii);
}

void bend_radii(const BendModel& m, const BoundSpheres& s, const SmoothGroups& groups,
                const std::vector<Motion>& bones, DeformMode mode, std::vector<double>& radii) {
    const std::vector<double> f = bend_factors(m, groups, bones, mode);
    for (std::size_t i = 0; i < s.n; ++i)
        if (groups.group_of[i] >= 0) radii[i] = bent_radius(radii[i], f[static_cast<std::size_t>(groups.group_of[i])]);
}

}  // namespace volrig::deform_detail

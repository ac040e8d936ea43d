// rig/autorig/markers.cpp: markers the user placed, as roles for the body-plan search and as joint positions on
// its rig (see templates.hpp).
#include <algorithm>
#include <cmath>

#include "rig/autorig/templates.hpp"

namespace volrig::rig_detail {

namespace {

/// The joint a marker names: the head (end 0) or tail (end 1) of a bone; a chin names the head bone's head (the
/// head joint, at the chin's height, centred in the neck: where ray_marker puts a click on the chin), a groin the
/// hips bone's head (the root, where the legs' bones fork).
struct MarkedJoint {
    const char* bone;
    int end;
};

/// The marker's name without its side suffix, and the suffix (".L", ".R" or "").
std::pair<std::string, std::string> split_side(const std::string& name) {
    if (name.size() > 2 && (name.compare(name.size() - 2, 2, ".L") == 0 || name.compare(name.size() - 2, 2, ".R") == 0))
        return {name.substr(0, name.size() - 2), name.substr(name.size() - 2)};
    return {name, ""};
}

MarkedJoint marked_joint(const std::string& base) {
    static const std::pair<const char*, MarkedJoint> kJoints[] = {
        {"chin", {"head", 0}},         {"neck", {"neck", 0}},    {"head_top", {"head", 1}},
        {"shoulder", {"upper_arm", 0}}, {"elbow", {"forearm", 0}}, {"wrist", {"hand", 0}},
        {"hand_tip", {"hand", 1}},     {"hip", {"thigh", 0}},    {"knee", {"shin", 0}},
        {"ankle", {"foot", 0}},        {"toe", {"foot", 1}},     {"groin", {"hips", 0}}};
    for (const auto& [n, j] : kJoints)
        if (base == n) return j;
    return {nullptr, 0};
}

double segment_distance(const Vec& p, const Vec& a, const Vec& b) {
    const Vec ab = b - a;
    const double t = ab.squaredNorm() > 0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
    return (p - (a + t * ab)).norm();
}

/// Distance from p to the bones of one limb side (e.g. upper_arm.L, forearm.L, hand.L), infinity when none.
double limb_distance(const Rig& rig, const Vec& p, const std::vector<std::string>& bones, const std::string& side) {
    double d = std::numeric_limits<double>::infinity();
    for (const std::string& name : bones)
        if (const std::int32_t b = bone_index(rig, name + side); b >= 0)
            d = std::min(d, segment_distance(p, bone_end(rig, static_cast<std::size_t>(b), 0),
                                             bone_end(rig, static_cast<std::size_t>(b), 1)));
    return d;
}

/// Swaps .L and .R of a limb's bones when more of its sided markers lie nearer the other side's bones.
void side_limb(Rig& rig, const std::vector<std::pair<std::string, Vec>>& markers, const std::vector<std::string>& bones,
               RoleMarker::Role role) {
    int agree = 0, disagree = 0;
    for (const auto& [name, at] : markers) {
        const auto [base, side] = split_side(name);
        if (side.empty() || marker_role(name) != role) continue;
        const std::string other = side == ".L" ? ".R" : ".L";
        (limb_distance(rig, at, bones, side) <= limb_distance(rig, at, bones, other) ? agree : disagree) += 1;
    }
    if (disagree <= agree) return;
    for (const std::string& b : bones) {
        const std::int32_t l = bone_index(rig, b + ".L"), r = bone_index(rig, b + ".R");
        if (l >= 0 && r >= 0) std::swap(rig.names[static_cast<std::size_t>(l)], rig.names[static_cast<std::size_t>(r)]);
    }
}

/// Whether a marker of this name was given.
bool marked(const std::vector<std::pair<std::string, Vec>>& markers, const std::string& name) {
    return std::any_of(markers.begin(), markers.end(), [&](const auto& m) { return m.first == name; });
}

/// The share along limb `first`'s head to limb `second`'s tail at which q lies (0.5 when they coincide).
double share_along(const Rig& rig, std::int32_t first, std::int32_t second, const Vec& q) {
    const Vec s = bone_end(rig, static_cast<std::size_t>(first), 0), e = bone_end(rig, static_cast<std::size_t>(second), 1);
    return (e - s).squaredNorm() > 0 ? (q - s).dot(e - s) / (e - s).squaredNorm() : 0.5;
}

/// The unmarked side's middle joint (a knee, an elbow: the tail of `proximal`) moved along its limb's line to the
/// share at which the marked side's lies between hip and ankle (shoulder and wrist), its offset off that line (a
/// bent knee's) kept: a body's two legs (arms) have the same proportions, and the marked one's are the user's.
void match_middle(Rig& rig, const std::vector<std::pair<std::string, Vec>>& markers, const std::string& marker,
                  const std::string& proximal, const std::string& distal) {
    for (const std::string side : {".L", ".R"}) {
        const std::string other = side == ".L" ? ".R" : ".L";
        if (!marked(markers, marker + side) || marked(markers, marker + other)) continue;
        const std::int32_t p = bone_index(rig, proximal + side), d = bone_index(rig, distal + side);
        const std::int32_t po = bone_index(rig, proximal + other), dd = bone_index(rig, distal + other);
        if (p < 0 || d < 0 || po < 0 || dd < 0) return;
        const double want = share_along(rig, p, d, bone_end(rig, static_cast<std::size_t>(p), 1));
        const Vec now = bone_end(rig, static_cast<std::size_t>(po), 1);
        const Vec line = bone_end(rig, static_cast<std::size_t>(dd), 1) - bone_end(rig, static_cast<std::size_t>(po), 0);
        move_joint(rig, rig.bones[static_cast<std::size_t>(po)][1], now + (want - share_along(rig, po, dd, now)) * line);
    }
}

}  // namespace

RoleMarker::Role marker_role(const std::string& name) {
    if (std::none_of(kMarkerNames.begin(), kMarkerNames.end(), [&](const char* n) { return name == n; })) {
        std::string known;
        for (const char* n : kMarkerNames) known += std::string(known.empty() ? "" : ", ") + n;
        throw Error("autorig: unknown marker '" + name + "' (markers: " + known + ")");
    }
    const std::string base = split_side(name).first;
    if (base == "chin" || base == "neck" || base == "head_top") return RoleMarker::Head;
    if (base == "groin") return RoleMarker::Pelvis;
    if (base == "shoulder" || base == "elbow" || base == "wrist" || base == "hand_tip") return RoleMarker::Arm;
    return RoleMarker::Leg;
}

void apply_markers(Rig& rig, const std::vector<std::pair<std::string, Vec>>& markers) {
    side_limb(rig, markers, {"shoulder", "upper_arm", "forearm", "hand"}, RoleMarker::Arm);
    side_limb(rig, markers, {"pelvis", "thigh", "shin", "foot"}, RoleMarker::Leg);
    for (const auto& [name, at] : markers) {
        const auto [base, side] = split_side(name);
        const MarkedJoint mj = marked_joint(base);
        if (!mj.bone) continue;
        const std::int32_t b = bone_index(rig, mj.bone + side);
        if (b < 0) continue;
        const std::int32_t j = rig.bones[static_cast<std::size_t>(b)][static_cast<std::size_t>(mj.end)];
        move_joint(rig, j, at);
    }
    match_middle(rig, markers, "knee", "thigh", "shin");
    match_middle(rig, markers, "elbow", "upper_arm", "forearm");
}

}  // namespace volrig::rig_detail

// volrig/mocap.hpp: motion capture in: the Biovision Hierarchy (BVH) reader.
//
// The reader follows volrig/io.hpp's rules: it validates everything it reads and every error is a FileFormatError
// (or FileNotFound) whose message starts with the file name and names the line and the problem
// ("131_01.bvh: line 190: frame 3 has 92 numbers but the hierarchy has 93 channels"). It checks the nesting of
// HIERARCHY / ROOT / JOINT / End Site / OFFSET / CHANNELS, channel names and counts, the MOTION header (Frames,
// Frame Time) and that every motion row holds exactly one finite number per channel. Declared sizes are checked
// before allocating: a frame count the rest of the file cannot hold (each number needs at least two bytes) or whose
// decoded size exceeds ReadOptions::max_bytes (8 bytes per number) is refused, as are more than kBvhMaxJoints
// joints or channels per joint beyond six.
//
// The reader only reads: forward kinematics and retargeting live in the Python package (volrig.mocap).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "volrig/io.hpp"

namespace volrig {

/// Most joints (ROOT and JOINT entries) a BVH file may declare.
constexpr std::size_t kBvhMaxJoints = 10000;

/// A BVH channel: a translation or a rotation (degrees) about one axis of the joint's parent frame.
enum class BvhChannel : std::uint8_t { Xposition, Yposition, Zposition, Xrotation, Yrotation, Zrotation };

/// "Xposition" ... "Zrotation".
const char* bvh_channel_name(BvhChannel c);

/// A ROOT or JOINT entry.
struct BvhJoint {
    std::string name;
    std::int32_t parent = -1;               ///< index of the parent joint, -1 for a ROOT
    std::array<double, 3> offset{};         ///< OFFSET: position in the parent's frame at rest
    std::vector<BvhChannel> channels;       ///< in file order (each at most once; at most 6)
    std::int64_t line = 0;                  ///< line of the ROOT/JOINT keyword, for messages
};

/// An End Site: a point fixed in its joint's frame (the tip of a head, a toe, a finger).
struct BvhEndSite {
    std::int32_t parent = -1;
    std::array<double, 3> offset{};
};

/// A BVH file: the hierarchy (joints in file order, so a parent always precedes its children) and the motion.
struct BvhMotion {
    std::vector<BvhJoint> joints;
    std::vector<BvhEndSite> end_sites;
    double frame_time = 0;                  ///< seconds per frame (> 0)
    std::uint64_t frame_count = 0;          ///< Frames: (>= 1)
    std::uint64_t channel_count = 0;        ///< sum of the joints' channel counts
    /// frame_count x channel_count numbers, frame by frame; a frame's channels follow the joints' file order.
    std::vector<double> frames;
};

/// Reads a BVH file:
///
///   HIERARCHY
///   ROOT <name> { OFFSET x y z  CHANNELS n <channel>...  (JOINT <name> { ... } | End Site { OFFSET x y z })* }
///   (further ROOTs)
///   MOTION
///   Frames: F
///   Frame Time: t
///   F lines of channel_count numbers
///
/// Keywords are case-insensitive; braces may share lines with other words; a joint's name is the rest of its line
/// (without a trailing '{'). Joint names must be unique. Blank lines in the motion are skipped; text after the last
/// frame is refused.
BvhMotion read_bvh(const ByteSource& src, const ReadOptions& opt = {});
BvhMotion read_bvh(const std::string& path, const ReadOptions& opt = {});

}  // namespace volrig

// deform/common.hpp: what every deformation stage shares: constants, the one distance expression, and the two
// rules every tier decides by (docs/ALGORITHMS.md §7).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>

namespace volrig::deform_detail {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
constexpr std::int64_t kBlock = 8;  // power-diagram and output blocks are 8³ voxels
constexpr double kInf = std::numeric_limits<double>::infinity();

/// Per output voxel (and per block or sub-block): the winning field when decided, else one of these.
constexpr std::int32_t kEmpty = -1;  // no sphere covers it
constexpr std::int32_t kOpen = -2;   // the bounds at hand do not decide

/// The 4³ sub-block (bits x, y, z) holding cell or voxel li (x + 8 y + 64 z) of an 8³ block.
inline std::size_t sub_of(std::size_t li) { return (((li >> 8) & 1) * 2 + ((li >> 5) & 1)) * 2 + ((li >> 2) & 1); }

using Vec3d = std::array<double, 3>;
/// An output box on the source lattice: {offset x, y, z, dims x, y, z}.
using Box = std::array<std::int64_t, 6>;

/// floor() without a libm call (x86-64's baseline has no SSE4.1 round); |x| must be far below 2^62.
inline double fast_floor(double x) {
    const double t = static_cast<double>(static_cast<std::int64_t>(x));
    return t > x ? t - 1.0 : t;
}

/// Squared world length of an index-space offset. Every distance test of the deformation goes through this one
/// expression, so that the fast path and the reference round identically.
inline double length2(double dx, double dy, double dz, const double* s2) {
    return s2[0] * dx * dx + s2[1] * dy * dy + s2[2] * dz * dz;
}

// ---- the two rules ------------------------------------------------------------------------------------------
// Power proximity: the sphere with the least power |q − c|² − r² wins, ties to the lower global sphere index (the
// brute-force scatter in index order with a strict comparison). A candidate is a field (a bone, or a group of
// blended spheres) with bounds L <= power <= U at the voxel.

/// Whether power a beats power b: the lower power wins; on a tie (rare) the lower global sphere index, which
/// `a_has_lower_index()` tells (called only then, so that indices are looked up only then).
template <class F>
inline bool beats(double a, double b, F&& a_has_lower_index) {
    return a < b || (a == b && a_has_lower_index());
}

/// Whether a candidate whose power is at most U covers the voxel and wins for certain over a rival whose power is
/// at least L: U < 0 (it covers) and U < L. With nearest-centre proximity power does not rank covers, so only a
/// rival that cannot cover at all (L >= 0) is beaten for certain. T is double or the int16 of quantised ranges.
template <class T>
inline bool certain(T U, T L, bool nearest) {
    return U < 0 && (nearest ? L >= 0 : U < L);
}

/// Whether a rival whose power is at least L may still cover and win against a best candidate with upper bound U.
template <class T>
inline bool in_running(T L, T U, bool nearest) {
    return L < 0 && !certain(U, L, nearest);
}

}  // namespace volrig::deform_detail

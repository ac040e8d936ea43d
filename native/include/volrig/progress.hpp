// volrig/progress.hpp: the progress/cancel callback that long operations take.
#pragma once

#include <functional>

#include "volrig/error.hpp"

namespace volrig {

/// Progress/cancel callback: receives the fraction done in [0, 1]; returns false to cancel.
/// volrig calls it only from the thread that started the operation, between parallel chunks.
using Progress = std::function<bool(double)>;

/// Calls `progress(fraction)` if set and throws Cancelled when it returns false.
inline void report(const Progress& progress, double fraction) {
    if (progress && !progress(fraction)) throw Cancelled("cancelled");
}

/// A callback that maps [0, 1] onto [a, b] of `progress` (empty when `progress` is); `progress` must outlive it.
inline Progress progress_span(const Progress& progress, double a, double b) {
    if (!progress) return {};
    return [&progress, a, b](double f) { return progress(a + (b - a) * f); };
}

}  // namespace volrig

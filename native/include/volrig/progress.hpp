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

}  // namespace volrig

// mesh/angle_sum.hpp: the sum of many angles atan2(y, x), with one atan2 call in all (for the winding number's
// exact near-field sums, mesh/winding.cpp). Internal to the core; not installed.
#pragma once

#include <cmath>
#include <utility>

namespace volrig::mesh_detail {

/// Sums atan2(y, x) over the pairs given to add(). A pair with x > 0 (an angle in (-pi/2, pi/2)) is multiplied
/// into a running complex product, whose argument is the sum of theirs: no atan2 for it. The product is kept within
/// pi/4 of the positive real axis by exact quarter turns (multiplying by -i or i swaps and negates its parts; the
/// turns are counted), so the next factor (less than pi/2 from the axis) can never carry it across the negative
/// real axis, where atan2's branch cut is; and its size is kept within 2^-400..2^400 by exact powers of two, so
/// with factors of size 2^-200..2^200 it cannot overflow or underflow. Any other pair (x <= 0, including atan2's
/// signed-zero cases, or a size outside that range) gets its own atan2, exactly as summed one by one. total()
/// adds the product's own argument (one atan2) and the turns. The result equals the sum of the atan2s up to
/// rounding (about 1e-16 per term, as summing the atan2s has).
class AngleSum {
public:
    void add(double y, double x) {
        const double size = x + std::abs(y);
        if (!(x > 0) || !(size >= kTiny && size <= kHuge)) {
            loose_ += std::atan2(y, x);
            return;
        }
        const double r = re_ * x - im_ * y, i = re_ * y + im_ * x;
        re_ = r;
        im_ = i;
        if (re_ <= std::abs(im_)) {  // more than pi/4 from the axis: a quarter turn back
            const double t = re_;
            if (im_ > 0) {  // times -i
                re_ = im_;
                im_ = -t;
                ++turns_;
            } else {  // times i
                re_ = -im_;
                im_ = t;
                --turns_;
            }
        }
        const double m = std::abs(re_) + std::abs(im_);
        if (m > kBig) {
            re_ *= kSmall;
            im_ *= kSmall;
        } else if (m < kSmall) {
            re_ *= kBig;
            im_ *= kBig;
        }
    }

    void add(const std::pair<double, double>& yx) { add(yx.first, yx.second); }

    /// The sum of the angles added so far.
    double total() const { return loose_ + (std::atan2(im_, re_) + static_cast<double>(turns_) * kQuarter); }

private:
    static constexpr double kBig = 0x1p400, kSmall = 0x1p-400, kHuge = 0x1p200, kTiny = 0x1p-200;
    static constexpr double kQuarter = 1.57079632679489661923132169163975144;  // pi / 2
    double re_ = 1, im_ = 0, loose_ = 0;
    long turns_ = 0;
};

}  // namespace volrig::mesh_detail

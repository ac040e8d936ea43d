#include <limits>

#include "volrig/components.hpp"
#include "volrig/track.hpp"

namespace volrig {

Features track_features(const Grid& g, const std::uint8_t* mask, std::int64_t min_size) {
    Components c = scan_components(g, mask, 6);
    std::vector<std::int32_t> renumber(c.sizes.size() + 1, 0);
    Features f;
    for (std::size_t k = 0; k < c.sizes.size(); ++k)
        if (c.sizes[k] >= min_size) {
            f.sizes.push_back(c.sizes[k]);
            renumber[k + 1] = static_cast<std::int32_t>(f.sizes.size());
        }
    f.centroids.assign(3 * f.sizes.size(), 0.0);
    const std::int64_t nx = g.dims[0], ny = g.dims[1];
    std::int64_t i = 0;
    for (std::int64_t z = 0; z < g.dims[2]; ++z)
        for (std::int64_t y = 0; y < ny; ++y)
            for (std::int64_t x = 0; x < nx; ++x, ++i) {
                auto& l = c.labels[static_cast<std::size_t>(i)];
                l = renumber[static_cast<std::size_t>(l)];
                if (!l) continue;
                double* s = &f.centroids[3 * static_cast<std::size_t>(l - 1)];
                s[0] += static_cast<double>(x), s[1] += static_cast<double>(y), s[2] += static_cast<double>(z);
            }
    for (std::size_t k = 0; k < f.sizes.size(); ++k)
        for (int a = 0; a < 3; ++a) f.centroids[3 * k + a] /= static_cast<double>(f.sizes[k]);
    f.labels = std::move(c.labels);
    return f;
}

}  // namespace volrig

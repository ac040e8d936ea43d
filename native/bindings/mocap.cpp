// Bindings for volrig/mocap.hpp: conversions only. Reading runs with the GIL released.
#include <string>
#include <utility>
#include <vector>

#include "convert.hpp"
#include "volrig/mocap.hpp"

namespace volrig::py {

void bind_mocap(py::module_& m) {
    m.def(
        "read_bvh",
        [](const std::string& path) {
            BvhMotion b;
            {
                py::gil_scoped_release release;
                b = read_bvh(path);
            }
            py::list names, channels;
            std::vector<std::int32_t> parents;
            std::vector<std::array<double, 3>> offsets;
            for (const BvhJoint& j : b.joints) {
                names.append(j.name);
                py::tuple c(j.channels.size());
                for (std::size_t k = 0; k < j.channels.size(); ++k) c[k] = bvh_channel_name(j.channels[k]);
                channels.append(c);
                parents.push_back(j.parent);
                offsets.push_back(j.offset);
            }
            std::vector<std::int32_t> end_parents;
            std::vector<std::array<double, 3>> end_offsets;
            for (const BvhEndSite& e : b.end_sites) {
                end_parents.push_back(e.parent);
                end_offsets.push_back(e.offset);
            }
            py::dict d;
            d["names"] = names;
            d["parents"] = to_numpy_shaped(std::move(parents), {static_cast<py::ssize_t>(b.joints.size())});
            d["offsets"] = rows(std::move(offsets));
            d["channels"] = channels;
            d["end_parents"] = to_numpy_shaped(std::move(end_parents), {static_cast<py::ssize_t>(b.end_sites.size())});
            d["end_offsets"] = rows(std::move(end_offsets));
            d["frame_time"] = b.frame_time;
            d["frames"] = to_numpy_shaped(std::move(b.frames), {static_cast<py::ssize_t>(b.frame_count),
                                                                static_cast<py::ssize_t>(b.channel_count)});
            return d;
        },
        py::arg("path"),
        "read_bvh(path) -> dict(names, parents (J,) int32, offsets (J, 3), channels [tuple of names per joint], "
        "end_parents (E,) int32, end_offsets (E, 3), frame_time, frames (F, C) float64). See volrig/mocap.hpp.");
}

}  // namespace volrig::py

// Bindings for volrig/drawing.hpp: conversions only; reading runs with the GIL released.
#include "volrig/drawing.hpp"

#include "convert.hpp"

namespace volrig::py {

void bind_drawing(py::module_& m) {
    m.def(
        "read_png",
        [](const std::string& path, std::int64_t max_bytes) {
            ReadOptions opt;
            if (max_bytes >= 0) opt.max_bytes = static_cast<std::uint64_t>(max_bytes), opt.max_bytes_given = true;
            Image im;
            {
                py::gil_scoped_release release;
                im = read_png(path, opt);
            }
            const auto h = static_cast<py::ssize_t>(im.height), w = static_cast<py::ssize_t>(im.width);
            return to_numpy_shaped(std::move(im.rgba), {h, w, 4});
        },
        py::arg("path"), py::arg("max_bytes") = -1,
        "Reads a PNG file as an (H, W, 4) uint8 RGBA array, top row first. max_bytes < 0: the default limit.");
}

}  // namespace volrig::py

// VTK XML image data (.vti): raw and zlib-compressed appended data read back exactly; lying block tables, offsets
// and extents are FileFormatErrors naming the file (under ASan/UBSan in CI; the Python tests cover every layout).
#include "io_fixture.hpp"

namespace {

/// A .vti holding `v` (float32, x fastest) appended raw: uncompressed, or zlib in blocks of `block` bytes.
Bytes vti_of(const std::vector<float>& v, std::array<int, 3> dims, std::size_t block = 0,
             const std::string& extent = "") {
    const Bytes payload(reinterpret_cast<const std::uint8_t*>(v.data()),
                        reinterpret_cast<const std::uint8_t*>(v.data() + v.size()));
    Bytes data;
    const auto word = [&data](std::size_t w) {  // a UInt32 header word, little-endian
        for (int k = 0; k < 4; ++k) data.push_back(static_cast<std::uint8_t>(w >> (8 * k)));
    };
    if (block == 0) {
        word(payload.size());
        data.insert(data.end(), payload.begin(), payload.end());
    } else {
        std::vector<Bytes> parts;
        for (std::size_t i = 0; i < payload.size(); i += block) {
            const auto from = payload.begin() + static_cast<std::ptrdiff_t>(i);
            parts.push_back(zlib(Bytes(from, from + static_cast<std::ptrdiff_t>(std::min(block, payload.size() - i)))));
        }
        word(parts.size());
        word(block);
        word(payload.size() % block);
        for (const Bytes& p : parts) word(p.size());
        for (const Bytes& p : parts) data.insert(data.end(), p.begin(), p.end());
    }
    const std::string ext = extent.empty() ? "0 " + std::to_string(dims[0] - 1) + " 0 " + std::to_string(dims[1] - 1) +
                                                 " 0 " + std::to_string(dims[2] - 1)
                                           : extent;
    const std::string head =
        std::string("<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\" "
                    "header_type=\"UInt32\"") +
        (block ? " compressor=\"vtkZLibDataCompressor\"" : "") + ">\n<ImageData WholeExtent=\"" + ext +
        "\" Origin=\"1 2 3\" Spacing=\"0.5 0.5 2\">\n<Piece Extent=\"" + ext +
        "\">\n<PointData Scalars=\"s\">\n<DataArray type=\"Float32\" Name=\"s\" format=\"appended\" offset=\"0\"/>\n"
        "</PointData>\n</Piece>\n</ImageData>\n<AppendedData encoding=\"raw\">\n _";
    return head + data + bytes("\n</AppendedData>\n</VTKFile>\n");
}

std::vector<float> ramp(std::size_t n) {
    std::vector<float> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = 0.25f * static_cast<float>(i) - 7.0f;
    return v;
}

}  // namespace

TEST_CASE("read_vti: raw and zlib blocks read back exactly", "[io][vti]") {
    const std::vector<float> v = ramp(5 * 4 * 3);
    for (const std::size_t block : {std::size_t(0), std::size_t(64), std::size_t(100), std::size_t(4096)}) {
        const Volume got = read_mem(read_vti, vti_of(v, {5, 4, 3}, block), "a.vti");
        CHECK(got.grid.dims == std::array<std::int64_t, 3>{5, 4, 3});
        CHECK(got.grid.spacing == std::array<double, 3>{0.5, 0.5, 2.0});
        CHECK(got.grid.origin == std::array<double, 3>{1.0, 2.0, 3.0});
        CHECK(values<float>(got) == v);
    }
    // An extent from (2, 0, 1): voxel 0 sits at Origin + Spacing * (2, 0, 1).
    const Volume moved = read_mem(read_vti, vti_of(v, {5, 4, 3}, 64, "2 6 0 3 1 3"), "b.vti");
    CHECK(moved.grid.origin == std::array<double, 3>{2.0, 2.0, 5.0});
}

TEST_CASE("read_vti: lying tables, offsets and extents are FileFormatErrors naming the file", "[io][vti]") {
    const std::vector<float> v = ramp(5 * 4 * 3);
    const Bytes good = vti_of(v, {5, 4, 3}, 64);
    const std::string text(good.begin(), good.end());
    const std::size_t data = text.find(" _") + 2;
    auto with_word = [&](std::size_t k, std::uint32_t w) {
        Bytes b = good;
        std::memcpy(&b[data + 4 * k], &w, 4);
        return b;
    };
    CHECK(message_of([&] { read_mem(read_vti, with_word(0, 0xFFFFFFFFu), "t.vti"); }).rfind("t.vti: ", 0) == 0);
    CHECK_THROWS_AS(read_mem(read_vti, with_word(1, 3), "t.vti"), FileFormatError);  // block size
    CHECK_THROWS_AS(read_mem(read_vti, with_word(2, 65), "t.vti"), FileFormatError);  // last block > block size
    CHECK_THROWS_AS(read_mem(read_vti, with_word(3, 0x7FFFFFFFu), "t.vti"), FileFormatError);  // past the end
    CHECK_THROWS_AS(read_mem(read_vti, with_word(3, 1), "t.vti"), FileFormatError);  // a block cut short
    const std::size_t tail = std::string("\n</AppendedData>\n</VTKFile>\n").size();  // not needed to read
    for (std::size_t cut = 1; cut < good.size() - tail; cut += 37)
        CHECK_THROWS_AS(
            read_mem(read_vti, Bytes(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(cut)), "c.vti"),
            FileFormatError);
    const Bytes raw = vti_of(v, {5, 4, 3});
    Bytes lying = raw;
    const std::string raw_text(raw.begin(), raw.end());
    const std::uint32_t more = 241;
    std::memcpy(&lying[raw_text.find(" _") + 2], &more, 4);
    CHECK(message_of([&] { read_mem(read_vti, lying, "r.vti"); }) ==
          "r.vti: DataArray 's' holds 241 bytes but 5x4x3 float32 needs 240");
    CHECK_THROWS_AS(read_mem(read_vti, vti_of(v, {5, 4, 3}, 64, "0 4 0 3 0 1073741824"), "e.vti"), FileFormatError);
    CHECK_THROWS_AS(read_mem(read_vti, vti_of(v, {5, 4, 3}, 64, "0 4 0 3 0 1e300"), "e.vti"), FileFormatError);
}

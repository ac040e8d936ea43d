// Bindings for volrig/io.hpp (except OpenVDB): conversions only. File reading, decompression and writing run
// with the GIL released.
#include "volrig/io.hpp"

#include "convert.hpp"

namespace volrig::py {

namespace {

ReadOptions options_of(std::int64_t max_bytes) {
    ReadOptions opt;
    if (max_bytes >= 0) opt.max_bytes = static_cast<std::uint64_t>(max_bytes), opt.max_bytes_given = true;
    return opt;
}

/// Text as os.fsdecode gives it: UTF-8, other bytes as surrogates (a name or DICOM text that is not UTF-8 must not
/// raise UnicodeDecodeError).
py::object fs_str(const std::string& s) {
    PyObject* o = PyUnicode_DecodeUTF8(s.data(), static_cast<Py_ssize_t>(s.size()), "surrogateescape");
    if (!o) throw py::error_already_set();
    return py::reinterpret_steal<py::object>(o);
}

/// The readers: read_volume, dicom_series, read_raw.
void bind_readers(py::module_& m) {
    m.def(
        "read_volume",
        [](const std::string& path, std::int64_t max_bytes, const std::string& series,
           const std::array<double, 3>& spacing) {
            ReadOptions opt = options_of(max_bytes);
            opt.series = series;
            opt.spacing = spacing;
            std::vector<std::string> warnings;
            opt.warn = [&warnings](const std::string& w) { warnings.push_back(w); };  // kept; told after reading
            Volume v;
            {
                py::gil_scoped_release release;
                v = read_volume(path, opt);
            }
            py::tuple t = oriented_volume_tuple(std::move(v));
            return py::make_tuple(t[0], t[1], t[2], t[3], py::cast(warnings));
        },
        py::arg("path"), py::arg("max_bytes") = -1, py::arg("series") = "",
        py::arg("spacing") = std::array<double, 3>{0, 0, 0},
        "Reads a .nrrd/.nhdr/.mhd/.mha/.nii/.nii.gz/.hdr/.vdb/.tif/.tiff/.dcm file, a DICOMDIR or a folder of DICOM "
        "or TIFF files: (array [z, y, x], spacing, origin, direction as 9 numbers row-major (LPS), warnings). "
        "max_bytes < 0 means the default limit; series: a DICOM SeriesInstanceUID (empty: the largest series); "
        "spacing: TIFF spacing (x, y, z), components <= 0 from the file.");

    m.def(
        "dicom_series",
        [](const std::string& path) {
            std::vector<DicomSeriesInfo> all;
            std::vector<std::string> warnings;
            {
                py::gil_scoped_release release;
                all = dicom_series(path, [&warnings](const std::string& w) { warnings.push_back(w); });
            }
            py::list out;
            for (const DicomSeriesInfo& s : all) {
                py::dict d;
                d["uid"] = fs_str(s.uid);
                d["description"] = fs_str(s.description);
                d["modality"] = fs_str(s.modality);
                d["dims"] = py::make_tuple(s.dims[0], s.dims[1], s.dims[2]);
                py::list files;
                for (const std::string& f : s.files) files.append(fs_str(f));
                d["files"] = files;
                out.append(d);
            }
            return py::make_tuple(out, py::cast(warnings));
        },
        py::arg("path"),
        "The DICOM image series under a folder, DICOMDIR or file, the largest first: (dicts with uid, description, "
        "modality, dims (columns, rows, slices) and files; what the folder walk skipped, as warnings).");

    m.def(
        "read_raw",
        [](const std::string& path, const std::array<std::int64_t, 3>& dims, const std::string& dtype,
           const std::array<double, 3>& spacing, const std::array<double, 3>& origin, bool big_endian,
           std::int64_t offset, std::int64_t max_bytes) {
            if (offset < 0) throw Error(path + ": offset " + std::to_string(offset) + " must not be negative");
            RawLayout layout;
            layout.dims = dims;
            layout.dtype = dtype_from_name(dtype);
            layout.spacing = spacing;
            layout.origin = origin;
            layout.big_endian = big_endian;
            layout.offset = static_cast<std::uint64_t>(offset);
            const ReadOptions opt = options_of(max_bytes);
            Volume v;
            {
                py::gil_scoped_release release;
                auto src = open_file(path);
                v = read_raw(*src, layout, opt);
            }
            return volume_tuple(std::move(v));
        },
        py::arg("path"), py::arg("dims"), py::arg("dtype"), py::arg("spacing"), py::arg("origin"),
        py::arg("big_endian") = false, py::arg("offset") = 0, py::arg("max_bytes") = -1,
        "Reads raw voxels: dims (x, y, z), numpy dtype name, spacing, origin, byte order, byte offset.");

}

/// The writers: write_nrrd, write_metaimage.
void bind_writers(py::module_& m) {
    m.def(
        "write_nrrd",
        [](const std::string& path, const py::array& array, const std::array<double, 3>& spacing,
           const std::array<double, 3>& origin, bool gzip, const Matrix3& direction) {
            VolumeView v = view_of(array, spacing, origin, "write_nrrd");
            v.grid.direction = direction;
            py::gil_scoped_release release;
            write_nrrd(path, v, gzip);
        },
        py::arg("path"), py::arg("array"), py::arg("spacing"), py::arg("origin"), py::arg("gzip") = true,
        py::arg("direction") = kIdentity3,
        "Writes a C-contiguous [z, y, x] array as NRRD (gzip or raw; direction: 9 numbers row-major, LPS), "
        "atomically.");

    m.def(
        "write_metaimage",
        [](const std::string& path, const py::array& array, const std::array<double, 3>& spacing,
           const std::array<double, 3>& origin, bool compress, const Matrix3& direction) {
            VolumeView v = view_of(array, spacing, origin, "write_metaimage");
            v.grid.direction = direction;
            py::gil_scoped_release release;
            write_metaimage(path, v, compress);
        },
        py::arg("path"), py::arg("array"), py::arg("spacing"), py::arg("origin"), py::arg("compress") = true,
        py::arg("direction") = kIdentity3,
        "Writes a C-contiguous [z, y, x] array as a single-file MetaImage (.mha, LOCAL data), atomically.");
}

}  // namespace

void bind_io(py::module_& m) {
    bind_readers(m);
    bind_writers(m);
}

}  // namespace volrig::py

// The _volrig extension module: registers exceptions and each capability's bindings.
#include <cstring>

#include "convert.hpp"

namespace py = pybind11;

PYBIND11_MODULE(_volrig, m) {
    m.doc() = "volrig native core (see the volrig package for the documented API)";
    static py::exception<volrig::Error> error(m, "VolrigError", PyExc_ValueError);
    static py::exception<volrig::FileFormatError> file_error(m, "FileFormatError", error.ptr());
    static py::exception<volrig::Cancelled> cancelled(m, "Cancelled", error.ptr());
    // Messages carry file names as the OS gave them (bytes): decoded as os.fsdecode does (UTF-8, undecodable bytes
    // as surrogates), so a name that is not UTF-8 still shows instead of an empty message.
    static const auto set = [](PyObject* type, const char* what) {
        PyObject* text = PyUnicode_DecodeUTF8(what, static_cast<Py_ssize_t>(std::strlen(what)), "surrogateescape");
        if (!text) return;  // PyUnicode_DecodeUTF8 set the error
        PyErr_SetObject(type, text);
        Py_DECREF(text);
    };
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const volrig::FileNotFound& e) {
            set(PyExc_FileNotFoundError, e.what());
        } catch (const volrig::FileFormatError& e) {
            set(file_error.ptr(), e.what());
        } catch (const volrig::Cancelled& e) {
            set(cancelled.ptr(), e.what());
        } catch (const volrig::Error& e) {
            set(error.ptr(), e.what());
        }
    });
    volrig::py::bind_io(m);
    volrig::py::bind_vdb(m);
    volrig::py::bind_skeleton(m);
    volrig::py::bind_medial(m);
    volrig::py::bind_tree(m);
    volrig::py::bind_rig(m);
    volrig::py::bind_skin(m);
    volrig::py::bind_mesh(m);
    volrig::py::bind_deform(m);
    volrig::py::bind_mocap(m);
    volrig::py::bind_centerline(m);
    volrig::py::bind_collide(m);
    volrig::py::bind_drawing(m);
    volrig::py::bind_track(m);
    volrig::py::bind_pores(m);
}

// The _volrig extension module: registers exceptions and each capability's bindings.
#include "convert.hpp"

namespace py = pybind11;

PYBIND11_MODULE(_volrig, m) {
    m.doc() = "volrig native core (see the volrig package for the documented API)";
    static py::exception<volrig::Error> error(m, "VolrigError", PyExc_ValueError);
    static py::exception<volrig::FileFormatError> file_error(m, "FileFormatError", error.ptr());
    static py::exception<volrig::Cancelled> cancelled(m, "Cancelled", error.ptr());
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const volrig::FileNotFound& e) {
            PyErr_SetString(PyExc_FileNotFoundError, e.what());
        } catch (const volrig::FileFormatError& e) {
            file_error(e.what());
        } catch (const volrig::Cancelled& e) {
            cancelled(e.what());
        } catch (const volrig::Error& e) {
            error(e.what());
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
}

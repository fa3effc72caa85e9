#include "bindings.hpp"

#include "flowvid/error.hpp"
#include "flowvid/progress.hpp"

namespace flowvid::python {

pybind11::str text_to_python(const std::string& text) {
    PyObject* decoded = PyUnicode_DecodeUTF8(text.data(), static_cast<Py_ssize_t>(text.size()), "replace");
    if (!decoded) throw pybind11::error_already_set();
    return pybind11::reinterpret_steal<pybind11::str>(decoded);
}

namespace {
void set_python_error(PyObject* type, const char* what) {
    PyErr_SetObject(type, text_to_python(what).ptr());
}
}  // namespace

// Library errors become Python exceptions with the same message, so that the
// add-on can show them in Blender's UI.
void bind_errors(pybind11::module_& module) {
    static pybind11::exception<flowvid::Error> error(module, "Error", PyExc_RuntimeError);
    static pybind11::exception<flowvid::IoError> io_error(module, "IoError", error.ptr());
    static pybind11::exception<flowvid::ValidationError> validation_error(module, "ValidationError", error.ptr());
    // Raised when a progress callback returned False.
    static pybind11::exception<flowvid::Cancelled> cancelled(module, "Cancelled", error.ptr());
    pybind11::register_exception_translator([](std::exception_ptr pointer) {
        try {
            if (pointer) std::rethrow_exception(pointer);
        } catch (const flowvid::Cancelled& e) {
            set_python_error(cancelled.ptr(), e.what());
        } catch (const flowvid::ValidationError& e) {
            set_python_error(validation_error.ptr(), e.what());
        } catch (const flowvid::IoError& e) {
            set_python_error(io_error.ptr(), e.what());
        } catch (const flowvid::Error& e) {
            set_python_error(error.ptr(), e.what());
        }
    });
}

}  // namespace flowvid::python

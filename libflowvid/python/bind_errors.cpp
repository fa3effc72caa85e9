#include "bindings.hpp"

#include "flowvid/error.hpp"

namespace flowvid::python {

// Library errors become Python exceptions with the same message, so that the
// add-on can show them in Blender's UI.
void bind_errors(pybind11::module_& module) {
    static pybind11::exception<flowvid::Error> error(module, "Error", PyExc_RuntimeError);
    static pybind11::exception<flowvid::IoError> io_error(module, "IoError", error.ptr());
    static pybind11::exception<flowvid::ValidationError> validation_error(module, "ValidationError", error.ptr());
    pybind11::register_exception_translator([](std::exception_ptr pointer) {
        try {
            if (pointer) std::rethrow_exception(pointer);
        } catch (const flowvid::ValidationError& e) {
            PyErr_SetString(validation_error.ptr(), e.what());
        } catch (const flowvid::IoError& e) {
            PyErr_SetString(io_error.ptr(), e.what());
        } catch (const flowvid::Error& e) {
            PyErr_SetString(error.ptr(), e.what());
        }
    });
}

}  // namespace flowvid::python

// The Python module stepcal (docs/python.md).
#include "bindings.hpp"

#include "stepcal/common/error.hpp"

namespace stepcal::python {

void bindErrors(py::module_& m) {
  // stepcal.InputError(ValueError): the C++ InputError's message, with its file, line and column
  // (field) as attributes ("" / 0 where it names none).
  static py::handle input_error =
      py::exception<InputError>(m, "InputError", PyExc_ValueError).release();
  py::register_exception_translator([](std::exception_ptr thrown) {
    try {
      if (thrown) std::rethrow_exception(thrown);
    } catch (const InputError& e) {
      py::object error = py::reinterpret_borrow<py::object>(input_error)(e.what());
      error.attr("file") = e.file();
      error.attr("line") = e.line();
      error.attr("column") = e.column();
      PyErr_SetObject(input_error.ptr(), error.ptr());
    }
  });
}

}  // namespace stepcal::python

PYBIND11_MODULE(stepcal, m) {
  using namespace stepcal::python;
  m.doc() =
      "stepcal: stepwise calibration of heavy-duty serial robots. Campaigns, calibration and "
      "diagnosis, model files, the real-time runtime's forward correction and inverse (vectorised "
      "over numpy arrays), and requests to the stepcal-runtime daemon over LCM.";
  m.attr("__version__") = STEPCAL_VERSION;
  bindErrors(m);
  bindCallTerms(m);
  bindRuntime(m);
  bindTrainer(m);
  bindClient(m);
}

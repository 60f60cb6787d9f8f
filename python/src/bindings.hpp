// The Python module stepcal: what each part binds, and the conversions they share.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <nlohmann/json.hpp>

#include "stepcal/common/types.hpp"

namespace stepcal::python {

namespace py = pybind11;

void bindErrors(py::module_& m);
void bindTrainer(py::module_& m);
void bindRuntime(py::module_& m);
void bindClient(py::module_& m);

/// A JSON value as Python objects: dict, list, float, int, str, bool, None.
py::object toPython(const nlohmann::json& value);

/// Rows of a float64 array of shape (rows, columns), or (columns,) as one row (single = true);
/// throws ValueError naming `what` and the shape expected.
struct Rows {
  py::array_t<double, py::array::c_style | py::array::forcecast> array;
  ssize_t rows = 0;
  bool single = false;
  const double* row(ssize_t i) const { return array.data() + i * array.shape(array.ndim() - 1); }
};
Rows rowsOf(const py::handle& value, ssize_t columns, const char* what);

/// A float64 array of shape (rows, shape...) or (shape...) when single.
py::array_t<double> outputArray(ssize_t rows, bool single, std::vector<ssize_t> shape);

/// stepcal.Status (an enum.IntEnum, so that it compares with numpy's integers) of a status value.
py::object statusObject(int8_t status);

/// FNV-1a 64 of bytes: the runtime's model id of a model file's bytes.
uint64_t fnv1a64(const std::vector<uint8_t>& bytes) noexcept;

}  // namespace stepcal::python

// The Python module stepcal: what each part binds, and the conversions they share.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <nlohmann/json.hpp>

#include "stepcal/common/types.hpp"
#include "stepcal/runtime/corrector.hpp"

namespace stepcal::python {

namespace py = pybind11;

void bindErrors(py::module_& m);
void bindTrainer(py::module_& m);
void bindRuntime(py::module_& m);
void bindClient(py::module_& m);
void bindCallTerms(py::module_& m);

/// A pose given as a (4, 4) homogeneous matrix or 7 numbers x, y, z [m], qw, qx, qy, qz; throws
/// ValueError naming `what` when it is neither, not finite, or its rotation is not one.
Pose poseOf(const py::handle& value, const char* what);
/// The runtime's terms of a call's `terms` argument: a stepcal.CallTerms, or None for the
/// calibration's own (tracker frame, the measured target, a wrench on the sensor).
runtime::CallTerms termsOf(const py::object& terms);
/// Throws ValueError when terms ask for what the model lacks (a flange, gravity for a payload).
void checkTermsForModel(const runtime::RuntimeModel& model, const runtime::CallTerms& terms);

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

/// stepcal.ModelId (an int shown as 16 hex digits, as stepcal-client and the daemon print it) of
/// a model id.
py::object modelIdObject(uint64_t model_id);

/// FNV-1a 64 of bytes: the runtime's model id of a model file's bytes.
uint64_t fnv1a64(const std::vector<uint8_t>& bytes) noexcept;

}  // namespace stepcal::python

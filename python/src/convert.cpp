// Conversions shared by the bindings (see bindings.hpp).
#include <string>

#include "bindings.hpp"

namespace stepcal::python {

py::object toPython(const nlohmann::json& value) {
  switch (value.type()) {
    case nlohmann::json::value_t::object: {
      py::dict out;
      for (const auto& [key, item] : value.items()) out[py::str(key)] = toPython(item);
      return std::move(out);
    }
    case nlohmann::json::value_t::array: {
      py::list out;
      for (const auto& item : value) out.append(toPython(item));
      return std::move(out);
    }
    case nlohmann::json::value_t::string: return py::str(value.get<std::string>());
    case nlohmann::json::value_t::boolean: return py::bool_(value.get<bool>());
    case nlohmann::json::value_t::number_integer: return py::int_(value.get<int64_t>());
    case nlohmann::json::value_t::number_unsigned: return py::int_(value.get<uint64_t>());
    case nlohmann::json::value_t::number_float: return py::float_(value.get<double>());
    default: return py::none();
  }
}

Rows rowsOf(const py::handle& value, ssize_t columns, const char* what) {
  Rows rows;
  rows.array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
  if (!rows.array) {
    throw py::value_error(std::string(what) + ": expected an array of numbers");
  }
  const ssize_t ndim = rows.array.ndim();
  if (ndim == 1 && rows.array.shape(0) == columns) {
    rows.single = true;
    rows.rows = 1;
  } else if (ndim == 2 && rows.array.shape(1) == columns) {
    rows.rows = rows.array.shape(0);
  } else {
    std::string shape = "(";
    for (ssize_t d = 0; d < ndim; ++d) shape += (d ? ", " : "") + std::to_string(rows.array.shape(d));
    shape += ndim == 1 ? ",)" : ")";
    throw py::value_error(std::string(what) + ": expected shape (" + std::to_string(columns) +
                          ",) or (N, " + std::to_string(columns) + "), got " + shape);
  }
  return rows;
}

py::array_t<double> outputArray(ssize_t rows, bool single, std::vector<ssize_t> shape) {
  if (!single) shape.insert(shape.begin(), rows);
  return py::array_t<double>(shape);
}

uint64_t fnv1a64(const std::vector<uint8_t>& bytes) noexcept {
  // The runtime's constants (runtime/src/corrector.cpp), so that ids agree with the daemon's.
  uint64_t hash = 1469598103934665603ull;
  for (const uint8_t b : bytes) {
    hash ^= b;
    hash *= 1099511628211ull;
  }
  return hash;
}

}  // namespace stepcal::python

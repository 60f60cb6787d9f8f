// stepcal.Model and the runtime's calls over numpy arrays (docs/python.md, "The runtime").
#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include <pybind11/eval.h>

#include "bindings.hpp"
#include "model_handle.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/pose_quaternion.hpp"
#include "stepcal/report/report.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/service/request.hpp"

namespace stepcal::python {
namespace {

using runtime::Status;


/// A per-row value given once for every row or once per row: scalars and (N,) arrays.
struct PerRow {
  py::array_t<double, py::array::c_style | py::array::forcecast> array;
  double value(ssize_t i) const { return array.size() == 1 ? array.data()[0] : array.data()[i]; }
};
PerRow perRowOf(const py::handle& value, ssize_t rows, const char* what) {
  PerRow out{py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value)};
  if (!out.array || !(out.array.size() == 1 || (out.array.ndim() == 1 && out.array.shape(0) == rows))) {
    throw py::value_error(std::string(what) + ": expected a number or an array of shape (" +
                          std::to_string(rows) + ",)");
  }
  return out;
}

/// Rows of a (N, columns) argument that may also be given once for all rows; None gives zeros.
struct Broadcast {
  Rows rows;
  bool none = false;
  Eigen::Map<const Eigen::VectorXd> row(ssize_t i, ssize_t columns) const {
    return {rows.row(rows.single ? 0 : i), columns};
  }
};
Broadcast broadcastOf(const py::object& value, ssize_t columns, ssize_t rows, const char* what) {
  Broadcast out;
  if (value.is_none()) {
    out.none = true;
    out.rows = rowsOf(py::array_t<double>(columns), columns, what);
    std::fill(out.rows.array.mutable_data(), out.rows.array.mutable_data() + columns, 0.0);
    return out;
  }
  out.rows = rowsOf(value, columns, what);
  if (!out.rows.single && out.rows.rows != rows) {
    throw py::value_error(std::string(what) + ": " + std::to_string(out.rows.rows) +
                          " rows where the joints have " + std::to_string(rows));
  }
  return out;
}

void writePose(const Pose& X, double* position_m, double* quaternion_wxyz, double* matrix) {
  toPositionQuaternion(X, position_m, quaternion_wxyz);
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) matrix[4 * r + c] = X.matrix()(r, c);
  }
}

/// Desired poses: (N, 4, 4) / (4, 4) homogeneous matrices or (N, 7) / (7,) rows x, y, z, qw,
/// qx, qy, qz. A quaternion whose norm is off by more than 1e-6 gives that row BAD_REQUEST.
struct DesiredPoses {
  std::vector<Pose> poses;
  std::vector<bool> valid;
  bool single = false;
};
DesiredPoses desiredPosesOf(const py::handle& value) {
  const auto array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
  if (!array) throw py::value_error("pose: expected an array of numbers");
  DesiredPoses out;
  const ssize_t ndim = array.ndim();
  const bool matrices = ndim >= 2 && array.shape(ndim - 1) == 4 && array.shape(ndim - 2) == 4 &&
                        ndim <= 3;
  const bool rows7 = (ndim == 1 || ndim == 2) && array.shape(ndim - 1) == 7;
  if (!matrices && !rows7) {
    throw py::value_error("pose: expected shape (4, 4), (N, 4, 4), (7,) or (N, 7) "
                          "(x, y, z [m], qw, qx, qy, qz)");
  }
  out.single = matrices ? ndim == 2 : ndim == 1;
  const ssize_t n = out.single ? 1 : array.shape(0);
  const double* data = array.data();
  for (ssize_t i = 0; i < n; ++i) {
    Pose X = Pose::Identity();
    bool valid = true;
    if (matrices) {
      const Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>> M(data + 16 * i);
      X.matrix() = M;
      valid = M.row(3) == Eigen::RowVector4d(0, 0, 0, 1);
    } else {
      const double* r = data + 7 * i;
      const Eigen::Quaterniond q(r[3], r[4], r[5], r[6]);
      valid = isUnitQuaternion(q);
      if (valid) X = poseFromPositionQuaternion(Vec3(r[0], r[1], r[2]), q);
      else X.translation() = Vec3(r[0], r[1], r[2]);
    }
    out.poses.push_back(X);
    out.valid.push_back(valid);
  }
  return out;
}

py::object statusOut(const py::array_t<int8_t>& statuses, bool single) {
  if (single) return statusObject(statuses.data()[0]);
  return statuses;
}

py::handle g_status_type;

py::object scalarOr(const py::array& array, bool single) {
  if (single) return array[py::int_(0)];
  return array;
}

/// The results of one call over N rows, as attributes (numpy arrays; one row's values for a
/// single row).
py::object resultObject(const py::dict& fields) {
  return py::module_::import("types").attr("SimpleNamespace")(**fields);
}

/// The terms of a call, checked against the model; a payload and a wrench are one load, not two.
runtime::CallTerms callTermsFor(const runtime::RuntimeModel& model, const py::object& terms,
                                const py::object& wrench) {
  runtime::CallTerms out = termsOf(terms);
  checkTermsForModel(model, out);
  if (out.load_from == runtime::LoadFrom::kPayload && !wrench.is_none()) {
    throw py::value_error("wrench and terms.payload_kg: give one load, not both");
  }
  return out;
}

py::object correctForward(const ModelHandle& model, const py::handle& q, const py::object& wrench,
                          const py::object& temp_c, const py::object& terms_arg) {
  const RuntimeModelPtr& rt = model.runtime();
  runtime::CallTerms terms = callTermsFor(*rt, terms_arg, wrench);
  const ssize_t n = rt->file.chain_Tracker.dof();
  const Rows joints = rowsOf(q, n, "q");
  const ssize_t rows = joints.rows;
  const Broadcast wrenches = broadcastOf(wrench, 6, rows, "wrench");
  const PerRow temps = perRowOf(temp_c, rows, "temp_c");

  py::array_t<int8_t> status(rows);
  py::array_t<uint32_t> uncovered(rows);
  py::array_t<double> position = outputArray(rows, false, {3});
  py::array_t<double> quaternion = outputArray(rows, false, {4});
  py::array_t<double> pose = outputArray(rows, false, {4, 4});
  py::array_t<double> gpr_std = outputArray(rows, false, {6});
  py::array_t<double> wrench_used = outputArray(rows, false, {6});
  py::array_t<double> position_bound = outputArray(rows, false, {});
  py::array_t<double> orientation_bound = outputArray(rows, false, {});
  {
    double* position_bound_out = position_bound.mutable_data();
    double* orientation_bound_out = orientation_bound.mutable_data();
    int8_t* status_out = status.mutable_data();
    uint32_t* uncovered_out = uncovered.mutable_data();
    double* wrench_out = wrench_used.mutable_data();
    double* position_out = position.mutable_data();
    double* quaternion_out = quaternion.mutable_data();
    double* pose_out = pose.mutable_data();
    double* std_out = gpr_std.mutable_data();
    const py::gil_scoped_release unlocked;
    runtime::Workspace ws = runtime::makeWorkspace(*rt);
    JointVector q_rad(n);
    for (ssize_t i = 0; i < rows; ++i) {
      q_rad = Eigen::Map<const Eigen::VectorXd>(joints.row(i), n);
      terms.wrench_Sensor = wrenches.row(i, 6);
      const runtime::ForwardResult r = runtime::correctForward(*rt, ws, q_rad, terms, temps.value(i));
      status_out[i] = int8_t(r.status);
      uncovered_out[i] = r.uncovered_joints;
      writePose(r.X_FrameTcp, position_out + 3 * i, quaternion_out + 4 * i, pose_out + 16 * i);
      for (int k = 0; k < 6; ++k) std_out[6 * i + k] = r.gpr_std(k);
      for (int k = 0; k < 6; ++k) wrench_out[6 * i + k] = r.wrench_Sensor(k);
      position_bound_out[i] = r.accuracy.position_bound_m;
      orientation_bound_out[i] = r.accuracy.orientation_bound_rad;
    }
  }
  const bool single = joints.single;
  py::dict fields;
  fields["status"] = statusOut(status, single);
  fields["position_m"] = scalarOr(position, single);
  fields["quaternion_wxyz"] = scalarOr(quaternion, single);
  fields["pose"] = scalarOr(pose, single);
  fields["gpr_std"] = scalarOr(gpr_std, single);
  fields["uncovered_joints"] = scalarOr(uncovered, single);
  fields["wrench"] = scalarOr(wrench_used, single);
  fields["position_bound_m"] = scalarOr(position_bound, single);
  fields["orientation_bound_rad"] = scalarOr(orientation_bound, single);
  return resultObject(fields);
}

py::object solveInverse(const ModelHandle& model, const py::handle& pose, const py::handle& seed,
                        const py::object& wrench, const py::object& temp_c,
                        const py::object& budget_us, const runtime::InverseOptions& options,
                        const py::object& terms_arg) {
  const RuntimeModelPtr& rt = model.runtime();
  runtime::CallTerms terms = callTermsFor(*rt, terms_arg, wrench);
  const ssize_t n = rt->file.chain_Tracker.dof();
  const DesiredPoses desired = desiredPosesOf(pose);
  const auto rows = ssize_t(desired.poses.size());
  const Broadcast seeds = broadcastOf(py::reinterpret_borrow<py::object>(seed), n, rows, "seed");
  const Broadcast wrenches = broadcastOf(wrench, 6, rows, "wrench");
  const PerRow temps = perRowOf(temp_c, rows, "temp_c");
  const bool deadline = !budget_us.is_none();
  const double budget = deadline ? budget_us.cast<double>() : 0.0;
  if (deadline && !(budget > 0.0)) throw py::value_error("budget_us: expected a time > 0 (µs) or None");

  py::array_t<int8_t> status(rows);
  py::array_t<int32_t> iterations(rows);
  py::array_t<uint32_t> uncovered(rows);
  py::array_t<double> q_target = outputArray(rows, false, {n});
  py::array_t<double> predicted_position = outputArray(rows, false, {3});
  py::array_t<double> predicted_quaternion = outputArray(rows, false, {4});
  py::array_t<double> predicted_pose = outputArray(rows, false, {4, 4});
  py::array_t<double> commanded_position = outputArray(rows, false, {3});
  py::array_t<double> commanded_quaternion = outputArray(rows, false, {4});
  py::array_t<double> commanded_pose = outputArray(rows, false, {4, 4});
  py::array_t<double> gpr_std = outputArray(rows, false, {6});
  py::array_t<double> residual_position = outputArray(rows, false, {});
  py::array_t<double> residual_orientation = outputArray(rows, false, {});
  py::array_t<double> wrench_used = outputArray(rows, false, {6});
  py::array_t<double> position_bound = outputArray(rows, false, {});
  py::array_t<double> orientation_bound = outputArray(rows, false, {});
  {
    double* position_bound_out = position_bound.mutable_data();
    double* orientation_bound_out = orientation_bound.mutable_data();
    double* wrench_out = wrench_used.mutable_data();
    int8_t* status_out = status.mutable_data();
    int32_t* iterations_out = iterations.mutable_data();
    uint32_t* uncovered_out = uncovered.mutable_data();
    double* q_out = q_target.mutable_data();
    double* pp = predicted_position.mutable_data();
    double* pq = predicted_quaternion.mutable_data();
    double* pm = predicted_pose.mutable_data();
    double* cp = commanded_position.mutable_data();
    double* cq = commanded_quaternion.mutable_data();
    double* cm = commanded_pose.mutable_data();
    double* std_out = gpr_std.mutable_data();
    double* rp = residual_position.mutable_data();
    double* ro = residual_orientation.mutable_data();
    const py::gil_scoped_release unlocked;
    runtime::Workspace ws = runtime::makeWorkspace(*rt);
    JointVector seed_rad(n);
    for (ssize_t i = 0; i < rows; ++i) {
      seed_rad = seeds.row(i, n);
      terms.wrench_Sensor = wrenches.row(i, 6);
      const runtime::Clock::time_point until =
          deadline ? runtime::Clock::now() + std::chrono::nanoseconds(int64_t(budget * 1e3))
                   : runtime::Clock::time_point::max();
      runtime::InverseResult r;
      if (desired.valid[size_t(i)]) {
        r = runtime::solveInverse(*rt, ws, desired.poses[size_t(i)], terms, temps.value(i),
                                  seed_rad, until, options);
      }
      status_out[i] = int8_t(r.status);
      iterations_out[i] = r.iterations;
      uncovered_out[i] = r.uncovered_joints;
      for (ssize_t k = 0; k < n; ++k) {
        q_out[n * i + k] = r.q_target_rad.size() == n ? r.q_target_rad(k)
                                                      : std::numeric_limits<double>::quiet_NaN();
      }
      writePose(r.X_FrameTcp_predicted, pp + 3 * i, pq + 4 * i, pm + 16 * i);
      writePose(r.X_ControllerTcp_commanded, cp + 3 * i, cq + 4 * i, cm + 16 * i);
      for (int k = 0; k < 6; ++k) std_out[6 * i + k] = r.gpr_std(k);
      for (int k = 0; k < 6; ++k) wrench_out[6 * i + k] = r.wrench_Sensor(k);
      rp[i] = r.residual_position_m;
      ro[i] = r.residual_orientation_rad;
      position_bound_out[i] = r.accuracy.position_bound_m;
      orientation_bound_out[i] = r.accuracy.orientation_bound_rad;
    }
  }
  const bool single = desired.single;
  py::dict fields;
  fields["status"] = statusOut(status, single);
  fields["q_target_rad"] = scalarOr(q_target, single);
  fields["predicted_position_m"] = scalarOr(predicted_position, single);
  fields["predicted_quaternion_wxyz"] = scalarOr(predicted_quaternion, single);
  fields["predicted_pose"] = scalarOr(predicted_pose, single);
  fields["commanded_position_m"] = scalarOr(commanded_position, single);
  fields["commanded_quaternion_wxyz"] = scalarOr(commanded_quaternion, single);
  fields["commanded_pose"] = scalarOr(commanded_pose, single);
  fields["gpr_std"] = scalarOr(gpr_std, single);
  fields["iterations"] = scalarOr(iterations, single);
  fields["residual_position_m"] = scalarOr(residual_position, single);
  fields["residual_orientation_rad"] = scalarOr(residual_orientation, single);
  fields["uncovered_joints"] = scalarOr(uncovered, single);
  fields["wrench"] = scalarOr(wrench_used, single);
  fields["position_bound_m"] = scalarOr(position_bound, single);
  fields["orientation_bound_rad"] = scalarOr(orientation_bound, single);
  return resultObject(fields);
}

}  // namespace

ModelHandle::ModelHandle(CalibratedModel model) {
  const uint64_t id = fnv1a64(serializeModel(model));
  runtime_ = runtime::RuntimeModel::fromModel(std::move(model), id);
}

ModelHandle ModelHandle::load(const std::string& path) {
  ModelHandle handle;
  handle.runtime_ = runtime::RuntimeModel::load(path);
  return handle;
}

py::object statusObject(int8_t status) {
  return py::reinterpret_borrow<py::object>(g_status_type)(int(status));
}

py::handle g_model_id_type;

py::object modelIdObject(uint64_t model_id) {
  return py::reinterpret_borrow<py::object>(g_model_id_type)(model_id);
}

namespace {

/// stepcal.ModelId: the id stays an int (it compares with ints and other ids), its text is the
/// 16 hex digits that stepcal-client (tools/client/replies.cpp) and the daemon's log print.
py::object makeModelIdType() {
  py::dict scope;
  scope["__builtins__"] = py::module_::import("builtins");
  py::exec(R"(
class ModelId(int):
    """A model's id (FNV-1a 64 of its file's bytes): an int, printed as 16 hex digits as
    stepcal-client and the daemon print it."""
    __slots__ = ()
    __module__ = "stepcal"
    def __repr__(self):
        return format(int(self), "016x")
    __str__ = __repr__
)", scope);
  return scope["ModelId"];
}

/// stepcal.status_names(statuses): the names of one status or of an array of them.
py::object statusNames(const py::object& statuses) {
  const auto values =
      py::array_t<int, py::array::c_style | py::array::forcecast>::ensure(statuses);
  if (!values) throw py::value_error("statuses: expected a status or an array of statuses");
  const auto name = [&](ssize_t i) { return statusObject(int8_t(values.data()[i])).attr("name"); };
  if (values.ndim() == 0) return name(0);
  py::list names;
  for (ssize_t i = 0; i < values.size(); ++i) names.append(name(i));
  return std::move(names);
}

}  // namespace

void bindRuntime(py::module_& m) {
  // The runtime's statuses by their names (runtime::toString) and values, which travel over LCM.
  py::list members;
  for (const Status s : {Status::kOk, Status::kNotConverged, Status::kStaleWrench,
                         Status::kOutOfDomain, Status::kUnreachable, Status::kNearSingular,
                         Status::kBadRequest}) {
    members.append(py::make_tuple(runtime::toString(s), int(s)));
  }
  py::object status = py::module_::import("enum").attr("IntEnum")("Status", members,
                                                                  py::arg("module") = "stepcal");
  status.attr("__doc__") =
      "Outcome of a real-time call: OK, NOT_CONVERGED (the best answer within the budget), "
      "STALE_WRENCH (the live wrench is older than allowed), OUT_OF_DOMAIN (the GPR "
      "extrapolates; answer returned), UNREACHABLE (outside the workspace or the joint limits), "
      "NEAR_SINGULAR (the Jacobian is nearly singular), BAD_REQUEST (NaN/inf, wrong sizes, not "
      "a rotation). The values travel over LCM.";
  m.attr("Status") = status;
  g_status_type = status.release();
  m.def("status_names", &statusNames, py::arg("statuses"),
        "The names of statuses: one name for one status, a list of names for an array (the int8 "
        "arrays of correct_forward and solve_inverse), e.g. ['OK', 'BAD_REQUEST']");
  py::object model_id = makeModelIdType();
  m.attr("ModelId") = model_id;
  g_model_id_type = model_id.release();

  py::class_<ModelHandle>(m, "Model",
                          "A calibrated model file, loaded for the runtime's calls (immutable)")
      .def_static("load", &ModelHandle::load, py::arg("path"),
                  "Loads and validates a model file; raises stepcal.InputError naming the byte "
                  "offset and field of what is wrong")
      .def("save", [](const ModelHandle& self, const std::string& path) {
             writeModelFile(self.runtime()->file, path);
           }, py::arg("path"), "Writes the model file atomically (the previous file stays on failure)")
      .def_property_readonly("joint_count", [](const ModelHandle& self) {
             return self.runtime()->file.chain_Tracker.dof();
           })
      .def_property_readonly("model_id", [](const ModelHandle& self) {
             return modelIdObject(self.runtime()->model_id);
           }, "the id the daemon's replies carry for this model (from its file's bytes): a "
              "stepcal.ModelId, an int printed as 16 hex digits as stepcal-client prints it")
      .def_property_readonly("has_gpr", [](const ModelHandle& self) {
             return self.runtime()->file.gpr.has_value();
           })
      .def_property_readonly("has_flange", [](const ModelHandle& self) {
             return self.runtime()->has_flange;
           }, "whether the model knows the robot's flange (its campaign's flange_link), so that "
              "tools and centres of gravity may be given from it")
      .def("describe", [](const ModelHandle& self) {
             return report::formatModel(self.runtime()->file, serializeModel(self.runtime()->file).size());
           }, "what the model holds, as `stepcal inspect` prints it")
      .def("correct_forward", &correctForward, py::arg("q"), py::arg("wrench") = py::none(),
           py::arg("temp_c") = std::numeric_limits<double>::quiet_NaN(),
           py::arg("terms") = py::none(),
           "Pose the robot's TCP reaches at commanded joints q [rad], shape (n,) or (N, n), under "
           "the wrench on the F/T sensor [N, N·m] (shape (6,) or (N, 6); None: zero) or the "
           "payload of terms, at structure temperature temp_c [°C; NaN: not measured], in the "
           "frame and for the tool of terms (a stepcal.CallTerms; None: the tracker frame and the "
           "measured target). Returns status (Status, or an int8 array of Status values), "
           "position_m, quaternion_wxyz, pose (4×4), gpr_std (v [m], ω [rad]), wrench (the one "
           "used, sensor axes), uncovered_joints (bit j-1: joint j outside its profile's "
           "coverage). The GIL is released while the rows are computed.")
      .def("solve_inverse",
           [](const ModelHandle& self, const py::handle& pose, const py::handle& seed,
              const py::object& wrench, const py::object& temp_c, const py::object& budget_us,
              int max_iterations, double position_tolerance_m, double orientation_tolerance_rad,
              const py::object& terms) {
             runtime::InverseOptions options;
             options.max_iterations = max_iterations;
             options.position_tolerance_m = position_tolerance_m;
             options.orientation_tolerance_rad = orientation_tolerance_rad;
             return solveInverse(self, pose, seed, wrench, temp_c, budget_us, options, terms);
           },
           py::arg("pose"), py::arg("seed"), py::arg("wrench") = py::none(),
           py::arg("temp_c") = std::numeric_limits<double>::quiet_NaN(),
           py::arg("budget_us") = py::none(),
           py::arg("max_iterations") = runtime::InverseOptions{}.max_iterations,
           py::arg("position_tolerance_m") = runtime::InverseOptions{}.position_tolerance_m,
           py::arg("orientation_tolerance_rad") = runtime::InverseOptions{}.orientation_tolerance_rad,
           py::arg("terms") = py::none(),
           "Joint targets [rad] that make the real robot's TCP reach the desired pose in the frame "
           "of terms (a stepcal.CallTerms; None: the measured target in the tracker frame): "
           "(4, 4) / (N, 4, 4) matrices or (7,) / (N, 7) rows x, y, z [m], qw, qx, qy, qz; from "
           "seed [rad], (n,) or (N, n). budget_us: the time per pose (None: no deadline, the "
           "iteration cap alone). Returns status, q_target_rad, predicted_* (where the real "
           "robot's TCP ends up, in the call's frame), commanded_* (the nominal kinematics' TCP "
           "at the targets, in the controller's frame: the user frame, else the base frame), "
           "gpr_std, wrench, iterations, residual_position_m, residual_orientation_rad, "
           "uncovered_joints. The GIL is released while the rows are computed.");
}

}  // namespace stepcal::python

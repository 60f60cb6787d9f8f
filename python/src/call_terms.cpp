// stepcal.CallTerms: a call in the controller's terms (frame, tool, payload), the runtime's
// runtime::CallTerms (docs/python.md, "Tool, frame and payload").
#include <cmath>
#include <cstdio>
#include <string>

#include "bindings.hpp"
#include "stepcal/common/pose_quaternion.hpp"

namespace stepcal::python {
namespace {

constexpr double kRotationTolerance = 1e-9;        // ‖RᵀR − I‖ of a (4, 4) matrix's rotation

template <typename Enum>
Enum choiceOf(const std::string& value, const char* what,
              std::initializer_list<std::pair<const char*, Enum>> choices) {
  std::string names;
  for (const auto& [name, e] : choices) {
    if (value == name) return e;
    names += std::string(names.empty() ? "" : " | ") + name;
  }
  throw py::value_error(std::string(what) + " '" + value + "': expected " + names);
}

const char* nameOf(runtime::PoseFrame f) {
  return f == runtime::PoseFrame::kTracker ? "tracker" : f == runtime::PoseFrame::kBase ? "base" : "user";
}

std::string poseText(const Pose& X) {
  double p[3], q[4];
  toPositionQuaternion(X, p, q);
  char text[160];
  std::snprintf(text, sizeof text, "[%.6g, %.6g, %.6g, %.6g, %.6g, %.6g, %.6g]", p[0], p[1], p[2],
                q[0], q[1], q[2], q[3]);
  return text;
}

}  // namespace

Pose poseOf(const py::handle& value, const char* what) {
  const auto array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
  const bool matrix = array && array.ndim() == 2 && array.shape(0) == 4 && array.shape(1) == 4;
  const bool row = array && array.ndim() == 1 && array.shape(0) == 7;
  if (!matrix && !row) {
    throw py::value_error(std::string(what) +
                          ": expected a (4, 4) matrix or 7 numbers x, y, z [m], qw, qx, qy, qz");
  }
  const double* d = array.data();
  for (ssize_t i = 0; i < array.size(); ++i) {
    if (!std::isfinite(d[i])) throw py::value_error(std::string(what) + ": expected finite numbers");
  }
  Pose X = Pose::Identity();
  if (matrix) {
    const Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>> M(d);
    const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
    if (M.row(3) != Eigen::RowVector4d(0, 0, 0, 1) ||
        (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > kRotationTolerance ||
        R.determinant() < 0.0) {
      throw py::value_error(std::string(what) +
                            ": expected a homogeneous transform (a rotation within 1e-9 and a "
                            "last row 0, 0, 0, 1)");
    }
    X.matrix() = M;
  } else {
    const Eigen::Quaterniond q(d[3], d[4], d[5], d[6]);
    if (!isUnitQuaternion(q)) {
      throw py::value_error(std::string(what) + ": quaternion of norm " + std::to_string(q.norm()) +
                            ", expected a unit quaternion (within 1e-6)");
    }
    X = poseFromPositionQuaternion(Vec3(d[0], d[1], d[2]), q);
  }
  return X;
}

runtime::CallTerms termsOf(const py::object& terms) {
  if (terms.is_none()) return runtime::CallTerms{};
  if (!py::isinstance<runtime::CallTerms>(terms)) {
    throw py::type_error("terms: expected a stepcal.CallTerms or None");
  }
  return terms.cast<runtime::CallTerms>();
}

void checkTermsForModel(const runtime::RuntimeModel& model, const runtime::CallTerms& terms) {
  const bool payload = terms.load_from == runtime::LoadFrom::kPayload && terms.payload.mass_kg > 0.0;
  if (!model.has_flange && (terms.tool_from == runtime::ToolFrom::kFlange ||
                            (payload && terms.payload.frame == runtime::CogFrame::kFlange))) {
    throw py::value_error(
        "terms: a tool or centre of gravity given from the flange, but this model does not know "
        "its flange; calibrate with the campaign's flange_link (campaign.yaml), or give them from "
        "the target (tool_from='target', cog_frame='tool')");
  }
  if (payload && model.physical.gravity_Tracker.isZero(0.0)) {
    throw py::value_error(
        "terms: a payload, but this model knows no gravity to weigh it with (no compliance, no "
        "self weight); give its wrench instead");
  }
}

void bindCallTerms(py::module_& m) {
  py::class_<runtime::CallTerms>(m, "CallTerms",
                                 "A call in the controller's terms: the frame of its poses, its "
                                 "tool (TCP) and its payload (docs/python.md)")
      .def(py::init([](const std::string& frame, const py::object& user_frame,
                       const py::object& tool, const std::string& tool_from,
                       const py::object& payload_kg, const py::object& cog_m,
                       const std::string& cog_frame) {
             runtime::CallTerms t;
             t.frame = choiceOf<runtime::PoseFrame>(frame, "frame",
                                                    {{"tracker", runtime::PoseFrame::kTracker},
                                                     {"base", runtime::PoseFrame::kBase},
                                                     {"user", runtime::PoseFrame::kUser}});
             if ((t.frame == runtime::PoseFrame::kUser) == user_frame.is_none()) {
               throw py::value_error("user_frame goes with frame='user', and frame='user' needs it");
             }
             if (!user_frame.is_none()) t.X_BaseUser = poseOf(user_frame, "user_frame");
             t.tool_from = choiceOf<runtime::ToolFrom>(tool_from, "tool_from",
                                                       {{"target", runtime::ToolFrom::kTarget},
                                                        {"flange", runtime::ToolFrom::kFlange}});
             if (!tool.is_none()) t.X_Tool = poseOf(tool, "tool");
             t.payload.frame = choiceOf<runtime::CogFrame>(cog_frame, "cog_frame",
                                                           {{"flange", runtime::CogFrame::kFlange},
                                                            {"tool", runtime::CogFrame::kTool}});
             if (payload_kg.is_none()) {
               if (!cog_m.is_none()) throw py::value_error("cog_m goes with payload_kg");
               return t;
             }
             t.load_from = runtime::LoadFrom::kPayload;
             t.payload.mass_kg = payload_kg.cast<double>();
             if (!(std::isfinite(t.payload.mass_kg) && t.payload.mass_kg >= 0.0)) {
               throw py::value_error("payload_kg " + std::to_string(t.payload.mass_kg) +
                                     ": expected a mass >= 0 (kg)");
             }
             if (!cog_m.is_none()) {
               const Rows cog = rowsOf(cog_m, 3, "cog_m");
               if (!cog.single) throw py::value_error("cog_m: expected 3 numbers x, y, z (m)");
               t.payload.p_CoG_m = Eigen::Map<const Vec3>(cog.row(0));
               if (!t.payload.p_CoG_m.allFinite()) throw py::value_error("cog_m: expected finite numbers");
             }
             return t;
           }),
           py::kw_only(), py::arg("frame") = "tracker", py::arg("user_frame") = py::none(),
           py::arg("tool") = py::none(), py::arg("tool_from") = "target",
           py::arg("payload_kg") = py::none(), py::arg("cog_m") = py::none(),
           py::arg("cog_frame") = "flange",
           "frame: 'tracker' (the calibration's), 'base' (the robot's base frame) or 'user' "
           "(user_frame, a pose in the base frame). tool: the TCP, a (4, 4) matrix or x, y, z "
           "[m], qw, qx, qy, qz, from tool_from: 'target' (the measured target) or 'flange' (the "
           "controller's tool data). payload_kg, cog_m (m, in cog_frame: 'flange' or 'tool'): "
           "the controller's load data, whose weight at the deflected pose replaces the wrench. "
           "Raises ValueError naming the argument.")
      .def_property_readonly("frame", [](const runtime::CallTerms& t) { return nameOf(t.frame); })
      .def_property_readonly("tool_from", [](const runtime::CallTerms& t) {
        return t.tool_from == runtime::ToolFrom::kFlange ? "flange" : "target";
      })
      .def_property_readonly("payload_kg", [](const runtime::CallTerms& t) -> py::object {
        if (t.load_from != runtime::LoadFrom::kPayload) return py::none();
        return py::float_(t.payload.mass_kg);
      })
      .def("__repr__", [](const runtime::CallTerms& t) {
        std::string text = std::string("stepcal.CallTerms(frame='") + nameOf(t.frame) + "'";
        if (t.frame == runtime::PoseFrame::kUser) text += ", user_frame=" + poseText(t.X_BaseUser);
        text += ", tool=" + poseText(t.X_Tool) + ", tool_from='" +
                (t.tool_from == runtime::ToolFrom::kFlange ? "flange" : "target") + "'";
        if (t.load_from == runtime::LoadFrom::kPayload) {
          const Vec3& c = t.payload.p_CoG_m;
          char load[160];
          std::snprintf(load, sizeof load, ", payload_kg=%.6g, cog_m=[%.6g, %.6g, %.6g], cog_frame='%s'",
                        t.payload.mass_kg, c(0), c(1), c(2),
                        t.payload.frame == runtime::CogFrame::kTool ? "tool" : "flange");
          text += load;
        }
        return text + ")";
      });
}

}  // namespace stepcal::python

#include <algorithm>
#include <cmath>
#include <sstream>

#include "internal.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/robots.hpp"
#include "stepcal/common/urdf.hpp"

namespace stepcal::twin {
namespace {

std::string show(double v) {
  std::ostringstream s;
  s.precision(10);
  s << v;
  return s.str();
}

void requireFinite(double v, const std::string& name, const std::string& hint) {
  if (!std::isfinite(v)) {
    throw InputError("TwinOptions." + name + " = " + show(v) + "; expected a finite value (hint: " +
                     hint + ")");
  }
}

void requireNonNegative(double v, const std::string& name, const std::string& hint) {
  if (!(std::isfinite(v) && v >= 0.0)) {
    throw InputError("TwinOptions." + name + " = " + show(v) +
                     "; expected a finite value >= 0 (hint: " + hint + ")");
  }
}

}  // namespace

std::vector<JointSampleRange> defaultIrb4400PoseRanges() {
  const double d = kRadPerDeg;
  return {{-60 * d, 60 * d, 0.0},   {-30 * d, 60 * d, 0.0},   {-50 * d, 40 * d, 0.0},
          {-150 * d, 150 * d, 0.0}, {-110 * d, 110 * d, 15 * d}, {-180 * d, 180 * d, 0.0}};
}

std::string resolvedUrdfPath(const TwinOptions& options) {
  return options.urdf_path.empty() ? robotDescriptionPath("irb4400") : options.urdf_path;
}

KinematicChain nominalChain(const std::string& urdf_xml, const TwinOptions& options,
                            const std::string& source) {
  std::vector<std::string> attached;
  if (!options.sensor_link.empty()) attached.push_back(options.sensor_link);
  return chainFromUrdf(urdf_xml, options.base_link, options.tip_link, attached, source);
}

TwinOptions twinOptionsForRobot(const std::string& urdf_path, const std::string& base_link,
                                const std::string& tip_link, const std::string& sensor_link) {
  const std::string urdf_xml = readTextFile(urdf_path);
  TwinOptions o;
  o.urdf_path = urdf_path;
  o.base_link = base_link;
  o.tip_link = tip_link;
  o.sensor_link = sensor_link;
  // A robot's flange is named in its campaign only when its description has one by that name.
  if (!urdfHasLink(urdf_xml, o.flange_link, urdf_path)) o.flange_link.clear();
  o.protocol = sensor_link.empty() ? "geometry" : "paper";
  if (urdfRobotName(urdf_xml, urdf_path) == kPaperRobotName) return o;

  const KinematicChain nominal = nominalChain(urdf_xml, o, urdf_path);
  o.pose_ranges.clear();
  for (const ChainJoint& joint : nominal.joints()) {
    const bool limited = std::isfinite(joint.lower_rad) && std::isfinite(joint.upper_rad);
    o.pose_ranges.push_back({limited ? joint.lower_rad : -kPi, limited ? joint.upper_rad : kPi, 0.0});
  }
  double reach_m = 0.0;
  for (int k = 1; k <= nominal.dof(); ++k) reach_m += nominal.initialPose(k).translation().norm();
  o.min_tip_forward_m = 0.3 * reach_m;
  o.min_tip_height_m = 0.1 * reach_m;
  o.min_link_height_m = 0.1;

  o.stiffness_nm_per_rad.clear();
  const std::vector<double> effort_nm = jointEffortLimits(urdf_xml, base_link, tip_link, urdf_path);
  if (std::all_of(effort_nm.begin(), effort_nm.end(), [](double e) { return e > 0.0; })) {
    for (const double e : effort_nm) o.stiffness_nm_per_rad.push_back(e / kRatedTorqueDeflection_rad);
  }

  if (const auto bodies = bodyMassesFromUrdf(urdf_xml, base_link, tip_link, urdf_path)) {
    nlohmann::json links = nlohmann::json::array();
    for (int k = 1; k <= nominal.dof(); ++k) {
      const double* body = bodies->data() + 4 * (k - 1);  // m, m · centre of mass (3)
      if (!(body[0] > 0.0)) continue;
      links.push_back({{"link", k},
                       {"mass_kg", body[0]},
                       {"com_m", {body[1] / body[0], body[2] / body[0], body[3] / body[0]}}});
    }
    if (!links.empty()) o.hidden_effects.push_back({{"name", "self_weight"}, {"links", links}});
  }
  return o;
}

void validateOptions(const TwinOptions& options, const KinematicChain& nominal) {
  if (options.protocol != "paper" && options.protocol != "geometry") {
    throw InputError("TwinOptions.protocol = '" + options.protocol +
                     "'; expected 'paper' or 'geometry' (hint: 'geometry' writes only the 130 "
                     "unloaded rows, for quick tests)");
  }
  if (options.protocol == "paper" && options.sensor_link.empty() &&
      options.planned_fit_rows.empty()) {
    throw InputError("TwinOptions.protocol = 'paper' without a sensor_link; expected a link the "
                     "payloads hang from for the paper's loaded rows (hint: protocol 'geometry' "
                     "measures a robot without an F/T sensor unloaded)");
  }
  if (options.sensor_link.empty()) {
    for (const PlannedMeasurement& row : options.planned_fit_rows) {
      if (row.load_kg != 0.0) {
        throw InputError("pose '" + row.pose_id + "' at " + std::to_string(row.load_kg) +
                             " kg, but the robot has no sensor_link; expected unloaded rows only "
                             "(hint: a payload needs the link it hangs from, whose axes its "
                             "wrench is written in: the F/T sensor's, or a flange for a payload "
                             "of known mass)",
                         "poses", row.source_line);
      }
    }
  }
  if (options.station < 0) {
    throw InputError("TwinOptions.station = " + std::to_string(options.station) +
                     "; expected a tracker station >= 0 (hint: 0 is the seed's own tracker "
                     "placement, k >= 1 the same robot measured from another one)");
  }
  if (options.min_link_height_m && !std::isfinite(*options.min_link_height_m)) {
    throw InputError("TwinOptions.min_link_height_m = " + show(*options.min_link_height_m) +
                     "; expected a finite height above the floor, m, or unset");
  }
  const std::string noise_hint = "0 switches this noise off";
  requireNonNegative(options.tracker_position_sigma_m, "tracker_position_sigma_m",
                     noise_hint + "; a laser tracker is about 10e-6 m");
  requireNonNegative(options.tracker_orientation_sigma_rad, "tracker_orientation_sigma_rad",
                     noise_hint + "; a T-Mac is about 8.7e-5 rad (0.005 deg)");
  requireNonNegative(options.ft_force_sigma_n, "ft_force_sigma_n", noise_hint);
  requireNonNegative(options.ft_moment_sigma_nm, "ft_moment_sigma_nm", noise_hint);
  requireNonNegative(options.temperature_sigma_c, "temperature_sigma_c", noise_hint);
  requireFinite(options.temperature_c, "temperature_c", "degrees Celsius, e.g. 20");
  if (!(std::isfinite(options.temperature_swing_c) && options.temperature_swing_c >= 0.0 &&
        options.temperature_swing_c < 30.0)) {
    throw InputError("TwinOptions.temperature_swing_c = " + show(options.temperature_swing_c) +
                     "; expected a finite value in [0, 30) degrees Celsius (hint: 0 keeps the "
                     "temperature constant; a workshop swings a few degrees)");
  }
  if (!(std::isfinite(options.temperature_period_rows) &&
        options.temperature_period_rows > 0.0)) {
    throw InputError("TwinOptions.temperature_period_rows = " +
                     show(options.temperature_period_rows) +
                     "; expected a finite number of rows > 0 (hint: the default 300 gives 3.6 periods over "
                     "the paper protocol)");
  }
  if (!(std::isfinite(options.temperature_ramp_c) && std::abs(options.temperature_ramp_c) < 30.0)) {
    throw InputError("TwinOptions.temperature_ramp_c = " + show(options.temperature_ramp_c) +
                     "; expected a finite rise over the campaign with |value| < 30 degrees "
                     "Celsius (hint: 0 for none; a workshop warms a few degrees in a day)");
  }
  if (options.load_order != "blocks" && options.load_order != "mixed") {
    throw InputError("TwinOptions.load_order = '" + options.load_order +
                     "'; expected 'blocks' (the paper's: the payload changed once per block) or "
                     "'mixed' (the fit rows shuffled, so that load and time order do not "
                     "correlate)");
  }
  requireNonNegative(options.joint_frame_translation_sigma_m, "joint_frame_translation_sigma_m",
                     "metres, e.g. 0.3e-3");
  requireNonNegative(options.joint_frame_rotation_sigma_rad, "joint_frame_rotation_sigma_rad",
                     "radians, e.g. 5.2e-4 (0.03 deg)");
  requireNonNegative(options.tool_translation_error_m, "tool_translation_error_m",
                     "metres, e.g. 4.5e-3");
  requireNonNegative(options.tool_rotation_error_rad, "tool_rotation_error_rad",
                     "radians, e.g. 0.022 (1.25 deg)");
  if (!(std::isfinite(options.tracker_distance_min_m) &&
        std::isfinite(options.tracker_distance_max_m) && options.tracker_distance_min_m > 0.0 &&
        options.tracker_distance_min_m <= options.tracker_distance_max_m)) {
    throw InputError("TwinOptions.tracker_distance_min_m/max_m = " +
                     show(options.tracker_distance_min_m) + "/" +
                     show(options.tracker_distance_max_m) +
                     "; expected 0 < min <= max, metres (hint: a tracker stands 3 to 5 m away)");
  }
  for (int a = 0; a < 3; ++a) {
    const std::string axis = std::string("[") + "xyz"[a] + "]";
    requireFinite(options.p_CoGInSensor_m[a], "p_CoGInSensor_m" + axis, "metres");
    requireFinite(options.gravity_in_base_m_per_s2[a], "gravity_in_base_m_per_s2" + axis,
                  "m/s^2, e.g. (0, 0, -9.80665)");
  }
  requireFinite(options.min_tip_forward_m, "min_tip_forward_m", "metres along base +x");
  requireFinite(options.min_tip_height_m, "min_tip_height_m", "metres along base +z");

  const size_t n = static_cast<size_t>(nominal.dof());
  if (options.compliance && options.stiffness_nm_per_rad.size() != n) {
    throw InputError("TwinOptions.stiffness_nm_per_rad has " +
                     std::to_string(options.stiffness_nm_per_rad.size()) +
                     " values; expected one per revolute joint, " + std::to_string(n) +
                     " (hint: kPaperStiffnessNmPerRad is for a 6-axis robot; without effort "
                     "limits in its URDF a robot's stiffness must be given, stepcal simulate "
                     "--stiffness K1,...,Kn in N·m/rad)");
  }
  if (options.pose_ranges.size() != n) {
    throw InputError("TwinOptions.pose_ranges has " + std::to_string(options.pose_ranges.size()) +
                     " ranges; expected one per revolute joint, " + std::to_string(n) +
                     " (hint: defaultIrb4400PoseRanges() is for the IRB4400)");
  }
  for (size_t i = 0; i < n; ++i) {
    const JointSampleRange& r = options.pose_ranges[i];
    const ChainJoint& joint = nominal.joints()[i];
    const double lo = std::max(r.lower_rad, joint.lower_rad);
    const double hi = std::min(r.upper_rad, joint.upper_rad);
    const bool ok = std::isfinite(r.lower_rad) && std::isfinite(r.upper_rad) &&
                    std::isfinite(r.min_abs_rad) && r.min_abs_rad >= 0.0 && lo <= hi &&
                    std::max(std::abs(lo), std::abs(hi)) >= r.min_abs_rad;
    if (!ok) {
      throw InputError("TwinOptions.pose_ranges[" + std::to_string(i) + "] = [" +
                       show(r.lower_rad) + ", " + show(r.upper_rad) + "] rad, |q| >= " +
                       show(r.min_abs_rad) + " rad; expected a finite range that overlaps the " +
                       "URDF limits [" + show(joint.lower_rad) + ", " + show(joint.upper_rad) +
                       "] of joint '" + joint.name + "' outside |q| < min_abs_rad");
    }
  }
}

nlohmann::json toJson(const TwinOptions& o) {
  nlohmann::json ranges = nlohmann::json::array();
  for (const JointSampleRange& r : o.pose_ranges) {
    ranges.push_back(
        {{"lower_rad", r.lower_rad}, {"upper_rad", r.upper_rad}, {"min_abs_rad", r.min_abs_rad}});
  }
  const auto vec3 = [](const Vec3& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); };
  return {
      {"urdf_path", resolvedUrdfPath(o)},
      {"base_link", o.base_link},
      {"tip_link", o.tip_link},
      {"sensor_link", o.sensor_link},
      {"protocol", o.protocol},
      {"planned_fit_rows", o.planned_fit_rows.size()},
      {"noiseless_validation", o.noiseless_validation},
      {"seed", o.seed},
      {"station", o.station},
      {"tracker_position_sigma_m", o.tracker_position_sigma_m},
      {"tracker_orientation_sigma_rad", o.tracker_orientation_sigma_rad},
      {"ft_force_sigma_n", o.ft_force_sigma_n},
      {"ft_moment_sigma_nm", o.ft_moment_sigma_nm},
      {"temperature_c", o.temperature_c},
      {"temperature_swing_c", o.temperature_swing_c},
      {"temperature_period_rows", o.temperature_period_rows},
      {"temperature_ramp_c", o.temperature_ramp_c},
      {"load_order", o.load_order},
      {"temperature_sigma_c", o.temperature_sigma_c},
      {"tracker_distance_min_m", o.tracker_distance_min_m},
      {"tracker_distance_max_m", o.tracker_distance_max_m},
      {"geometric_errors", o.geometric_errors},
      {"joint_frame_translation_sigma_m", o.joint_frame_translation_sigma_m},
      {"joint_frame_rotation_sigma_rad", o.joint_frame_rotation_sigma_rad},
      {"tool_translation_error_m", o.tool_translation_error_m},
      {"tool_rotation_error_rad", o.tool_rotation_error_rad},
      {"compliance", o.compliance},
      {"stiffness_nm_per_rad", o.stiffness_nm_per_rad},
      {"hidden_effects", o.hidden_effects},
      {"p_CoGInSensor_m", vec3(o.p_CoGInSensor_m)},
      {"gravity_in_base_m_per_s2", vec3(o.gravity_in_base_m_per_s2)},
      {"pose_ranges", ranges},
      {"min_tip_forward_m", o.min_tip_forward_m},
      {"min_tip_height_m", o.min_tip_height_m},
      {"min_link_height_m",
       o.min_link_height_m ? nlohmann::json(*o.min_link_height_m) : nlohmann::json(nullptr)},
  };
}

nlohmann::json poseToJson(const Pose& X) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) {
    rows.push_back({X.matrix()(r, 0), X.matrix()(r, 1), X.matrix()(r, 2), X.matrix()(r, 3)});
  }
  return rows;
}

Pose poseFromJson(const nlohmann::json& j, const std::string& key) {
  Eigen::Matrix4d M;
  if (!j.is_array() || j.size() != 4) {
    throw InputError("'" + key + "' is not a 4x4 matrix; expected 4 rows of 4 numbers");
  }
  for (int r = 0; r < 4; ++r) {
    if (!j[r].is_array() || j[r].size() != 4) {
      throw InputError("'" + key + "' row " + std::to_string(r) +
                       " is not 4 numbers; expected a 4x4 matrix");
    }
    for (int c = 0; c < 4; ++c) M(r, c) = j[r][c].get<double>();
  }
  const Mat3 R = M.topLeftCorner<3, 3>();
  const bool rigid = M.allFinite() && (R.transpose() * R - Mat3::Identity()).norm() < 1e-9 &&
                     R.determinant() > 0.0 &&
                     (M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() == 0.0;
  if (!rigid) {
    throw InputError("'" + key +
                     "' is not a rigid transform; expected a rotation block and last row 0 0 0 1");
  }
  Pose X;
  X.matrix() = M;
  return X;
}

}  // namespace stepcal::twin

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "internal.hpp"
#include "random.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/twin/twin.hpp"

namespace stepcal::twin {
namespace {

constexpr char kTruthFormat[] = "stepcal-twin-truth/1";
// The compliance fixed point contracts by about m·g·r/K ≈ 1e-3 per iteration; 100 iterations
// are only reached when a mechanism makes the structure unstable.
constexpr int kMaxFixedPointIterations = 100;
constexpr double kFixedPointTolerance_rad = 1e-12;

nlohmann::json vecToJson(const Eigen::Ref<const Eigen::VectorXd>& v) {
  nlohmann::json a = nlohmann::json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v(i));
  return a;
}

template <int N>
Eigen::Matrix<double, N, 1> vecFromJson(const nlohmann::json& j, const std::string& key) {
  if (!j.is_array() || j.size() != static_cast<size_t>(N)) {
    throw InputError("'" + key + "' is not " + std::to_string(N) + " numbers");
  }
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) v(i) = j[static_cast<size_t>(i)].get<double>();
  return v;
}

// JSON has no infinity: an unlimited (continuous) joint limit is written as null.
nlohmann::json limitToJson(double v) { return std::isfinite(v) ? nlohmann::json(v) : nullptr; }
double limitFromJson(const nlohmann::json& j, double if_null) {
  return j.is_null() ? if_null : j.get<double>();
}

// Where the tracker stands: see TwinOptions::tracker_distance_min_m.
Pose drawTrackerBase(Rng& rng, const TwinOptions& o) {
  const double distance = rng.uniform(o.tracker_distance_min_m, o.tracker_distance_max_m);
  const double azimuth = rng.uniform(-60.0 * kRadPerDeg, 60.0 * kRadPerDeg);
  const double height = rng.uniform(0.8, 1.6);
  const double yaw = rng.uniform(-kPi, kPi);
  const double tilt_x = rng.uniform(-2.0 * kRadPerDeg, 2.0 * kRadPerDeg);
  const double tilt_y = rng.uniform(-2.0 * kRadPerDeg, 2.0 * kRadPerDeg);
  Pose X_BaseTracker = Pose::Identity();
  X_BaseTracker.translation() =
      Vec3(distance * std::cos(azimuth), distance * std::sin(azimuth), height);
  X_BaseTracker.linear() = lie::rotationFromRpy(tilt_x, tilt_y, yaw);
  return X_BaseTracker.inverse();
}

}  // namespace

TwinRobot::TwinRobot(const TwinOptions& options) {
  const std::string path = resolvedUrdfPath(options);
  const KinematicChain nominal = nominalChain(readTextFile(path), options, path);
  validateOptions(options, nominal);

  // Draw order is part of the format: the tracker first, then the initial poses. Station 0's
  // tracker is drawn at every station, so that every station has the same robot.
  Rng rng(options.seed, Stream::kTruth);
  X_TrackerBase_ = drawTrackerBase(rng, options);
  if (options.station > 0) {
    Rng station_rng(options.seed, Stream::kStation, static_cast<uint32_t>(options.station));
    X_TrackerBase_ = drawTrackerBase(station_rng, options);
  }
  chain_ = nominal;
  const int n = nominal.dof();
  geometric_errors_.assign(static_cast<size_t>(n + 1), Vec6::Zero());
  if (options.geometric_errors) {
    for (int k = 0; k <= n; ++k) {
      Vec6& delta = geometric_errors_[static_cast<size_t>(k)];
      if (k < n) {
        delta.head<3>() = rng.normal3(options.joint_frame_translation_sigma_m);
        delta.tail<3>() = rng.normal3(options.joint_frame_rotation_sigma_rad);
      } else {
        // The tool (T-Mac mount) is where a real robot's nominal model is worst.
        delta.head<3>() = options.tool_translation_error_m * rng.unitVector();
        delta.tail<3>() = options.tool_rotation_error_rad * rng.unitVector();
      }
      chain_.setInitialPose(k, nominal.initialPose(k) * lie::expSE3(delta));
    }
  }
  // The sensor keeps its nominal offset from joint n: the tool error lies beyond it.
  sensor_frame_ = options.sensor_link.empty() ? -1 : chain_.findFrame(options.sensor_link);
  p_CoGInSensor_m_ = options.p_CoGInSensor_m;
  gravity_in_base_ = options.gravity_in_base_m_per_s2;
  if (options.compliance) {
    effects_.link_angle.push_back(std::make_shared<JointCompliance>(options.stiffness_nm_per_rad));
  }
  for (const nlohmann::json& effect : options.hidden_effects) {
    try {
      effects_.add(effect, chain_.dof());
    } catch (const nlohmann::json::exception& e) {
      throw InputError("hidden effect " + effect.dump() + ": " + e.what() +
                       "; expected a name and its parameters (tools/twin/.../effects.hpp)");
    }
  }
  base_link_ = options.base_link;
  tip_link_ = options.tip_link;
  sensor_link_ = options.sensor_link;
  provenance_ = {
      {"seed", options.seed},
      {"options", toJson(options)},
      {"noise",
       {{"tracker_position_sigma_m", options.tracker_position_sigma_m},
        {"tracker_orientation_sigma_rad", options.tracker_orientation_sigma_rad},
        {"ft_force_sigma_n", options.ft_force_sigma_n},
        {"ft_moment_sigma_nm", options.ft_moment_sigma_nm},
        {"temperature_sigma_c", options.temperature_sigma_c}}},
  };
}

Vec6 TwinRobot::payloadWrenchAtBase(const ChainWorkspace& ws, double load_kg) const {
  if (sensor_frame_ < 0) {
    STEPCAL_INVARIANT(load_kg == 0.0, "a payload hangs from the sensor link (validateOptions)");
    return Vec6::Zero();
  }
  const Vec3 p_CoGInBase = framePose(chain_, ws, sensor_frame_) * p_CoGInSensor_m_;
  const Vec3 f = load_kg * gravity_in_base_;
  Vec6 W;
  W.head<3>() = f;
  W.tail<3>() = p_CoGInBase.cross(f);
  return W;
}

TwinRobot::Deflection TwinRobot::deflection(const JointVector& q_cmd_rad, double load_kg,
                                            double temp_c) const {
  STEPCAL_INVARIANT(q_cmd_rad.size() == chain_.dof(), "one commanded angle per joint");
  const double scale = effects_.linkLengthScale(temp_c);
  ChainWorkspace ws;
  Jacobian J;
  Deflection d{q_cmd_rad, std::vector<Vec3>(static_cast<size_t>(chain_.dof()), Vec3::Zero())};
  std::vector<Vec3> next_tilt = d.tilt_rad;
  for (int iteration = 0; iteration < kMaxFixedPointIterations; ++iteration) {
    framesAt(d, scale, ws);
    spatialJacobian(chain_, ws, J);
    const Vec6 W_payload = payloadWrenchAtBase(ws, load_kg);
    JointVector tau = J.transpose() * W_payload;
    if (effects_.self_weight) effects_.self_weight->addTorques(ws, J, gravity_in_base_, tau);
    JointVector next = q_cmd_rad;
    for (const auto& effect : effects_.link_angle) effect->apply(q_cmd_rad, tau, next);
    for (const JointZeroDrift& drift : effects_.zero_drift) drift.apply(temp_c, next);
    double step = (next - d.link_angles_rad).cwiseAbs().maxCoeff();
    d.link_angles_rad = next;
    if (!effects_.bearing_tilt.empty()) {
      bearingTilts(ws, W_payload, next_tilt);
      for (size_t k = 0; k < next_tilt.size(); ++k) {
        step = std::max(step, (next_tilt[k] - d.tilt_rad[k]).cwiseAbs().maxCoeff());
      }
      d.tilt_rad = next_tilt;
    }
    if (step <= kFixedPointTolerance_rad) {
      if (effects_.tool_mount && sensor_frame_ >= 0) {
        d.tool_shift_m = effects_.tool_mount->shift(
            W_payload.head<3>(), framePose(chain_, ws, sensor_frame_).linear().col(2));
      }
      return d;
    }
  }
  throw InputError("the link angles under a " + std::to_string(load_kg) +
                   " kg payload did not converge; expected a structure stiff enough to carry it "
                   "(hint: check stiffness_nm_per_rad, bearing_tilt's compliance, the payload "
                   "and self_weight's masses)");
}

JointVector TwinRobot::linkAngles(const JointVector& q_cmd_rad, double load_kg,
                                  double temp_c) const {
  return deflection(q_cmd_rad, load_kg, temp_c).link_angles_rad;
}

void TwinRobot::framesAt(const Deflection& d, double scale, ChainWorkspace& ws) const {
  forwardKinematics(chain_, d.link_angles_rad, ws, scale);
  const size_t tip = static_cast<size_t>(chain_.dof() + 1);
  for (const BearingTilt& bearing : effects_.bearing_tilt) {
    const size_t j = static_cast<size_t>(bearing.joint());
    if (d.tilt_rad[j - 1].isZero(0.0)) continue;  // unloaded: the frames exactly as they are
    // X_0,k ← X_0,j · exp(δ̂) · X_0,j⁻¹ · X_0,k for k = j … tip: the frames beyond turn with j's.
    Pose X_Tilt = Pose::Identity();
    X_Tilt.linear() = lie::expSO3(d.tilt_rad[j - 1]);
    const Pose moved = ws.X_RootFrame[j] * X_Tilt * ws.X_RootFrame[j].inverse();
    for (size_t k = j; k <= tip; ++k) ws.X_RootFrame[k] = moved * ws.X_RootFrame[k];
  }
  ws.X_RootFrame[tip].translation() += d.tool_shift_m;
}

void TwinRobot::bearingTilts(const ChainWorkspace& ws, const Vec6& W_payload,
                             std::vector<Vec3>& tilt_rad) const {
  for (const BearingTilt& bearing : effects_.bearing_tilt) {
    const int j = bearing.joint();
    Vec6 W = W_payload;
    if (effects_.self_weight) {
      W += effects_.self_weight->wrenchOfLinksFrom(j, ws, gravity_in_base_);
    }
    // The moment about the joint frame's origin, in its axes.
    const Pose& X_BaseJoint = ws.X_RootFrame[static_cast<size_t>(j)];
    const Vec3 moment_Base = W.tail<3>() - X_BaseJoint.translation().cross(W.head<3>());
    const Vec3 moment_Joint = X_BaseJoint.linear().transpose() * moment_Base;
    const Vec3 axis_Joint = chain_.joints()[static_cast<size_t>(j - 1)].twist_Local.tail<3>();
    tilt_rad[static_cast<size_t>(j - 1)] = bearing.tilt(moment_Joint, axis_Joint);
  }
}

void TwinRobot::deflectedFrames(const JointVector& q_cmd_rad, double load_kg, double temp_c,
                                ChainWorkspace& ws) const {
  framesAt(deflection(q_cmd_rad, load_kg, temp_c), effects_.linkLengthScale(temp_c), ws);
}

Pose TwinRobot::X_BaseTip(const JointVector& q_cmd_rad, double load_kg, double temp_c) const {
  ChainWorkspace ws;
  deflectedFrames(q_cmd_rad, load_kg, temp_c, ws);
  return tipPose(ws);
}

Pose TwinRobot::X_TrackerTip(const JointVector& q_cmd_rad, double load_kg,
                             double temp_c) const {
  return X_TrackerBase_ * X_BaseTip(q_cmd_rad, load_kg, temp_c);
}

Vec6 TwinRobot::sensorWrench(const JointVector& q_cmd_rad, double load_kg, double temp_c) const {
  if (sensor_frame_ < 0) return Vec6::Zero();
  ChainWorkspace ws;
  deflectedFrames(q_cmd_rad, load_kg, temp_c, ws);
  const Mat3 R_BaseSensor = framePose(chain_, ws, sensor_frame_).linear();
  const Vec3 f_Sensor = R_BaseSensor.transpose() * (load_kg * gravity_in_base_);
  Vec6 W;
  W.head<3>() = f_Sensor;
  W.tail<3>() = p_CoGInSensor_m_.cross(f_Sensor);
  return W;
}

Vec6 TwinRobot::sensorReading(const JointVector& q_cmd_rad, double load_kg, double temp_c) const {
  return sensorWrench(q_cmd_rad, load_kg, temp_c) + effects_.sensorBias_Sensor();
}

nlohmann::json TwinRobot::truthJson() const {
  nlohmann::json joints = nlohmann::json::array();
  for (const ChainJoint& j : chain_.joints()) {
    joints.push_back({{"name", j.name},
                      {"twist_local", vecToJson(j.twist_Local)},
                      {"lower_rad", limitToJson(j.lower_rad)},
                      {"upper_rad", limitToJson(j.upper_rad)}});
  }
  nlohmann::json initial = nlohmann::json::array();
  for (const Pose& X : chain_.initialPoses()) initial.push_back(poseToJson(X));
  nlohmann::json errors = nlohmann::json::array();
  for (const Vec6& d : geometric_errors_) errors.push_back(vecToJson(d));

  nlohmann::json truth = provenance_;
  truth["format"] = kTruthFormat;
  truth["base_link"] = base_link_;
  truth["tip_link"] = tip_link_;
  truth["sensor_link"] = sensor_link_;
  truth["X_TrackerBase_m"] = poseToJson(X_TrackerBase_);
  truth["joints"] = joints;
  truth["initial_poses_m"] = initial;
  truth["initial_pose_errors_m_rad"] = errors;
  if (sensor_frame_ >= 0) {
    const AttachedFrame& sensor = chain_.frames()[static_cast<size_t>(sensor_frame_)];
    truth["sensor_frame"] = {{"parent_joint", sensor.parent},
                             {"X_ParentSensor_m", poseToJson(sensor.X_ParentFrame)}};
  } else {
    truth["sensor_frame"] = nullptr;  // no sensor: every row unloaded
  }
  truth["effects"] = effects_.toJson();
  truth["p_CoGInSensor_m"] = vecToJson(p_CoGInSensor_m_);
  truth["gravity_in_base_m_per_s2"] = vecToJson(gravity_in_base_);
  return truth;
}

TwinRobot TwinRobot::fromTruthJson(const nlohmann::json& truth) {
  try {
    const std::string format = truth.at("format").get<std::string>();
    if (format != kTruthFormat) {
      throw InputError("truth format '" + format + "'; expected '" + kTruthFormat + "'");
    }
    TwinRobot robot;
    std::vector<ChainJoint> joints;
    for (const nlohmann::json& j : truth.at("joints")) {
      ChainJoint joint;
      joint.name = j.at("name").get<std::string>();
      joint.twist_Local = vecFromJson<6>(j.at("twist_local"), "twist_local");
      joint.lower_rad =
          limitFromJson(j.at("lower_rad"), -std::numeric_limits<double>::infinity());
      joint.upper_rad = limitFromJson(j.at("upper_rad"), std::numeric_limits<double>::infinity());
      joints.push_back(joint);
    }
    std::vector<Pose> initial;
    for (const nlohmann::json& X : truth.at("initial_poses_m")) {
      initial.push_back(poseFromJson(X, "initial_poses_m"));
    }
    if (joints.empty() || joints.size() > static_cast<size_t>(kMaxJoints) ||
        initial.size() != joints.size() + 1) {
      throw InputError("truth has " + std::to_string(joints.size()) + " joints and " +
                       std::to_string(initial.size()) + " initial poses; expected 1 to " +
                       std::to_string(kMaxJoints) + " joints and one initial pose more");
    }
    for (const nlohmann::json& d : truth.at("initial_pose_errors_m_rad")) {
      robot.geometric_errors_.push_back(vecFromJson<6>(d, "initial_pose_errors_m_rad"));
    }
    robot.sensor_link_ = truth.at("sensor_link").get<std::string>();
    const nlohmann::json& sensor = truth.at("sensor_frame");
    std::vector<AttachedFrame> frames;
    if (!sensor.is_null()) {
      AttachedFrame frame;
      frame.name = robot.sensor_link_;
      frame.parent = sensor.at("parent_joint").get<int>();
      frame.X_ParentFrame = poseFromJson(sensor.at("X_ParentSensor_m"), "X_ParentSensor_m");
      if (frame.parent < 0 || frame.parent > static_cast<int>(joints.size())) {
        throw InputError("sensor_frame.parent_joint = " + std::to_string(frame.parent) +
                         "; expected 0 to the number of joints");
      }
      frames.push_back(frame);
    }
    const size_t n = joints.size();
    robot.chain_ = KinematicChain(std::move(joints), std::move(initial), frames);
    robot.sensor_frame_ = frames.empty() ? -1 : 0;
    for (const nlohmann::json& e : truth.at("effects")) robot.effects_.add(e, static_cast<int>(n));
    robot.X_TrackerBase_ = poseFromJson(truth.at("X_TrackerBase_m"), "X_TrackerBase_m");
    robot.p_CoGInSensor_m_ = vecFromJson<3>(truth.at("p_CoGInSensor_m"), "p_CoGInSensor_m");
    robot.gravity_in_base_ =
        vecFromJson<3>(truth.at("gravity_in_base_m_per_s2"), "gravity_in_base_m_per_s2");
    robot.base_link_ = truth.at("base_link").get<std::string>();
    robot.tip_link_ = truth.at("tip_link").get<std::string>();
    for (const char* key : {"seed", "options", "noise"}) {
      if (truth.contains(key)) robot.provenance_[key] = truth.at(key);
    }
    return robot;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("truth JSON: ") + e.what() +
                     "; expected the layout written by TwinRobot::truthJson");
  }
}

}  // namespace stepcal::twin

// The twin of a calibrated robot: a simulated robot that behaves as a model file says the real
// one does, measured like the campaign the model came from.
//
// Where the twin of twin.hpp draws a robot that differs from its nominal URDF at random, this
// one's truth is a model file (`stepcal calibrate --out`, `stepcal diagnose --out`): its
// calibrated chain and tracker registration, its joint compliances and every mechanism it holds
// (self weight, transmission profiles and their share of the geometry, backlash, …), applied by
// common's physicalLinkAngles, the runtime's own physics. The GPR layer is not applied: it is a
// fit of what the physical model leaves, not a mechanism. So a geometric model fitted on this
// twin's campaign leaves what the model's mechanisms make of the geometry plus the tracker's noise;
// on the real robot it also leaves what the model does not explain.
//
// It measures a campaign's rows (its joint angles, sets, loads, F/T readings and temperatures, in
// its time order), or a pose list as the fit rows followed by the campaign's validation rows, with
// the tracker noise the campaign states. Like the other twin it shares only common with the
// trainer.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/model_file.hpp"

namespace stepcal::twin {

/// What a twin of a calibrated robot measures. Bad values throw InputError.
struct ModelTwinOptions {
  /// The model file whose robot is simulated.
  std::string model_path;
  /// The campaign whose robot description, stated tracker noise and rows are used; empty: the
  /// model's own (its provenance's campaign path).
  std::string campaign_dir;
  /// A pose list (readPoseList): when not empty, these are the fit rows in their order (unloaded
  /// rows set=geometry, loaded ones set=stiffness under the same pose_id), followed by the
  /// campaign's validation rows; loaded rows need the model's F/T sensor frame.
  std::vector<PlannedMeasurement> planned_fit_rows;
  /// Seeds the noise; same seed, same campaign.
  uint64_t seed = 1;
  /// Tracker position noise per axis, 1-σ, m; unset: the campaign's stated noise.
  std::optional<double> tracker_position_sigma_m;
  /// Tracker orientation noise per axis, 1-σ, rad; unset: the campaign's stated noise.
  std::optional<double> tracker_orientation_sigma_rad;
  /// F/T noise per axis of the planned loaded rows' readings, 1-σ, N and N·m. The campaign's own
  /// rows keep their recorded readings (they are the physical model's input, noise and all).
  double ft_force_sigma_n = 0.2;
  double ft_moment_sigma_nm = 0.01;
  /// The planned payloads' centre of gravity in the sensor frame, m.
  Vec3 p_CoGInSensor_m = Vec3(0.03, -0.02, 0.15);
  /// Tilts switched on in the twin beside the model's own mechanisms: per entry (joint 0-based,
  /// c rad/(N·m)) an isotropic off_axis_compliance of that joint (a bearing's tilt across its
  /// axis, c M⊥; about 1e-7 on a heavy robot's base), where the model holds none.
  std::vector<std::pair<int, double>> off_axis_compliance;
  /// The tool's mount switched on in the twin beside the model's own mechanisms: a
  /// tool_mount_compliance giving along the sensor's z by this many m/N (as the URDF twin's
  /// tool_mount_compliance; about 2e-7 for a compliant mount), where the model holds none; 0 none.
  double tool_mount_compliance_m_per_n = 0.0;
};

/// A robot that moves as a model's physical part says (no GPR). Noiseless.
class ModelTwin {
 public:
  /// The physical part of model (physicalModelOf), with the mechanisms added (each checked:
  /// InputError naming it when it does not fit the model).
  explicit ModelTwin(const CalibratedModel& model, const std::vector<Mechanism>& added = {});

  /// Tip pose in the tracker frame at commanded angles q_cmd_rad [rad], with the F/T sensor
  /// reading wrench_Sensor (f N, m N·m, sensor axes, as a campaign records it: a sensor_bias of
  /// the model is in it) and at temp_c [°C] (NaN: unknown, the links at reference length), m.
  Pose X_TrackerTip(const JointVector& q_cmd_rad, const Vec6& wrench_Sensor, double temp_c) const;
  /// The reading (f N, m N·m, sensor axes) of a payload of load_kg [kg] with its centre of gravity
  /// at p_CoGInSensor_m [m], at the pose it deflects the arm to, plus the model's sensor_bias.
  /// Needs the model's sensor frame (STEPCAL_INVARIANT).
  Vec6 payloadReading(const JointVector& q_cmd_rad, double load_kg, const Vec3& p_CoGInSensor_m,
                      double temp_c) const;

  const PhysicalModel& physical() const noexcept { return physical_; }

 private:
  PhysicalModel physical_;
  PhysicalConstants constants_;
};

/// Simulates the campaign of ModelTwinOptions: its robot description, links and gravity, the
/// tracker noise used (stated), and each row measured on the model's robot with noise. Throws
/// InputError (bad model file or campaign, a model that is not of the campaign's robot, no
/// stated tracker noise and none given, loaded planned rows without a sensor frame). truth_out
/// (may be null) receives what made it: the model file, campaign, seed and noise
/// (format "stepcal-model-twin/1").
Campaign simulateFromModel(const ModelTwinOptions& options, nlohmann::json* truth_out);

/// Writes simulateFromModel's campaign into out_dir (writeCampaign) and truth.json beside it.
void writeModelSimulation(const ModelTwinOptions& options, const std::string& out_dir);

}  // namespace stepcal::twin

// The simulated robot (digital twin): a robot that differs from its nominal URDF the way a real
// one does, measured by a laser tracker and an F/T sensor.
//
// The campaign it writes has the form of a real one (campaign-format.md); the true parameters go
// to a separate truth.json that calibration never reads. Everything is SI inside.
//
// Randomness: every draw comes from std::mt19937_64 engines seeded from TwinOptions::seed, one
// independent stream each for the truth, the commanded poses, the measurement noise and a mixed
// load order (TwinOptions::load_order), so that switching a mechanism or a noise level off
// leaves every other draw unchanged; a tracker
// station k >= 1 (TwinOptions::station) shares the truth's and has streams of its own for its
// tracker placement, poses and noise. Normal variates use Box–Muller on 53-bit uniforms rather
// than std::normal_distribution, whose output differs between standard libraries.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"
#include "stepcal/common/types.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/twin/effects.hpp"

namespace stepcal::twin {

/// Temperature argument of TwinRobot's pose functions meaning "no thermal expansion": the links
/// at their reference length (scale 1), whatever thermal_expansion the robot has.
inline constexpr double kNoThermalExpansion = std::numeric_limits<double>::quiet_NaN();

/// Joint stiffness identified in the reference paper for the IRB4400, joints 1–6, N·m/rad.
inline const std::vector<double> kPaperStiffnessNmPerRad = {501130.0, 633590.0, 508209.0,
                                                            124391.0, 75782.0,  74226.0};

/// Where one joint's commanded angle is drawn from (clipped to the URDF limits).
struct JointSampleRange {
  double lower_rad = 0.0;    ///< rad
  double upper_rad = 0.0;    ///< rad
  double min_abs_rad = 0.0;  ///< angles with |q| below this are redrawn (singularity), rad
};

/// Sampling ranges for the IRB4400: tip in front of the robot, |q5| ≥ 15° (wrist singularity),
/// elbow away from stretched.
std::vector<JointSampleRange> defaultIrb4400PoseRanges();

/// `<robot name>` of the shipped IRB 4400/60 (robots/irb4400.urdf): the robot whose stiffness
/// and pose ranges the paper gives (TwinOptions' defaults).
inline constexpr const char* kPaperRobotName = "abb_irb4400_60";

/// What sets a joint's stiffness in a twin of a robot the paper does not give it for: the joint
/// deflects this much at its rated torque (URDF <limit effort>), K = effort / this, rad. On the
/// real UR10 (Series C, identified from the arm's own weight, docs/diagnosis.md) the shoulder
/// deflects 3.5 mrad at its 330 N·m and the elbow 2.3 mrad at its 150 N·m.
inline constexpr double kRatedTorqueDeflection_rad = 3e-3;

/// Everything that defines a simulated campaign. Bad values throw InputError.
struct TwinOptions {
  /// Nominal robot description; empty: the shipped irb4400 (robots.hpp: found at run time).
  std::string urdf_path;
  std::string base_link = "base_link";  ///< root of the chain
  std::string tip_link = "tmac";        ///< frame the tracker measures
  /// The link the payload hangs from and whose axes its wrench is read in: the F/T sensor's, or
  /// for a payload of known mass without a sensor any link of the arm (its wrench is then the
  /// known weight, written as the reading). Empty: none, so every row is unloaded and has no
  /// wrench (protocol "geometry", or a pose list at 0 kg).
  std::string sensor_link = "ft_sensor";
  /// The robot's mounting flange, named in the campaign (flange_link; empty: none;
  /// twinOptionsForRobot empties it when the robot's description has no link of that name).
  std::string flange_link = "flange";
  /// "paper" (the reference protocol, 1070 rows; needs sensor_link) or "geometry" (its 80 + 50
  /// unloaded rows).
  std::string protocol = "paper";
  /// Seeds every random draw; same seed, same campaign.
  uint64_t seed = 1;
  /// Tracker station, >= 0: the same robot measured in another session with the tracker moved.
  /// 0 is the seed's own campaign. A station k >= 1 keeps everything drawn from the seed's truth
  /// (geometric errors, compliance, hidden effects) but places the tracker anew (as
  /// tracker_distance_min_m describes, from a stream of its own for seed and k) and draws its
  /// commanded poses and its noise (tracker, sensor, temperature reading) from streams of their
  /// own, so that each station measures other poses with independent noise.
  int station = 0;
  /// A planned campaign (readPoseList): when not empty, these are the fit rows, measured in
  /// their order (unloaded rows set=geometry, loaded rows set=stiffness under the same pose_id),
  /// followed by the protocol's validation rows at the same poses as without them.
  std::vector<PlannedMeasurement> planned_fit_rows;
  /// Validation rows measured without noise (tracker, sensor, temperature; the draws still
  /// happen, so every other row stays): a model's error on them is its error against the truth.
  bool noiseless_validation = false;

  /// Tracker position noise per axis, 1-σ, m.
  double tracker_position_sigma_m = 10e-6;
  /// Tracker orientation noise per axis (rotation vector in tracker axes), 1-σ, rad.
  double tracker_orientation_sigma_rad = 0.005 * kRadPerDeg;
  /// F/T force noise per axis, 1-σ, N.
  double ft_force_sigma_n = 0.2;
  /// F/T moment noise per axis, 1-σ, N·m.
  double ft_moment_sigma_nm = 0.01;
  /// Order of the fit rows (set geometry, stiffness, residual; or planned_fit_rows): "blocks"
  /// (the paper's: every pose at one load before the payload changes, so the load rises and
  /// falls with the time order) or "mixed" (the same rows shuffled among the fit rows' places
  /// in the time order, from a stream of their own for seed and station, so that the load and
  /// the time order do not correlate and a tracker's drift can be told from a load effect).
  /// The validation rows keep their blocks and places. Every other draw is unchanged.
  std::string load_order = "blocks";
  /// Mean ambient temperature, °C. The true temperature of row seq (1, 2, …, rows) is
  ///   T(seq) = temperature_c + temperature_swing_c · sin(2π seq / temperature_period_rows)
  ///            + temperature_ramp_c · (seq − 1) / (rows − 1),
  /// which drives thermal_expansion; temp_c reads it with noise. By default 2.7 periods over
  /// the paper protocol's 1070 rows: the temperature varies within the blocks (geometry,
  /// stiffness loads, residual loads, 55 kg) instead of being one value per block.
  double temperature_c = 20.0;
  /// Amplitude of the temperature's sinusoid, °C, finite, ≥ 0 and < 30 (0: constant).
  double temperature_swing_c = 3.0;
  /// Period of the temperature's sinusoid in rows, > 0.
  double temperature_period_rows = 300.0;
  /// Rise of the temperature over the campaign, first row to last, °C, finite with |ramp| < 30
  /// (0: none). With temperature_swing_c 0 a steady ramp: temperature and time order then
  /// correlate fully (a workshop warming through the day), which no thermal effect can be told
  /// apart from a drift in time by.
  double temperature_ramp_c = 0.0;
  /// Noise of the temperature reading, 1-σ, °C.
  double temperature_sigma_c = 0.05;

  /// Tracker placement: horizontal distance of the tracker from the base origin, m (uniform
  /// in [min, max]); it stands within ±60° of base +x, its head 0.8–1.6 m above the base
  /// origin, levelled to within ±2°, its frame's zero azimuth arbitrary.
  double tracker_distance_min_m = 3.0;
  double tracker_distance_max_m = 5.0;  ///< m

  /// Perturb the initial pose matrices (false: the true geometry is the nominal one).
  bool geometric_errors = true;
  /// Joint frames T_{k,k+1}(0), k < n: translation error per axis, 1-σ, m.
  double joint_frame_translation_sigma_m = 0.3e-3;
  /// Joint frames: rotation error per axis, 1-σ, rad.
  double joint_frame_rotation_sigma_rad = 0.03 * kRadPerDeg;
  /// Tool frame T_{n,n+1}: length of the translation error (direction uniform), m.
  double tool_translation_error_m = 4.5e-3;
  /// Tool frame: angle of the rotation error (axis uniform), rad.
  double tool_rotation_error_rad = 1.25 * kRadPerDeg;

  /// Joints deflect under the payload (JointCompliance).
  bool compliance = true;
  /// K_θ per joint, N·m/rad; one per revolute joint of the chain.
  std::vector<double> stiffness_nm_per_rad = kPaperStiffnessNmPerRad;
  /// Hidden mechanisms, each as its truth.json object (effects.hpp, EffectSet::add), e.g.
  /// {"name": "backlash", "joint": 2, "lost_motion_rad": 2e-4}; the link-angle effects act after
  /// the compliance, in the order given; self_weight, thermal_expansion and sensor_bias at most
  /// once each. Bad ones throw InputError when the robot is built.
  std::vector<nlohmann::json> hidden_effects;

  /// Payload centre of gravity in sensor_link, m.
  Vec3 p_CoGInSensor_m = Vec3(0.03, -0.02, 0.15);
  /// Gravity in base_link axes, m/s².
  Vec3 gravity_in_base_m_per_s2 = Vec3(0.0, 0.0, -9.80665);

  /// Commanded joint angles are drawn uniformly from these, one per joint.
  std::vector<JointSampleRange> pose_ranges = defaultIrb4400PoseRanges();
  /// Nominal tip at least this far along base +x (in front of the robot), m.
  double min_tip_forward_m = 0.5;
  /// Nominal tip at least this high above the base origin, m.
  double min_tip_height_m = 0.2;
  /// When set, every nominal joint frame after joint 1's (the links' origins, and the tip) at
  /// least this high above base_link's z = 0 plane, the floor, m; unset: not checked (the paper's
  /// pose ranges keep the IRB4400 above it).
  std::optional<double> min_link_height_m;
};

/// Options for a twin of the robot urdf_path describes, chain base_link → tip_link, payload at
/// sensor_link (empty: no sensor, so unloaded rows; protocol "paper" with a sensor, else
/// "geometry"). For the paper's robot (`<robot name>` kPaperRobotName) they are TwinOptions'
/// defaults. For any other: the commanded angles drawn within the URDF's joint limits (±π for a
/// continuous joint), the nominal tip in front of and above the base by 0.3 and 0.1 × the arm's
/// reach (the lengths of its initial poses after joint 1's), every link 0.1 m above the floor;
/// the stiffness from the joints' rated torque (kRatedTorqueDeflection_rad; left empty, and
/// refused by the twin, when a joint has no effort limit); and, when the URDF has <inertial>s,
/// a self_weight of its links' masses and centres of mass (each body as bodyMassesFromUrdf
/// lumps it), so that the arm deflects under its own weight. Throws InputError on a bad URDF.
TwinOptions twinOptionsForRobot(const std::string& urdf_path, const std::string& base_link,
                                const std::string& tip_link, const std::string& sensor_link);

/// The options as JSON (SI, units in the names), as stored in truth.json.
nlohmann::json toJson(const TwinOptions& options);

/// The true robot: its geometry, where the tracker stands, its hidden mechanisms. Noiseless;
/// noise is added by simulateCampaign. Every initial pose is the nominal one times exp(δ)
/// (TwinOptions geometric error sizes); the F/T sensor keeps its nominal offset from joint n, so
/// the tool error lies between the sensor and the tip. The payload is a point mass at
/// p_CoGInSensor_m; joint torques τ = J_sᵀ W + τ_self with W its wrench at the base origin and
/// τ_self the links' own (self_weight) (effects.hpp).
///
/// The pose functions take the true temperature temp_c [°C] of the measurement (thermal
/// expansion); the default kNoThermalExpansion (NaN) keeps the links at their reference length,
/// which is exact for a robot without thermal_expansion.
class TwinRobot {
 public:
  /// Reads the nominal URDF and draws the truth from the seed. Throws InputError.
  explicit TwinRobot(const TwinOptions& options);
  /// Rebuilds a robot from truthJson(). Throws InputError naming the bad key.
  static TwinRobot fromTruthJson(const nlohmann::json& truth);
  /// Everything true, SI, units in the key names (format "stepcal-twin-truth/1").
  nlohmann::json truthJson() const;

  /// The deflected robot at one measurement: the pipeline's fixed point (effects.hpp).
  struct Deflection {
    JointVector link_angles_rad;  ///< θ, rad
    /// Per joint, its bearing_tilt δ: rotation vector in the frame after the joint's motion,
    /// rad; zero for a joint without one.
    std::vector<Vec3> tilt_rad;
    /// The tool's shift on its mount (tool_mount_compliance), base axes, m; zero without one.
    Vec3 tool_shift_m = Vec3::Zero();
  };
  /// The link angles and bearing tilts the robot reaches at commanded angles q_cmd_rad [rad]
  /// under a payload of load_kg [kg] at the CoG and its own weight, at temp_c [°C]: the
  /// pipeline's fixed point, to 1e-12 rad.
  Deflection deflection(const JointVector& q_cmd_rad, double load_kg,
                        double temp_c = kNoThermalExpansion) const;
  /// deflection()'s link angles, rad. With a bearing_tilt they alone do not place the frames:
  /// see deflectedFrames.
  JointVector linkAngles(const JointVector& q_cmd_rad, double load_kg,
                         double temp_c = kNoThermalExpansion) const;
  /// Every chain frame of the deflected robot (link angles, bearing tilts, lengths scaled at
  /// temp_c [°C]) into ws, base_link root, m.
  void deflectedFrames(const JointVector& q_cmd_rad, double load_kg, double temp_c,
                       ChainWorkspace& ws) const;
  /// True tip pose in base_link, deflected, at temp_c [°C], m.
  Pose X_BaseTip(const JointVector& q_cmd_rad, double load_kg,
                 double temp_c = kNoThermalExpansion) const;
  /// True tip pose in the tracker frame, deflected, at temp_c [°C], noiseless, m.
  Pose X_TrackerTip(const JointVector& q_cmd_rad, double load_kg,
                    double temp_c = kNoThermalExpansion) const;
  /// Noiseless wrench the payload exerts on the sensor: (f [N], m [N·m]) in sensor_link axes,
  /// moment about the sensor_link origin, at the true deflected pose at temp_c [°C]. The
  /// physics only: without sensor_bias (see sensorReading).
  Vec6 sensorWrench(const JointVector& q_cmd_rad, double load_kg,
                    double temp_c = kNoThermalExpansion) const;
  /// Noiseless F/T reading, tared unloaded: sensorWrench plus the sensor_bias (if any),
  /// (f [N], m [N·m]) in sensor_link axes.
  Vec6 sensorReading(const JointVector& q_cmd_rad, double load_kg,
                     double temp_c = kNoThermalExpansion) const;

  /// True chain, root base_link, tip tip_link; the sensor is attached frame sensorFrame().
  const KinematicChain& trueChain() const noexcept { return chain_; }
  /// Index of the sensor's attached frame; −1: no sensor (no payload, zero wrench).
  int sensorFrame() const noexcept { return sensor_frame_; }
  /// Pose of base_link in the tracker frame (at TwinOptions::station's placement), m.
  const Pose& X_TrackerBase() const noexcept { return X_TrackerBase_; }
  /// Payload centre of gravity in sensor_link, m.
  const Vec3& p_CoGInSensor_m() const noexcept { return p_CoGInSensor_m_; }
  /// Gravity in base_link axes, m/s².
  const Vec3& gravityInBase() const noexcept { return gravity_in_base_; }
  /// Its mechanisms: link-angle effects in pipeline order, self weight, thermal expansion,
  /// sensor bias.
  const EffectSet& effects() const noexcept { return effects_; }

 private:
  TwinRobot() = default;
  // Payload wrench at the base origin, base axes, (f [N], m [N·m]), from frames in ws.
  Vec6 payloadWrenchAtBase(const ChainWorkspace& ws, double load_kg) const;
  // Evaluates ws at the deflection d with lengths scaled by scale: forward kinematics at its
  // link angles, then each bearing tilt turns its joint's frame and every frame beyond.
  void framesAt(const Deflection& d, double scale, ChainWorkspace& ws) const;
  // Each bearing tilt's δ at the frames in ws, under the payload's wrench W_payload (at the
  // base origin) and the links' weight beyond its joint; into tilt_rad (one per joint).
  void bearingTilts(const ChainWorkspace& ws, const Vec6& W_payload,
                    std::vector<Vec3>& tilt_rad) const;

  KinematicChain chain_;
  int sensor_frame_ = -1;
  Pose X_TrackerBase_ = Pose::Identity();
  Vec3 p_CoGInSensor_m_ = Vec3::Zero();
  Vec3 gravity_in_base_ = Vec3::Zero();
  EffectSet effects_;
  std::vector<Vec6> geometric_errors_;  // δ_k: true T_k = nominal T_k · exp(δ_k), for truth.json
  std::string base_link_, tip_link_, sensor_link_;
  nlohmann::json provenance_;  // seed and options the truth was drawn from
};

/// Simulates a campaign: the rows of options.protocol in time order, measured on the true robot
/// with noise. The campaign carries the nominal URDF text, the stated tracker noise (stated only
/// when both sigmas are > 0), gravity and the sensor. truth_out (may be null) receives
/// truthJson(). Throws InputError on bad options.
///
/// Protocol "paper", in measurement order (pose_id prefix, set, poses × loads in kg):
///   geo  geometry   80 × 0            geov validation  50 × 0
///   stf  stiffness  80 × 0,20,30,40   stfv validation  30 × 0,20,30,40
///   res  residual  100 × 20,30,40     resv validation  50 × 20,30,40
///   ext  validation 50 × 55 (load extrapolation)
/// Within a block every pose is measured at one load before the payload changes
/// (TwinOptions::load_order "blocks"; "mixed" shuffles the fit rows among their places). With
/// planned_fit_rows, those rows come first and replace the geo, stf and res blocks; the
/// validation blocks keep their poses (every block's poses are still drawn, in order). "geometry" is
/// the first two blocks. Every row has a wrench: the sensor stays mounted and tared unloaded, so
/// unloaded rows read its noise around zero (around the bias with sensor_bias). Each row is
/// measured at its true temperature T(seq) (TwinOptions::temperature_c); temp_c is T(seq) plus
/// the reading's noise.
Campaign simulateCampaign(const TwinOptions& options, nlohmann::json* truth_out);

/// A pose list (readPoseList's rows) of `poses` commanded poses drawn as the protocol draws its
/// own (pose_ranges, tip in front of the robot), from a stream of their own (one per
/// TwinOptions::station) so that they are not the protocol's poses, each measured at every load
/// of loads_kg (which holds 0): the random campaign a planned one is compared with. Throws
/// InputError.
std::vector<PlannedMeasurement> randomPoseList(const TwinOptions& options, int poses,
                                               const std::vector<double>& loads_kg);

/// Writes the simulated campaign into out_dir (writeCampaign) and truth.json beside it.
void writeSimulation(const TwinOptions& options, const std::string& out_dir);

}  // namespace stepcal::twin

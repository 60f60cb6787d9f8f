// The physical model and its catalogue of mechanisms: what the robot does beyond rigid geometry
// and linear joint compliance. Found by `stepcal diagnose`, stored in the model file, applied
// by the runtime. Shared by the trainer and the runtime; evaluation is allocation-free.
//
// One pose of the physical model at commanded angles q [rad], a measured wrench W_meas and a
// temperature T, in this order:
//   θ₀ = q + Σ_coupling c q_i e_j + Σ_transmission (a sin k q_j + b cos k q_j) e_j
//   W  = W_meas − b_sensor                                   (sensor_bias)
//   τ  = J_s(θ)ᵀ W_root(θ) + τ_self(θ)                       (self_weight: link gravity torques)
//   θ  = θ₀ + C τ + Σ_backlash b tanh(τ_j / τ_b) e_j
//               + Σ_nonlinear c τ_j τ₀ / (τ₀ + |τ_j|) e_j     (the fixed point, three passes)
//   X_TrackerTip = FK(θ) with the links' lengths × (1 + α (T − T_ref))   (thermal_expansion)
// Joints are 0-based here and 1-based in names, reports and JSON.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "stepcal/common/chain.hpp"

namespace stepcal {

/// The catalogue. Values are stable: they are stored in the model file.
enum class MechanismKind : uint32_t {
  kBacklash = 1,            ///< joint j: lost motion b, taken up in the direction of τ_j
  kSelfWeight = 2,          ///< every link: lumped mass and first moment; C acts on their gravity
  kTransmissionError = 3,   ///< joint j, harmonic k: a sin(k q_j) + b cos(k q_j)
  kNonlinearStiffness = 4,  ///< joint j: extra compliance c at small torque, fading above τ₀
  kThermalExpansion = 5,    ///< link lengths × (1 + α (T − T_ref))
  kSensorBias = 6,          ///< a constant offset of the F/T reading
  kJointCoupling = 7,       ///< joint j's link angle moves with joint i's commanded angle
};

/// Snake-case name, e.g. "transmission_error".
const char* toString(MechanismKind kind) noexcept;
/// Kind of a snake-case name; nullopt when it names none.
std::optional<MechanismKind> mechanismKindFromString(const std::string& name);

/// One identified mechanism with its parameters (SI) and their 1-σ.
struct Mechanism {
  MechanismKind kind = MechanismKind::kBacklash;
  int joint = -1;         ///< joint it moves (0-based): backlash, transmission, nonlinear, coupling
  int source_joint = -1;  ///< joint_coupling: the joint whose commanded angle drives it
  int harmonic = 0;       ///< transmission_error: k ≥ 1
  /// Layout per kind (mechanismParameterNames):
  ///   backlash            [b rad, τ_b N·m]: b tanh(τ_j/τ_b), a sign smoothed over ±τ_b (with
  ///                       no load the joint sits mid-play; τ_b is set from the loads, not fitted)
  ///   self_weight         per link k = 1..n: [m_k kg, h_k kg·m (3)], h_k = m_k · centre of mass
  ///                       in frame k (the frame after joint k's motion)
  ///   transmission_error  [a rad, b rad]
  ///   nonlinear_stiffness [c rad/(N·m), τ₀ N·m]
  ///   thermal_expansion   [α 1/K, T_ref °C]
  ///   sensor_bias         [f N (3), m N·m (3)], sensor_link axes
  ///   joint_coupling      [c rad/rad]
  std::vector<double> parameters;
  std::vector<double> sigma;  ///< 1-σ of each parameter, same size (0 = not estimated)
};

/// Names of a kind's parameters, units in the names, for an n-joint chain.
std::vector<std::string> mechanismParameterNames(MechanismKind kind, int dof);

/// Empty when the mechanism is well formed for an n-joint chain; else what is wrong and what
/// was expected (joint ranges, parameter count, finite values, τ₀ > 0, harmonic ≥ 1, …).
std::string mechanismProblem(const Mechanism& mechanism, int dof);

/// Short human name, e.g. "backlash (joint 2)", "transmission_error (joint 3, harmonic 2)".
std::string describe(const Mechanism& mechanism);

/// The calibrated physical model: geometry, compliance and mechanisms (no GPR).
struct PhysicalModel {
  KinematicChain chain_Tracker;         ///< calibrated, rooted at the tracker
  int sensor_frame = -1;                ///< attached frame of the F/T sensor, −1 = none
  JointVector compliance_rad_per_nm;    ///< n entries (zeros: rigid)
  Vec3 gravity_Tracker = Vec3::Zero();  ///< m/s², tracker axes (zero: unknown)
  std::vector<Mechanism> mechanisms;

  /// The chain's translation scale at temperature temp_c (NaN: unknown → 1).
  double linkLengthScale(double temp_c) const noexcept;
  /// Whether any mechanism is of this kind.
  bool has(MechanismKind kind) const noexcept;
};

/// Link angles θ [rad] and joint torques τ [N·m] of the physical model at commanded angles q,
/// a measured wrench (sensor axes; zero when unloaded or no sensor) and a temperature (NaN:
/// unknown). Leaves ws evaluated at θ (with the thermal length scale). Allocation-free; false
/// when sizes disagree.
bool physicalLinkAngles(const PhysicalModel& model, const JointVector& q_rad,
                        const Vec6& wrench_Sensor, double temp_c, ChainWorkspace& ws,
                        JointVector& theta_rad, JointVector& tau_nm) noexcept;

/// Gravity torques of the lumped link masses of a self_weight mechanism at the pose in ws,
/// N·m (n entries). Allocation-free.
void selfWeightTorques(const KinematicChain& chain, const ChainWorkspace& ws,
                       const Vec3& gravity_Root, const std::vector<double>& parameters,
                       JointVector& tau_nm) noexcept;

}  // namespace stepcal

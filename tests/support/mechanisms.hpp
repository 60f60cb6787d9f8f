// Mechanisms of every kind for the six-joint test arms (shaped like the IRB 4400), at magnitudes
// a heavy robot shows; shared by the model-file, runtime and service tests.
#pragma once

#include <cmath>
#include <utility>
#include <vector>

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::test {

/// Self-weight parameters of six links: [m_k kg, h_k = m_k · c_k kg·m (3)] per link, centres of
/// mass c_k a few decimetres from each link's frame (mechanisms.hpp layout).
inline std::vector<double> selfWeightParameters() {
  const double mass_kg[6] = {180, 120, 90, 25, 12, 4};
  const Vec3 centre_m[6] = {{0.05, 0.0, -0.2}, {0.0, 0.4, 0.05}, {0.15, 0.05, 0.0},
                            {0.0, 0.0, 0.3},   {0.02, 0.0, 0.05}, {0.0, 0.0, 0.03}};
  std::vector<double> p;
  for (int k = 0; k < 6; ++k) {
    const Vec3 h = mass_kg[k] * centre_m[k];
    p.insert(p.end(), {mass_kg[k], h.x(), h.y(), h.z()});
  }
  return p;
}

/// A profile geometry of a six-joint arm: 7 initial-pose corrections (v m, ω rad), tens of µm
/// and µrad, different on every pose and axis.
inline std::vector<double> profileGeometryParameters() {
  std::vector<double> p;
  for (int k = 0; k < 7; ++k) {
    for (int i = 0; i < 3; ++i) p.push_back(1e-6 * (10.0 + 7.0 * k - 4.0 * i));
    for (int i = 0; i < 3; ++i) p.push_back(1e-6 * (-20.0 + 5.0 * k + 9.0 * i));
  }
  return p;
}

/// A mechanism whose 1-σ are 5 % of its parameters' magnitudes.
inline Mechanism mechanism(MechanismKind kind, int joint, int source_joint, int order,
                           std::vector<double> parameters, AngleCoverage coverage = {}) {
  std::vector<double> sigma;
  for (const double p : parameters) sigma.push_back(0.05 * std::abs(p));
  return {kind, joint, source_joint, order, std::move(parameters), std::move(sigma),
          std::move(coverage)};
}

/// One mechanism of every kind for a six-joint arm, joints 0-based, in the catalogue's order:
/// [0] backlash (joint 2), [1] self_weight, [2] transmission_error (joint 3, harmonics 1 and 2,
/// covering 57°–315°),
/// [3] nonlinear_stiffness (joint 4, linear above 300 N·m), [4] thermal_expansion (T_ref 20 °C),
/// [5] sensor_bias, [6] joint_coupling (joint 5 → joint 6), [7] profile_geometry (joint 3: tens
/// of µm and µrad on every initial pose), [8] torsion_curve (joint 5: lost motion and two knees,
/// linear above 400 N·m), [9] joint_zero_drift (joint 2: 30 µrad/K about 20 °C), [10]
/// off_axis_compliance (joint 1: a base bearing 5e6 and 7e6 N·m/rad stiff across its axis), [11]
/// tool_mount_compliance (a mount 1e7, 7e6 and 5e6 N/m stiff along the sensor's x, y, z).
inline std::vector<Mechanism> mechanismOfEveryKind() {
  return {mechanism(MechanismKind::kBacklash, 1, -1, 0, {2e-4, 5.0}),
          mechanism(MechanismKind::kSelfWeight, -1, -1, 0, selfWeightParameters()),
          mechanism(MechanismKind::kTransmissionError, 2, -1, 2, {1e-5, 2e-5, 3e-5, -1.5e-5},
                    {{1.0, 4.5}, 0.2}),
          mechanism(MechanismKind::kNonlinearStiffness, 3, -1, 0, {4e-6, 60.0, 300.0}),
          mechanism(MechanismKind::kThermalExpansion, -1, -1, 0, {1.15e-5, 20.0}),
          mechanism(MechanismKind::kSensorBias, -1, -1, 0, {1.5, -0.8, 2.1, 0.03, -0.02, 0.01}),
          mechanism(MechanismKind::kJointCoupling, 5, 4, 0, {-1.2e-3}),
          mechanism(MechanismKind::kProfileGeometry, 2, -1, 0, profileGeometryParameters()),
          mechanism(MechanismKind::kTorsionCurve, 4, -1, 2,
                    {1.5e-4, 4.0, 3e-6, 40.0, 1e-6, 150.0, 400.0}),
          mechanism(MechanismKind::kJointZeroDrift, 1, -1, 0, {3e-5, 20.0}),
          mechanism(MechanismKind::kOffAxisCompliance, 0, -1, 0, {2e-7, 1.4e-7}),
          mechanism(MechanismKind::kToolMountCompliance, -1, -1, 0, {1e-7, 1.4e-7, 2e-7})};
}

}  // namespace stepcal::test

// Step 2's weighted least-squares system of several sessions' pairs (internal to
// stepcal::trainer): what identifyCompliance solves and the held-out test of the sessions'
// compliances splits.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "stepcal/trainer/stiffness.hpp"

namespace stepcal::trainer {

// The deflections of every pair, sessions in order, linear in C_θ: B C_θ ≈ y (docs/method.md eq. 19–20),
// each equation divided by the deflection's 1-σ (σ√2, a difference of two measurements).
struct DeflectionSystem {
  Eigen::MatrixXd B;               // equations × n
  Eigen::VectorXd y;               // weighted measured deflections
  std::vector<int> first_equation;  // per pair, its first equation; one more entry: the count
  std::vector<int> session;         // per pair, its session
  std::vector<double> position_weight;  // per pair, 1/m
  JointVector max_torque_nm;        // largest |τ| per joint over the pairs
};

// Builds the system. Throws InputError when a loaded row has no wrench.
DeflectionSystem deflectionSystem(const std::vector<StiffnessSession>& sessions, int sensor_frame);

}  // namespace stepcal::trainer

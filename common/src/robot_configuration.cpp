#include "stepcal/common/robot_configuration.hpp"

#include <cmath>

namespace stepcal {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoPi = 2.0 * kPi;

}  // namespace

bool shippedControllerJoints(const std::string& robot, ControllerJoints& joints) {
  joints = ControllerJoints{};
  // robots/irb4400.urdf: ABB's calibration position is q = 0 (upper arm vertical, forearm
  // horizontal), and its axes turn as ABB's (1 about +z, 2, 3 and 5 about +y, 4 and 6 about +x
  // of the zero pose). robots/ur10.urdf: the controller's joint variables, signs and zeros (its
  // header). Both: identity.
  return robot == "irb4400" || robot == "ur10";
}

JointVector controllerFromChain(const ControllerJoints& joints,
                                const JointVector& q_chain_rad) noexcept {
  JointVector q = q_chain_rad;
  for (Eigen::Index j = 0; j < q.size() && j < 6; ++j) {
    q(j) = joints.direction[size_t(j)] * q(j) + joints.offset_rad[size_t(j)];
  }
  return q;
}

JointVector chainFromController(const ControllerJoints& joints,
                                const JointVector& q_controller_rad) noexcept {
  JointVector q = q_controller_rad;
  for (Eigen::Index j = 0; j < q.size() && j < 6; ++j) {
    q(j) = (q(j) - joints.offset_rad[size_t(j)]) * joints.direction[size_t(j)];
  }
  return q;
}

KukaStatusTurn kukaStatusTurn(const ArmBranch& branch,
                              const JointVector& q_controller_rad) noexcept {
  KukaStatusTurn st;
  if (q_controller_rad.size() < 6) return st;
  st.status = (branch.shoulder_back ? 1 : 0) | (branch.elbow_down ? 0 : 2) |
              (q_controller_rad(4) < 0.0 ? 4 : 0);
  for (int j = 0; j < 6; ++j) {
    if (q_controller_rad(j) < 0.0) st.turn |= 1 << j;
  }
  return st;
}

void applyKukaTurn(int turn, JointVector& q_controller_rad) noexcept {
  for (Eigen::Index j = 0; j < q_controller_rad.size() && j < 6; ++j) {
    double& q = q_controller_rad(j);
    const bool negative = (turn >> j) & 1;
    while (negative && q >= 0.0) q -= kTwoPi;
    while (!negative && q < 0.0) q += kTwoPi;
  }
}

ArmBranch branchOfKukaStatus(int status, const ControllerJoints& joints) noexcept {
  ArmBranch branch;
  branch.shoulder_back = (status & 1) != 0;
  branch.elbow_down = (status & 2) == 0;
  const bool a5_negative = (status & 4) != 0;
  branch.wrist_flipped = a5_negative == (joints.direction[4] > 0.0);
  return branch;
}

int abbQuadrant(double angle_rad) noexcept {
  return static_cast<int>(std::floor(angle_rad / (kPi / 2.0)));
}

AbbConfData abbConfData(const ArmBranch& branch, const JointVector& q_controller_rad) noexcept {
  AbbConfData conf;
  if (q_controller_rad.size() < 6) return conf;
  conf.cf1 = abbQuadrant(q_controller_rad(0));
  conf.cf4 = abbQuadrant(q_controller_rad(3));
  conf.cf6 = abbQuadrant(q_controller_rad(5));
  conf.cfx = (branch.shoulder_back ? 4 : 0) + (branch.elbow_down ? 2 : 0) +
             (q_controller_rad(4) < 0.0 ? 1 : 0);
  return conf;
}

ArmBranch branchOfAbbCfx(int cfx, const ControllerJoints& joints) noexcept {
  ArmBranch branch;
  branch.shoulder_back = (cfx & 4) != 0;
  branch.elbow_down = (cfx & 2) != 0;
  branch.wrist_flipped = ((cfx & 1) != 0) == (joints.direction[4] > 0.0);
  return branch;
}

int fanucTurn(double angle_rad) noexcept {
  return static_cast<int>(std::ceil((angle_rad - kPi) / kTwoPi));
}

FanucConfig fanucConfig(const ArmBranch& branch, const JointVector& q_controller_rad) noexcept {
  FanucConfig config;
  if (q_controller_rad.size() < 6) return config;
  config.flip = q_controller_rad(4) > 0.0;
  config.up = !branch.elbow_down;
  config.front = !branch.shoulder_back;
  config.turn1 = fanucTurn(q_controller_rad(0));
  config.turn4 = fanucTurn(q_controller_rad(3));
  config.turn6 = fanucTurn(q_controller_rad(5));
  return config;
}

ArmBranch branchOfFanucConfig(const FanucConfig& config, const ControllerJoints& joints) noexcept {
  ArmBranch branch;
  branch.shoulder_back = !config.front;
  branch.elbow_down = !config.up;
  const bool j5_negative = !config.flip;
  branch.wrist_flipped = j5_negative == (joints.direction[4] > 0.0);
  return branch;
}

void applyFanucTurn(int joint, int turn, JointVector& q_controller_rad) noexcept {
  if (joint < 0 || joint >= q_controller_rad.size()) return;
  double& q = q_controller_rad(joint);
  q += kTwoPi * (turn - fanucTurn(q));
}

void applyAbbQuadrants(const AbbConfData& conf, JointVector& q_controller_rad) noexcept {
  if (q_controller_rad.size() < 6) return;
  const int wanted[3] = {conf.cf1, conf.cf4, conf.cf6};
  const int joint[3] = {0, 3, 5};
  for (int k = 0; k < 3; ++k) {
    double& q = q_controller_rad(joint[k]);
    // A whole turn is four quadrants: move by the nearest whole number of turns.
    q += kTwoPi * std::round((wanted[k] - abbQuadrant(q)) / 4.0);
  }
}

}  // namespace stepcal

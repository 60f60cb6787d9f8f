// The controllers' configuration words: KUKA Status/Turn, ABB confdata, Fanuc CONFIG, from an
// arm branch (closed_form_ik.hpp) and the joints in the controller's own convention, and back.
//
// Joint conventions. The chain's joints (URDF: zero and direction of each joint as the file
// gives them) need not be the controller's: q_controller = direction · q_chain + offset, per
// joint (ControllerJoints). The shipped robots' tables are in shippedControllerJoints; any other
// robot's is an input (the default, identity, is right only when the URDF was written in the
// controller's convention, as both shipped robots are).
//
// What each word means, as the vendors document it:
//  - KUKA (KSS 8 "Operating and Programming Instructions for System Integrators", E6POS S and
//    T): Status bit 0 = 1 when the wrist point's x in the A1 coordinate system is negative
//    ("overhead area"); bit 1 = 1 when the wrist point lies in front of the line through A2 and
//    A3, which for an arm without an A3–A4 offset is A3 ≥ 0°; bit 2 = 1 when A5 < 0°. Turn bit
//    i (i = 0..5) = 1 when A(i+1) < 0°.
//    With the geometric branch of closed_form_ik.hpp: bit 0 = shoulder_back, bit 1 = !elbow_down,
//    bit 2 from A5's sign.
//  - ABB (Technical reference manual "RAPID Instructions, Functions and Data types", confdata):
//    cf1, cf4, cf6 = the quadrant of axes 1, 4, 6: ⌊angle / 90°⌋ (0 for 0…90°, −1 for −90…0°);
//    cfx (serial 6-axis arms) = 4 · (wrist centre behind axis 1) + 2 · (wrist centre behind the
//    lower arm) + (axis 5 negative), i.e. 0…7 in the manual's table.
//  - Fanuc (R-30iA/iB operator's manual, "Configuration"): 'F|N U|D T|B, t1, t4, t6': wrist Flip
//    or Non-flip, elbow Up or Down, arm front (T) or Back; turn number t of J1, J4, J6 = the k
//    with angle in (−180° + 360° k, 180° + 360° k]. Non-flip is J5 ≤ 0° in Fanuc's convention
//    (its J5 turns the opposite way to KUKA's A5 and ABB's axis 5: the usual tool-down pose,
//    J4 = 0, J5 = −90°, is 'N U T').
// A singular joint value (A5 = 0) goes to the side the vendor's inequality puts it.
#pragma once

#include <array>
#include <string>

#include "stepcal/common/closed_form_ik.hpp"
#include "stepcal/common/types.hpp"

namespace stepcal {

/// How a controller counts the chain's joints: q_controller = direction · q_chain + offset.
struct ControllerJoints {
  std::array<double, 6> direction{{1, 1, 1, 1, 1, 1}};  ///< +1 or −1
  std::array<double, 6> offset_rad{};                  ///< rad
};
/// The table of a shipped robot ("irb4400", "ur10"); false (and identity) for any other name.
bool shippedControllerJoints(const std::string& robot, ControllerJoints& joints);
/// q_chain [rad] in the controller's convention, and back. Allocation-free.
JointVector controllerFromChain(const ControllerJoints& joints, const JointVector& q_chain_rad) noexcept;
JointVector chainFromController(const ControllerJoints& joints, const JointVector& q_controller_rad) noexcept;
/// Whether the controller's joint 5 is negative in a branch: the chain's wrist_flipped side
/// when the controller counts joint 5 as the chain does (direction +1, and the chain's φ₀ and
/// the controller's offset 0, as every vendor puts the wrist singularity at 0°).
inline bool joint5Negative(const ArmBranch& branch, const ControllerJoints& joints) noexcept {
  return branch.wrist_flipped == (joints.direction[4] > 0.0);
}

struct KukaStatusTurn {
  int status = 0;  ///< bits 0..2 as above
  int turn = 0;    ///< bits 0..5 as above
};
/// KUKA S and T of a branch at the controller's joints (A1…A6, rad).
KukaStatusTurn kukaStatusTurn(const ArmBranch& branch, const JointVector& q_controller_rad) noexcept;
/// Moves each joint of q_controller by whole turns (the fewest) to the sign its Turn bit names,
/// where a whole turn can (a joint within ±180° of 0 already has the sign its angle gives).
void applyKukaTurn(int turn, JointVector& q_controller_rad) noexcept;
/// The branch a Status names (bit 2 read through joint5Negative).
ArmBranch branchOfKukaStatus(int status, const ControllerJoints& joints) noexcept;

struct AbbConfData {
  int cf1 = 0, cf4 = 0, cf6 = 0, cfx = 0;
};
/// ABB's quadrant of an angle: ⌊angle / 90°⌋.
int abbQuadrant(double angle_rad) noexcept;
AbbConfData abbConfData(const ArmBranch& branch, const JointVector& q_controller_rad) noexcept;
ArmBranch branchOfAbbCfx(int cfx, const ControllerJoints& joints) noexcept;

struct FanucConfig {
  bool flip = false;   ///< 'F' (else 'N')
  bool up = true;      ///< 'U' (else 'D')
  bool front = true;   ///< 'T' (else 'B')
  int turn1 = 0, turn4 = 0, turn6 = 0;
};
/// Fanuc's turn number of an angle: the k with angle ∈ (−π + 2πk, π + 2πk].
int fanucTurn(double angle_rad) noexcept;
FanucConfig fanucConfig(const ArmBranch& branch, const JointVector& q_controller_rad) noexcept;
/// The branch a CONFIG names (flip, J5 > 0, read through joint5Negative).
ArmBranch branchOfFanucConfig(const FanucConfig& config, const ControllerJoints& joints) noexcept;
/// Moves joint `joint` (0-based) of q_controller by whole turns into Fanuc turn number `turn`.
void applyFanucTurn(int joint, int turn, JointVector& q_controller_rad) noexcept;
/// Moves joints 1, 4, 6 by whole turns (or none) into ABB's quadrants cf1, cf4, cf6, where a
/// whole turn can: a quadrant differs from the joint's by a multiple of 4 after the solve.
void applyAbbQuadrants(const AbbConfData& conf, JointVector& q_controller_rad) noexcept;

}  // namespace stepcal

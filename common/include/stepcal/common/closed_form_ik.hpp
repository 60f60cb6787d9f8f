// Closed-form inverse kinematics of a nominal 6R chain, every branch.
//
// Two layouts, recognised from the chain's geometry at q = 0 (axes as lines in the root frame):
//   kSphericalWrist   axes 2 ∥ 3, axis 1 not ∥ 2, axes 4, 5, 6 meet in one point (the wrist
//                     point) with 4 ⟂ 5 ⟂ 6: KUKA, ABB (the IRB4400), Fanuc, Yaskawa arms.
//   kUniversalRobots  axes 2 ∥ 3 ∥ 4, axis 1 not ∥ 2, axes 5 and 6 meet, 5 ⟂ 4 and 6 ⟂ 5: the UR.
// Any other arm is kOther, and the numeric inverse is the only one (runtime solveInverse).
// The chain is the local-POE chain of chain.hpp, read as X_BaseTip(q) = E1(q1) … E6(q6) · M with
// E_i the screw motion about joint i's axis at q = 0 and M the tip at q = 0 (Paden–Kahan
// subproblems on those axes; no DH parameters are needed).
//
// Branches (ArmBranch; shoulder and elbow geometric, the wrist relative to joint 5's direction):
//   shoulder_back  the wrist point (spherical wrist; the UR: the point where axes 5 and 6 meet)
//                  lies behind joint 1's axis: its coordinate along "forward" is negative,
//                  forward being, with joint 1 undone, the direction ⟂ axes 1 and 2 in which the
//                  wrist point lies at q = 0 (KUKA's "overhead area", ABB cfx "behind axis 1",
//                  Fanuc 'B').
//   elbow_down     the wrist point (the UR: axis 4) lies on the other side of the line through
//                  axes 2 and 3 than at the zero pose of an arm whose upper arm stands up and
//                  whose forearm points forward (IRB4400 q = 0 is elbow up): the sign of
//                  a₂ · ((axis 3 − axis 2) × (wrist − axis 3)), a₂ the axis-2 direction that
//                  makes up × forward = a₂, up = axis 1 oriented so that axis 2 lies above the
//                  root (ABB cfx "wrist centre behind the lower arm", KUKA Status bit 1 = 0,
//                  Fanuc 'D').
//   wrist_flipped  joint 5 lies on the negative side of its wrist singularity (axis 6 ∥ axis 4,
//                  the UR: axis 6 ∥ axes 2–4): sin(q5 + φ₀) < 0, φ₀ the angle about axis 5 from
//                  axis 4 (the UR: axis 2) to axis 6 at q = 0 (the IRB4400: q5 < 0).
// The controllers' configuration words (KUKA S/T, ABB confdata, Fanuc CONFIG) are built from a
// branch and the joints in robot_configuration.hpp.
//
// Everything here, recognise() included, is allocation-free and noexcept; fixed-size Eigen only.
#pragma once

#include <array>
#include <cstdint>

#include "stepcal/common/chain.hpp"
#include "stepcal/common/types.hpp"

namespace stepcal {

/// One of the eight solutions of a 6R arm with a closed-form inverse (see the file comment).
struct ArmBranch {
  bool shoulder_back = false;
  bool elbow_down = false;
  bool wrist_flipped = false;

  /// 0..7: shoulder_back · 4 + elbow_down · 2 + wrist_flipped.
  int index() const noexcept { return (shoulder_back ? 4 : 0) + (elbow_down ? 2 : 0) + (wrist_flipped ? 1 : 0); }
  static ArmBranch fromIndex(int index) noexcept {
    return {(index & 4) != 0, (index & 2) != 0, (index & 1) != 0};
  }
  bool operator==(const ArmBranch& o) const noexcept { return index() == o.index(); }
  bool operator!=(const ArmBranch& o) const noexcept { return index() != o.index(); }
};

/// The kinds of arm the closed form solves (see the file comment).
enum class ArmLayout : int8_t { kSphericalWrist = 0, kUniversalRobots = 1, kOther = 2 };
/// "spherical_wrist", "universal_robots" or "other".
const char* toString(ArmLayout layout) noexcept;

/// Outcome of a closed-form solve.
enum class ClosedFormStatus : int8_t {
  kOk = 0,
  /// Within 1 µm (the wrist: 1e-6 rad) of a singularity (wrist: axes 4 and 6 in line, the UR:
  /// axis 6 ∥ axes 2–4; shoulder: the wrist point on joint 1's axis or, with a lateral offset,
  /// its cylinder; elbow stretched): the answer reaches the pose exactly, but neighbouring
  /// branches (nearly) coincide, and exactly there a free joint is taken from q_near (or 0).
  kSingular = 1,
  kUnreachable = 2,    ///< beyond the nominal arm's reach in that branch; q_out untouched
  kBeyondLimits = 3,   ///< reaches the pose, but some joint is outside its limits at every turn
  kNoClosedForm = 4,   ///< the chain is ArmLayout::kOther
  kBadRequest = 5,     ///< NaN/inf, a non-rotation, q_near of the wrong size
};
/// "OK", "SINGULAR", "UNREACHABLE", "BEYOND_LIMITS", "NO_CLOSED_FORM", "BAD_REQUEST".
const char* toString(ClosedFormStatus status) noexcept;

/// The closed-form inverse of one chain's nominal geometry (a copy: the chain need not outlive it).
class ClosedFormInverse {
 public:
  /// Distance (m) within which two axes meet, and sine of the angle within which two axes are
  /// parallel or perpendicular, when a chain's layout is recognised.
  static constexpr double kMeetTolerance_m = 1e-9;
  static constexpr double kAngleTolerance = 1e-9;

  /// A kOther inverse (every solve answers kNoClosedForm).
  ClosedFormInverse() = default;
  /// The chain's layout and geometry at q = 0 (allocates nothing either; may be called anywhere).
  static ClosedFormInverse recognise(const KinematicChain& chain) noexcept;

  ArmLayout layout() const noexcept { return layout_; }
  bool solvable() const noexcept { return layout_ != ArmLayout::kOther; }

  /// Every branch's joints for the tip pose X_BaseTip (the chain's root frame, m): up to 8
  /// solutions, each joint in (−π, π], with their branches; returns how many (0 when
  /// unreachable or kOther). At a singularity two branches give the same joints and both are
  /// listed. Joint limits are not applied.
  int solveAll(const Pose& X_BaseTip, std::array<JointVector, 8>& q_out,
               std::array<ArmBranch, 8>& branch_out) const noexcept;

  /// The joints of one branch for X_BaseTip, each joint the whole turn (2π multiple) nearest
  /// q_near within its limits (nearest q_near when no turn is within them: kBeyondLimits).
  /// q_near also gives the free joint at a singularity. q_out is written on kOk, kSingular and
  /// kBeyondLimits.
  ClosedFormStatus solve(const Pose& X_BaseTip, ArmBranch branch, const JointVector& q_near,
                         JointVector& q_out) const noexcept;

  /// As solve, each joint the whole turn nearest q_near whether or not within its limits
  /// (kBeyondLimits when outside): the seed of a numeric inverse that clamps into the limits on
  /// its own. Near the wrist singularity joints 4 and 6 of a nominal answer may lie a radian
  /// from the real arm's, and the turn within the limits then another 2π away.
  ClosedFormStatus solveNearest(const Pose& X_BaseTip, ArmBranch branch, const JointVector& q_near,
                                JointVector& q_out) const noexcept;

  /// The branch of joints q (6 entries; the chain's convention).
  ArmBranch branchOf(const JointVector& q) const noexcept;

 private:
  /// An angle as its cosine and sine: the solve composes angles without sin, cos or acos and
  /// takes atan2 once per joint.
  struct Angle {
    double c = 1.0, s = 0.0;
  };
  ClosedFormStatus solveBranch(const Pose& X_BaseTip, ArmBranch branch, const JointVector* q_near,
                               bool within_limits, JointVector& q_out) const noexcept;
  ClosedFormStatus solveSpherical(const Pose& X_BaseTip, ArmBranch branch,
                                  const JointVector* q_near, JointVector& q_out) const noexcept;
  ClosedFormStatus solveUniversal(const Pose& X_BaseTip, ArmBranch branch,
                                  const JointVector* q_near, JointVector& q_out) const noexcept;
  ClosedFormStatus solveJoint1(const Vec3& p_WristInBase, bool shoulder_back, double q_near1,
                               Angle& q1) const noexcept;
  ClosedFormStatus solveArmPlane(const Vec3& p_TargetAfterJoint1, const Vec3& p_Arm,
                                 bool elbow_down, Angle& q2, Angle& q3) const noexcept;
  bool shoulderBack(const Vec3& p_WristAfterJoint1) const noexcept;
  /// a₂ · (upper arm × forearm) at q3, p_Arm the forearm's point at q = 0: < 0 is elbow down.
  double elbowSide(const Angle& q3, const Vec3& p_Arm) const noexcept;

  ArmLayout layout_ = ArmLayout::kOther;
  std::array<Vec3, 6> axis_{};   ///< ω_i at q = 0, root frame, unit
  std::array<Vec3, 6> point_{};  ///< a point of axis i at q = 0, root frame, m
  Pose M_ = Pose::Identity();    ///< X_BaseTip at q = 0
  /// The spherical wrist's wrist point, or the UR's meeting point of axes 5 and 6, at q = 0, m.
  Vec3 p_Wrist_ = Vec3::Zero();
  Vec3 p_WristInTip_ = Vec3::Zero();  ///< the same in the tip frame (fixed: joint 6 keeps it)
  Vec3 forward_ = Vec3::UnitX();  ///< ⟂ axes 1 and 2, towards the wrist at q = 0
  Vec3 arm_axis_ = Vec3::UnitY(); ///< a₂ oriented as up × forward (the elbow's sign)
  /// The wrist's reference axis (axis 4, the UR: axis 2) and φ₀ (see the file comment).
  Vec3 wrist_reference_ = Vec3::UnitX();
  double wrist_phi0_rad_ = 0.0;
  Angle wrist_phi0_;
  std::array<double, 6> lower_rad_{}, upper_rad_{};
};

}  // namespace stepcal

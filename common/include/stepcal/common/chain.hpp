// Serial robot in local product-of-exponentials form, split into a model and a workspace.
//
// Frames along the chain: frame 0 is the chain's root (the robot base, or the tracker once
// registered), frame i (1..n) is joint i's frame after its motion, frame n+1 is the tip:
//   X_0,i(q) = X_0,i-1(q) · T_{i-1,i}(0) · exp(ŝ_i q_i)          (docs/method.md eq. 1, 5)
//   X_0,n+1  = X_0,n(q) · T_{n,n+1}
// Lengths are metres, angles radians. The model is immutable after construction; all scratch
// space lives in ChainWorkspace, whose buffers are fixed-size, so evaluation never allocates.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "stepcal/common/types.hpp"

namespace stepcal {

/// Name of the attached frame that is the robot's mounting flange (campaign.yaml flange_link):
/// the frame of a controller's tool data.
inline constexpr const char* kFlangeFrameName = "flange";

/// A frame rigidly attached to the chain (for example the F/T sensor or the flange).
struct AttachedFrame {
  std::string name;
  int parent = 0;        ///< chain frame it hangs from: 0 = root, i = after joint i's motion
  Pose X_ParentFrame;    ///< its pose in that chain frame
};

/// One revolute axis of the chain.
struct ChainJoint {
  std::string name;
  Vec6 twist_Local = Vec6::Zero();  ///< s_i = (v, ω) in the joint's own frame, |ω| = 1 (eq. 3)
  double lower_rad = -3.14159265358979;
  double upper_rad = 3.14159265358979;
};

/// Local-POE model of a serial chain: n joints and n+1 initial pose matrices.
class KinematicChain {
 public:
  KinematicChain() = default;
  /// Builds a chain; aborts if sizes disagree or n > kMaxJoints (a programming error).
  KinematicChain(std::vector<ChainJoint> joints, std::vector<Pose> initial_poses,
                 std::vector<AttachedFrame> frames = {});

  int dof() const noexcept { return static_cast<int>(joints_.size()); }
  const std::vector<ChainJoint>& joints() const noexcept { return joints_; }
  /// T_{k,k+1}(0) for k = 0..n; index n is the tip (tool) frame.
  const std::vector<Pose>& initialPoses() const noexcept { return initial_; }
  const Pose& initialPose(int k) const noexcept { return initial_[static_cast<size_t>(k)]; }
  const std::vector<AttachedFrame>& frames() const noexcept { return frames_; }
  /// Index into frames() of a named frame, or −1.
  int findFrame(const std::string& name) const noexcept;

  /// Replaces initial pose k (0..n); used by calibration.
  void setInitialPose(int k, const Pose& X);
  /// Returns a copy with T_{k,k+1}(0) ← T_{k,k+1}(0)·exp(δt_k) for every k (docs/method.md eq. 9).
  /// delta has 6(n+1) entries ordered (δt_0 … δt_n), each (v, ω).
  KinematicChain corrected(const Eigen::VectorXd& delta) const;
  /// Returns a copy whose root frame is moved: T_{0,1}(0) ← X_NewRootOldRoot · T_{0,1}(0).
  KinematicChain rerooted(const Pose& X_NewRootOldRoot) const;

  /// Per joint, 0, 1 or 2 when its twist is a pure rotation about ±x, ±y or ±z of its frame
  /// (most URDF axes: forward kinematics then mixes two columns only), else −1.
  int coordinateAxis(int joint) const noexcept { return axis_[static_cast<size_t>(joint)]; }

 private:
  std::vector<ChainJoint> joints_;
  std::vector<Pose> initial_;
  std::vector<AttachedFrame> frames_;
  std::vector<int> axis_;
};

/// Scratch space for one chain: poses of every chain frame at the last evaluated q.
struct ChainWorkspace {
  /// X_0,i for i = 0..n+1 (index 0 is identity, n+1 the tip).
  std::array<Pose, kMaxJoints + 2> X_RootFrame;
  int dof = 0;
};

/// Evaluates every chain frame at q (rad). Allocation-free. Returns false on a size mismatch.
/// link_length_scale multiplies the translations of T_{1,2}(0) … T_{n,n+1}(0), the robot's own
/// links (thermal expansion, mechanisms.hpp); T_{0,1}(0), the root's offset, is never scaled.
bool forwardKinematics(const KinematicChain& chain, const JointVector& q, ChainWorkspace& ws,
                       double link_length_scale = 1.0) noexcept;

/// The initial poses T_{k,k+1}(0), k = 0..n, as one evaluation uses them.
using InitialPoses = std::array<Pose, kMaxJoints + 1>;
/// The chain's initial poses with the translations scaled as forwardKinematics scales them, then
/// each moved to T_{k,k+1}(0) · exp(δ̂_k) when delta is given (6(n+1) entries: δ_0 … δ_n, each
/// (v m, ω rad); docs/method.md eq. 9). Allocation-free.
void evaluateInitialPoses(const KinematicChain& chain, double link_length_scale,
                          const double* delta, InitialPoses& initial) noexcept;
/// As evaluateInitialPoses with exp(δ̂_k) given instead of δ (k = 0..n; null: none), the same
/// products, so the same poses bit for bit when exp_delta holds expSE3 of that δ.
void evaluateInitialPoses(const KinematicChain& chain, double link_length_scale,
                          const InitialPoses* exp_delta, InitialPoses& initial) noexcept;
/// sin and cos of each joint angle of one evaluation.
struct JointTrig {
  JointVector sin, cos;
};
/// sin and cos of every entry of q. Allocation-free.
void jointTrig(const JointVector& q_rad, JointTrig& trig) noexcept;
/// sin and cos of q + δ from those of q: by the angle sum with a series for sin δ and cos δ
/// where |δ| ≤ 0.01 rad (exact to rounding there), directly elsewhere. Allocation-free.
void shiftedJointTrig(const JointTrig& trig, const JointVector& q_rad, const JointVector& delta_rad,
                      JointTrig& shifted) noexcept;
/// forwardKinematics with initial poses evaluated once (evaluateInitialPoses), for a model that
/// evaluates the chain several times at one scale and correction, and, when given, the joint
/// angles' sin and cos (jointTrig of q).
bool forwardKinematics(const KinematicChain& chain, const JointVector& q, ChainWorkspace& ws,
                       const InitialPoses& initial, const JointTrig* trig = nullptr) noexcept;
/// Tip pose X_0,n+1 from a workspace filled by forwardKinematics.
inline const Pose& tipPose(const ChainWorkspace& ws) noexcept {
  return ws.X_RootFrame[static_cast<size_t>(ws.dof + 1)];
}
/// Pose of an attached frame in the root frame.
Pose framePose(const KinematicChain& chain, const ChainWorkspace& ws, int frame_index) noexcept;

/// Joint i's twist (1-based) in the root frame at the root origin, Ad_{X_0,i} s_i (v m/rad,
/// ω 1/rad), of the chain evaluated in ws: spatialJacobian's column i.
Vec6 jointTwistInRoot(const KinematicChain& chain, const ChainWorkspace& ws, int joint) noexcept;

/// Spatial Jacobian J_s (6×n): column i = Ad_{X_0,i} s_i; maps q̇ to the twist of the moving
/// body expressed in the root frame at the root origin.
void spatialJacobian(const KinematicChain& chain, const ChainWorkspace& ws, Jacobian& J) noexcept;
/// Body Jacobian of the tip: J_b = Ad_{X_0,n+1}^{-1} J_s.
void bodyJacobian(const KinematicChain& chain, const ChainWorkspace& ws, Jacobian& J) noexcept;
/// Twist Jacobian with the tip frame's origin as reference point and root-frame axes:
/// rows 0..2 are ṗ_Tip (m/s), rows 3..5 are ω (rad/s).
void tipPointJacobian(const KinematicChain& chain, const ChainWorkspace& ws, Jacobian& J) noexcept;

/// Identification matrix of the geometric error model (docs/method.md eq. 7), 6 × 6(n+1):
/// block k = Ad_{X_0,k · T_{k,k+1}(0)}, the spatial twist of the tip per right-perturbation
/// δt_k of initial pose k. J must be 6 × 6(dof+1).
void parameterJacobian(const KinematicChain& chain, const ChainWorkspace& ws,
                       Eigen::Ref<Eigen::Matrix<double, 6, Eigen::Dynamic>> J) noexcept;

}  // namespace stepcal

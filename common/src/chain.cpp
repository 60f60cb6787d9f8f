#include "stepcal/common/chain.hpp"

#include <cmath>
#include <utility>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"

namespace stepcal {
namespace {

// 0, 1 or 2 when the twist is a pure rotation about ±x, ±y or ±z of its frame (exactly), else −1.
int coordinateAxisOf(const Vec6& twist) noexcept {
  if (!twist.head<3>().isZero(0.0)) return -1;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(twist(3 + a)) == 1.0 && twist(3 + (a + 1) % 3) == 0.0 &&
        twist(3 + (a + 2) % 3) == 0.0) {
      return a;
    }
  }
  return -1;
}

}  // namespace

KinematicChain::KinematicChain(std::vector<ChainJoint> joints, std::vector<Pose> initial_poses,
                               std::vector<AttachedFrame> frames)
    : joints_(std::move(joints)), initial_(std::move(initial_poses)), frames_(std::move(frames)) {
  STEPCAL_INVARIANT(joints_.size() <= static_cast<size_t>(kMaxJoints),
                    "chain has more joints than kMaxJoints");
  STEPCAL_INVARIANT(initial_.size() == joints_.size() + 1,
                    "a chain of n joints needs n+1 initial poses");
  for (const ChainJoint& j : joints_) {
    STEPCAL_INVARIANT(std::abs(j.twist_Local.tail<3>().norm() - 1.0) < 1e-9,
                      "a revolute joint's twist needs a unit rotation axis");
  }
  for (const AttachedFrame& f : frames_) {
    STEPCAL_INVARIANT(f.parent >= 0 && f.parent <= dof(), "attached frame parent out of range");
  }
  for (const ChainJoint& j : joints_) axis_.push_back(coordinateAxisOf(j.twist_Local));
}

int KinematicChain::findFrame(const std::string& name) const noexcept {
  for (size_t i = 0; i < frames_.size(); ++i) {
    if (frames_[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

void KinematicChain::setInitialPose(int k, const Pose& X) {
  STEPCAL_INVARIANT(k >= 0 && k <= dof(), "initial pose index out of range");
  initial_[static_cast<size_t>(k)] = X;
}

KinematicChain KinematicChain::corrected(const Eigen::VectorXd& delta) const {
  STEPCAL_INVARIANT(delta.size() == 6 * (dof() + 1), "correction needs 6(n+1) entries");
  KinematicChain out = *this;
  for (int k = 0; k <= dof(); ++k) {
    out.initial_[static_cast<size_t>(k)] =
        initial_[static_cast<size_t>(k)] * lie::expSE3(delta.segment<6>(6 * k));
  }
  return out;
}

KinematicChain KinematicChain::rerooted(const Pose& X_NewRootOldRoot) const {
  KinematicChain out = *this;
  out.initial_[0] = X_NewRootOldRoot * initial_[0];
  for (AttachedFrame& f : out.frames_) {
    if (f.parent == 0) f.X_ParentFrame = X_NewRootOldRoot * f.X_ParentFrame;
  }
  return out;
}

namespace {

// X_0,i for every frame, with initial pose k given by initial(k) (a Pose) and, when trig is
// given, the joint angles' sin and cos from it.
template <typename InitialPoseOf>
bool evaluateFrames(const KinematicChain& chain, const JointVector& q, ChainWorkspace& ws,
                    const InitialPoseOf& initial, const JointTrig* trig = nullptr) noexcept {
  const int n = chain.dof();
  if (q.size() != n) return false;
  ws.dof = n;
  ws.X_RootFrame[0] = Pose::Identity();
  for (int i = 1; i <= n; ++i) {
    const Vec6& s = chain.joints()[static_cast<size_t>(i - 1)].twist_Local;
    const Pose& X_prev = ws.X_RootFrame[static_cast<size_t>(i - 1)];
    const Pose T = initial(i - 1);
    Pose& X = ws.X_RootFrame[static_cast<size_t>(i)];
    // X_0,i = X_0,i-1 · T · exp(ŝ q), composed as rotation and translation (no 4×4 products).
    const Mat3 R_prevT = X_prev.linear() * T.linear();
    const Vec3 p_prevT = X_prev.linear() * T.translation() + X_prev.translation();
    const int axis = chain.coordinateAxis(i - 1);
    if (axis >= 0) {
      // About ±x, ±y or ±z of its frame (as URDF axes mostly are): the rotation mixes two
      // columns of R_prevT only.
      const double c = trig ? trig->cos(i - 1) : std::cos(q(i - 1));
      const double sn = s(3 + axis) * (trig ? trig->sin(i - 1) : std::sin(q(i - 1)));
      const int u = (axis + 1) % 3, w = (axis + 2) % 3;
      X.linear().col(axis) = R_prevT.col(axis);
      X.linear().col(u) = c * R_prevT.col(u) + sn * R_prevT.col(w);
      X.linear().col(w) = c * R_prevT.col(w) - sn * R_prevT.col(u);
      X.translation() = p_prevT;
    } else if (s.head<3>().isZero(0.0)) {
      // A revolute axis through the frame origin: Rodrigues' formula for the unit axis a.
      const Vec3 a = s.tail<3>();
      const double c = trig ? trig->cos(i - 1) : std::cos(q(i - 1));
      const double sn = trig ? trig->sin(i - 1) : std::sin(q(i - 1));
      const Mat3 R_joint =
          c * Mat3::Identity() + sn * lie::hat(a) + (1.0 - c) * (a * a.transpose());
      X.linear() = R_prevT * R_joint;
      X.translation() = p_prevT;
    } else {
      const Pose E = lie::expSE3(s * q(i - 1));
      X.linear() = R_prevT * E.linear();
      X.translation() = R_prevT * E.translation() + p_prevT;
    }
  }
  const Pose& X_n = ws.X_RootFrame[static_cast<size_t>(n)];
  const Pose T_tip = initial(n);
  Pose& X_tip = ws.X_RootFrame[static_cast<size_t>(n + 1)];
  X_tip.linear() = X_n.linear() * T_tip.linear();
  X_tip.translation() = X_n.linear() * T_tip.translation() + X_n.translation();
  return true;
}

// Initial pose k with its translation scaled (k ≥ 1: the robot's own links).
Pose scaledInitialPose(const KinematicChain& chain, int k, double link_length_scale) noexcept {
  Pose T = chain.initialPose(k);
  if (k > 0) T.translation() *= link_length_scale;
  return T;
}

}  // namespace

bool forwardKinematics(const KinematicChain& chain, const JointVector& q, ChainWorkspace& ws,
                       double link_length_scale) noexcept {
  return evaluateFrames(chain, q, ws, [&](int k) {
    return scaledInitialPose(chain, k, link_length_scale);
  });
}

void evaluateInitialPoses(const KinematicChain& chain, double link_length_scale,
                          const double* delta, InitialPoses& initial) noexcept {
  for (int k = 0; k <= chain.dof(); ++k) {
    Pose& T = initial[static_cast<size_t>(k)];
    T = scaledInitialPose(chain, k, link_length_scale);
    if (delta != nullptr) T = T * lie::expSE3(Eigen::Map<const Vec6>(delta + 6 * k));
  }
}

void evaluateInitialPoses(const KinematicChain& chain, double link_length_scale,
                          const InitialPoses* exp_delta, InitialPoses& initial) noexcept {
  for (int k = 0; k <= chain.dof(); ++k) {
    Pose& T = initial[static_cast<size_t>(k)];
    T = scaledInitialPose(chain, k, link_length_scale);
    if (exp_delta != nullptr) T = T * (*exp_delta)[static_cast<size_t>(k)];
  }
}

bool forwardKinematics(const KinematicChain& chain, const JointVector& q, ChainWorkspace& ws,
                       const InitialPoses& initial, const JointTrig* trig) noexcept {
  return evaluateFrames(
      chain, q, ws, [&](int k) -> const Pose& { return initial[static_cast<size_t>(k)]; }, trig);
}

void jointTrig(const JointVector& q_rad, JointTrig& trig) noexcept {
  trig.sin.resize(q_rad.size());
  trig.cos.resize(q_rad.size());
  for (Eigen::Index i = 0; i < q_rad.size(); ++i) {
    const double q = q_rad(i);  // read once: the compiler then joins sin and cos into one sincos
    trig.sin(i) = std::sin(q);
    trig.cos(i) = std::cos(q);
  }
}

void shiftedJointTrig(const JointTrig& trig, const JointVector& q_rad, const JointVector& delta_rad,
                      JointTrig& shifted) noexcept {
  shifted.sin.resize(q_rad.size());
  shifted.cos.resize(q_rad.size());
  for (Eigen::Index i = 0; i < q_rad.size(); ++i) {
    const double d = delta_rad(i);
    if (d == 0.0) {  // a joint the deflection leaves alone (rigid): the same angle
      shifted.sin(i) = trig.sin(i);
      shifted.cos(i) = trig.cos(i);
      continue;
    }
    if (std::abs(d) > 0.01) {
      const double q = q_rad(i) + d;
      shifted.sin(i) = std::sin(q);
      shifted.cos(i) = std::cos(q);
      continue;
    }
    // Taylor to d⁵ / d⁶: the next terms are below 1e-18 of 1 for |d| ≤ 0.01.
    const double d2 = d * d;
    const double sin_d = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0));
    const double cos_d = 1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0));
    shifted.sin(i) = trig.sin(i) * cos_d + trig.cos(i) * sin_d;
    shifted.cos(i) = trig.cos(i) * cos_d - trig.sin(i) * sin_d;
  }
}

Pose framePose(const KinematicChain& chain, const ChainWorkspace& ws, int frame_index) noexcept {
  const AttachedFrame& f = chain.frames()[static_cast<size_t>(frame_index)];
  return ws.X_RootFrame[static_cast<size_t>(f.parent)] * f.X_ParentFrame;
}

Vec6 jointTwistInRoot(const KinematicChain& chain, const ChainWorkspace& ws, int joint) noexcept {
  const Pose& X = ws.X_RootFrame[static_cast<size_t>(joint)];
  const Vec6& s = chain.joints()[static_cast<size_t>(joint - 1)].twist_Local;
  const int axis = chain.coordinateAxis(joint - 1);
  if (axis < 0) return lie::adjointTimes(X, s);
  // A rotation about ±e_axis: Ad_X s = (p × ω, ω) with ω the rotated axis.
  const Vec3 omega = s(3 + axis) * X.linear().col(axis);
  const Vec3 p = X.translation();
  Vec6 out;
  out.head<3>() = p.cross(omega);
  out.tail<3>() = omega;
  return out;
}

void spatialJacobian(const KinematicChain& chain, const ChainWorkspace& ws, Jacobian& J) noexcept {
  const int n = chain.dof();
  J.resize(6, n);
  for (int i = 1; i <= n; ++i) J.col(i - 1) = jointTwistInRoot(chain, ws, i);
}

void bodyJacobian(const KinematicChain& chain, const ChainWorkspace& ws, Jacobian& J) noexcept {
  spatialJacobian(chain, ws, J);
  const Mat6 Ad_TipRoot = lie::adjoint(tipPose(ws).inverse());
  for (int i = 0; i < J.cols(); ++i) J.col(i) = Ad_TipRoot * J.col(i);
}

void tipPointJacobian(const KinematicChain& chain, const ChainWorkspace& ws,
                      Jacobian& J) noexcept {
  spatialJacobian(chain, ws, J);
  // ṗ = v + ω × p for the point p attached to the moving body.
  const Mat3 p_hat = lie::hat(tipPose(ws).translation());
  for (int i = 0; i < J.cols(); ++i) {
    J.col(i).head<3>() -= p_hat * J.col(i).tail<3>();
  }
}

void parameterJacobian(const KinematicChain& chain, const ChainWorkspace& ws,
                       Eigen::Ref<Eigen::Matrix<double, 6, Eigen::Dynamic>> J) noexcept {
  const int n = chain.dof();
  for (int k = 0; k <= n; ++k) {
    J.block<6, 6>(0, 6 * k) =
        lie::adjoint(ws.X_RootFrame[static_cast<size_t>(k)] * chain.initialPose(k));
  }
}

}  // namespace stepcal

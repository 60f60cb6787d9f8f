#include "stepcal/common/chain.hpp"

#include <cmath>
#include <utility>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"

namespace stepcal {

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

// Initial pose k as evaluated: its translation scaled, then the weighted correction applied.
Pose evaluatedInitialPose(const KinematicChain& chain, int k, double scale,
                          const InitialPoseCorrection& correction) noexcept {
  Pose T = chain.initialPose(k);
  T.translation() *= scale;
  if (correction.delta != nullptr && correction.weight != 0.0) {
    const Vec6 delta = correction.weight * Eigen::Map<const Vec6>(correction.delta + 6 * k);
    T = T * lie::expSE3(delta);
  }
  return T;
}

}  // namespace

bool forwardKinematics(const KinematicChain& chain, const JointVector& q, ChainWorkspace& ws,
                       double link_length_scale, const InitialPoseCorrection& correction) noexcept {
  const int n = chain.dof();
  if (q.size() != n) return false;
  ws.dof = n;
  ws.X_RootFrame[0] = Pose::Identity();
  for (int i = 1; i <= n; ++i) {
    const Vec6& s = chain.joints()[static_cast<size_t>(i - 1)].twist_Local;
    const Pose& X_prev = ws.X_RootFrame[static_cast<size_t>(i - 1)];
    const Pose T = evaluatedInitialPose(chain, i - 1, i == 1 ? 1.0 : link_length_scale, correction);
    Pose& X = ws.X_RootFrame[static_cast<size_t>(i)];
    // X_0,i = X_0,i-1 · T · exp(ŝ q), composed as rotation and translation (no 4×4 products).
    const Mat3 R_prevT = X_prev.linear() * T.linear();
    const Vec3 p_prevT = X_prev.linear() * T.translation() + X_prev.translation();
    if (s.head<3>().isZero(0.0)) {
      // A revolute axis through the frame origin: Rodrigues' formula for the unit axis a.
      const Vec3 a = s.tail<3>();
      const double angle = q(i - 1), c = std::cos(angle), sn = std::sin(angle);
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
  const Pose T_tip = evaluatedInitialPose(chain, n, link_length_scale, correction);
  Pose& X_tip = ws.X_RootFrame[static_cast<size_t>(n + 1)];
  X_tip.linear() = X_n.linear() * T_tip.linear();
  X_tip.translation() = X_n.linear() * T_tip.translation() + X_n.translation();
  return true;
}

Pose framePose(const KinematicChain& chain, const ChainWorkspace& ws, int frame_index) noexcept {
  const AttachedFrame& f = chain.frames()[static_cast<size_t>(frame_index)];
  return ws.X_RootFrame[static_cast<size_t>(f.parent)] * f.X_ParentFrame;
}

void spatialJacobian(const KinematicChain& chain, const ChainWorkspace& ws, Jacobian& J) noexcept {
  const int n = chain.dof();
  J.resize(6, n);
  for (int i = 1; i <= n; ++i) {
    J.col(i - 1) = lie::adjoint(ws.X_RootFrame[static_cast<size_t>(i)]) *
                   chain.joints()[static_cast<size_t>(i - 1)].twist_Local;
  }
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

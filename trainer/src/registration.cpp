#include "stepcal/trainer/registration.hpp"

#include <Eigen/SVD>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"

namespace stepcal::trainer {

Pose fitRigidTransform(const std::vector<Vec3>& p_InA, const std::vector<Vec3>& p_InB) {
  STEPCAL_INVARIANT(p_InA.size() == p_InB.size(), "point sets differ in size");
  const size_t m = p_InA.size();
  if (m < 3) {
    throw InputError("registration needs at least 3 measured positions, got " +
                     std::to_string(m));
  }
  Vec3 c_A = Vec3::Zero(), c_B = Vec3::Zero();
  for (size_t i = 0; i < m; ++i) {
    c_A += p_InA[i];
    c_B += p_InB[i];
  }
  c_A /= static_cast<double>(m);
  c_B /= static_cast<double>(m);
  Mat3 H = Mat3::Zero();
  for (size_t i = 0; i < m; ++i) H += (p_InA[i] - c_A) * (p_InB[i] - c_B).transpose();
  const Eigen::JacobiSVD<Mat3> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Vec3 s = svd.singularValues();
  // A rotation is determined only if the points span at least a plane.
  if (s(1) <= 1e-12 * std::max(s(0), 1e-300)) {
    throw InputError("registration: the measured positions are (nearly) collinear; "
                     "hint: measure poses spread over the workspace");
  }
  Mat3 D = Mat3::Identity();
  D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  Pose X_BA = Pose::Identity();
  X_BA.linear() = svd.matrixV() * D * svd.matrixU().transpose();
  X_BA.translation() = c_B - X_BA.linear() * c_A;
  return X_BA;
}

Pose registerTracker(const KinematicChain& chain_Root, const std::vector<const Measurement*>& rows) {
  std::vector<Vec3> p_TipInRoot, p_TipInTracker;
  ChainWorkspace ws;
  for (const Measurement* row : rows) {
    if (!forwardKinematics(chain_Root, row->q_rad, ws)) {
      throw InputError("row has " + std::to_string(row->q_rad.size()) +
                           " joint angles but the chain has " + std::to_string(chain_Root.dof()),
                       "measurements.csv", row->source_line);
    }
    p_TipInRoot.push_back(tipPose(ws).translation());
    p_TipInTracker.push_back(row->p_TipInTracker_m);
  }
  return fitRigidTransform(p_TipInRoot, p_TipInTracker);
}

Mat3 registerToolRotation(const KinematicChain& chain_Tracker,
                          const std::vector<const Measurement*>& rows) {
  Mat3 sum = Mat3::Zero();
  int count = 0;
  ChainWorkspace ws;
  for (const Measurement* row : rows) {
    if (!row->has_orientation || !forwardKinematics(chain_Tracker, row->q_rad, ws)) continue;
    sum += tipPose(ws).linear().transpose() * row->q_TrackerTip.toRotationMatrix();
    ++count;
  }
  return count == 0 ? Mat3::Identity() : lie::projectToSO3(sum);
}

}  // namespace stepcal::trainer

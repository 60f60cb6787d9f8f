#include "stepcal/common/compliance.hpp"

#include "stepcal/common/lie.hpp"

namespace stepcal {

Vec6 wrenchInRoot(const Pose& X_RootSensor, const Vec6& wrench_Sensor) noexcept {
  const Mat3& R = X_RootSensor.linear();
  const Vec3 f = R * wrench_Sensor.head<3>();
  Vec6 W;
  W.head<3>() = f;
  W.tail<3>() = X_RootSensor.translation().cross(f) + R * wrench_Sensor.tail<3>();
  return W;
}

JointVector jointTorques(const Jacobian& J_spatial, const Vec6& wrench_Root) noexcept {
  return J_spatial.transpose() * wrench_Root;
}

bool deflectedJointAngles(const KinematicChain& chain, int sensor_frame, const JointVector& q,
                          const Vec6& wrench_Sensor, const JointVector& compliance_rad_per_nm,
                          ChainWorkspace& ws, JointVector& q_link) noexcept {
  const int n = chain.dof();
  if (q.size() != n || compliance_rad_per_nm.size() != n || sensor_frame < 0 ||
      sensor_frame >= static_cast<int>(chain.frames().size())) {
    return false;
  }
  Jacobian J;
  q_link = q;
  for (int iteration = 0; iteration < 2; ++iteration) {
    forwardKinematics(chain, q_link, ws);
    spatialJacobian(chain, ws, J);
    const Vec6 W = wrenchInRoot(framePose(chain, ws, sensor_frame), wrench_Sensor);
    q_link = q + compliance_rad_per_nm.cwiseProduct(jointTorques(J, W));
  }
  forwardKinematics(chain, q_link, ws);
  return true;
}

}  // namespace stepcal

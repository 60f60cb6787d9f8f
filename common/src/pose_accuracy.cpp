#include "stepcal/common/pose_accuracy.hpp"

#include <algorithm>
#include <cmath>

#include "stepcal/common/lie.hpp"

namespace stepcal {
namespace {

/// χ²_h's 95 % point at h = 1, 2, 3.
constexpr double kChiSquare95[3] = {3.841459, 5.991465, 7.814728};

/// Most columns of G: the initial poses' 6(n+1) and the compliances' n.
constexpr int kMaxFactorColumns = 6 * (kMaxJoints + 1) + kMaxJoints;
using PoseFactor = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxFactorColumns>;
using ParameterJacobian = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6 * (kMaxJoints + 1)>;

/// Σ += (A F)(A F)ᵀ for A 6 × p and F p × r, column by column of F (no temporary beyond 6).
template <class A_t>
void addPropagated(const A_t& A, const Eigen::MatrixXd& F, Mat6& covariance) noexcept {
  for (Eigen::Index c = 0; c < F.cols(); ++c) {
    Vec6 g = Vec6::Zero();
    for (Eigen::Index i = 0; i < F.rows(); ++i) {
      if (F(i, c) != 0.0) g += A.col(i) * F(i, c);
    }
    covariance.noalias() += g * g.transpose();
  }
}

}  // namespace

GprUncertainty gprUncertainty(const GprPredictor& gpr, const Vec6& noise, const double* x_raw,
                              const Vec6& std) noexcept {
  GprUncertainty out;
  const GprParameters& g = gpr.parameters();
  if (g.alpha.cols() != 6) return out;
  out.std = std;
  out.noise = noise * gpr.outputGain(x_raw);
  out.tracker_axes = g.payload_force_reference_n > 0.0;
  return out;
}

double lengthBound95(const Mat3& S) noexcept {
  const double t1 = S.trace();
  const double t2 = S.squaredNorm();  // tr S² for a symmetric S
  if (!(t1 > 0.0) || !(t2 > 0.0)) return 0.0;
  const double h = std::clamp(t1 * t1 / t2, 1.0, 3.0);
  const int below = std::min(1, static_cast<int>(h) - 1);
  const double chi2 =
      kChiSquare95[below] + (h - (below + 1)) * (kChiSquare95[below + 1] - kChiSquare95[below]);
  return std::sqrt(t2 / t1 * chi2);
}

Mat6 parameterCovariance(const CalibratedModel& model, const KinematicChain& chain,
                         const ChainWorkspace& at_link_angles, const JointVector& torque_nm,
                         const Mat6* mechanism_covariance) noexcept {
  Mat6 covariance = mechanism_covariance != nullptr ? *mechanism_covariance : Mat6::Zero();
  if (!model.accuracy) return covariance;
  const AccuracyFactors& factors = *model.accuracy;
  const int n = chain.dof();
  const Vec3 p_Tip = tipPose(at_link_angles).translation();
  if (factors.geometry_factor.rows() == 6 * (n + 1)) {
    ParameterJacobian A(6, 6 * (n + 1));
    parameterJacobian(chain, at_link_angles, A);
    // The tip point's velocity from the spatial twist: ṗ = v − p̂ ω.
    A.topRows<3>() -= lie::hat(p_Tip) * A.bottomRows<3>();
    addPropagated(A, factors.geometry_factor, covariance);
  }
  if (factors.compliance_factor.rows() == n && torque_nm.size() == n) {
    Jacobian J(6, n);
    tipPointJacobian(chain, at_link_angles, J);
    for (int j = 0; j < n; ++j) J.col(j) *= torque_nm(j);
    addPropagated(J, factors.compliance_factor, covariance);
  }
  return covariance;
}

PoseAccuracy poseAccuracy(const AccuracyFactors& factors, const Mat6& parameter_covariance,
                          const Mat3& R_TrackerTip, const GprUncertainty& gpr) noexcept {
  PoseAccuracy out;
  // The GPR's latent variance and the measurement's noise, per output axis.
  Vec6 variance;
  for (int o = 0; o < 6; ++o) {
    const double stated = o < 3 ? factors.position_noise_m : factors.orientation_noise_rad;
    variance(o) = gpr.std(o) * gpr.std(o) + std::max(stated * stated, gpr.noise(o) * gpr.noise(o));
  }
  const Mat3 R = gpr.tracker_axes ? Mat3::Identity() : R_TrackerTip;
  const Mat3 S_p = parameter_covariance.topLeftCorner<3, 3>() +
                   R * variance.head<3>().asDiagonal() * R.transpose();
  const Mat3 S_w = parameter_covariance.bottomRightCorner<3, 3>() +
                   R * variance.tail<3>().asDiagonal() * R.transpose();
  out.position_rms_m = std::sqrt(std::max(0.0, S_p.trace()));
  out.position_bound_m = lengthBound95(S_p);
  out.orientation_rms_rad = std::sqrt(std::max(0.0, S_w.trace()));
  out.orientation_bound_rad = lengthBound95(S_w);
  return out;
}

}  // namespace stepcal

// The inverse's damped least-squares step (Levenberg–Marquardt) on a 6 × n Jacobian, and the
// smallest singular value that decides its damping and NEAR_SINGULAR (solveInverse,
// corrector.hpp). Fixed-capacity, allocation-free, no exceptions.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "stepcal/runtime/corrector.hpp"

namespace stepcal::runtime::detail {

/// Gram matrix of J on its smaller side, min(6, n) square: J Jᵀ when n ≥ 6, else Jᵀ J. Its
/// eigenvalues are the squared singular values of J (thin SVD). Fixed 6 × 6 for six joints.
using GramMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;

template <typename Gram>
void gramMatrix(const Jacobian& J, Gram& G) noexcept {
  if (J.cols() >= 6) {
    G.noalias() = J * J.transpose();
  } else {
    G.noalias() = J.transpose() * J;
  }
}

/// Cholesky factor L Lᵀ = G + shift·I of a symmetric matrix of at most 6 rows (its lower
/// triangle is read), in plain loops over fixed arrays: Eigen's LLT works through dynamic blocks
/// even at a fixed 6 × 6 and was 9 % of the UR10 inverse, two factorisations per step.
class SmallCholesky {
 public:
  /// Factors G + shift·I; false unless every pivot is positive and finite (not positive definite).
  template <typename Gram>
  bool factor(const Gram& G, double shift) noexcept {
    n_ = static_cast<int>(G.rows());
    for (int j = 0; j < n_; ++j) {
      double pivot = G(j, j) + shift;
      for (int k = 0; k < j; ++k) pivot -= L_[j][k] * L_[j][k];
      if (!(pivot > 0.0 && pivot < std::numeric_limits<double>::infinity())) return false;
      L_[j][j] = std::sqrt(pivot);
      inverse_diagonal_[j] = 1.0 / L_[j][j];
      for (int i = j + 1; i < n_; ++i) {
        double v = G(i, j);
        for (int k = 0; k < j; ++k) v -= L_[i][k] * L_[j][k];
        L_[i][j] = v * inverse_diagonal_[j];
      }
    }
    return true;
  }
  /// x = (G + shift·I)⁻¹ b of the last successful factor(); b and x have its n rows (may alias).
  template <typename In, typename Out>
  void solve(const In& b, Out& x) const noexcept {
    double y[6];
    for (int i = 0; i < n_; ++i) {
      double v = b(i);
      for (int k = 0; k < i; ++k) v -= L_[i][k] * y[k];
      y[i] = v * inverse_diagonal_[i];
    }
    for (int i = n_ - 1; i >= 0; --i) {
      double v = y[i];
      for (int k = i + 1; k < n_; ++k) v -= L_[k][i] * y[k];
      y[i] = v * inverse_diagonal_[i];
    }
    for (int i = 0; i < n_; ++i) x(i) = y[i];
  }

 private:
  int n_ = 0;
  double L_[6][6];
  double inverse_diagonal_[6];
};

/// Smallest singular value of J from its Gram matrix G, or `floor` when it is above floor (the
/// common case, decided by a Cholesky factorisation of G − floor² I rather than eigenvalues).
template <typename Gram>
double smallestSingularValueOrFloor(const Gram& G, double floor) noexcept {
  if (SmallCholesky().factor(G, -floor * floor)) return floor;
  const Eigen::SelfAdjointEigenSolver<Gram> eigen(G, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, eigen.eigenvalues()(0)));
}

/// A damped step's Jacobian J and its Cholesky factor of J Jᵀ + λ² I (n ≥ 6) or Jᵀ J + λ² I
/// (n < 6), kept for a chord step: another step with the same J and λ².
struct StepFactor {
  SmallCholesky cholesky;
  bool valid = false;  ///< false when the step went by the SVD (the matrix was singular)
};

/// Δq = Jᵀ (J Jᵀ + λ² I)⁻¹ e (n ≥ 6) or (Jᵀ J + λ² I)⁻¹ Jᵀ e (n < 6) with that matrix factored.
inline void stepFromFactor(const Jacobian& J, const SmallCholesky& cholesky, const Vec6& e,
                    JointVector& dq_rad) noexcept {
  if (J.cols() >= 6) {
    Vec6 y;
    cholesky.solve(e, y);
    dq_rad.noalias() = J.transpose() * y;
  } else {
    dq_rad.noalias() = J.transpose() * e;
    cholesky.solve(dq_rad, dq_rad);
  }
}

template <typename Gram>
double dampedStepWith(const Jacobian& J, const Vec6& e, const InverseOptions& options,
                      JointVector& dq_rad, StepFactor& factor) noexcept {
  Gram G;
  gramMatrix(J, G);
  // Only σ_min < threshold matters (ratio < 1); above it ratio = 1 gives the same λ² = 0.
  const double sigma_min = smallestSingularValueOrFloor(G, options.singular_value_threshold);
  const double ratio = sigma_min / options.singular_value_threshold;
  const double lambda2 = ratio < 1.0 ? options.damping * (1.0 - ratio * ratio) : 0.0;
  factor.valid = factor.cholesky.factor(G, lambda2);
  if (factor.valid) {
    stepFromFactor(J, factor.cholesky, e, dq_rad);
    if (dq_rad.allFinite()) return sigma_min;
    factor.valid = false;
  }
  const Eigen::JacobiSVD<Jacobian> svd(J, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const auto& sigma = svd.singularValues();
  dq_rad.setZero(J.cols());
  for (Eigen::Index i = 0; i < sigma.size(); ++i) {
    const double denominator = sigma(i) * sigma(i) + lambda2;
    if (denominator > 0.0) {
      dq_rad += (sigma(i) / denominator * svd.matrixU().col(i).dot(e)) * svd.matrixV().col(i);
    }
  }
  return sigma_min;
}

/// Damped least-squares step Δq = Σ_i σ_i / (σ_i² + λ²) v_i u_iᵀ e, rad, with λ² rising from 0
/// at σ_min ≥ singular_value_threshold to options.damping at σ_min = 0 (Levenberg–Marquardt).
/// Solved as Jᵀ (J Jᵀ + λ² I)⁻¹ e (n ≥ 6) or (Jᵀ J + λ² I)⁻¹ Jᵀ e (n < 6), the same sum, by
/// Cholesky; by the SVD only when that matrix is singular (σ_i = 0 terms are left out).
/// Returns σ_min of J, or singular_value_threshold when it is above that; factor keeps the
/// Cholesky factor for a chord step (not valid after the SVD).
inline double dampedStep(const Jacobian& J, const Vec6& e, const InverseOptions& options,
                  JointVector& dq_rad, StepFactor& factor) noexcept {
  if (J.cols() == 6) return dampedStepWith<Mat6>(J, e, options, dq_rad, factor);
  return dampedStepWith<GramMatrix>(J, e, options, dq_rad, factor);
}

/// σ_min of J, or `floor` when it is above floor (smallestSingularValueOrFloor).
inline double smallestSingularValueOfJacobianOrFloor(const Jacobian& J, double floor) noexcept {
  if (J.cols() == 6) {
    Mat6 G;
    gramMatrix(J, G);
    return smallestSingularValueOrFloor(G, floor);
  }
  GramMatrix G;
  gramMatrix(J, G);
  return smallestSingularValueOrFloor(G, floor);
}

}  // namespace stepcal::runtime::detail

// What a transmission profile holds at one harmonic, measured the way the data determine it:
// over the angles it was fitted on. On an arc narrower than the full turn neighbouring
// harmonics are not orthogonal, so a profile's single coefficients are not its content there;
// the least-squares projection of its values (gate included) onto sin k q, cos k q over the fit
// rows' angles is.
#pragma once

#include <vector>

#include <Eigen/Dense>

#include "stepcal/common/mechanisms.hpp"

namespace stepcal::test {

/// (sin, cos) coefficients of harmonic k in the values of a profile (null: zero) at the angles.
inline Eigen::Vector2d harmonicOver(const Mechanism* profile, int k,
                                    const std::vector<double>& angles_rad) {
  Eigen::MatrixXd X(static_cast<Eigen::Index>(angles_rad.size()), 2);
  Eigen::VectorXd y(X.rows());
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    const double q = angles_rad[static_cast<size_t>(i)];
    X(i, 0) = std::sin(k * q);
    X(i, 1) = std::cos(k * q);
    y(i) = profile ? transmissionOffset(*profile, q) : 0.0;
  }
  return X.colPivHouseholderQr().solve(y);
}

/// RMS of a profile's values (gate included; null: zero) minus a harmonic (sin, cos) at k, at
/// the angles, rad.
inline double rmsBeside(const Mechanism* profile, int k, const Eigen::Vector2d& harmonic,
                        const std::vector<double>& angles_rad) {
  double sum = 0.0;
  for (double q : angles_rad) {
    const double v = (profile ? transmissionOffset(*profile, q) : 0.0) -
                     harmonic(0) * std::sin(k * q) - harmonic(1) * std::cos(k * q);
    sum += v * v;
  }
  return std::sqrt(sum / static_cast<double>(angles_rad.size()));
}

}  // namespace stepcal::test

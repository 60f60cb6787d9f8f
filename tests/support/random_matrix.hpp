// Random test matrices from a seeded generator.
#pragma once

#include <random>

#include <Eigen/Core>

namespace stepcal::test {

/// rows × cols entries uniform in [low, high), drawn in storage (column-major) order.
inline Eigen::MatrixXd uniformMatrix(Eigen::Index rows, Eigen::Index cols, double low,
                                     double high, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(low, high);
  Eigen::MatrixXd A(rows, cols);
  for (Eigen::Index i = 0; i < A.size(); ++i) A.data()[i] = u(rng);
  return A;
}

}  // namespace stepcal::test

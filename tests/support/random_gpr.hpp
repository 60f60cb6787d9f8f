// A consistent random GPR for tests and fuzz seeds: random normalised inputs and targets, α
// solved from the same kernel the model-file loader checks (docs/method.md eq. 27, 30).
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

#include <Eigen/Cholesky>

#include "stepcal/common/model_file.hpp"

namespace stepcal::test {

/// m training points, D inputs, P outputs; σ_f = 1, σ_n = 0.1, every length scale 2.
inline GprParameters randomConsistentGpr(int m, int D, int P, uint64_t seed = 1) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  GprParameters g;
  g.inputs_normalised = Eigen::MatrixXd::NullaryExpr(m, D, [&] { return normal(rng); });
  g.input_offset = Eigen::VectorXd::Zero(D);
  g.input_scale = Eigen::VectorXd::Ones(D);
  g.output_mean = Eigen::VectorXd::Zero(P);
  g.output_scale = Eigen::VectorXd::Constant(P, 1e-4);
  g.length_scales = Eigen::VectorXd::Constant(D, 2.0);
  g.signal_sigma = 1.0;
  g.noise_sigma = 0.1;
  g.targets_standardised = Eigen::MatrixXd::NullaryExpr(m, P, [&] { return normal(rng); });
  Eigen::MatrixXd K(m, m);
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < m; ++j) {
      const double d2 = ((g.inputs_normalised.row(i) - g.inputs_normalised.row(j)).array() /
                         g.length_scales.transpose().array())
                            .square()
                            .sum();
      K(i, j) = g.signal_sigma * g.signal_sigma * std::exp(-0.5 * d2);
    }
  }
  K.diagonal().array() += g.noise_sigma * g.noise_sigma;
  g.alpha = K.llt().solve(g.targets_standardised);
  return g;
}

}  // namespace stepcal::test

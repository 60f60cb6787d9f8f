// GprPredictor, the GPR's predictive side in common: the trainer's predictions bit for bit, the
// closed form for one training point, the relative std near data and far from it,
// allocation-free prediction, and refusal of inconsistent parameters.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Cholesky>

#include "stepcal/common/error.hpp"
#include "stepcal/common/gpr_predictor.hpp"
#include "stepcal/trainer/gpr.hpp"
#include "stepcal/allocation_counter.hpp"
#include "support/random_matrix.hpp"

namespace stepcal {
namespace {

using test::uniformMatrix;

/// A smooth function of the first two inputs per output, plus uniform noise of ± noise.
Eigen::MatrixXd noisyTargets(const Eigen::MatrixXd& X, Eigen::Index outputs, double noise,
                             std::mt19937_64& rng) {
  Eigen::MatrixXd Y = noise * uniformMatrix(X.rows(), outputs, -1.0, 1.0, rng);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    for (Eigen::Index o = 0; o < outputs; ++o) {
      Y(i, o) += std::sin(1.1 * X(i, 0) + 0.5 * o) + 0.2 * (o + 1) * std::cos(0.7 * X(i, 1));
    }
  }
  return Y;
}

/// Parameters for m random training points with α solved by the predictor itself.
GprParameters randomParameters(std::mt19937_64& rng, Eigen::Index m, Eigen::Index D,
                               Eigen::Index P, double noise_sigma) {
  GprParameters g;
  g.inputs_normalised = uniformMatrix(m, D, -1.5, 1.5, rng);
  g.input_offset = uniformMatrix(D, 1, -0.5, 0.5, rng);
  g.input_scale = uniformMatrix(D, 1, 0.5, 3.0, rng);
  g.output_mean = uniformMatrix(P, 1, -1e-3, 1e-3, rng);
  g.output_scale = uniformMatrix(P, 1, 1e-4, 1e-3, rng);
  g.length_scales = uniformMatrix(D, 1, 0.8, 2.0, rng);
  g.signal_sigma = 1.3;
  g.noise_sigma = noise_sigma;
  g.targets_standardised = uniformMatrix(m, P, -2.0, 2.0, rng);
  return GprPredictor::conditioned(g).parameters();
}

/// Raw input whose normalised value is row i of the training inputs.
Eigen::VectorXd rawTrainingInput(const GprParameters& g, Eigen::Index i) {
  return g.input_offset + g.input_scale.cwiseProduct(g.inputs_normalised.row(i).transpose());
}

TEST(GprPredictor, ReproducesTheTrainersPredictionsBitForBit) {
  std::mt19937_64 rng(3);
  const Eigen::MatrixXd X = uniformMatrix(60, 4, -2.0, 2.0, rng);
  const Eigen::MatrixXd Y = noisyTargets(X, 3, 0.01, rng);
  trainer::GprOptions options;
  options.restarts = 2;
  const trainer::GaussianProcess gp = trainer::GaussianProcess::fit(X, Y, options);
  // A copy, as the model file carries it to the runtime.
  const GprParameters parameters = gp.parameters();
  const GprPredictor predictor = GprPredictor::fromParameters(parameters);
  ASSERT_EQ(predictor.inputDim(), 4);
  ASSERT_EQ(predictor.outputDim(), 3);
  ASSERT_EQ(predictor.trainingSize(), 60);
  GprPredictor::Workspace workspace = predictor.makeWorkspace();
  for (int q = 0; q < 20; ++q) {
    const Eigen::VectorXd x = uniformMatrix(4, 1, -3.0, 3.0, rng);
    Eigen::VectorXd mean(3), std_dev(3);
    predictor.predictInto(x.data(), mean.data(), std_dev.data(), workspace);
    const Eigen::VectorXd trainer_mean = gp.predictMean(x), trainer_std = gp.predictStd(x);
    for (int o = 0; o < 3; ++o) {
      EXPECT_EQ(mean(o), trainer_mean(o)) << q << " " << o;
      EXPECT_EQ(std_dev(o), trainer_std(o)) << q << " " << o;
    }
    const double relative = predictor.relativeStd(x.data(), workspace);
    EXPECT_NEAR(relative,
                trainer_std(1) / (gp.scaling().output_scale(1) * gp.hyperparameters().signal_sigma),
                1e-15);
  }
}

TEST(GprPredictor, OneTrainingPointMatchesTheClosedForm) {
  const double sf = 1.7, sn = 0.3, ell = 0.8;
  GprParameters g;
  g.inputs_normalised = Eigen::MatrixXd::Constant(1, 1, 0.4);
  g.input_offset = Eigen::VectorXd::Constant(1, 2.0);
  g.input_scale = Eigen::VectorXd::Constant(1, 0.5);
  g.output_mean = Eigen::Vector2d(0.1, -0.2);
  g.output_scale = Eigen::Vector2d(3.0, 0.01);
  g.length_scales = Eigen::VectorXd::Constant(1, ell);
  g.signal_sigma = sf;
  g.noise_sigma = sn;
  g.targets_standardised = Eigen::RowVector2d(2.5, -1.0);
  const GprPredictor predictor = GprPredictor::conditioned(g);
  const double k_train = sf * sf + sn * sn;
  EXPECT_NEAR(predictor.parameters().alpha(0, 0), 2.5 / k_train, 1e-15);
  EXPECT_NEAR(predictor.parameters().alpha(0, 1), -1.0 / k_train, 1e-15);
  EXPECT_NEAR(predictor.choleskyLower()(0, 0), std::sqrt(k_train), 1e-15);

  const double x_raw = 2.55, x_normalised = (x_raw - 2.0) / 0.5;
  const double k_star = sf * sf * std::exp(-0.5 * std::pow((x_normalised - 0.4) / ell, 2));
  const double latent_std = std::sqrt(sf * sf - k_star * k_star / k_train);
  GprPredictor::Workspace workspace = predictor.makeWorkspace();
  double mean[2], std_dev[2];
  predictor.predictInto(&x_raw, mean, std_dev, workspace);
  EXPECT_NEAR(mean[0], 0.1 + 3.0 * k_star * 2.5 / k_train, 1e-14);
  EXPECT_NEAR(mean[1], -0.2 + 0.01 * k_star * -1.0 / k_train, 1e-16);
  EXPECT_NEAR(std_dev[0], 3.0 * latent_std, 1e-14);
  EXPECT_NEAR(std_dev[1], 0.01 * latent_std, 1e-16);
  EXPECT_NEAR(predictor.relativeStd(&x_raw, workspace), latent_std / sf, 1e-15);
  // The mean alone (std_out null) is the same mean.
  double mean_only[2];
  predictor.predictInto(&x_raw, mean_only, nullptr, workspace);
  EXPECT_EQ(mean_only[0], mean[0]);
  EXPECT_EQ(mean_only[1], mean[1]);
}

TEST(GprPredictor, RelativeStdIsNearZeroAtTheDataAndOneFarAway) {
  std::mt19937_64 rng(11);
  const GprParameters g = randomParameters(rng, 40, 3, 2, 1e-3);
  const GprPredictor predictor = GprPredictor::fromParameters(g);
  GprPredictor::Workspace workspace = predictor.makeWorkspace();
  for (Eigen::Index i = 0; i < 40; i += 7) {
    const Eigen::VectorXd x = rawTrainingInput(g, i);
    const double relative = predictor.relativeStd(x.data(), workspace);
    EXPECT_GE(relative, 0.0);
    EXPECT_LT(relative, 2e-3) << "training point " << i;
  }
  // Far outside the data (hundreds of length scales) the data say nothing.
  const Eigen::VectorXd far = g.input_offset + 500.0 * g.input_scale;
  EXPECT_EQ(predictor.relativeStd(far.data(), workspace), 1.0);
  double mean[2], std_dev[2];
  predictor.predictInto(far.data(), mean, std_dev, workspace);
  for (int o = 0; o < 2; ++o) {
    EXPECT_EQ(mean[o], g.output_mean(o));  // the prior mean
    EXPECT_DOUBLE_EQ(std_dev[o], g.output_scale(o) * g.signal_sigma);
  }
  // In between it stays in [0, 1], close to 1 a few length scales outside the data.
  for (double step : {0.5, 1.0, 2.0, 4.0}) {
    const Eigen::VectorXd x = rawTrainingInput(g, 0) + step * g.input_scale;
    const double relative = predictor.relativeStd(x.data(), workspace);
    EXPECT_GE(relative, 0.0) << step;
    EXPECT_LE(relative, 1.0) << step;
  }
  const Eigen::VectorXd outside = g.input_offset + 8.0 * g.input_scale;
  EXPECT_GT(predictor.relativeStd(outside.data(), workspace), 0.99);
}

TEST(GprPredictor, ConditionedAlphaSolvesTheKernelSystem) {
  std::mt19937_64 rng(5);
  const GprParameters g = randomParameters(rng, 50, 4, 3, 0.05);
  // The kernel written out independently (docs/method.md eq. 27).
  Eigen::MatrixXd K(50, 50);
  for (Eigen::Index i = 0; i < 50; ++i) {
    for (Eigen::Index j = 0; j < 50; ++j) {
      const double d2 = ((g.inputs_normalised.row(i) - g.inputs_normalised.row(j)).transpose()
                             .cwiseQuotient(g.length_scales))
                            .squaredNorm();
      K(i, j) = g.signal_sigma * g.signal_sigma * std::exp(-0.5 * d2) +
                (i == j ? g.noise_sigma * g.noise_sigma : 0.0);
    }
  }
  EXPECT_LT((K * g.alpha - g.targets_standardised).cwiseAbs().maxCoeff(), 1e-10);
  const GprPredictor predictor = GprPredictor::fromParameters(g);
  const Eigen::MatrixXd L = predictor.choleskyLower();
  EXPECT_TRUE(L.isLowerTriangular(0.0));
  EXPECT_LT((L * L.transpose() - K).cwiseAbs().maxCoeff(), 1e-13);
}

TEST(GprPredictor, PredictsWithoutAllocating) {
  std::mt19937_64 rng(13);
  const GprParameters g = randomParameters(rng, 80, 12, 6, 0.1);
  const GprPredictor predictor = GprPredictor::fromParameters(g);
  GprPredictor::Workspace workspace = predictor.makeWorkspace();
  const Eigen::VectorXd x = uniformMatrix(12, 1, -1.0, 1.0, rng);
  double mean[6], std_dev[6], mean_only[6];
  double relative = 0.0;
  long allocations = 0;
  {
    test::AllocationCounter counter;
    predictor.predictInto(x.data(), mean, std_dev, workspace);
    predictor.predictInto(x.data(), mean_only, nullptr, workspace);
    relative = predictor.relativeStd(x.data(), workspace);
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  for (int o = 0; o < 6; ++o) {
    EXPECT_TRUE(std::isfinite(mean[o]));
    EXPECT_EQ(mean_only[o], mean[o]);
    EXPECT_NEAR(std_dev[o], g.output_scale(o) * g.signal_sigma * relative, 1e-14 * std_dev[o]);
  }
}

TEST(GprPredictor, StdBoundIsNeverBelowTheExactStd) {
  // m = 150 > 48: the bound conditions on a subset; random points near, inside and far from the
  // data, and every training point.
  std::mt19937_64 rng(19);
  for (const double noise_sigma : {1e-3, 0.1, 2.0}) {
    SCOPED_TRACE(noise_sigma);
    const GprParameters g = randomParameters(rng, 150, 5, 3, noise_sigma);
    const GprPredictor predictor = GprPredictor::fromParameters(g);
    ASSERT_EQ(predictor.boundSubsetSize(), GprPredictor::kMaxBoundSubset);
    GprPredictor::Workspace workspace = predictor.makeWorkspace();
    const auto check = [&](const Eigen::VectorXd& x, const std::string& where) {
      double mean[3], exact[3], bound_mean[3], bound[3];
      predictor.predictInto(x.data(), mean, exact, workspace);
      predictor.predictMeanAndBoundInto(x.data(), bound_mean, bound, workspace);
      const double relative = predictor.relativeStd(x.data(), workspace);
      const double relative_bound = predictor.relativeStdBound(x.data(), workspace);
      EXPECT_GE(relative_bound, relative - 1e-12) << where;
      EXPECT_LE(relative_bound, 1.0) << where;
      for (int o = 0; o < 3; ++o) {
        EXPECT_EQ(bound_mean[o], mean[o]) << where;  // the same mean
        EXPECT_GE(bound[o], exact[o] - 1e-12 * g.output_scale(o) * g.signal_sigma) << where;
        EXPECT_NEAR(bound[o], g.output_scale(o) * g.signal_sigma * relative_bound,
                    1e-14 * g.output_scale(o)) << where;
      }
    };
    for (Eigen::Index i = 0; i < 150; ++i) check(rawTrainingInput(g, i), "training " + std::to_string(i));
    for (int q = 0; q < 200; ++q) {
      const double spread = q < 100 ? 1.5 : 4.0;
      const Eigen::VectorXd z = uniformMatrix(5, 1, -spread, spread, rng);
      check(g.input_offset + g.input_scale.cwiseProduct(z), "random " + std::to_string(q));
    }
    // The subset's own points are covered like the full GP's: the bound is small there when
    // the noise is.
    if (noise_sigma < 0.01) {
      const Eigen::VectorXd x = rawTrainingInput(g, predictor.boundSubset()(7));
      EXPECT_LT(predictor.relativeStdBound(x.data(), workspace), 2e-2);
    }
  }
}

TEST(GprPredictor, StdBoundSubsetIsDeterministicFarthestPointSampling) {
  std::mt19937_64 rng(23);
  const GprParameters g = randomParameters(rng, 100, 4, 2, 0.05);
  const GprPredictor a = GprPredictor::fromParameters(g), b = GprPredictor::fromParameters(g);
  ASSERT_EQ(a.boundSubsetSize(), 48);
  EXPECT_EQ(a.boundSubset(), b.boundSubset());
  const Eigen::VectorXi& S = a.boundSubset();
  EXPECT_EQ(S(0), 0);  // sampling starts from training point 0
  for (Eigen::Index s = 1; s < S.size(); ++s) EXPECT_LT(S(s - 1), S(s));  // ascending, distinct
  // Spread out: the closest pair in the subset is farther apart than the closest pair overall.
  const Eigen::MatrixXd Z = g.inputs_normalised * g.length_scales.cwiseInverse().asDiagonal();
  const auto closest = [&](const std::vector<Eigen::Index>& rows) {
    double d = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < rows.size(); ++i) {
      for (size_t j = i + 1; j < rows.size(); ++j) {
        d = std::min(d, (Z.row(rows[i]) - Z.row(rows[j])).norm());
      }
    }
    return d;
  };
  std::vector<Eigen::Index> all(100), subset;
  for (Eigen::Index i = 0; i < 100; ++i) all[static_cast<size_t>(i)] = i;
  for (Eigen::Index s = 0; s < S.size(); ++s) subset.push_back(S(s));
  EXPECT_GT(closest(subset), closest(all));
}

TEST(GprPredictor, StdBoundEqualsTheExactStdWhenTheSubsetIsEverything) {
  std::mt19937_64 rng(29);
  const GprParameters g = randomParameters(rng, 30, 4, 2, 0.05);
  const GprPredictor predictor = GprPredictor::fromParameters(g);
  ASSERT_EQ(predictor.boundSubsetSize(), 30);
  EXPECT_EQ(predictor.boundSubset(), Eigen::VectorXi::LinSpaced(30, 0, 29));
  GprPredictor::Workspace workspace = predictor.makeWorkspace();
  for (int q = 0; q < 50; ++q) {
    const Eigen::VectorXd x = uniformMatrix(4, 1, -3.0, 3.0, rng);
    double mean[2], exact[2], bound[2];
    predictor.predictInto(x.data(), mean, exact, workspace);
    predictor.predictMeanAndBoundInto(x.data(), mean, bound, workspace);
    for (int o = 0; o < 2; ++o) EXPECT_EQ(bound[o], exact[o]) << q;
    EXPECT_EQ(predictor.relativeStdBound(x.data(), workspace),
              predictor.relativeStd(x.data(), workspace));
  }
}

TEST(GprPredictor, StdBoundAllocatesNothing) {
  std::mt19937_64 rng(31);
  const GprParameters g = randomParameters(rng, 120, 12, 6, 0.1);
  const GprPredictor predictor = GprPredictor::fromParameters(g);
  GprPredictor::Workspace workspace = predictor.makeWorkspace();
  const Eigen::VectorXd x = uniformMatrix(12, 1, -1.0, 1.0, rng);
  double mean[6], bound[6], mean_only[6];
  double relative = 0.0;
  long allocations = 0;
  {
    test::AllocationCounter counter;
    predictor.predictMeanAndBoundInto(x.data(), mean, bound, workspace);
    predictor.predictMeanAndBoundInto(x.data(), mean_only, nullptr, workspace);
    relative = predictor.relativeStdBound(x.data(), workspace);
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  for (int o = 0; o < 6; ++o) {
    EXPECT_EQ(mean_only[o], mean[o]);
    EXPECT_NEAR(bound[o], g.output_scale(o) * g.signal_sigma * relative, 1e-14 * bound[o]);
  }
}

/// Mean and std of predictInto at 40 queries (5 at training inputs: distance 0, the clamp)
/// against the kernel written out term by term (docs/method.md eq. 27, 30, 31).
void expectPredictionsMatchTheDirectSum(const GprParameters& g, std::mt19937_64& rng) {
  const Eigen::Index m = g.inputs_normalised.rows(), D = g.inputs_normalised.cols();
  const GprPredictor predictor = GprPredictor::fromParameters(g);
  GprPredictor::Workspace workspace = predictor.makeWorkspace();
  const Eigen::MatrixXd& L = predictor.choleskyLower();
  for (int q = 0; q < 40; ++q) {
    const Eigen::VectorXd x = q < 5 ? rawTrainingInput(g, q)
                                    : Eigen::VectorXd(uniformMatrix(D, 1, -3.0, 3.0, rng));
    const Eigen::VectorXd z = (x - g.input_offset).cwiseQuotient(g.input_scale);
    Eigen::VectorXd k(m);
    for (Eigen::Index i = 0; i < m; ++i) {
      double d2 = 0.0;
      for (Eigen::Index d = 0; d < D; ++d) {
        d2 += std::pow((g.inputs_normalised(i, d) - z(d)) / g.length_scales(d), 2);
      }
      k(i) = g.signal_sigma * g.signal_sigma * std::exp(-0.5 * d2);
    }
    const Eigen::VectorXd v = L.triangularView<Eigen::Lower>().solve(k);
    const double latent = std::sqrt(std::max(0.0, g.signal_sigma * g.signal_sigma - v.squaredNorm()));
    double mean[3], std_dev[3];
    predictor.predictInto(x.data(), mean, std_dev, workspace);
    for (int o = 0; o < 3; ++o) {
      const double expected_mean = g.output_mean(o) + g.output_scale(o) * k.dot(g.alpha.col(o));
      EXPECT_NEAR(mean[o], expected_mean, 1e-12 * g.output_scale(o) * g.alpha.col(o).cwiseAbs().sum()) << q;
      EXPECT_NEAR(std_dev[o], g.output_scale(o) * latent, 1e-12 * g.output_scale(o) * g.signal_sigma) << q;
    }
  }
}

TEST(GprPredictor, VectorisedKernelColumnMatchesTheDirectSum) {
  std::mt19937_64 rng(37);
  expectPredictionsMatchTheDirectSum(randomParameters(rng, 70, 6, 3, 0.05), rng);
}

// Inputs every training point shares (a wrench that is always zero without an F/T sensor) leave
// the matrix–vector product and enter once per query: the same predictions, queried off them too.
TEST(GprPredictor, InputsConstantOverTrainingGiveTheSamePredictions) {
  std::mt19937_64 rng(41);
  GprParameters g = randomParameters(rng, 70, 6, 3, 0.05);
  g.inputs_normalised.col(2).setZero();
  g.inputs_normalised.col(5).setConstant(0.7);
  const GprParameters conditioned = GprPredictor::conditioned(g).parameters();
  ASSERT_EQ(GprPredictor::fromParameters(conditioned).varyingInputs(), 4);
  expectPredictionsMatchTheDirectSum(conditioned, rng);
}

// A GPR per payload force (docs/method.md eq. 30a): its correction is the same GP's times
// ‖f‖ / f_ref, f the wrench's force (inputs D−6 .. D−4); at zero force exactly zero, mean and
// std, without evaluating the GP; allocation-free.
TEST(GprPredictor, PerPayloadForceScalesByTheForceAndIsZeroAtZeroLoad) {
  std::mt19937_64 rng(23);
  const GprParameters paper = randomParameters(rng, 30, 12, 6, 0.1);
  GprParameters per_force = paper;
  per_force.payload_force_reference_n = 300.0;
  const GprPredictor plain = GprPredictor::fromParameters(paper);
  const GprPredictor gated = GprPredictor::fromParameters(per_force);
  GprPredictor::Workspace ws_plain = plain.makeWorkspace(), ws_gated = gated.makeWorkspace();
  Eigen::VectorXd x = rawTrainingInput(paper, 3);
  x.segment<3>(6) << 120.0, -160.0, 0.0;  // ‖f‖ = 200 N: gain 2/3
  Eigen::VectorXd mean(6), std_dev(6), mean_gated(6), std_gated(6), bound(6), bound_gated(6);
  plain.predictInto(x.data(), mean.data(), std_dev.data(), ws_plain);
  gated.predictInto(x.data(), mean_gated.data(), std_gated.data(), ws_gated);
  EXPECT_DOUBLE_EQ(gated.outputGain(x.data()), 200.0 / 300.0);
  for (int o = 0; o < 6; ++o) {
    EXPECT_NEAR(mean_gated(o), 2.0 / 3.0 * mean(o), 1e-15 * std::abs(mean(o)) + 1e-300);
    EXPECT_NEAR(std_gated(o), 2.0 / 3.0 * std_dev(o), 1e-15 * std_dev(o) + 1e-300);
  }
  EXPECT_GT(mean.cwiseAbs().maxCoeff(), 0.0);
  plain.predictMeanAndBoundInto(x.data(), mean.data(), bound.data(), ws_plain);
  gated.predictMeanAndBoundInto(x.data(), mean_gated.data(), bound_gated.data(), ws_gated);
  EXPECT_NEAR(bound_gated(0), 2.0 / 3.0 * bound(0), 1e-15 * bound(0));
  EXPECT_NEAR(gated.relativeStdBound(x.data(), ws_gated),
              2.0 / 3.0 * plain.relativeStdBound(x.data(), ws_plain), 1e-15);

  x.segment<3>(6).setZero();  // no load; the moments alone do not count
  x.segment<3>(9) << 5.0, -3.0, 1.0;
  long allocations = 0;
  {
    test::AllocationCounter counter;
    gated.predictInto(x.data(), mean_gated.data(), std_gated.data(), ws_gated);
    gated.predictMeanAndBoundInto(x.data(), mean_gated.data(), bound_gated.data(), ws_gated);
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_TRUE((mean_gated.array() == 0.0).all()) << mean_gated.transpose();
  EXPECT_TRUE((std_gated.array() == 0.0).all());
  EXPECT_TRUE((bound_gated.array() == 0.0).all());
  EXPECT_EQ(gated.relativeStd(x.data(), ws_gated), 0.0);

  GprParameters bad = per_force;
  bad.payload_force_reference_n = -1.0;
  EXPECT_THROW(GprPredictor::fromParameters(bad), InputError);
}

TEST(GprPredictor, RefusesInconsistentParameters) {
  std::mt19937_64 rng(17);
  const GprParameters good = randomParameters(rng, 10, 3, 2, 0.1);
  EXPECT_NO_THROW(GprPredictor::fromParameters(good));
  const auto refused = [&](auto edit) {
    GprParameters g = good;
    edit(g);
    try {
      GprPredictor::fromParameters(g);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // Sizes.
  EXPECT_NE(refused([](GprParameters& g) { g.length_scales.conservativeResize(2); })
                .find("length_scales is 2 × 1; expected 3 × 1"),
            std::string::npos);
  EXPECT_NE(refused([](GprParameters& g) { g.alpha.conservativeResize(9, 2); }).find("alpha"),
            std::string::npos);
  EXPECT_NE(refused([](GprParameters& g) { g.output_scale.conservativeResize(3); })
                .find("output_scale"),
            std::string::npos);
  EXPECT_NE(refused([](GprParameters& g) { g.targets_standardised.conservativeResize(10, 3); })
                .find("targets_standardised"),
            std::string::npos);
  EXPECT_NE(refused([](GprParameters& g) { g = GprParameters(); }).find("at least one"),
            std::string::npos);
  // Values.
  EXPECT_NE(refused([&](GprParameters& g) { g.inputs_normalised(4, 1) = nan; }).find("finite"),
            std::string::npos);
  EXPECT_NE(refused([&](GprParameters& g) { g.alpha(2, 0) = nan; }).find("finite"),
            std::string::npos);
  EXPECT_NE(refused([](GprParameters& g) { g.length_scales(1) = -1.0; }).find("length_scales"),
            std::string::npos);
  EXPECT_NE(refused([](GprParameters& g) { g.input_scale(0) = 0.0; }).find("input_scale"),
            std::string::npos);
  EXPECT_NE(refused([](GprParameters& g) { g.signal_sigma = 0.0; }).find("σ_f"),
            std::string::npos);
  EXPECT_NE(refused([&](GprParameters& g) { g.noise_sigma = nan; }).find("σ_n"),
            std::string::npos);
  // Two identical training inputs without noise: K = [1 1; 1 1] is singular.
  EXPECT_NE(refused([](GprParameters& g) {
              g.inputs_normalised = Eigen::MatrixXd::Constant(2, 3, 0.25);
              g.targets_standardised = g.targets_standardised.topRows(2).eval();
              g.alpha = g.alpha.topRows(2).eval();
              g.signal_sigma = 1.0;
              g.noise_sigma = 0.0;
            }).find("not positive definite"),
            std::string::npos);
  // Overflowing hyperparameters cannot give a factor either.
  EXPECT_NE(refused([](GprParameters& g) { g.signal_sigma = 1e200; }).find("not positive definite"),
            std::string::npos);
  GprParameters no_targets = good;
  no_targets.targets_standardised.resize(0, 0);
  EXPECT_THROW(GprPredictor::conditioned(no_targets), InputError);
}

/// A GP over two inputs whose outputs share sin(x₀) cos(x₁) but carry their own Gaussian noise,
/// noise_per_output[o] in standardised units, with the given shared σ_n; α solved.
GprParameters twoNoiseLevels(std::mt19937_64& rng, Eigen::Index m,
                             const std::vector<double>& noise_per_output, double noise_sigma) {
  const Eigen::Index P = static_cast<Eigen::Index>(noise_per_output.size());
  GprParameters g;
  g.inputs_normalised = uniformMatrix(m, 2, -2.0, 2.0, rng);
  g.input_offset = Eigen::Vector2d(0.1, -0.2);
  g.input_scale = Eigen::Vector2d(2.0, 0.5);
  g.output_mean = Eigen::VectorXd::Zero(P);
  g.output_scale = Eigen::VectorXd::LinSpaced(P, 1e-4, 1e-3);
  g.length_scales = Eigen::Vector2d::Ones();
  g.signal_sigma = 1.0;
  g.noise_sigma = noise_sigma;
  std::normal_distribution<double> normal;
  g.targets_standardised.resize(m, P);
  for (Eigen::Index i = 0; i < m; ++i) {
    const double f = std::sin(g.inputs_normalised(i, 0)) * std::cos(g.inputs_normalised(i, 1));
    for (Eigen::Index o = 0; o < P; ++o) {
      g.targets_standardised(i, o) = f + noise_per_output[static_cast<size_t>(o)] * normal(rng);
    }
  }
  return GprPredictor::conditioned(g).parameters();
}

// The held-out noise against its definition computed the long way: each training point left out
// by a GP conditioned on the others (same hyperparameters), its residual and latent variance
// predicted there; the closed form α_i / [K⁻¹]_ii is the same residual.
TEST(GprPredictor, HeldOutNoiseIsWhatTheLeftOutPointsShowBeyondTheLatentVariance) {
  std::mt19937_64 rng(41);
  const Eigen::Index m = 60;
  const GprParameters g = twoNoiseLevels(rng, m, {0.2, 0.4}, 0.2);
  const GprPredictor predictor = GprPredictor::fromParameters(g);
  Eigen::Vector2d squared_residual = Eigen::Vector2d::Zero();
  double latent_variance = 0.0;
  for (Eigen::Index i = 0; i < m; ++i) {
    GprParameters others = g;
    Eigen::Index row = 0;
    others.inputs_normalised.resize(m - 1, 2);
    others.targets_standardised.resize(m - 1, 2);
    for (Eigen::Index k = 0; k < m; ++k) {
      if (k == i) continue;
      others.inputs_normalised.row(row) = g.inputs_normalised.row(k);
      others.targets_standardised.row(row++) = g.targets_standardised.row(k);
    }
    const GprPredictor without = GprPredictor::conditioned(others);
    GprPredictor::Workspace workspace = without.makeWorkspace();
    const Eigen::VectorXd x = rawTrainingInput(g, i);
    double mean[2], std[2];
    without.predictInto(x.data(), mean, std, workspace);
    for (int o = 0; o < 2; ++o) {
      const double y_raw = g.output_mean(o) + g.output_scale(o) * g.targets_standardised(i, o);
      squared_residual(o) += std::pow((y_raw - mean[o]) / g.output_scale(o), 2) / m;
    }
    latent_variance += std::pow(std[0] / g.output_scale(0), 2) / m;
  }
  for (int o = 0; o < 2; ++o) {
    const double expected = std::sqrt(std::max(0.0, squared_residual(o) - latent_variance));
    ASSERT_GT(expected, 0.1);
    EXPECT_NEAR(predictor.heldOutNoise()(o), expected, 1e-9 * expected) << o;
  }
}

// Outputs under one σ_n (0.2, as the fit gives the six outputs one): an output as noisy as σ_n
// says and one twice as noisy each get their own noise, 0.2 and 0.4, within 10 % (400 points: a
// standard error of 3.5 %); one quieter than σ_n (0.05) gets no more than its own.
TEST(GprPredictor, HeldOutNoiseTellsTheOutputsNoiseApartUnderOneSharedNoise) {
  std::mt19937_64 rng(43);
  const GprParameters g = twoNoiseLevels(rng, 400, {0.2, 0.4, 0.05}, 0.2);
  const GprPredictor predictor = GprPredictor::fromParameters(g);
  std::cout << "[ held out ] noise " << predictor.heldOutNoise().transpose()
            << " (true 0.2 0.4 0.05)\n";
  EXPECT_NEAR(predictor.heldOutNoise()(0), 0.2, 0.1 * 0.2);
  EXPECT_NEAR(predictor.heldOutNoise()(1), 0.4, 0.1 * 0.4);
  EXPECT_LE(predictor.heldOutNoise()(2), 0.05);
  // Conditioned or read back from its parameters, the same.
  EXPECT_EQ(GprPredictor::conditioned(g).heldOutNoise(), predictor.heldOutNoise());
}

}  // namespace
}  // namespace stepcal

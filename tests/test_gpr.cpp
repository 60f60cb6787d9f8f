// Step 3 GPR: closed forms on tiny cases, an independent dense computation, the analytic
// likelihood gradient against finite differences, hyperparameter recovery, cross-validation
// against refitting, allocation-free prediction, and the fit time at the paper's size.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <iostream>
#include <random>

#include <Eigen/LU>

#include "stepcal/common/error.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/trainer/gpr.hpp"
#include "stepcal/allocation_counter.hpp"
#include "support/random_matrix.hpp"

namespace stepcal::trainer {
namespace {

using test::uniformMatrix;

GprHyperparameters hyperparameters(const Eigen::VectorXd& length_scales, double signal_sigma,
                                   double noise_sigma) {
  GprHyperparameters h;
  h.length_scales = length_scales;
  h.signal_sigma = signal_sigma;
  h.noise_sigma = noise_sigma;
  return h;
}

// Smooth multi-output test function of the first two inputs; the others are irrelevant.
Eigen::MatrixXd smoothTargets(const Eigen::MatrixXd& X, Eigen::Index outputs) {
  Eigen::MatrixXd Y(X.rows(), outputs);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    for (Eigen::Index o = 0; o < outputs; ++o) {
      Y(i, o) = std::sin(1.3 * X(i, 0) + 0.4 * o) + 0.3 * (o + 1) * std::cos(0.8 * X(i, 1));
    }
  }
  return Y;
}

/// Training data: inputs uniform in [low, high], targets smoothTargets of them plus noise
/// uniform in [-noise, noise]; drawn from rng in that order (inputs, then noise).
struct Sample {
  Eigen::MatrixXd X, Y;
};
Sample noisySmoothSample(Eigen::Index rows, Eigen::Index inputs, Eigen::Index outputs, double low,
                         double high, double noise, std::mt19937_64& rng) {
  Sample s;
  s.X = uniformMatrix(rows, inputs, low, high, rng);
  s.Y = smoothTargets(s.X, outputs) + noise * uniformMatrix(rows, outputs, -1.0, 1.0, rng);
  return s;
}

// Squared-exponential kernel on raw inputs, written out independently of gpr.cpp.
double kernel(const Eigen::VectorXd& a, const Eigen::VectorXd& b, const GprHyperparameters& h) {
  return h.signal_sigma * h.signal_sigma *
         std::exp(-0.5 * (a - b).cwiseQuotient(h.length_scales).squaredNorm());
}

TEST(Gpr, SinglePointMatchesHandFormula) {
  const double sf = 1.7, sn = 0.3, ell = 0.8, y = 2.5;
  const double x_train = 0.4, x_query = 1.1;
  Eigen::MatrixXd X(1, 1), Y(1, 1);
  X << x_train;
  Y << y;
  const GaussianProcess gp = GaussianProcess::withHyperparameters(
      X, Y, GprScaling::identity(1, 1), hyperparameters(Eigen::VectorXd::Constant(1, ell), sf, sn));
  const double k_star = sf * sf * std::exp(-0.5 * std::pow((x_query - x_train) / ell, 2));
  const double k_train = sf * sf + sn * sn;
  const Eigen::VectorXd query = Eigen::VectorXd::Constant(1, x_query);
  EXPECT_NEAR(gp.predictMean(query)(0), k_star * y / k_train, 1e-14);
  EXPECT_NEAR(gp.predictStd(query)(0), std::sqrt(sf * sf - k_star * k_star / k_train), 1e-14);
  EXPECT_NEAR(gp.alpha()(0, 0), y / k_train, 1e-14);
  EXPECT_NEAR(gp.logMarginalLikelihood(),
              -0.5 * y * y / k_train - 0.5 * std::log(k_train) - 0.5 * std::log(2 * kPi), 1e-13);
}

TEST(Gpr, TwoPointsMatchHandFormula) {
  const double sf = 0.9, sn = 0.2;
  const Eigen::Vector2d ell(0.7, 1.5);
  Eigen::MatrixXd X(2, 2), Y(2, 1);
  X << 0.1, -0.3,  //
      0.6, 0.4;
  Y << 1.0, -0.5;
  const GprHyperparameters h = hyperparameters(ell, sf, sn);
  const GaussianProcess gp =
      GaussianProcess::withHyperparameters(X, Y, GprScaling::identity(2, 1), h);
  const Eigen::Vector2d query(0.3, 0.2);
  // [a b; b a]⁻¹ = [a −b; −b a] / (a² − b²).
  const double a = sf * sf + sn * sn;
  const double b = kernel(X.row(0).transpose(), X.row(1).transpose(), h);
  const double k0 = kernel(X.row(0).transpose(), query, h);
  const double k1 = kernel(X.row(1).transpose(), query, h);
  const double det = a * a - b * b;
  const double alpha0 = (a * Y(0) - b * Y(1)) / det, alpha1 = (a * Y(1) - b * Y(0)) / det;
  const double variance = sf * sf - (a * k0 * k0 - 2 * b * k0 * k1 + a * k1 * k1) / det;
  EXPECT_NEAR(gp.predictMean(query)(0), k0 * alpha0 + k1 * alpha1, 1e-14);
  EXPECT_NEAR(gp.predictStd(query)(0), std::sqrt(variance), 1e-14);
}

TEST(Gpr, MatchesIndependentDenseComputation) {
  std::mt19937_64 rng(7);
  const Eigen::Index m = 25, D = 3, P = 2;
  const Eigen::MatrixXd X = uniformMatrix(m, D, -2.0, 3.0, rng) * 4.0;
  Eigen::MatrixXd Y = smoothTargets(X / 4.0, P) * 1e-3;
  Y.col(1).array() += 0.02;
  const GprScaling scaling = GprScaling::fromData(X, Y);
  const GprHyperparameters h = hyperparameters(Eigen::Vector3d(0.8, 1.3, 2.0), 1.2, 0.05);
  const GaussianProcess gp = GaussianProcess::withHyperparameters(X, Y, scaling, h);

  // Dense reference in normalised/standardised units with an explicit inverse.
  Eigen::MatrixXd Xn(m, D), Yn(m, P), K(m, m);
  for (Eigen::Index i = 0; i < m; ++i) {
    for (Eigen::Index d = 0; d < D; ++d) {
      Xn(i, d) = (X(i, d) - X.col(d).mean()) / scaling.input_scale(d);
    }
    for (Eigen::Index o = 0; o < P; ++o) {
      Yn(i, o) = (Y(i, o) - Y.col(o).mean()) / scaling.output_scale(o);
    }
  }
  for (Eigen::Index i = 0; i < m; ++i) {
    for (Eigen::Index j = 0; j < m; ++j) {
      K(i, j) = kernel(Xn.row(i).transpose(), Xn.row(j).transpose(), h);
    }
  }
  K.diagonal().array() += h.noise_sigma * h.noise_sigma;
  const Eigen::MatrixXd K_inverse = K.inverse();
  EXPECT_LT((gp.alpha() - K_inverse * Yn).cwiseAbs().maxCoeff(), 1e-10);
  const double lml_dense = -0.5 * (Yn.transpose() * K_inverse * Yn).trace() -
                           0.5 * P * std::log(K.determinant()) - 0.5 * P * m * std::log(2 * kPi);
  EXPECT_NEAR(gp.logMarginalLikelihood(), lml_dense, 1e-10 * std::abs(lml_dense));

  for (int q = 0; q < 5; ++q) {
    const Eigen::VectorXd x = uniformMatrix(D, 1, -8.0, 12.0, rng);
    const Eigen::VectorXd xn = (x - scaling.input_offset).cwiseQuotient(scaling.input_scale);
    Eigen::VectorXd k_star(m);
    for (Eigen::Index i = 0; i < m; ++i) k_star(i) = kernel(Xn.row(i).transpose(), xn, h);
    const Eigen::VectorXd mean_n = Yn.transpose() * K_inverse * k_star;
    const double variance = h.signal_sigma * h.signal_sigma - k_star.dot(K_inverse * k_star);
    const Eigen::VectorXd mean = gp.predictMean(x);
    const Eigen::VectorXd std_dev = gp.predictStd(x);
    for (Eigen::Index o = 0; o < P; ++o) {
      EXPECT_NEAR(mean(o), scaling.output_mean(o) + scaling.output_scale(o) * mean_n(o),
                  1e-10 * scaling.output_scale(o));
      EXPECT_NEAR(std_dev(o), scaling.output_scale(o) * std::sqrt(std::max(0.0, variance)),
                  1e-7 * scaling.output_scale(o));  // sqrt near 0 amplifies round-off
    }
  }
}

TEST(Gpr, GradientMatchesCentralDifferences) {
  std::mt19937_64 rng(11);
  const Eigen::Index m = 40, D = 4, P = 3;
  auto [Xn, Yn] = noisySmoothSample(m, D, P, -1.5, 1.5, 0.1, rng);
  Yn = Yn.rowwise() - Yn.colwise().mean();
  for (const Eigen::VectorXd& log_theta :
       {Eigen::VectorXd((Eigen::VectorXd(D + 2) << 0.0, 0.5, -0.3, 1.0, 0.2, -2.0).finished()),
        Eigen::VectorXd((Eigen::VectorXd(D + 2) << -1.0, 2.0, 0.3, -0.5, -0.4, -1.0).finished()),
        Eigen::VectorXd((Eigen::VectorXd(D + 2) << 1.5, 1.5, 1.5, 1.5, 0.0, -4.0).finished())}) {
    Eigen::VectorXd gradient;
    const double lml = logMarginalLikelihood(Xn, Yn, log_theta, &gradient);
    ASSERT_TRUE(std::isfinite(lml));
    ASSERT_EQ(gradient.size(), D + 2);
    const double h = 1e-5;
    for (Eigen::Index j = 0; j < D + 2; ++j) {
      Eigen::VectorXd plus = log_theta, minus = log_theta;
      plus(j) += h;
      minus(j) -= h;
      const double finite_difference = (logMarginalLikelihood(Xn, Yn, plus, nullptr) -
                                        logMarginalLikelihood(Xn, Yn, minus, nullptr)) /
                                       (2 * h);
      EXPECT_NEAR(gradient(j), finite_difference, 1e-6 * std::max(std::abs(finite_difference), 1.0))
          << "θ_" << j << " at " << log_theta.transpose();
    }
  }
}

TEST(Gpr, FitNeverEndsBelowItsStarts) {
  std::mt19937_64 rng(3);
  const auto [X, Y] = noisySmoothSample(60, 3, 2, -2.0, 2.0, 0.05, rng);
  GprOptions options;
  options.restarts = 5;
  GprFitReport report;
  const GaussianProcess gp = GaussianProcess::fit(X, Y, options, &report);
  ASSERT_EQ(report.restarts.size(), 5u);
  for (int r = 0; r < 5; ++r) {
    const GprRestart& restart = report.restarts[r];
    EXPECT_EQ(restart.start_log_theta, GaussianProcess::startingPoint(r, 3, options.bounds));
    EXPECT_GE(restart.final_lml, restart.start_lml);
    EXPECT_GE(gp.logMarginalLikelihood(), restart.start_lml);
    // Starts compete on the likelihood plus the length-scale prior.
    EXPECT_GE(report.restarts[report.best_restart].final_log_posterior,
              restart.final_log_posterior);
  }
  EXPECT_NEAR(gp.logMarginalLikelihood(), report.restarts[report.best_restart].final_lml,
              1e-9 * std::abs(gp.logMarginalLikelihood()));
  // The log posterior (likelihood + one-sided length-scale prior) is stationary at the optimum
  // in every free direction.
  Eigen::VectorXd gradient;
  const Eigen::VectorXd& best = report.restarts[report.best_restart].final_log_theta;
  logMarginalLikelihood(gp.normalisedInputs(), gp.standardisedTargets(), best, &gradient);
  const double log_prior_scale = std::log(options.short_length_scale_prior * std::sqrt(3.0));
  for (Eigen::Index j = 0; j < 3; ++j) gradient(j) -= std::min(0.0, best(j) - log_prior_scale);
  const GprBounds& b = options.bounds;
  for (Eigen::Index j = 0; j < best.size(); ++j) {
    const double low = j < 3
                           ? std::log(b.min_length_scale)
                           : (j == 3 ? std::log(b.min_signal_sigma) : std::log(b.min_noise_sigma));
    const double high = j < 3
                            ? std::log(b.max_length_scale)
                            : (j == 3 ? std::log(b.max_signal_sigma) : std::log(b.max_noise_sigma));
    if (best(j) > low + 1e-6 && best(j) < high - 1e-6) {
      EXPECT_LT(std::abs(gradient(j)) / Y.size(), 1e-3) << "θ_" << j;
    }
  }
}

TEST(Gpr, RecoversRelevantInputAndNoiseLevel) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 1.0);
  const Eigen::Index m = 150, D = 4;
  const double noise_sigma = 0.05;
  auto truth = [](const Eigen::VectorXd& x) { return std::sin(1.5 * x(0)); };
  const Eigen::MatrixXd X = uniformMatrix(m, D, -2.0, 2.0, rng);
  Eigen::MatrixXd Y(m, 1);
  for (Eigen::Index i = 0; i < m; ++i)
    Y(i) = truth(X.row(i).transpose()) + noise_sigma * noise(rng);
  GprFitReport report;
  const GaussianProcess gp = GaussianProcess::fit(X, Y, {}, &report);
  const GprHyperparameters& h = gp.hyperparameters();
  for (Eigen::Index d = 1; d < D; ++d) {
    EXPECT_GT(h.length_scales(d), 10.0 * h.length_scales(0)) << "input " << d;
  }
  EXPECT_NEAR(h.noise_sigma * gp.scaling().output_scale(0), noise_sigma, 0.3 * noise_sigma);

  const Eigen::MatrixXd fresh = uniformMatrix(200, D, -1.9, 1.9, rng);
  double sum_squares = 0.0;
  for (Eigen::Index i = 0; i < fresh.rows(); ++i) {
    const Eigen::VectorXd x = fresh.row(i).transpose();
    sum_squares += std::pow(gp.predictMean(x)(0) - truth(x), 2);
  }
  EXPECT_LT(std::sqrt(sum_squares / fresh.rows()), noise_sigma);
  // The held-out error of noisy targets is about the noise variance.
  ASSERT_EQ(report.cv_mse.size(), 1);
  EXPECT_GT(report.cv_mse(0), 0.8 * noise_sigma * noise_sigma);
  EXPECT_LT(report.cv_mse(0), 1.6 * noise_sigma * noise_sigma);
}

TEST(Gpr, CrossValidationMatchesRefittingEachFold) {
  std::mt19937_64 rng(9);
  const Eigen::Index m = 37, D = 2, P = 2;
  const Eigen::MatrixXd X = uniformMatrix(m, D, -2.0, 2.0, rng);
  const Eigen::MatrixXd Y = smoothTargets(X, P) * 0.01 + 1e-3 * uniformMatrix(m, P, -1, 1, rng);
  const GprScaling scaling = GprScaling::fromData(X, Y);
  const GprHyperparameters h = hyperparameters(Eigen::Vector2d(0.9, 1.4), 1.1, 0.08);
  const GaussianProcess gp = GaussianProcess::withHyperparameters(X, Y, scaling, h);
  for (int folds : {10, 5, 100}) {
    const int k = std::min<int>(folds, m);
    Eigen::VectorXd sum_squares = Eigen::VectorXd::Zero(P);
    for (int fold = 0; fold < k; ++fold) {
      std::vector<Eigen::Index> train, test;
      for (Eigen::Index i = 0; i < m; ++i) (i % k == fold ? test : train).push_back(i);
      const GaussianProcess refit = GaussianProcess::withHyperparameters(
          X(train, Eigen::all), Y(train, Eigen::all), scaling, h);
      for (Eigen::Index i : test) {
        const Eigen::VectorXd error =
            refit.predictMean(X.row(i).transpose()) - Y.row(i).transpose();
        sum_squares += error.cwiseAbs2();
      }
    }
    const Eigen::VectorXd expected = sum_squares / m;
    const Eigen::VectorXd mse = gp.crossValidationMse(folds);
    for (Eigen::Index o = 0; o < P; ++o) {
      EXPECT_NEAR(mse(o), expected(o), 1e-9 * expected(o)) << folds << " folds, output " << o;
    }
  }
}

TEST(Gpr, PredictsWithoutAllocating) {
  std::mt19937_64 rng(13);
  const Eigen::MatrixXd X = uniformMatrix(80, 12, -1.0, 1.0, rng);
  const Eigen::MatrixXd Y = smoothTargets(X, 6);
  GprOptions options;
  options.restarts = 1;
  options.max_iterations = 20;
  const GaussianProcess gp = GaussianProcess::fit(X, Y, options);
  GprWorkspace workspace = gp.makeWorkspace();
  const Eigen::VectorXd x = uniformMatrix(12, 1, -1.0, 1.0, rng);
  double mean[6], std_dev[6], mean_only[6];
  long allocations = 0;
  {
    test::AllocationCounter counter;
    gp.predictMeanInto(x.data(), mean_only, workspace);
    gp.predictInto(x.data(), mean, std_dev, workspace);
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  const Eigen::VectorXd mean_reference = gp.predictMean(x);
  const Eigen::VectorXd std_reference = gp.predictStd(x);
  for (int o = 0; o < 6; ++o) {
    EXPECT_EQ(mean[o], mean_reference(o));
    EXPECT_EQ(mean_only[o], mean_reference(o));
    EXPECT_EQ(std_dev[o], std_reference(o));
  }
}

// The fit is bit-identical whatever its thread count and whatever cache sizes the CPU reports:
// Eigen sizes its product blocks from the latter (here those of a 48 KiB-L1 host and of qemu's
// -cpu max) and the blocks set the rounding. At the paper's size, so the blocked code runs.
TEST(Gpr, FitIsBitIdenticalWhateverThreadsAndCaches) {
  std::mt19937_64 rng(29);
  const auto [X, Y] = noisySmoothSample(300, 12, 6, -2.0, 2.0, 0.3, rng);
  GprOptions options;
  options.threads = 1;
  Eigen::setCpuCacheSizes(48 * 1024, 1024 * 1024, 32 * 1024 * 1024);
  GprFitReport serial_report;
  const GaussianProcess serial = GaussianProcess::fit(X, Y, options, &serial_report);
  options.threads = 2;
  Eigen::setCpuCacheSizes(64 * 1024, 512 * 1024, 16 * 1024 * 1024);
  GprFitReport parallel_report;
  const GaussianProcess parallel = GaussianProcess::fit(X, Y, options, &parallel_report);

  EXPECT_EQ(serial.hyperparameters().length_scales, parallel.hyperparameters().length_scales);
  EXPECT_EQ(serial.hyperparameters().signal_sigma, parallel.hyperparameters().signal_sigma);
  EXPECT_EQ(serial.hyperparameters().noise_sigma, parallel.hyperparameters().noise_sigma);
  EXPECT_EQ(serial.alpha(), parallel.alpha());
  EXPECT_EQ(serial.logMarginalLikelihood(), parallel.logMarginalLikelihood());
  EXPECT_EQ(serial_report.cv_mse, parallel_report.cv_mse);
  EXPECT_EQ(serial_report.best_restart, parallel_report.best_restart);
  ASSERT_EQ(serial_report.restarts.size(), parallel_report.restarts.size());
  for (size_t r = 0; r < serial_report.restarts.size(); ++r) {
    const GprRestart &a = serial_report.restarts[r], &b = parallel_report.restarts[r];
    EXPECT_EQ(a.final_log_theta, b.final_log_theta) << "start " << r;
    EXPECT_EQ(a.final_log_posterior, b.final_log_posterior) << "start " << r;
    EXPECT_EQ(a.evaluations, b.evaluations) << "start " << r;
  }
}

TEST(Gpr, ConstantInputColumnIsHarmless) {
  std::mt19937_64 rng(17);
  Eigen::MatrixXd X = uniformMatrix(50, 3, -2.0, 2.0, rng);
  X.col(1).setConstant(4.2);
  X.col(2).setZero();
  const Eigen::MatrixXd Y = smoothTargets(X, 2);
  GprFitReport report;
  const GaussianProcess gp = GaussianProcess::fit(X, Y, {}, &report);
  EXPECT_EQ(gp.scaling().input_scale(1), 1.0);
  EXPECT_EQ(gp.scaling().input_scale(2), 1.0);
  EXPECT_TRUE(gp.normalisedInputs().allFinite());
  EXPECT_TRUE(gp.alpha().allFinite());
  EXPECT_TRUE(std::isfinite(gp.logMarginalLikelihood()));
  EXPECT_TRUE(report.cv_mse.allFinite());
  Eigen::Vector3d x(0.3, 4.2, 0.0);
  EXPECT_TRUE(gp.predictMean(x).allFinite());
  EXPECT_TRUE(gp.predictStd(x).allFinite());
  EXPECT_NEAR(gp.predictMean(x)(0), smoothTargets(x.transpose(), 2)(0), 0.02);
}

TEST(Gpr, FromPartsReproducesPredictionsBitExactly) {
  std::mt19937_64 rng(19);
  const auto [X, Y] = noisySmoothSample(70, 5, 3, -3.0, 3.0, 0.01, rng);
  GprOptions options;
  options.restarts = 2;
  const GaussianProcess gp = GaussianProcess::fit(X, Y, options);
  EXPECT_LT(gp.alphaBackwardError(), 1e-12);
  const GaussianProcess loaded =
      GaussianProcess::fromParts(gp.normalisedInputs(), gp.scaling(), gp.hyperparameters(),
                                 gp.alpha(), gp.standardisedTargets());
  EXPECT_EQ(loaded.logMarginalLikelihood(), gp.logMarginalLikelihood());
  for (int q = 0; q < 10; ++q) {
    const Eigen::VectorXd x = uniformMatrix(5, 1, -3.0, 3.0, rng);
    const Eigen::VectorXd mean = gp.predictMean(x), loaded_mean = loaded.predictMean(x);
    const Eigen::VectorXd std_dev = gp.predictStd(x), loaded_std = loaded.predictStd(x);
    for (int o = 0; o < 3; ++o) {
      EXPECT_EQ(loaded_mean(o), mean(o));
      EXPECT_EQ(loaded_std(o), std_dev(o));
    }
  }
  Eigen::MatrixXd corrupted = gp.alpha();
  corrupted(10, 1) += 1e-3 * corrupted.cwiseAbs().maxCoeff();
  EXPECT_THROW(GaussianProcess::fromParts(gp.normalisedInputs(), gp.scaling(), gp.hyperparameters(),
                                          corrupted, gp.standardisedTargets()),
               InputError);
  GprHyperparameters wrong = gp.hyperparameters();
  wrong.length_scales.conservativeResize(4);
  EXPECT_THROW(GaussianProcess::fromParts(gp.normalisedInputs(), gp.scaling(), wrong, gp.alpha(),
                                          gp.standardisedTargets()),
               InputError);
}

TEST(Gpr, RejectsBadTrainingData) {
  Eigen::MatrixXd X = Eigen::MatrixXd::Random(10, 2), Y = Eigen::MatrixXd::Random(9, 1);
  EXPECT_THROW(GaussianProcess::fit(X, Y), InputError);
  Y = Eigen::MatrixXd::Random(10, 1);
  X(3, 1) = std::nan("");
  EXPECT_THROW(GaussianProcess::fit(X, Y), InputError);
}

// The paper's size: 300 samples of (q, wrench) → ξ. Prints the wall time of fit().
TEST(Gpr, FitTimeAtPaperSize) {
  std::mt19937_64 rng(23);
  const Eigen::Index m = 300, D = 12, P = 6;
  Eigen::MatrixXd X(m, D);
  X.leftCols(6) = uniformMatrix(m, 6, -2.0, 2.0, rng);       // q, rad
  X.rightCols(6) = uniformMatrix(m, 6, -400.0, 400.0, rng);  // wrench, N and N·m
  Eigen::MatrixXd Y(m, P);
  for (Eigen::Index i = 0; i < m; ++i) {
    for (Eigen::Index o = 0; o < P; ++o) {
      Y(i, o) = 1e-4 * (std::sin(X(i, o % 6) + 0.3 * X(i, (o + 1) % 6)) +
                        2e-3 * X(i, 6 + o) * std::cos(X(i, 1)));
    }
  }
  Y += 5e-6 * uniformMatrix(m, P, -1.0, 1.0, rng);
  GprFitReport report;
  const std::clock_t cpu_start = std::clock();
  const auto start = std::chrono::steady_clock::now();
  const GaussianProcess gp = GaussianProcess::fit(X, Y, {}, &report);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double cpu_seconds = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
  int evaluations = 0, iterations = 0;
  for (const GprRestart& r : report.restarts) {
    evaluations += r.evaluations;
    iterations += r.iterations;
  }
  std::cout << "fit(m=300, D=12, P=6) with 10-fold CV: " << seconds << " s wall, " << cpu_seconds
            << " s CPU (all threads); " << report.restarts.size() << " starts, " << iterations
            << " iterations, " << evaluations << " likelihood evaluations\n";
  RecordProperty("fit_seconds", std::to_string(seconds));
  EXPECT_TRUE(std::isfinite(gp.logMarginalLikelihood()));
  EXPECT_EQ(report.cv_mse.size(), P);
  // A model file's loader checks ‖K α − Y‖ / ‖Y‖ with K = σ_f² E + σ_n² I written out.
  const GprHyperparameters& h = gp.hyperparameters();
  Eigen::MatrixXd K(m, m);
  for (Eigen::Index i = 0; i < m; ++i) {
    for (Eigen::Index j = 0; j < m; ++j) {
      K(i, j) = kernel(gp.normalisedInputs().row(i).transpose(),
                       gp.normalisedInputs().row(j).transpose(), h);
    }
  }
  K.diagonal().array() += h.noise_sigma * h.noise_sigma;
  const double relative_residual =
      (K * gp.alpha() - gp.standardisedTargets()).norm() / gp.standardisedTargets().norm();
  std::cout << "σ_n = " << h.noise_sigma << ", σ_f = " << h.signal_sigma
            << ", ‖K α − Y‖ / ‖Y‖ = " << relative_residual << "\n";
  EXPECT_LT(relative_residual, 1e-8);
  // CPU time, which a loaded machine does not stretch as it does the wall time; generous: only
  // catches a pathological slowdown (about 0.5 s here).
  EXPECT_LT(cpu_seconds, 10.0);
}

}  // namespace
}  // namespace stepcal::trainer

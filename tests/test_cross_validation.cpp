// The diagnosis's cross-validation linearised at the current model: the Grams of a residual with a
// part of the model taken out, and the joint fit with the ridges on the parameters' values, each
// against the same least squares solved directly.
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include <Eigen/Cholesky>

#include "../trainer/src/diagnose/cross_validation.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// 40 poses of one position-only row each, in 5 folds, with random columns and residual.
struct Problem {
  std::vector<Measurement> measurements;
  FitRows fit;
  Eigen::MatrixXd A;
  Eigen::VectorXd r0;

  explicit Problem(Eigen::Index columns, unsigned seed = 7) {
    measurements.resize(40);
    for (size_t i = 0; i < measurements.size(); ++i) {
      measurements[i].pose_id = "p" + std::to_string(i);
      measurements[i].q_rad = JointVector::Zero(6);
    }
    std::vector<const Measurement*> rows;
    for (const Measurement& m : measurements) rows.push_back(&m);
    fit = makeFitRows(rows, TrackerNoise{}, 5);
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    A = Eigen::MatrixXd::NullaryExpr(fit.count, columns, [&] { return normal(rng); });
    r0 = Eigen::VectorXd::NullaryExpr(fit.count, [&] { return normal(rng); });
  }
};

TEST(FoldGrams, WithoutAPartAreTheGramsOfTheMovedResidual) {
  const Problem problem(4);
  Eigen::VectorXd v(4);
  v << 0.3, 0.0, -1.2, 0.05;
  const FoldGrams moved = FoldGrams(problem.A, problem.r0, problem.fit).without(v);
  const FoldGrams direct(problem.A, problem.r0 + problem.A * v, problem.fit);
  for (size_t f = 0; f <= static_cast<size_t>(problem.fit.folds); ++f) {
    EXPECT_LT((moved.b[f] - direct.b[f]).norm(), 1e-12 * direct.b[f].norm()) << "fold " << f;
  }
  for (size_t f = 0; f < static_cast<size_t>(problem.fit.folds); ++f) {
    EXPECT_NEAR(moved.e0[f], direct.e0[f], 1e-12 * direct.e0[f]) << "fold " << f;
    EXPECT_LT((moved.r0_fold[f] - direct.r0_fold[f]).norm(), 1e-12 * direct.r0_fold[f].norm());
  }
}

// Linearised at current values c, with r0 the residual there, the joint fit's value c + δ is the
// ridge regression solved from zero on the residual at zero, r0 + A c: the ridge pulls the value,
// not the change, to zero.
TEST(CrossValidation, JointFitHoldsTheRidgeOnTheValues) {
  const Problem problem(3);
  const Eigen::VectorXd ridge = Eigen::Vector3d(0.0, 5.0, 40.0);
  const Eigen::VectorXd current = Eigen::Vector3d(0.4, -0.7, 0.2);
  const FoldGrams grams(problem.A, problem.r0, problem.fit);
  const CrossValidation cv(grams, problem.fit, {0, 1, 2}, {}, ridge, current);
  const CrossValidation::JointFit joint = cv.jointFit({0, 1, 2});

  const Eigen::VectorXd y = problem.r0 + problem.A * current;
  Eigen::MatrixXd H = problem.A.transpose() * problem.A;
  H.diagonal() += ridge;
  const Eigen::LLT<Eigen::MatrixXd> llt(H);
  const Eigen::VectorXd value = llt.solve(problem.A.transpose() * y);
  EXPECT_LT((current + joint.change - value).norm(), 1e-10 * value.norm());
  const Eigen::VectorXd unit = llt.solve(Eigen::MatrixXd::Identity(3, 3)).diagonal();
  EXPECT_LT((joint.unit_variance - unit).norm(), 1e-10 * unit.norm());
  const double sse = (problem.r0 - problem.A * joint.change).squaredNorm();
  EXPECT_NEAR(joint.variance, sse / (problem.fit.count - 3), 1e-10 * sse);
}

// At the joint fit the held-out base changes nothing on every row: what the two stages fit from
// there is zero, with the ridged column in stage 2.
TEST(CrossValidation, FromTheJointFitTheStagesFitNothingMore) {
  const Problem problem(3, 11);
  const Eigen::VectorXd ridge = Eigen::Vector3d(0.0, 0.0, 8.0);
  Eigen::VectorXd current = Eigen::Vector3d(0.1, 0.2, -0.3);
  const FoldGrams start(problem.A, problem.r0, problem.fit);
  const Eigen::VectorXd change =
      CrossValidation(start, problem.fit, {0, 1}, {2}, ridge, current).jointFit({0, 1, 2}).change;
  const FoldGrams there = start.without(-change);
  current += change;
  const CrossValidation cv(there, problem.fit, {0, 1}, {2}, ridge, current);
  const Eigen::VectorXd& all_rows = cv.base().x.back();
  EXPECT_LT(all_rows.norm(), 1e-10 * current.norm()) << all_rows.transpose();
}

}  // namespace
}  // namespace stepcal::trainer::diagnosis

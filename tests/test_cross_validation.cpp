// The diagnosis's cross-validation linearised at the current model: the Grams of a residual with a
// part of the model taken out, the columns it makes again (features, profiles) against the same
// columns stored, the Grams summed chunk by chunk and a tall system reduced block by block against
// the whole matrix's, and the joint fit with the ridges on the parameters' values, each against
// the same least squares solved directly.
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include <Eigen/Cholesky>

#include "../trainer/src/diagnose/chunked_gram.hpp"
#include "../trainer/src/least_squares.hpp"
#include "../trainer/src/diagnose/cross_validation.hpp"
#include "../trainer/src/diagnose/profiles.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// Poses of one row each (position only, or every third with orientation too), in 5 folds, with
// random joint angles, columns and residual.
struct Problem {
  std::vector<Measurement> measurements;
  FitRows fit;
  Eigen::MatrixXd A;
  Eigen::VectorXd r0;

  explicit Problem(Eigen::Index columns, unsigned seed = 7, size_t poses = 40,
                   bool orientation = false) {
    std::mt19937 angles(seed + 1);
    std::uniform_real_distribution<double> angle(-3.0, 3.0);
    measurements.resize(poses);
    for (size_t i = 0; i < measurements.size(); ++i) {
      measurements[i].pose_id = "p" + std::to_string(i);
      measurements[i].q_rad = JointVector::NullaryExpr(6, [&] { return angle(angles); });
      measurements[i].has_orientation = orientation && i % 3 == 0;
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

// A screening matrix whose feature and profile columns are made again from the link-angle columns
// (and whose second geometry is a stored column repeated) gives the Grams, the held-out errors and
// the moved residual of the same matrix with every column stored, over folds of more rows than a
// chunk.
TEST(FoldGrams, ColumnsMadeAgainAreTheColumnsStored) {
  const Problem problem(2, 5, 3 * kGramChunkRows + 17, true);
  const FitRows& fit = problem.fit;
  std::mt19937 rng(3);
  std::normal_distribution<double> normal;
  const Eigen::MatrixXd L = Eigen::MatrixXd::NullaryExpr(fit.count, 6, [&] { return normal(rng); });
  std::vector<double> angles;
  for (const Measurement& m : problem.measurements) angles.push_back(m.q_rad(1));
  const AngleCoverage coverage = coverageOfAngles(angles, 0.05, 0.02);
  const int order = 3;

  ScreeningColumns made;
  made.link_angle = L;
  made.stored = {problem.A.col(0), problem.A.col(1)};
  made.source = {{ColumnSource::Kind::kStored, 0}, {ColumnSource::Kind::kStored, 1},
                 {ColumnSource::Kind::kStored, 0}, {ColumnSource::Kind::kFeature, 0}};
  FeatureColumn feature{4, Eigen::VectorXd::NullaryExpr(static_cast<Eigen::Index>(fit.rows.size()),
                                                        [&] { return normal(rng); })};
  made.blocks = {{4, 1, coverage, order}};
  for (int k = 0; k < 2 * order; ++k) made.source.push_back({ColumnSource::Kind::kProfile, 0});
  Eigen::MatrixXd A(fit.count, 4 + 2 * order);
  A << problem.A, problem.A.col(0), Eigen::VectorXd::Zero(fit.count),
      profileColumns(L, fit, 1, coverage, order);
  for (size_t i = 0; i < fit.rows.size(); ++i) {
    A.col(3).segment(fit.start[i], fit.equations(i)) =
        L.block(fit.start[i], 4, fit.equations(i), 1) * feature.feature(static_cast<Eigen::Index>(i));
  }
  made.features = {feature};

  FoldGrams implicit(made, problem.r0, fit);
  FoldGrams stored(A, problem.r0, fit);
  for (size_t f = 0; f <= static_cast<size_t>(fit.folds); ++f) {
    EXPECT_LT((implicit.G[f] - stored.G[f]).norm(), 1e-12 * stored.G[f].norm()) << "fold " << f;
    EXPECT_LT((implicit.b[f] - stored.b[f]).norm(), 1e-12 * stored.b[f].norm()) << "fold " << f;
  }
  // The held-out errors of a model using every column, the profile's with a ridge in stage 2.
  Eigen::VectorXd ridge = Eigen::VectorXd::Zero(A.cols());
  ridge.tail(2 * order).setConstant(0.5);
  std::vector<Eigen::Index> stage1 = {0, 1, 3}, stage2 = {2, 4, 5, 6, 7, 8, 9};
  const auto outcome = [&](const FoldGrams& grams) {
    const CrossValidation cv(grams, fit, stage1, stage2, ridge, Eigen::VectorXd::Zero(A.cols()));
    return cv.heldOut(cv.base());
  };
  const CrossValidation::Outcome a = outcome(implicit), b = outcome(stored);
  for (size_t pose = 0; pose < a.pose_sse.size(); ++pose) {
    ASSERT_NEAR(a.pose_sse[pose], b.pose_sse[pose], 1e-12 * (1.0 + b.pose_sse[pose])) << pose;
  }
  const Eigen::VectorXd v = Eigen::VectorXd::NullaryExpr(A.cols(), [&] { return normal(rng); });
  implicit.takeOut(v);
  stored.takeOut(v);
  for (size_t f = 0; f < static_cast<size_t>(fit.folds); ++f) {
    EXPECT_LT((implicit.r0_fold[f] - stored.r0_fold[f]).norm(), 1e-12 * stored.r0_fold[f].norm());
    EXPECT_NEAR(implicit.e0[f], stored.e0[f], 1e-12 * stored.e0[f]);
  }
}

// The Grams summed over chunks of rows (in slices, on the cores) are the whole matrix's.
TEST(ChunkedGram, IsTheWholeMatrixsGram) {
  const Problem problem(7, 13, 5 * kGramChunkRows + 3, true);
  const FitRows& fit = problem.fit;
  const auto rows = [&](size_t begin, size_t end) {
    const Eigen::Index e = equationOf(fit, begin);
    return Eigen::MatrixXd(problem.A.middleRows(e, equationOf(fit, end) - e));
  };
  const ChunkedGram gram = chunkedGram(fit, 7, problem.r0, rows);
  const Eigen::MatrixXd H = problem.A.transpose() * problem.A;
  EXPECT_LT((gram.H - H).norm(), 1e-12 * H.norm());
  const Eigen::VectorXd rhs = problem.A.transpose() * problem.r0;
  EXPECT_LT((gram.rhs - rhs).norm(), 1e-12 * rhs.norm());
  const Eigen::VectorXd x = H.llt().solve(rhs);
  const double sse = (problem.r0 - problem.A * x).squaredNorm();
  EXPECT_NEAR(chunkedSse(fit, problem.r0, x, rows), sse, 1e-12 * sse);
}

// A tall system reduced block by block (as the global refit reduces its Jacobian chunk by chunk of
// rows, then its priors' rows) solves as the whole matrix does: the same rank (one column repeats
// another, so one direction is unobservable), singular values, column norms and truncated solution.
TEST(TallQr, ReducedSolveIsTheWholeMatrixsSolve) {
  std::mt19937 rng(21);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd J = Eigen::MatrixXd::NullaryExpr(2500, 9, [&] { return normal(rng); });
  J.col(8) = J.col(2);
  J.col(5) *= 1e4;  // columns of very different scale, as geometry and compliance are
  const Eigen::VectorXd r = Eigen::VectorXd::NullaryExpr(2500, [&] { return normal(rng); });
  const SvdSolution whole = solveTruncated(J, r, 1e-9);
  TallQr reduced(9);
  for (Eigen::Index begin = 0, size = 3; begin < J.rows(); begin += size, size = size * 3 + 1) {
    const Eigen::Index n = std::min(size, J.rows() - begin);
    reduced.add(J.middleRows(begin, n), r.segment(begin, n));
  }
  const SvdSolution s = solveReduced(reduced, 1e-9);
  EXPECT_EQ(s.rank, 8);
  EXPECT_EQ(s.rank, whole.rank);
  EXPECT_LT((s.singular_values - whole.singular_values).norm(), 1e-12 * whole.singular_values(0));
  EXPECT_LT((s.column_scale - whole.column_scale).norm(), 1e-12 * whole.column_scale.norm());
  EXPECT_LT((s.x - whole.x).norm(), 1e-10 * whole.x.norm());
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

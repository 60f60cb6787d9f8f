// The diagnosis's cross-validation linearised at the current model: the Grams of a residual with a
// part of the model taken out, the scaled columns (features, profiles) against the same columns
// dense, held-out errors of several corrections in one pass against each alone and made directly, the Grams summed chunk by chunk and a tall system reduced block by block against
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

// A's columns all dense, made chunk by chunk from the whole matrix.
ScreeningColumns denseColumns(const Eigen::MatrixXd& A, const FitRows& fit) {
  ScreeningColumns columns;
  columns.layout.dense = A.cols();
  for (Eigen::Index c = 0; c < A.cols(); ++c) columns.layout.place.push_back({-1, c});
  columns.make = [A, &fit](size_t begin, size_t end, const std::vector<bool>&, ColumnChunk& chunk) {
    const Eigen::Index e = equationOf(fit, begin);
    chunk.dense = A.middleRows(e, equationOf(fit, end) - e);
    chunk.link_angle.resize(chunk.dense.rows(), 0);
  };
  return columns;
}

FoldGrams gramsOf(const Eigen::MatrixXd& A, const Eigen::VectorXd& r0, const FitRows& fit) {
  return FoldGrams(denseColumns(A, fit), r0, fit);
}

// Per pose, the held-out weighted squared error of x (per fold, fitted without it) on A and r0,
// and the rows' position errors summed, made directly.
CrossValidation::Outcome directOutcome(const Eigen::MatrixXd& A, const Eigen::VectorXd& r0,
                                       const FitRows& fit, const std::vector<Eigen::Index>& columns,
                                       const std::vector<Eigen::VectorXd>& x) {
  CrossValidation::Outcome out;
  out.pose_sse.assign(static_cast<size_t>(fit.poses), 0.0);
  out.rows = fit.rows.size();
  for (size_t i = 0; i < fit.rows.size(); ++i) {
    const Eigen::Index e = fit.start[i], k = fit.equations(i);
    const Eigen::VectorXd error =
        r0.segment(e, k) - A.middleRows(e, k)(Eigen::all, columns) * x[static_cast<size_t>(fit.fold[i])];
    out.pose_sse[static_cast<size_t>(fit.pose[i])] += error.squaredNorm();
    out.position_sum_m += error.head<3>().norm() / fit.w_p;
  }
  return out;
}

void expectSameOutcome(const CrossValidation::Outcome& a, const CrossValidation::Outcome& b) {
  ASSERT_EQ(a.pose_sse.size(), b.pose_sse.size());
  for (size_t pose = 0; pose < a.pose_sse.size(); ++pose) {
    ASSERT_NEAR(a.pose_sse[pose], b.pose_sse[pose], 1e-11 * (1.0 + b.pose_sse[pose])) << pose;
  }
  EXPECT_NEAR(a.position_sum_m, b.position_sum_m, 1e-11 * b.position_sum_m);
  EXPECT_EQ(a.rows, b.rows);
}

// Taken out through the Grams, a part of the model gives the Grams and the held-out errors of
// the residual moved by it on every row.
TEST(FoldGrams, WithoutAPartAreTheGramsOfTheMovedResidual) {
  const Problem problem(4, 7, 2 * kGramChunkRows + 9);
  Eigen::VectorXd v(4);
  v << 0.3, 0.0, -1.2, 0.05;
  const FoldGrams moved = gramsOf(problem.A, problem.r0, problem.fit).without(v);
  const FoldGrams direct = gramsOf(problem.A, problem.r0 + problem.A * v, problem.fit);
  for (size_t f = 0; f <= static_cast<size_t>(problem.fit.folds); ++f) {
    EXPECT_LT((moved.b[f] - direct.b[f]).norm(), 1e-12 * direct.b[f].norm()) << "fold " << f;
  }
  for (size_t f = 0; f < static_cast<size_t>(problem.fit.folds); ++f) {
    EXPECT_NEAR(moved.e0[f], direct.e0[f], 1e-12 * direct.e0[f]) << "fold " << f;
  }
  const Eigen::VectorXd none = Eigen::VectorXd::Zero(4);
  const auto outcome = [&](const FoldGrams& grams) {
    const CrossValidation cv(grams, problem.fit, {0, 2}, {}, none, none);
    return cv.heldOut(cv.withGlobal({1}));
  };
  expectSameOutcome(outcome(moved), outcome(direct));
}

// A screening matrix whose features and profile are held as scaled columns (a joint's link-angle
// column times a value per row), and whose second geometry shares the first's place, gives the
// Grams, the held-out errors and the moved residual of the same matrix with every column dense,
// over folds of more rows than a chunk.
TEST(FoldGrams, ScaledColumnsAreTheirDenseColumns) {
  const Problem problem(2, 5, 3 * kGramChunkRows + 17, true);
  const FitRows& fit = problem.fit;
  std::mt19937 rng(3);
  std::normal_distribution<double> normal;
  const Eigen::MatrixXd L = Eigen::MatrixXd::NullaryExpr(fit.count, 6, [&] { return normal(rng); });
  std::vector<double> angles;
  for (const Measurement& m : problem.measurements) angles.push_back(m.q_rad(1));
  const AngleCoverage coverage = coverageOfAngles(angles, 0.05, 0.02);
  const int order = 3;
  const Eigen::Index rows = static_cast<Eigen::Index>(fit.rows.size());
  const Eigen::VectorXd feature4 = Eigen::VectorXd::NullaryExpr(rows, [&] { return normal(rng); });
  const Eigen::VectorXd feature1 = Eigen::VectorXd::NullaryExpr(rows, [&] { return normal(rng); });
  // Columns: two dense, the first again, a feature of joint 4, a profile of joint 1, a feature
  // of joint 1 after it.
  ScreeningColumns scaled;
  scaled.layout.dense = 2;
  scaled.layout.scaled = {0, 2 * order + 1, 0, 0, 1, 0};
  scaled.layout.place = {{-1, 0}, {-1, 1}, {-1, 0}, {4, 0}};
  for (int k = 0; k < 2 * order; ++k) scaled.layout.place.push_back({1, k});
  scaled.layout.place.push_back({1, 2 * order});
  scaled.make = [&](size_t begin, size_t end, const std::vector<bool>&, ColumnChunk& chunk) {
    const Eigen::Index e = equationOf(fit, begin), count = equationOf(fit, end) - e;
    chunk.dense = problem.A.middleRows(e, count);
    chunk.link_angle = L.middleRows(e, count);
    chunk.scaled.assign(6, Eigen::MatrixXd());
    chunk.scaled[1].resize(static_cast<Eigen::Index>(end - begin), 2 * order + 1);
    chunk.scaled[4].resize(static_cast<Eigen::Index>(end - begin), 1);
    Eigen::VectorXd harmonics(2 * order);
    for (size_t i = begin; i < end; ++i) {
      const Eigen::Index r = static_cast<Eigen::Index>(i - begin);
      profileFeatures(coverage, order, fit.rows[i]->q_rad(1), harmonics.data());
      chunk.scaled[1].row(r).head(2 * order) = harmonics.transpose();
      chunk.scaled[1](r, 2 * order) = feature1(static_cast<Eigen::Index>(i));
      chunk.scaled[4](r, 0) = feature4(static_cast<Eigen::Index>(i));
    }
  };
  Eigen::MatrixXd A(fit.count, 5 + 2 * order);
  A << problem.A, problem.A.col(0), Eigen::VectorXd::Zero(fit.count),
      profileColumns(L, fit, 1, coverage, order, 0, fit.rows.size()), Eigen::VectorXd::Zero(fit.count);
  for (size_t i = 0; i < fit.rows.size(); ++i) {
    const Eigen::Index e = fit.start[i], k = fit.equations(i), r = static_cast<Eigen::Index>(i);
    A.col(3).segment(e, k) = L.block(e, 4, k, 1) * feature4(r);
    A.col(4 + 2 * order).segment(e, k) = L.block(e, 1, k, 1) * feature1(r);
  }

  FoldGrams implicit(scaled, problem.r0, fit);
  FoldGrams dense = gramsOf(A, problem.r0, fit);
  for (size_t f = 0; f <= static_cast<size_t>(fit.folds); ++f) {
    EXPECT_LT((implicit.G[f] - dense.G[f]).norm(), 1e-12 * dense.G[f].norm()) << "fold " << f;
    EXPECT_LT((implicit.b[f] - dense.b[f]).norm(), 1e-12 * dense.b[f].norm()) << "fold " << f;
  }
  // The held-out errors of a model using every column, the profile's with a ridge in stage 2,
  // against the errors made directly.
  Eigen::VectorXd ridge = Eigen::VectorXd::Zero(A.cols());
  ridge.segment(4, 2 * order).setConstant(0.5);
  std::vector<Eigen::Index> stage1 = {0, 1, 3, 4 + 2 * order}, stage2 = {2, 4, 5, 6, 7, 8, 9};
  const auto outcome = [&](const FoldGrams& grams) {
    const CrossValidation cv(grams, fit, stage1, stage2, ridge, Eigen::VectorXd::Zero(A.cols()));
    return cv.heldOut(cv.base());
  };
  const CrossValidation cv(dense, fit, stage1, stage2, ridge, Eigen::VectorXd::Zero(A.cols()));
  const CrossValidation::Outcome made = directOutcome(A, problem.r0, fit, cv.base().columns,
                                                      cv.base().x);
  expectSameOutcome(outcome(implicit), made);
  expectSameOutcome(outcome(dense), made);
  // With a part taken out, the errors of the residual it moves to.
  const Eigen::VectorXd v = Eigen::VectorXd::NullaryExpr(A.cols(), [&] { return normal(rng); });
  implicit.takeOut(v);
  for (size_t f = 0; f < static_cast<size_t>(fit.folds); ++f) {
    EXPECT_NEAR(implicit.e0[f], dense.without(v).e0[f], 1e-12 * dense.without(v).e0[f]);
  }
  const CrossValidation moved(dense.without(v), fit, stage1, stage2, ridge, Eigen::VectorXd::Zero(A.cols()));
  expectSameOutcome(outcome(implicit),
                    directOutcome(A, problem.r0 + A * v, fit, moved.base().columns, moved.base().x));
}

// Corrections' held-out errors from one pass over the rows are each one's alone, and those made
// directly; grouped into passes of at most a few corrections, each group gets its own, in order.
TEST(CrossValidation, HeldOutTogetherIsEachAlone) {
  const Problem problem(5, 9, 2 * kGramChunkRows + 40, true);
  const FitRows& fit = problem.fit;
  const FoldGrams grams = gramsOf(problem.A, problem.r0, fit);
  const CrossValidation cv(grams, fit, {0, 1}, {}, Eigen::VectorXd::Zero(5), Eigen::VectorXd::Zero(5));
  std::vector<CrossValidation::Correction> corrections = {cv.base(), cv.withGlobal({2}),
                                                          cv.withGlobal({3, 4}), cv.withGlobal({4})};
  std::vector<const CrossValidation::Correction*> all;
  for (const CrossValidation::Correction& c : corrections) all.push_back(&c);
  const std::vector<CrossValidation::Outcome> together = cv.heldOut(all);
  ASSERT_EQ(together.size(), corrections.size());
  for (size_t k = 0; k < corrections.size(); ++k) {
    expectSameOutcome(together[k], cv.heldOut(corrections[k]));
    expectSameOutcome(together[k], directOutcome(problem.A, problem.r0, fit,
                                                 corrections[k].columns, corrections[k].x));
  }
  const std::vector<std::vector<const CrossValidation::Correction*>> groups = {
      {all[0], all[1]}, {}, {all[2]}, {all[3], all[0], all[1]}};
  std::vector<size_t> seen, passes;
  cv.heldOutInGroups(groups, 2, [&](size_t first, std::vector<std::vector<CrossValidation::Outcome>> outcomes) {
    passes.push_back(first);
    for (size_t i = 0; i < outcomes.size(); ++i) {
      const size_t g = first + i;
      seen.push_back(g);
      ASSERT_EQ(outcomes[i].size(), groups[g].size());
      for (size_t k = 0; k < outcomes[i].size(); ++k) {
        const size_t index = static_cast<size_t>(groups[g][k] - all.front());
        expectSameOutcome(outcomes[i][k], together[index]);
      }
    }
  });
  EXPECT_EQ(seen, (std::vector<size_t>{0, 1, 2, 3}));
  // Groups 0 and 1 (two corrections), 2 (one: with the next it would be four), 3 (three: alone).
  EXPECT_EQ(passes, (std::vector<size_t>{0, 2, 3}));
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
  const FoldGrams grams = gramsOf(problem.A, problem.r0, problem.fit);
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
  const FoldGrams start = gramsOf(problem.A, problem.r0, problem.fit);
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

// The trainer's bounded least squares (trainer/src/least_squares.hpp): the global refit's step
// under the bounds its physics sets (a compliance, a lost motion, an extra compliance ≥ 0; a
// lumped link mass ≥ 0 with its first moment within its reach, as general rows C x ≥ d).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include <Eigen/LU>

#include "../trainer/src/least_squares.hpp"

namespace stepcal::trainer {
namespace {

constexpr double kNone = -std::numeric_limits<double>::infinity();

struct System {
  Eigen::MatrixXd J;
  Eigen::VectorXd r;
  TallQr reduced{0};
};

System randomSystem(unsigned seed, Eigen::Index rows, Eigen::Index cols) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal;
  System s;
  s.J = Eigen::MatrixXd::NullaryExpr(rows, cols, [&] { return normal(rng); });
  s.r = Eigen::VectorXd::NullaryExpr(rows, [&] { return normal(rng); });
  return s;
}

void reduce(System& s) {
  s.reduced = TallQr(s.J.cols());
  s.reduced.add(s.J, s.r);
}

// The bounds' optimality conditions (Karush–Kuhn–Tucker) of min |J x − r|² under x ≥ lower: x
// feasible; where a variable is above its bound the gradient Jᵀ(J x − r) vanishes along it,
// where it sits on its bound the gradient points into the feasible side (≥ 0).
void expectOptimal(const System& s, const Eigen::VectorXd& x, const Eigen::VectorXd& lower,
                   const std::vector<bool>& at_bound) {
  const Eigen::VectorXd gradient = s.J.transpose() * (s.J * x - s.r);
  const double scale = (s.J.transpose() * s.r).cwiseAbs().maxCoeff();
  for (Eigen::Index c = 0; c < x.size(); ++c) {
    SCOPED_TRACE("variable " + std::to_string(c));
    EXPECT_GE(x(c), lower(c));
    if (at_bound[static_cast<size_t>(c)]) {
      EXPECT_EQ(x(c), lower(c));
      EXPECT_GT(gradient(c), -1e-9 * scale);
    } else {
      EXPECT_NEAR(gradient(c), 0.0, 1e-9 * scale);
    }
  }
}

// Bounds the solution respects anyway change nothing: the step is solveReduced's.
TEST(BoundedLeastSquares, InactiveBoundsGiveTheUnboundedSolution) {
  System s = randomSystem(3, 400, 6);
  reduce(s);
  const SvdSolution free = solveReduced(s.reduced, 1e-9);
  Eigen::VectorXd lower = Eigen::VectorXd::Constant(6, kNone);
  lower(1) = std::min(0.0, free.x(1) - 1.0);
  lower(4) = std::min(0.0, free.x(4) - 0.5);
  std::vector<bool> at_bound;
  const Eigen::VectorXd x = solveReducedBounded(s.reduced, 1e-9, lower, &at_bound);
  EXPECT_LT((x - free.x).norm(), 1e-10 * free.x.norm());
  for (bool held : at_bound) EXPECT_FALSE(held);
}

// Where the unbounded solution crosses bounds, the bounded one satisfies the optimality
// conditions and beats every feasible point tried at random; the variables held are exactly at
// their bound. Columns of very different scale (geometry beside compliance) and a column that
// repeats another (an unobservable direction) included.
TEST(BoundedLeastSquares, ActiveBoundsMeetTheOptimalityConditions) {
  for (unsigned seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    System s = randomSystem(seed, 300, 7);
    s.J.col(2) *= 1e5;
    s.r += 3.0 * s.J.col(0) - 2.0 * s.J.col(3) - 1.5e-5 * s.J.col(2) + 0.5 * s.J.col(5);
    reduce(s);
    const SvdSolution free = solveReduced(s.reduced, 1e-9);
    Eigen::VectorXd lower = Eigen::VectorXd::Constant(7, kNone);
    // Half way to a negative solution: that bound cuts it.
    for (Eigen::Index c : {1, 2, 3, 6}) lower(c) = std::min(0.0, 0.5 * free.x(c));
    std::vector<bool> at_bound;
    const Eigen::VectorXd x = solveReducedBounded(s.reduced, 1e-9, lower, &at_bound);
    expectOptimal(s, x, lower, at_bound);
    int held = 0;
    for (bool h : at_bound) held += h;
    EXPECT_GE(held, 1);
    const double cost = (s.J * x - s.r).squaredNorm();
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    for (int trial = 0; trial < 200; ++trial) {
      Eigen::VectorXd y = x;
      for (Eigen::Index c = 0; c < 7; ++c) y(c) = std::max(lower(c), x(c) + 0.1 * std::abs(x(c)) * normal(rng));
      EXPECT_GE((s.J * y - s.r).squaredNorm(), cost * (1.0 - 1e-12));
    }
  }
}

// Two equal columns determine only their sum: with one held at its bound, the other carries it.
TEST(BoundedLeastSquares, AVariableHeldLeavesWhatItSharesToItsTwin) {
  System s = randomSystem(11, 300, 5);
  s.J.col(4) = s.J.col(1);  // x1 + x4 is determined, x1 − x4 is not
  s.r += -2.0 * s.J.col(1) + 1.0 * s.J.col(2);
  reduce(s);
  Eigen::VectorXd lower = Eigen::VectorXd::Constant(5, kNone);
  lower(1) = 0.0;  // the pair wants x1 + x4 ≈ −2: x1 held at 0, x4 takes it all
  std::vector<bool> at_bound;
  const Eigen::VectorXd x = solveReducedBounded(s.reduced, 1e-9, lower, &at_bound);
  EXPECT_TRUE(at_bound[1]);
  EXPECT_EQ(x(1), 0.0);
  const SvdSolution free = solveReduced(s.reduced, 1e-9);
  EXPECT_NEAR(x(4), free.x(1) + free.x(4), 1e-9);
}

// min |J x − r|² under C x ≥ d by enumeration: every subset of rows held as equalities (the KKT
// system of the equality-constrained problem), the best feasible point. Exact for small systems.
Eigen::VectorXd bruteForce(const System& s, const Eigen::MatrixXd& C, const Eigen::VectorXd& d) {
  const Eigen::Index p = s.J.cols(), rows = C.rows();
  double best_cost = std::numeric_limits<double>::infinity();
  Eigen::VectorXd best;
  for (unsigned mask = 0; mask < (1u << rows); ++mask) {
    std::vector<Eigen::Index> w;
    for (Eigen::Index i = 0; i < rows; ++i) {
      if (mask & (1u << i)) w.push_back(i);
    }
    const Eigen::Index k = static_cast<Eigen::Index>(w.size());
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(p + k, p + k);
    K.topLeftCorner(p, p) = s.J.transpose() * s.J;
    K.topRightCorner(p, k) = C(w, Eigen::all).transpose();
    K.bottomLeftCorner(k, p) = C(w, Eigen::all);
    Eigen::VectorXd rhs(p + k);
    rhs << s.J.transpose() * s.r, d(w);
    const Eigen::VectorXd x = K.fullPivLu().solve(rhs).head(p);
    if (((C * x - d).array() < -1e-9).any()) continue;
    const double cost = (s.J * x - s.r).squaredNorm();
    if (cost < best_cost) {
      best_cost = cost;
      best = x;
    }
  }
  return best;
}

// General rows (a first moment within ±L times a mass, the mass ≥ 0, as a lumped link's bounds):
// the constrained step is the enumeration's optimum, and feasible.
TEST(ConstrainedLeastSquares, MatchesTheEnumeratedOptimum) {
  for (unsigned seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    System s = randomSystem(seed, 300, 5);
    s.J.col(1) *= 1e3;
    // Wants a negative mass x0 and first moments x1, x2 far beyond its reach.
    s.r += -2.0 * s.J.col(0) + 3e-3 * s.J.col(1) - 4.0 * s.J.col(2) + 1.0 * s.J.col(4);
    reduce(s);
    const double L = 0.5;
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(5, 5);
    C(0, 0) = 1.0;
    C(1, 0) = L, C(1, 1) = -1.0;
    C(2, 0) = L, C(2, 1) = 1.0;
    C(3, 0) = L, C(3, 2) = -1.0;
    C(4, 0) = L, C(4, 2) = 1.0;
    const Eigen::VectorXd d = Eigen::VectorXd::Zero(5);
    std::vector<bool> active;
    const Eigen::VectorXd x = solveReducedConstrained(s.reduced, 1e-9, C, d, &active);
    const Eigen::VectorXd expected = bruteForce(s, C, d);
    EXPECT_LT((x - expected).norm(), 1e-7 * (1.0 + expected.norm()));
    EXPECT_GE((C * x - d).minCoeff(), -1e-9 * x.norm());
    int held = 0;
    for (bool h : active) held += h;
    EXPECT_GE(held, 1);
  }
}

// Simple bounds as rows give solveReducedBounded's step.
TEST(ConstrainedLeastSquares, SimpleBoundsAsRowsGiveTheBoundedStep) {
  for (unsigned seed = 1; seed <= 10; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    System s = randomSystem(seed, 300, 6);
    s.r += 2.0 * s.J.col(0) - 3.0 * s.J.col(2) - 1.0 * s.J.col(5);
    reduce(s);
    Eigen::VectorXd lower = Eigen::VectorXd::Constant(6, kNone);
    lower(2) = 0.0;
    lower(5) = -0.3;
    const Eigen::VectorXd bounded = solveReducedBounded(s.reduced, 1e-9, lower);
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(2, 6);
    C(0, 2) = 1.0;
    C(1, 5) = 1.0;
    const Eigen::Vector2d d(0.0, -0.3);
    const Eigen::VectorXd x = solveReducedConstrained(s.reduced, 1e-9, C, d);
    EXPECT_LT((x - bounded).norm(), 1e-9 * (1.0 + bounded.norm()));
  }
}

// A mass the rows cannot see (its column zero) with a first moment they determine beyond
// L × 0: the mass rises to |h| / L and the residual stays the unbounded one.
TEST(ConstrainedLeastSquares, AnUnseenMassCarriesItsFirstMoment) {
  System s = randomSystem(5, 300, 3);
  s.J.col(0).setZero();
  s.r += 6.0 * s.J.col(1);
  reduce(s);
  const double L = 2.0;
  Eigen::MatrixXd C(3, 3);
  C << 1.0, 0.0, 0.0, L, -1.0, 0.0, L, 1.0, 0.0;
  const Eigen::VectorXd x = solveReducedConstrained(s.reduced, 1e-9, C, Eigen::VectorXd::Zero(3));
  const SvdSolution free = solveReduced(s.reduced, 1e-9);
  EXPECT_NEAR(x(1), free.x(1), 1e-9 * std::abs(free.x(1)));
  EXPECT_NEAR(x(0), std::abs(free.x(1)) / L, 1e-9 * std::abs(free.x(1)));
  EXPECT_NEAR((s.J * x - s.r).squaredNorm(), (s.J * free.x - s.r).squaredNorm(), 1e-9);
}

// The Gram form (the screening's folds) gives the reduced form's constrained step.
TEST(ConstrainedLeastSquares, TheGramFormGivesTheSameStep) {
  for (unsigned seed = 1; seed <= 10; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    System s = randomSystem(seed, 300, 4);
    s.r += -2.0 * s.J.col(0) - 4.0 * s.J.col(1) + 1.0 * s.J.col(3);
    reduce(s);
    Eigen::MatrixXd C(3, 4);
    C << 1.0, 0.0, 0.0, 0.0, 0.5, -1.0, 0.0, 0.0, 0.5, 1.0, 0.0, 0.0;
    const Eigen::VectorXd d = Eigen::VectorXd::Zero(3);
    const Eigen::VectorXd reduced = solveReducedConstrained(s.reduced, 1e-9, C, d);
    const Eigen::VectorXd gram =
        solveConstrainedGram(s.J.transpose() * s.J, s.J.transpose() * s.r, 1e-12, C, d);
    EXPECT_LT((gram - reduced).norm(), 1e-8 * (1.0 + reduced.norm()));
    EXPECT_LT((gram - bruteForce(s, C, d)).norm(), 1e-8 * (1.0 + reduced.norm()));
  }
}

}  // namespace
}  // namespace stepcal::trainer

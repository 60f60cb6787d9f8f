// Confounds of the time-order families (confounds.hpp).
#include "confounds.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/QR>

#include "scoring.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// A variable with at most this many distinct values is a set of levels (a load's blocks, a
// temperature read in coarse steps, a grid's angles); a nuisance column per level.
constexpr size_t kMaxLevels = 8;
// Degree of the polynomials of a variable with more values: the trend test's cubic.
constexpr int kConfounderDegree = 3;
// From this multiple correlation on a variable moves with the driver enough to stand in for it.
constexpr double kMovesWithDriver = 0.3;
// The family is told apart from at most this many of them, those that move most with the driver:
// on the paper's protocol the load, the torques it loads and the wrench's six components all
// move with the blocks (13 variables), and each costs the screening matrix 18–42 columns whose
// Grams grow with their square, for variables that stand in for the same blocks.
constexpr size_t kMostConfounders = 6;

bool sameLevel(double a, double b) { return std::abs(a - b) <= 1e-9 * std::max(1.0, std::abs(b)); }

ConfounderPtr variableOf(std::string name, std::vector<double> values) {
  auto v = std::make_shared<ConfounderVariable>();
  v->name = std::move(name);
  v->values = std::move(values);
  std::vector<double> known;
  for (double x : v->values) {
    if (std::isfinite(x)) known.push_back(x);
  }
  if (known.size() < 2) return nullptr;
  std::sort(known.begin(), known.end());
  v->lo = known.front();
  v->hi = known.back();
  if (!(v->hi > v->lo)) return nullptr;  // constant: it cannot stand in for anything
  std::vector<double> levels;
  for (double x : known) {
    if (levels.empty() || !sameLevel(x, levels.back())) levels.push_back(x);
    if (levels.size() > kMaxLevels) break;
  }
  if (levels.size() <= kMaxLevels) v->levels = std::move(levels);
  return v;
}

}  // namespace

int ConfounderVariable::functions() const {
  return levels.empty() ? kConfounderDegree : static_cast<int>(levels.size()) - 1;
}

double ConfounderVariable::function(int k, size_t row) const {
  const double x = values[row];
  if (!std::isfinite(x)) return 0.0;
  if (!levels.empty()) return sameLevel(x, levels[static_cast<size_t>(k) + 1]) ? 1.0 : 0.0;
  return legendrePolynomial(k + 1, 2.0 * (x - lo) / (hi - lo) - 1.0);
}

std::vector<ConfounderPtr> confounderVariables(const FitRows& fit, const Evaluation& start) {
  const size_t rows = fit.rows.size();
  const int n = rows == 0 ? 0 : static_cast<int>(fit.rows.front()->q_rad.size());
  std::vector<ConfounderPtr> all;
  const auto add = [&](std::string name, auto value) {
    std::vector<double> values(rows);
    for (size_t i = 0; i < rows; ++i) values[i] = value(i);
    if (ConfounderPtr v = variableOf(std::move(name), std::move(values))) all.push_back(std::move(v));
  };
  add("load_kg", [&](size_t i) { return fit.rows[i]->load_kg; });
  add("temp_c", [&](size_t i) { return rowTemperature(*fit.rows[i]); });
  for (int j = 0; j < n; ++j) {
    add("q" + std::to_string(j + 1) + "_deg", [&](size_t i) { return kDegPerRad * fit.rows[i]->q_rad(j); });
  }
  for (int j = 0; j < n && start.tau_nm.size() == rows; ++j) {
    add("tau" + std::to_string(j + 1) + "_nm", [&](size_t i) { return start.tau_nm[i](j); });
  }
  const bool wrench = std::any_of(fit.rows.begin(), fit.rows.end(),
                                  [](const Measurement* row) { return row->has_wrench; });
  static const char* const kWrench[] = {"fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"};
  for (int k = 0; k < 6 && wrench; ++k) {
    add(kWrench[k], [&](size_t i) {
      return fit.rows[i]->has_wrench ? fit.rows[i]->wrench_Sensor(k)
                                     : std::numeric_limits<double>::quiet_NaN();
    });
  }
  add("seq", [&](size_t i) { return static_cast<double>(fit.rows[i]->seq); });
  return all;
}

double driverCorrelation(const std::vector<double>& driver, const ConfounderVariable& variable) {
  std::vector<size_t> used;
  for (size_t i = 0; i < driver.size(); ++i) {
    if (std::isfinite(driver[i]) && std::isfinite(variable.values[i])) used.push_back(i);
  }
  const int k = variable.functions();
  if (used.size() < static_cast<size_t>(k + 2)) return 0.0;
  Eigen::MatrixXd F(static_cast<Eigen::Index>(used.size()), k + 1);
  Eigen::VectorXd y(F.rows());
  for (Eigen::Index r = 0; r < F.rows(); ++r) {
    const size_t i = used[static_cast<size_t>(r)];
    F(r, 0) = 1.0;
    for (int f = 0; f < k; ++f) F(r, f + 1) = variable.function(f, i);
    y(r) = driver[i];
  }
  const double total = (y.array() - y.mean()).square().sum();
  if (!(total > 0.0)) return 0.0;
  const Eigen::VectorXd left = y - F * F.colPivHouseholderQr().solve(y);
  return std::sqrt(std::clamp(1.0 - left.squaredNorm() / total, 0.0, 1.0));
}

std::vector<Confounder> confoundersOf(const std::vector<ConfounderPtr>& variables,
                                      const std::string& driver) {
  const auto it = std::find_if(variables.begin(), variables.end(),
                               [&](const ConfounderPtr& v) { return v->name == driver; });
  if (it == variables.end()) return {};
  const std::vector<double>& values = (*it)->values;
  std::vector<Confounder> moving;
  for (const ConfounderPtr& v : variables) {
    if (v->name == driver) continue;
    const double r = driverCorrelation(values, *v);
    if (r >= kMovesWithDriver) moving.push_back({v, r});
  }
  std::stable_sort(moving.begin(), moving.end(),
                   [](const Confounder& a, const Confounder& b) { return a.r > b.r; });
  if (moving.size() > kMostConfounders) moving.resize(kMostConfounders);
  return moving;
}

void testConfounds(std::vector<Scored>& scored, const CrossValidation& cv,
                   const std::function<bool(const CandidateScore&)>& is_significant, int round,
                   std::vector<ConfoundTest>& tests) {
  // Per family tested, per confounder: the model with the nuisance, and with the family beside.
  struct Pending {
    size_t scored;
    std::vector<CrossValidation::Correction> nuisance, both;
  };
  std::vector<Pending> pending;
  for (size_t k = 0; k < scored.size(); ++k) {
    const Family& family = *scored[k].family;
    if (family.driver.empty() || !scored[k].score.significant) continue;
    Pending p{k, {}, {}};
    for (const Family::Confound& c : family.confounds) {
      std::vector<Eigen::Index> columns = c.columns;
      p.nuisance.push_back(cv.withGlobal(columns));
      columns.insert(columns.end(), family.columns.begin(), family.columns.end());
      p.both.push_back(cv.withGlobal(columns));
    }
    pending.push_back(std::move(p));
  }
  std::vector<const CrossValidation::Correction*> corrections;
  for (const Pending& p : pending) {
    for (size_t c = 0; c < p.nuisance.size(); ++c) {
      corrections.push_back(&p.nuisance[c]);
      corrections.push_back(&p.both[c]);
    }
  }
  const std::vector<CrossValidation::Outcome> outcomes =
      corrections.empty() ? std::vector<CrossValidation::Outcome>() : cv.heldOut(corrections);
  size_t next = 0;
  for (const Pending& p : pending) {
    Scored& s = scored[p.scored];
    const Family& family = *s.family;
    ConfoundTest test;
    test.mechanism = s.score.mechanism;
    test.round = round;
    test.driver = family.driver;
    test.z_statistic = s.score.z_statistic;
    for (const Family::Confound& c : family.confounds) {
      const Comparison beside = compare(outcomes[next], outcomes[next + 1]);
      next += 2;
      CandidateScore as_candidate;  // the family's score with the nuisance in the model
      as_candidate.p_value = beside.p;
      as_candidate.relative_reduction = beside.relative_reduction;
      ConfoundTest::Beside b{c.variable, c.r, beside.gain_mm, beside.relative_reduction,
                             beside.z, beside.p, is_significant(as_candidate)};
      test.told_apart = test.told_apart && b.told_apart;
      test.beside.push_back(std::move(b));
    }
    s.score.significant = test.told_apart;
    tests.push_back(std::move(test));
  }
}

}  // namespace stepcal::trainer::diagnosis

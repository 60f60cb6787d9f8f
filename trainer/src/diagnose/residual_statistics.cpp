#include "residual_statistics.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>

#include "cross_validation.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// Cubic trend of each residual component in one variable, cross-validated against no trend.
std::optional<Comparison> trendOf(const std::vector<double>& values, const Eigen::VectorXd& r,
                                  const FitRows& eq) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  size_t present = 0;
  for (double x : values) {
    if (!std::isfinite(x)) continue;
    lo = std::min(lo, x);
    hi = std::max(hi, x);
    ++present;
  }
  if (present * 10 < values.size() * 9 || !(hi - lo > 1e-9 * std::max(1.0, std::abs(hi)))) {
    return std::nullopt;
  }
  auto basis = [&](size_t row) {
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    if (!std::isfinite(values[row])) return b;
    const double x = 2.0 * (values[row] - lo) / (hi - lo) - 1.0;
    b << x, 0.5 * (3 * x * x - 1), 0.5 * (5 * x * x * x - 3 * x);  // Legendre P1..P3
    return b;
  };
  // Per fold and component: normal equations of the training rows.
  const int folds = eq.folds;
  std::vector<std::array<Eigen::Matrix3d, 6>> G(static_cast<size_t>(folds));
  std::vector<std::array<Eigen::Vector3d, 6>> b(static_cast<size_t>(folds));
  for (auto& g : G) g.fill(Eigen::Matrix3d::Zero());
  for (auto& v : b) v.fill(Eigen::Vector3d::Zero());
  for (size_t i = 0; i < eq.rows.size(); ++i) {
    const Eigen::Vector3d B = basis(i);
    const int k = eq.equations(i);
    for (int c = 0; c < k; ++c) {
      G[static_cast<size_t>(eq.fold[i])][static_cast<size_t>(c)] += B * B.transpose();
      b[static_cast<size_t>(eq.fold[i])][static_cast<size_t>(c)] += B * r(eq.start[i] + c);
    }
  }
  CrossValidation::Outcome none, with;
  none.pose_sse.assign(static_cast<size_t>(eq.poses), 0.0);
  with.pose_sse = none.pose_sse;
  none.rows = with.rows = eq.rows.size();
  std::vector<std::array<Eigen::Vector3d, 6>> beta(static_cast<size_t>(folds));
  for (int f = 0; f < folds; ++f) {
    for (int c = 0; c < 6; ++c) {
      Eigen::Matrix3d Gt = Eigen::Matrix3d::Zero();
      Eigen::Vector3d bt = Eigen::Vector3d::Zero();
      for (int g = 0; g < folds; ++g) {
        if (g == f) continue;
        Gt += G[static_cast<size_t>(g)][static_cast<size_t>(c)];
        bt += b[static_cast<size_t>(g)][static_cast<size_t>(c)];
      }
      beta[static_cast<size_t>(f)][static_cast<size_t>(c)] =
          Gt.trace() > 0.0 ? Eigen::Vector3d(Gt.ldlt().solve(bt)) : Eigen::Vector3d::Zero();
    }
  }
  for (size_t i = 0; i < eq.rows.size(); ++i) {
    const Eigen::Vector3d B = basis(i);
    const int k = eq.equations(i);
    Eigen::Matrix<double, 6, 1> e0 = Eigen::Matrix<double, 6, 1>::Zero(), e1 = e0;
    for (int c = 0; c < k; ++c) {
      e0(c) = r(eq.start[i] + c);
      e1(c) = e0(c) - B.dot(beta[static_cast<size_t>(eq.fold[i])][static_cast<size_t>(c)]);
    }
    const size_t pose = static_cast<size_t>(eq.pose[i]);
    none.pose_sse[pose] += e0.squaredNorm();
    with.pose_sse[pose] += e1.squaredNorm();
    none.position_sum_m += e0.head<3>().norm() / eq.w_p;
    with.position_sum_m += e1.head<3>().norm() / eq.w_p;
  }
  return compare(none, with);
}

}  // namespace

Variables trendVariables(const FitRows& eq, const std::vector<JointVector>& tau, int n) {
  Variables v;
  auto add = [&](const std::string& name, auto value) {
    std::vector<double> column;
    for (size_t i = 0; i < eq.rows.size(); ++i) column.push_back(value(i));
    v.names.push_back(name);
    v.values.push_back(std::move(column));
  };
  for (int j = 0; j < n; ++j) {
    add("q" + std::to_string(j + 1) + "_deg", [&](size_t i) { return kDegPerRad * eq.rows[i]->q_rad(j); });
  }
  for (int j = 0; j < n; ++j) {
    add("tau" + std::to_string(j + 1) + "_nm", [&](size_t i) { return tau[i](j); });
  }
  add("load_kg", [&](size_t i) { return eq.rows[i]->load_kg; });
  add("temp_c", [&](size_t i) { return rowTemperature(*eq.rows[i]); });
  add("seq", [&](size_t i) { return static_cast<double>(eq.rows[i]->seq); });
  return v;
}

ResidualStatistics statistics(const Eigen::VectorXd& r, const FitRows& eq,
                              const Variables& variables, double alpha) {
  ResidualStatistics s;
  s.rows = static_cast<int>(eq.rows.size());
  double sum_p = 0.0, sum_p2 = 0.0, sum_r2 = 0.0;
  int oriented = 0;
  for (size_t i = 0; i < eq.rows.size(); ++i) {
    const double p = r.segment<3>(eq.start[i]).norm() / eq.w_p;
    s.position_error_m.push_back(p);
    sum_p += p;
    sum_p2 += p * p;
    s.max_position_m = std::max(s.max_position_m, p);
    if (eq.rows[i]->has_orientation) {
      sum_r2 += (r.segment<3>(eq.start[i] + 3) / eq.w_r).squaredNorm();
      ++oriented;
    }
  }
  s.mean_position_m = sum_p / s.rows;
  s.rms_position_m = std::sqrt(sum_p2 / s.rows);
  s.rms_orientation_rad = oriented > 0 ? std::sqrt(sum_r2 / oriented) : 0.0;
  s.noise_ratio = std::sqrt(r.squaredNorm() / static_cast<double>(eq.count));
  int tested = 0;
  for (size_t v = 0; v < variables.names.size(); ++v) {
    const std::optional<Comparison> c = trendOf(variables.values[v], r, eq);
    if (!c) continue;
    ++tested;
    s.trends.push_back({variables.names[v], c->gain_mm, c->z, c->p, false});
  }
  for (TrendScore& t : s.trends) {
    t.significant = t.p_value < alpha / std::max(1, tested) && t.cv_gain_mm > 0.0;
  }
  std::sort(s.trends.begin(), s.trends.end(), [](const TrendScore& a, const TrendScore& b) {
    return a.z_statistic > b.z_statistic;
  });
  return s;
}

std::string trendSummary(const ResidualStatistics& s, double limit) {
  std::string out;
  for (const TrendScore& t : s.trends) {
    if (!t.significant) continue;
    char line[160];
    std::snprintf(line, sizeof line, "%s%s (a cubic trend in it removes %.4f mm held-out, z = %.1f)",
                  out.empty() ? "" : "; ", t.variable.c_str(), t.cv_gain_mm, t.z_statistic);
    out += line;
  }
  if (out.empty() && s.noise_ratio > limit) {
    char line[200];
    std::snprintf(line, sizeof line,
                  "no tested variable; the residual is %.1f times the stated tracker noise "
                  "(scatter from pose to pose, or the noise is understated)",
                  s.noise_ratio);
    out = line;
  }
  return out;
}

}  // namespace stepcal::trainer::diagnosis

// A geometric model's position residual on a campaign's rows, and its per-joint signature
// (docs/diagnosis.md, "The twin of the calibrated robot"):
//
//   e_i   = p_measured,i − p_model(q_i), the tip position residual of row i (tracker frame, m);
//   u_ij  = the unit direction the model's tip moves in when joint j turns, at q_i (column j of
//           the tip point Jacobian's position rows, normalised);
//   r_ij  = u_ij · e_i, the residual along joint j's motion;
//   joint j's signature: the mean of r_ij over bins of equal row count in q_j (the rows sorted by
//           their angle q_j, split into B bins), i.e. the residual's conditional mean given q_j;
//           its size s_j = √(Σ_b n_b m_b² / N), the RMS over the rows of their bin's mean.
// Two campaigns at the same joint angles have the same bins, so their signatures compare bin by
// bin: the size ratio, and the shape difference √(Σ_b n_b (m_b − m'_b)² / N) / s'_j.
#pragma once

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"

namespace stepcal::test {

/// p_measured − p_model per row, tracker frame, m.
inline std::vector<Vec3> positionResiduals(const KinematicChain& chain_Tracker,
                                           const std::vector<const Measurement*>& rows) {
  std::vector<Vec3> e;
  ChainWorkspace ws;
  for (const Measurement* row : rows) {
    forwardKinematics(chain_Tracker, row->q_rad, ws);
    e.push_back(row->p_TipInTracker_m - tipPose(ws).translation());
  }
  return e;
}

struct ResidualSize {
  double mean_m = 0.0, rms_m = 0.0;  ///< of |e_i|, m
};

inline ResidualSize residualSize(const std::vector<Vec3>& e) {
  ResidualSize s;
  for (const Vec3& v : e) {
    s.mean_m += v.norm();
    s.rms_m += v.squaredNorm();
  }
  s.mean_m /= static_cast<double>(e.size());
  s.rms_m = std::sqrt(s.rms_m / static_cast<double>(e.size()));
  return s;
}

struct JointSignature {
  std::vector<double> bin_mean_m;  ///< m_b, m
  std::vector<int> bin_rows;       ///< n_b
  double size_m = 0.0;             ///< s_j, m
};

/// Joint j's (0-based) signature of residuals e on rows, with `bins` bins.
inline JointSignature jointSignature(const KinematicChain& chain_Tracker,
                                     const std::vector<const Measurement*>& rows,
                                     const std::vector<Vec3>& e, int joint, int bins) {
  const size_t n = rows.size();
  std::vector<double> r(n);
  ChainWorkspace ws;
  Jacobian J(6, chain_Tracker.dof());
  for (size_t i = 0; i < n; ++i) {
    forwardKinematics(chain_Tracker, rows[i]->q_rad, ws);
    tipPointJacobian(chain_Tracker, ws, J);
    const Vec3 u = J.col(joint).head<3>().normalized();
    r[i] = u.dot(e[i]);
  }
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return rows[a]->q_rad(joint) < rows[b]->q_rad(joint);
  });
  JointSignature s;
  double sum_squares = 0.0;
  for (int b = 0; b < bins; ++b) {
    const size_t first = n * static_cast<size_t>(b) / static_cast<size_t>(bins);
    const size_t last = n * static_cast<size_t>(b + 1) / static_cast<size_t>(bins);
    double sum = 0.0;
    for (size_t k = first; k < last; ++k) sum += r[order[k]];
    const int count = static_cast<int>(last - first);
    const double mean = count > 0 ? sum / count : 0.0;
    s.bin_mean_m.push_back(mean);
    s.bin_rows.push_back(count);
    sum_squares += count * mean * mean;
  }
  s.size_m = std::sqrt(sum_squares / static_cast<double>(n));
  return s;
}

/// √(Σ_b n_b (m_b − m'_b)² / N) / s'_j of a signature against a reference on the same bins.
inline double shapeDifference(const JointSignature& s, const JointSignature& reference) {
  double sum = 0.0, rows = 0.0;
  for (size_t b = 0; b < s.bin_mean_m.size(); ++b) {
    const double d = s.bin_mean_m[b] - reference.bin_mean_m[b];
    sum += reference.bin_rows[b] * d * d;
    rows += reference.bin_rows[b];
  }
  return std::sqrt(sum / rows) / reference.size_m;
}

}  // namespace stepcal::test

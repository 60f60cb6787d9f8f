// Step 1's fit of several sessions with its solver state (internal to stepcal::trainer): what the
// held-out test of the sessions' differences needs beyond GeometricResult, their covariance.
#pragma once

#include <algorithm>
#include <vector>

#include "stepcal/trainer/geometric.hpp"
#include "least_squares.hpp"

namespace stepcal::trainer {

// Where each of a chain's 6(n+1) initial-pose parameters sits among the fit's unknowns: every
// session has its own tracker registration T_{0,1} and tool T_{n,n+1} (and, when asked, joint
// frames of its own), the joint frames between are shared. Columns block by block, an own block
// session by session.
class ParameterLayout {
 public:
  ParameterLayout(int dof, int sessions, const GeometricOptions& options)
      : sessions_(sessions), offset_(static_cast<size_t>(dof + 1), -1), own_(offset_.size(), false) {
    int next = 0;
    for (int k = 0; k <= dof; ++k) {
      const bool frame = k == 0 || k == dof;
      if (!frame && options.scope != GeometricScope::kFullPoe) continue;
      own_[static_cast<size_t>(k)] =
          frame || std::find(options.own_frames.begin(), options.own_frames.end(), k) !=
                       options.own_frames.end();
      offset_[static_cast<size_t>(k)] = next;
      next += own_[static_cast<size_t>(k)] ? 6 * sessions : 6;
    }
    count_ = next;
  }
  int count() const { return count_; }
  int sessions() const { return sessions_; }
  /// Column of chain parameter 6k + c in a session; −1: not fitted.
  int column(int session, int parameter) const {
    const auto k = static_cast<size_t>(parameter / 6);
    if (offset_[k] < 0) return -1;
    return offset_[k] + (own_[k] ? 6 * session : 0) + parameter % 6;
  }
  /// Every column of a chain parameter (one per session for an own block, one when shared).
  std::vector<int> columns(int parameter) const {
    std::vector<int> out;
    for (int s = 0; s < sessions_; ++s) {
      const int c = column(s, parameter);
      if (c >= 0 && (out.empty() || out.back() != c)) out.push_back(c);
    }
    return out;
  }
  /// The session's chain parameters of a solution (0 where not fitted).
  Eigen::VectorXd chainDelta(int session, const Eigen::VectorXd& x) const {
    Eigen::VectorXd delta = Eigen::VectorXd::Zero(6 * static_cast<Eigen::Index>(offset_.size()));
    for (int i = 0; i < delta.size(); ++i) {
      if (const int c = column(session, i); c >= 0) delta(i) = x(c);
    }
    return delta;
  }

 private:
  int sessions_, count_ = 0;
  std::vector<int> offset_;  // first column of each block, −1: not fitted
  std::vector<bool> own_;    // a block each session has its own
};

// A fit of several sessions and the solver's state at its end.
struct GeometricFit {
  GeometricResult result;
  ParameterLayout layout;
  SvdSolution last;          // the truncated SVD of the last linearisation (at the final chains)
  double chi2_reduced = 1.0;  // weighted cost over (equations − rank), final
};

// calibrateGeometry of several sessions, keeping the solver's state. Throws as it does.
GeometricFit fitGeometry(const KinematicChain& nominal_Base, const std::vector<GeometricSession>& sessions,
                         const GeometricOptions& options);

}  // namespace stepcal::trainer

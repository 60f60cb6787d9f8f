// KDL's inverse kinematics on a stepcal chain, for stepcal-bench --compare-kdl (Debian's
// liborocos-kdl-dev, an optional dependency of the bench only).
#pragma once

#include <memory>
#include <vector>

#include "stepcal/common/chain.hpp"

namespace stepcal::bench {

/// One inverse problem: the tip pose to reach (the chain's root frame) and where to start.
struct KdlTarget {
  Pose X_RootTip;
  JointVector seed_q_rad;
};

/// KDL's ChainIkSolverPos_NR_JL (Newton–Raphson with joint limits, ChainIkSolverVel_pinv inside)
/// on the chain as a KDL::Chain (T_{0,1}(0) a fixed segment, then per joint the rotation about
/// its axis followed by T_{k,k+1}(0); the attached frames left out), at tolerance eps, maxiter 100
/// (KDL's default), ready to solve each target in turn so that the bench times it call by call
/// beside its own.
class KdlInverse {
 public:
  KdlInverse(const KinematicChain& chain, const std::vector<KdlTarget>& targets, double eps);
  ~KdlInverse();
  KdlInverse(const KdlInverse&) = delete;
  KdlInverse& operator=(const KdlInverse&) = delete;

  /// Solves target i (of those given) from its seed; true when KDL converged within eps (its
  /// error code ≥ 0).
  bool solve(size_t i);

 private:
  struct Solver;
  std::unique_ptr<Solver> solver_;
};

/// Largest distance (m) between the chain's own forward kinematics and KDL's over the targets'
/// seeds: the two chains must be the same robot for the comparison to mean anything.
double kdlChainMismatch_m(const KinematicChain& chain, const std::vector<KdlTarget>& targets);

}  // namespace stepcal::bench

// KDL's inverse kinematics on a stepcal chain, for stepcal-bench --compare-kdl (Debian's
// liborocos-kdl-dev, an optional dependency of the bench only).
#pragma once

#include <vector>

#include "stepcal/common/chain.hpp"

namespace stepcal::bench {

/// One inverse problem: the tip pose to reach (the chain's root frame) and where to start.
struct KdlTarget {
  Pose X_RootTip;
  JointVector seed_q_rad;
};

/// Per call, in target order: the latency (µs, one call to CartToJnt timed alone with
/// steady_clock) and whether KDL converged within eps (its error code ≥ 0).
struct KdlTimes {
  std::vector<double> latency_us;
  long failures = 0;
};

/// The chain as a KDL::Chain (T_{0,1}(0) a fixed segment, then per joint the rotation about its
/// axis followed by T_{k,k+1}(0); the attached frames left out), solved by
/// ChainIkSolverPos_NR_JL (Newton–Raphson with joint limits, ChainIkSolverVel_pinv inside) at
/// tolerance eps, maxiter 100 (KDL's default), calls times over the targets in turn after a
/// warm-up of every target once.
KdlTimes timeKdlInverse(const KinematicChain& chain, const std::vector<KdlTarget>& targets,
                        int calls, double eps);

/// Largest distance (m) between the chain's own forward kinematics and KDL's over the targets'
/// seeds: the two chains must be the same robot for the comparison to mean anything.
double kdlChainMismatch_m(const KinematicChain& chain, const std::vector<KdlTarget>& targets);

}  // namespace stepcal::bench

#include "kdl_compare.hpp"

#include <algorithm>
#include <utility>

#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainiksolverpos_nr_jl.hpp>
#include <kdl/chainiksolvervel_pinv.hpp>

namespace stepcal::bench {
namespace {

KDL::Frame toKdl(const Pose& X) {
  const Mat3& R = X.linear();
  const Vec3& p = X.translation();
  return KDL::Frame(KDL::Rotation(R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0),
                                  R(2, 1), R(2, 2)),
                    KDL::Vector(p.x(), p.y(), p.z()));
}

KDL::JntArray toKdl(const JointVector& q) {
  KDL::JntArray out(static_cast<unsigned>(q.size()));
  for (Eigen::Index i = 0; i < q.size(); ++i) out(static_cast<unsigned>(i)) = q(i);
  return out;
}

// Local POE X = T_0 e^{ŝ_1 q_1} T_1 … e^{ŝ_n q_n} T_n as KDL segments: a segment's pose is its
// joint's motion followed by its f_tip, so T_0 comes first as a fixed segment, then each joint
// (a rotation about ω through the point ω × v of its unit twist (v, ω)) with T_k as its f_tip.
KDL::Chain kdlChain(const KinematicChain& chain) {
  KDL::Chain out;
  out.addSegment(KDL::Segment("root", KDL::Joint(KDL::Joint::None), toKdl(chain.initialPose(0))));
  for (int k = 1; k <= chain.dof(); ++k) {
    const ChainJoint& joint = chain.joints()[static_cast<size_t>(k - 1)];
    const Vec3 w = joint.twist_Local.tail<3>(), v = joint.twist_Local.head<3>();
    const Vec3 point = w.cross(v);
    out.addSegment(KDL::Segment(
        joint.name,
        KDL::Joint(joint.name, KDL::Vector(point.x(), point.y(), point.z()),
                   KDL::Vector(w.x(), w.y(), w.z()), KDL::Joint::RotAxis),
        toKdl(chain.initialPose(k))));
  }
  return out;
}

}  // namespace

struct KdlInverse::Solver {
  Solver(KDL::Chain chain_in, const KDL::JntArray& q_min, const KDL::JntArray& q_max, double eps)
      : chain(std::move(chain_in)),
        fk(chain),
        ik_velocity(chain),
        ik(chain, q_min, q_max, fk, ik_velocity, 100, eps),
        q_out(chain.getNrOfJoints()) {}
  KDL::Chain chain;  // the solvers keep references to it
  KDL::ChainFkSolverPos_recursive fk;
  KDL::ChainIkSolverVel_pinv ik_velocity;
  KDL::ChainIkSolverPos_NR_JL ik;
  std::vector<KDL::Frame> frames;
  std::vector<KDL::JntArray> seeds;
  KDL::JntArray q_out;
};

KdlInverse::KdlInverse(const KinematicChain& chain, const std::vector<KdlTarget>& targets,
                       double eps) {
  const auto n = static_cast<unsigned>(chain.dof());
  KDL::JntArray q_min(n), q_max(n);
  for (unsigned i = 0; i < n; ++i) {
    q_min(i) = chain.joints()[i].lower_rad;
    q_max(i) = chain.joints()[i].upper_rad;
  }
  solver_ = std::make_unique<Solver>(kdlChain(chain), q_min, q_max, eps);
  for (const KdlTarget& t : targets) {
    solver_->frames.push_back(toKdl(t.X_RootTip));
    solver_->seeds.push_back(toKdl(t.seed_q_rad));
  }
}

KdlInverse::~KdlInverse() = default;

bool KdlInverse::solve(size_t i) {
  return solver_->ik.CartToJnt(solver_->seeds[i], solver_->frames[i], solver_->q_out) >= 0;
}

double kdlChainMismatch_m(const KinematicChain& chain, const std::vector<KdlTarget>& targets) {
  const KDL::Chain kdl = kdlChain(chain);
  KDL::ChainFkSolverPos_recursive fk(kdl);
  ChainWorkspace ws;
  double worst = 0.0;
  for (const KdlTarget& t : targets) {
    KDL::Frame X;
    fk.JntToCart(toKdl(t.seed_q_rad), X);
    forwardKinematics(chain, t.seed_q_rad, ws);
    const Vec3 p = tipPose(ws).translation();
    worst = std::max(worst, (Vec3(X.p.x(), X.p.y(), X.p.z()) - p).norm());
  }
  return worst;
}

}  // namespace stepcal::bench

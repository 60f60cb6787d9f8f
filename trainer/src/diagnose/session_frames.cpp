#include "session_frames.hpp"

#include "../least_squares.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/trainer/registration.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

constexpr double kRankTolerance = 1e-9;
constexpr int kFrameIterations = 10;
// A station and a tool are 12 parameters; a position-only row gives 3 equations.
constexpr size_t kLeastRowsPerStation = 4;

}  // namespace

void registerInClosedForm(PhysicalModel& model, const FitRows& fit) {
  std::vector<Vec3> p_model, p_measured;
  ChainWorkspace ws;
  JointVector theta, tau;
  for (const Measurement* row : fit.rows) {
    physicalLinkAngles(model, row->q_rad, row->wrenchOrZero(), rowTemperature(*row),
                       {ws, theta, tau});
    p_model.push_back(tipPose(ws).translation());
    p_measured.push_back(row->p_TipInTracker_m);
  }
  const Pose X_NewOld = fitRigidTransform(p_model, p_measured);
  model.chain_Tracker = model.chain_Tracker.rerooted(X_NewOld);
  model.gravity_Tracker = X_NewOld.linear() * model.gravity_Tracker;
}

PhysicalModel refitFrames(PhysicalModel model, const FitRows& fit) {
  const int n = model.chain_Tracker.dof();
  registerInClosedForm(model, fit);
  Eigen::VectorXd r = residuals(model, fit);
  double cost = r.squaredNorm();
  for (int it = 0; it < kFrameIterations; ++it) {
    const Eigen::MatrixXd G = linearise(model, fit, r).geometry;
    Eigen::MatrixXd A(fit.count, 12);
    A << G.leftCols(6), G.rightCols(6);
    const SvdSolution s = solveTruncated(A, r, kRankTolerance);
    bool improved = false;
    for (double fraction = 1.0; fraction > 1e-3; fraction *= 0.5) {
      Eigen::VectorXd delta = Eigen::VectorXd::Zero(6 * (n + 1));
      delta.head(6) = fraction * s.x.head(6);
      delta.tail(6) = fraction * s.x.tail(6);
      PhysicalModel moved = model;
      moved.chain_Tracker = model.chain_Tracker.corrected(delta);
      const Eigen::VectorXd r_moved = residuals(moved, fit);
      if (r_moved.squaredNorm() < cost) {
        improved = cost - r_moved.squaredNorm() > 1e-12 * cost;
        model = std::move(moved);
        r = r_moved;
        cost = r.squaredNorm();
        break;
      }
    }
    if (!improved) break;
  }
  return model;
}

std::vector<Mechanism> startingSessionFrames(const PhysicalModel& model,
                                             const std::vector<const Measurement*>& rows,
                                             int sessions, const TrackerNoise& noise,
                                             const std::vector<std::string>& directories) {
  const int n = model.chain_Tracker.dof();
  const Pose& X_TrackerRoot = model.chain_Tracker.initialPose(0);
  const Pose& X_LastTool = model.chain_Tracker.initialPose(n);
  std::vector<Mechanism> frames;
  for (int s = 1; s < sessions; ++s) {
    std::vector<const Measurement*> own;
    for (const Measurement* row : rows) {
      if (row->session == s) own.push_back(row);
    }
    if (own.size() < kLeastRowsPerStation) {
      throw InputError("campaign " + std::to_string(s + 1) + " has " + std::to_string(own.size()) +
                           " fit rows (outside set=validation); expected at least " +
                           std::to_string(kLeastRowsPerStation) +
                           " to place its own tracker station and tool (hint: measure more poses "
                           "there, or leave the campaign out)",
                       directories[static_cast<size_t>(s)]);
    }
    const KinematicChain chain = refitFrames(model, makeFitRows(own, noise, 1)).chain_Tracker;
    Mechanism m;
    m.kind = MechanismKind::kSessionFrames;
    m.order = s;
    m.parameters = stationAndToolParameters(chain.initialPose(0) * X_TrackerRoot.inverse(),
                                          X_LastTool.inverse() * chain.initialPose(n));
    m.sigma.assign(m.parameters.size(), 0.0);
    frames.push_back(std::move(m));
  }
  return frames;
}

std::vector<double> sessionMeanErrors(const Eigen::VectorXd& r, const FitRows& fit,
                                      int sessions) {
  std::vector<double> sum(static_cast<size_t>(sessions), 0.0);
  std::vector<int> count(static_cast<size_t>(sessions), 0);
  for (size_t i = 0; i < fit.rows.size(); ++i) {
    const size_t s = static_cast<size_t>(fit.rows[i]->session);
    sum[s] += r.segment<3>(fit.start[i]).norm() / fit.w_p;
    ++count[s];
  }
  for (size_t s = 0; s < sum.size(); ++s) sum[s] = count[s] > 0 ? sum[s] / count[s] : 0.0;
  return sum;
}

}  // namespace stepcal::trainer::diagnosis

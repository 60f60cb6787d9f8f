#include "fit_rows.hpp"

#include <algorithm>
#include <limits>
#include <map>
#include <random>
#include <string>

#include "parallel.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

constexpr uint64_t kFoldSeed = 20240521;
// Rows per task of the parallel loops: each row is independent (own workspace, own equations).
constexpr size_t kRowsPerTask = 256;

// A temperature for which physicalLinkAngles scales no link length (PhysicalModel's
// linkLengthScale is 1 at NaN).
constexpr double kUnscaledLinks = std::numeric_limits<double>::quiet_NaN();

// Calls row_body(i, ws) for every row, in blocks over the cores.
template <typename Body>
void forEachRow(const FitRows& fit, const Body& row_body) {
  const size_t rows = fit.rows.size();
  parallelFor((rows + kRowsPerTask - 1) / kRowsPerTask, [&](size_t block) {
    ChainWorkspace ws;
    for (size_t i = block * kRowsPerTask; i < std::min(rows, (block + 1) * kRowsPerTask); ++i) {
      row_body(i, ws);
    }
  });
}

}  // namespace

void requireJointCount(const Campaign& campaign, int n) {
  for (const Measurement& row : campaign.rows) {
    if (row.q_rad.size() != n) {
      throw InputError("row has " + std::to_string(row.q_rad.size()) +
                           " joint angles but the model's chain has " + std::to_string(n),
                       campaign.measurements_file, row.source_line);
    }
  }
}

FitRows makeFitRows(const std::vector<const Measurement*>& rows, const TrackerNoise& noise,
                    int folds) {
  FitRows fit;
  fit.rows = rows;
  fit.folds = folds;
  fit.w_p = 1.0 / noise.position_sigma_m;
  fit.w_r = 1.0 / noise.orientation_sigma_rad;
  std::map<std::string, int> pose_index;
  for (const Measurement* row : rows) pose_index.emplace(row->pose_id, 0);
  std::vector<int> order(pose_index.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::mt19937_64 rng(kFoldSeed);
  std::shuffle(order.begin(), order.end(), rng);
  int i = 0;
  for (auto& [id, index] : pose_index) index = i++;
  fit.poses = static_cast<int>(pose_index.size());
  for (const Measurement* row : rows) {
    const int p = pose_index.at(row->pose_id);
    fit.start.push_back(fit.count);
    fit.pose.push_back(p);
    fit.fold.push_back(order[static_cast<size_t>(p)] % folds);
    fit.count += row->has_orientation ? 6 : 3;
  }
  return fit;
}

FitRows chunkOf(const FitRows& fit, size_t begin, size_t end) {
  FitRows chunk;
  chunk.rows.assign(fit.rows.begin() + static_cast<long>(begin), fit.rows.begin() + static_cast<long>(end));
  chunk.fold.assign(fit.fold.begin() + static_cast<long>(begin), fit.fold.begin() + static_cast<long>(end));
  chunk.pose.assign(fit.pose.begin() + static_cast<long>(begin), fit.pose.begin() + static_cast<long>(end));
  for (const Measurement* row : chunk.rows) {
    chunk.start.push_back(chunk.count);
    chunk.count += row->has_orientation ? 6 : 3;
  }
  chunk.poses = fit.poses;
  chunk.folds = fit.folds;
  chunk.w_p = fit.w_p;
  chunk.w_r = fit.w_r;
  return chunk;
}

Evaluation evaluate(const PhysicalModel& model, const FitRows& fit) {
  Evaluation out;
  out.r.resize(fit.count);
  out.theta_rad.resize(fit.rows.size());
  out.tau_nm.resize(fit.rows.size());
  forEachRow(fit, [&](size_t i, ChainWorkspace& ws) {
    const Measurement& row = *fit.rows[i];
    physicalLinkAngles(model, row.q_rad, row.wrenchOrZero(), rowTemperature(row), ws,
                       out.theta_rad[i], out.tau_nm[i]);
    const Pose& X = tipPose(ws);
    const int e = fit.start[i];
    out.r.segment<3>(e) = fit.w_p * (row.p_TipInTracker_m - X.translation());
    if (row.has_orientation) {
      out.r.segment<3>(e + 3) =
          fit.w_r * lie::logSO3(row.q_TrackerTip.toRotationMatrix() * X.linear().transpose());
    }
  });
  return out;
}

Eigen::VectorXd residuals(const PhysicalModel& model, const FitRows& fit) {
  Eigen::VectorXd r(fit.count);
  forEachRow(fit, [&](size_t i, ChainWorkspace& ws) {
    const Measurement& row = *fit.rows[i];
    JointVector theta, tau;
    physicalLinkAngles(model, row.q_rad, row.wrenchOrZero(), rowTemperature(row), ws, theta, tau);
    const Pose& X = tipPose(ws);
    const int e = fit.start[i];
    r.segment<3>(e) = fit.w_p * (row.p_TipInTracker_m - X.translation());
    if (row.has_orientation) {
      r.segment<3>(e + 3) =
          fit.w_r * lie::logSO3(row.q_TrackerTip.toRotationMatrix() * X.linear().transpose());
    }
  });
  return r;
}

Linearisation linearise(const PhysicalModel& model, const FitRows& fit, const Eigen::VectorXd& r) {
  const KinematicChain& chain = model.chain_Tracker;
  const int n = chain.dof();
  Linearisation lin;
  lin.geometry.resize(fit.count, 6 * (n + 1));
  lin.link_angle.resize(fit.count, n);
  forEachRow(fit, [&](size_t i, ChainWorkspace& ws) {
    const Measurement& row = *fit.rows[i];
    Eigen::Matrix<double, 6, Eigen::Dynamic> P(6, 6 * (n + 1));
    JointVector theta, tau;
    Jacobian J;
    // Links unscaled: a link scale that varies by row (thermal expansion) makes
    // the geometry's gauge directions observable at α·ΔT ≈ 1e-4 of the others, and fits then
    // step along them (a refit stalled, profiles took up noise); the Jacobian it leaves out is
    // that small.
    physicalLinkAngles(model, row.q_rad, row.wrenchOrZero(), kUnscaledLinks, ws, theta, tau);
    parameterJacobian(chain, ws, P);
    spatialJacobian(chain, ws, J);
    const Mat3 p_hat = lie::hat(tipPose(ws).translation());
    const int e = fit.start[i];
    // Spatial twists (v, ω) → tip position ṗ = v − p̂ ω and rotation ω (METHOD.md, weighting).
    lin.geometry.middleRows<3>(e) = fit.w_p * (P.topRows<3>() - p_hat * P.bottomRows<3>());
    lin.link_angle.middleRows<3>(e) = fit.w_p * (J.topRows<3>() - p_hat * J.bottomRows<3>());
    if (row.has_orientation) {
      const Mat3 Jr_inv = lie::rightJacobianInverseSO3(r.segment<3>(e + 3) / fit.w_r);
      lin.geometry.middleRows<3>(e + 3) = fit.w_r * Jr_inv * P.bottomRows<3>();
      lin.link_angle.middleRows<3>(e + 3) = fit.w_r * Jr_inv * J.bottomRows<3>();
    }
  });
  return lin;
}

}  // namespace stepcal::trainer::diagnosis

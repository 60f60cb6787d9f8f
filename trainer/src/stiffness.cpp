#include "stepcal/trainer/stiffness.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <Eigen/QR>
#include <Eigen/SVD>

#include "stepcal/common/compliance.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "deflection_system.hpp"

namespace stepcal::trainer {
namespace {

// Wrench the payload adds between the unloaded and the loaded reading, sensor axes.
Vec6 payloadWrench(const DeflectionPair& p) {
  return p.loaded->wrenchOrZero() - p.unloaded->wrenchOrZero();
}

// Joint torques of a pair's payload at the commanded angles, N·m.
JointVector pairTorques(const KinematicChain& chain, int sensor_frame, const DeflectionPair& p,
                        ChainWorkspace& ws, Jacobian& J_s) {
  forwardKinematics(chain, p.loaded->q_rad, ws);
  spatialJacobian(chain, ws, J_s);
  return jointTorques(J_s, wrenchInRoot(framePose(chain, ws, sensor_frame), payloadWrench(p)));
}

}  // namespace

std::vector<DeflectionPair> deflectionPairs(const std::vector<const Measurement*>& rows) {
  // A pose is its pose_id within its session: merged campaigns may use the same names.
  std::map<std::pair<int, std::string>, std::vector<const Measurement*>> by_pose;
  for (const Measurement* row : rows) by_pose[{row->session, row->pose_id}].push_back(row);
  std::vector<DeflectionPair> pairs;
  for (const auto& [key, group] : by_pose) {
    const std::string& pose_id = key.second;
    const Measurement* unloaded = nullptr;
    for (const Measurement* row : group) {
      if (row->load_kg != 0.0) continue;
      if (unloaded) {
        throw InputError("pose_id '" + pose_id + "' has two unloaded rows (lines " +
                             std::to_string(unloaded->source_line) + " and " +
                             std::to_string(row->source_line) +
                             "); expected one unloaded row per pose to measure deflections from",
                         "measurements.csv", row->source_line, "pose_id");
      }
      unloaded = row;
    }
    if (!unloaded) continue;
    for (const Measurement* row : group) {
      if (row == unloaded) continue;
      if ((row->q_rad - unloaded->q_rad).cwiseAbs().maxCoeff() > 1e-9) {
        throw InputError("pose_id '" + pose_id + "': joint angles differ from the unloaded row's (line " +
                             std::to_string(unloaded->source_line) +
                             "); rows sharing a pose_id must be commanded to the same angles",
                         "measurements.csv", row->source_line, "pose_id");
      }
      pairs.push_back({unloaded, row});
    }
  }
  std::sort(pairs.begin(), pairs.end(), [](const DeflectionPair& a, const DeflectionPair& b) {
    return std::pair(a.loaded->session, a.loaded->seq) < std::pair(b.loaded->session, b.loaded->seq);
  });
  return pairs;
}

DeflectionSystem deflectionSystem(const std::vector<StiffnessSession>& sessions, int sensor_frame) {
  const int n = sessions.at(0).chain_Tracker->dof();
  ChainWorkspace ws;
  Jacobian J_s, J_tip;
  DeflectionSystem out;
  out.max_torque_nm = JointVector::Zero(n);
  std::vector<JointVector> torques;  // per pair, sessions in order
  int equations = 0;
  for (size_t s = 0; s < sessions.size(); ++s) {
    for (const DeflectionPair& p : sessions[s].pairs) {
      if (!p.loaded->has_wrench) {
        throw InputError("loaded row has no wrench; step 2 needs the F/T sensor reading",
                         "measurements.csv", p.loaded->source_line, "fx_n");
      }
      torques.push_back(pairTorques(*sessions[s].chain_Tracker, sensor_frame, p, ws, J_s));
      out.max_torque_nm = out.max_torque_nm.cwiseMax(torques.back().cwiseAbs());
      out.first_equation.push_back(equations);
      out.session.push_back(static_cast<int>(s));
      equations += p.loaded->has_orientation && p.unloaded->has_orientation ? 6 : 3;
    }
  }
  out.first_equation.push_back(equations);
  out.B = Eigen::MatrixXd::Zero(equations, n);
  out.y = Eigen::VectorXd::Zero(equations);
  size_t i = 0;
  for (const StiffnessSession& session : sessions) {
    const double w_p = 1.0 / (std::sqrt(2.0) * session.noise.position_sigma_m);
    const double w_r = 1.0 / (std::sqrt(2.0) * session.noise.orientation_sigma_rad);
    for (const DeflectionPair& p : session.pairs) {
      int eq = out.first_equation[i];
      forwardKinematics(*session.chain_Tracker, p.loaded->q_rad, ws);
      tipPointJacobian(*session.chain_Tracker, ws, J_tip);
      for (int j = 0; j < n; ++j) {
        out.B.block(eq, j, 3, 1) = w_p * J_tip.block<3, 1>(0, j) * torques[i](j);
      }
      out.y.segment<3>(eq) = w_p * (p.loaded->p_TipInTracker_m - p.unloaded->p_TipInTracker_m);
      eq += 3;
      if (p.loaded->has_orientation && p.unloaded->has_orientation) {
        for (int j = 0; j < n; ++j) {
          out.B.block(eq, j, 3, 1) = w_r * J_tip.block<3, 1>(3, j) * torques[i](j);
        }
        out.y.segment<3>(eq) = w_r * lie::logSO3(p.loaded->q_TrackerTip.toRotationMatrix() *
                                                 p.unloaded->q_TrackerTip.toRotationMatrix().transpose());
      }
      out.position_weight.push_back(w_p);
      ++i;
    }
  }
  return out;
}

StiffnessResult identifyCompliance(const KinematicChain& chain_Tracker, int sensor_frame,
                                   const std::vector<DeflectionPair>& pairs,
                                   const TrackerNoise& noise, const StiffnessOptions& options) {
  return identifyCompliance(std::vector<StiffnessSession>{{&chain_Tracker, pairs, noise}},
                            sensor_frame, options);
}

StiffnessResult identifyCompliance(const std::vector<StiffnessSession>& sessions, int sensor_frame,
                                   const StiffnessOptions& options) {
  const KinematicChain& first_chain = *sessions.at(0).chain_Tracker;
  const int n = first_chain.dof();
  size_t pair_count = 0;
  for (const StiffnessSession& session : sessions) pair_count += session.pairs.size();
  if (pair_count == 0) {
    throw InputError("no loaded/unloaded pair among the stiffness rows; step 2 needs each "
                     "stiffness pose measured unloaded and loaded under one pose_id");
  }
  if (sensor_frame < 0) {
    throw InputError("the campaign names no sensor_link; step 2 needs the F/T sensor's wrench");
  }
  const DeflectionSystem system = deflectionSystem(sessions, sensor_frame);
  const Eigen::MatrixXd& B_all = system.B;
  const Eigen::VectorXd& y = system.y;
  const auto equations = static_cast<int>(y.size());
  StiffnessResult result;
  result.pairs = static_cast<int>(pair_count);
  std::vector<int> excited;
  for (int j = 0; j < n; ++j) {
    JointCompliance jc;
    jc.joint = first_chain.joints()[static_cast<size_t>(j)].name;
    jc.max_torque_nm = system.max_torque_nm(j);
    if (system.max_torque_nm(j) > 0.0) excited.push_back(j);
    result.joints.push_back(jc);
  }

  // Least squares (eq. 22) on the identifiable joints; drop the least certain until all are.
  Eigen::VectorXd c, residual;
  Eigen::MatrixXd covariance;
  while (true) {
    if (excited.empty()) {
      throw InputError("the loads put too little torque on every joint to identify a compliance; "
                       "check the wrench columns and the loads");
    }
    const Eigen::Index k = static_cast<Eigen::Index>(excited.size());
    Eigen::MatrixXd B(equations, k);
    for (Eigen::Index i = 0; i < k; ++i) B.col(i) = B_all.col(excited[static_cast<size_t>(i)]);
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(B);
    c = qr.solve(y);
    residual = y - B * c;
    // Scale the covariance by the reduced χ² when the fit is worse than the stated noise.
    const double dof_residual = std::max<double>(1.0, static_cast<double>(equations - k));
    const double chi2_reduced = std::max(1.0, residual.squaredNorm() / dof_residual);
    covariance = (B.transpose() * B).completeOrthogonalDecomposition().pseudoInverse() * chi2_reduced;
    Eigen::Index worst = 0;
    double worst_relative = 0.0;
    for (Eigen::Index i = 0; i < k; ++i) {
      const double relative = qr.rank() < k || c(i) <= 0.0
                                  ? std::numeric_limits<double>::infinity()
                                  : std::sqrt(covariance(i, i)) / c(i);
      if (relative > worst_relative) {
        worst_relative = relative;
        worst = i;
      }
    }
    if (worst_relative <= options.max_relative_sigma) break;
    excited.erase(excited.begin() + worst);
  }

  result.compliance_rad_per_nm = JointVector::Zero(n);
  result.compliance_sigma_rad_per_nm = JointVector::Zero(n);
  result.compliance_covariance = Eigen::MatrixXd::Zero(n, n);
  for (size_t i = 0; i < excited.size(); ++i) {
    const int j = excited[i];
    const Eigen::Index e = static_cast<Eigen::Index>(i);
    for (size_t k = 0; k < excited.size(); ++k) {
      result.compliance_covariance(j, excited[k]) = covariance(e, static_cast<Eigen::Index>(k));
    }
    JointCompliance& jc = result.joints[static_cast<size_t>(j)];
    jc.excited = true;
    jc.compliance_rad_per_nm = c(e);
    jc.compliance_sigma_rad_per_nm = std::sqrt(covariance(e, e));
    jc.stiffness_nm_per_rad = 1.0 / c(e);
    jc.stiffness_sigma_nm_per_rad = jc.compliance_sigma_rad_per_nm / (c(e) * c(e));
    result.compliance_rad_per_nm(j) = c(e);
    result.compliance_sigma_rad_per_nm(j) = jc.compliance_sigma_rad_per_nm;
  }
  double sum_p2 = 0.0;
  for (size_t i = 0; i < pair_count; ++i) {
    const double w = system.position_weight[i];
    sum_p2 += residual.segment<3>(system.first_equation[i]).squaredNorm() / (w * w);
  }
  result.rms_position_residual_m = std::sqrt(sum_p2 / static_cast<double>(pair_count));
  return result;
}

std::vector<StiffnessValidation> validateCompliance(const KinematicChain& chain_Tracker,
                                                    int sensor_frame,
                                                    const JointVector& compliance_rad_per_nm,
                                                    const std::vector<DeflectionPair>& pairs) {
  std::map<double, StiffnessValidation> by_load;
  ChainWorkspace ws;
  JointVector q_link;
  for (const DeflectionPair& p : pairs) {
    forwardKinematics(chain_Tracker, p.loaded->q_rad, ws);
    const Vec3 p_rigid = tipPose(ws).translation();
    deflectedJointAngles(chain_Tracker, sensor_frame, p.loaded->q_rad, payloadWrench(p),
                         compliance_rad_per_nm, ws, q_link);
    const Vec3 modelled = tipPose(ws).translation() - p_rigid;
    const Vec3 measured = p.loaded->p_TipInTracker_m - p.unloaded->p_TipInTracker_m;
    const double deviation_pct = 100.0 * (modelled - measured).norm() / measured.norm();
    StiffnessValidation& v = by_load[p.loaded->load_kg];
    v.load_kg = p.loaded->load_kg;
    ++v.pairs;
    v.mean_deviation_pct += deviation_pct;
    v.max_deviation_pct = std::max(v.max_deviation_pct, deviation_pct);
    v.mean_deflection_m += measured.norm();
  }
  std::vector<StiffnessValidation> out;
  for (auto& [load, v] : by_load) {
    v.mean_deviation_pct /= v.pairs;
    v.mean_deflection_m /= v.pairs;
    out.push_back(v);
  }
  return out;
}

}  // namespace stepcal::trainer

#include "fit_rows.hpp"

#include <algorithm>
#include <limits>
#include <map>
#include <random>
#include <string>

#include "parallel.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/mechanisms/campaign_joint_zero.hpp"
#include "stepcal/common/mechanisms/registration_drift.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

constexpr uint64_t kFoldSeed = 20240521;
// Rows per task of the parallel loops: each row is independent (own workspace, own equations).
constexpr size_t kRowsPerTask = 256;

// A temperature for which physicalLinkAngles scales no link length (PhysicalModel's
// linkLengthScale is 1 at NaN).
constexpr double kUnscaledLinks = std::numeric_limits<double>::quiet_NaN();

// Calls body(begin, end, ws) for every block of rows, on the cores.
template <typename Body>
void forEachBlock(const FitRows& fit, const Body& body) {
  const size_t rows = fit.rows.size();
  parallelFor((rows + kRowsPerTask - 1) / kRowsPerTask, [&](size_t block) {
    ChainWorkspace ws;
    body(block * kRowsPerTask, std::min(rows, (block + 1) * kRowsPerTask), ws);
  });
}

}  // namespace

Pose X_FittedLast(const Mechanism& drift) {
  constexpr double kLastShare = 0.1;
  constexpr int kSamples = 50;
  const mechanism::RegistrationDrift<const double> span = view<mechanism::RegistrationDrift>(drift);
  const double first = span.firstSeq(), last = span.lastSeq();
  Vec6 mean = Vec6::Zero();
  for (int i = 0; i <= kSamples; ++i) {
    mean += registrationDrift(drift, last - kLastShare * (last - first) * i / kSamples);
  }
  return lie::expSE3(mean / (kSamples + 1));
}

MeasurementFrames measurementFramesOf(const PhysicalModel& model) {
  MeasurementFrames frames;
  const int n = model.chain_Tracker.dof();
  for (const Mechanism& m : model.mechanisms) {
    const size_t campaign = static_cast<size_t>(m.order);
    switch (m.kind) {
      case MechanismKind::kRegistrationDrift: frames.drift = &m; break;
      case MechanismKind::kSessionFrames:
        if (frames.sessions.size() <= campaign) frames.sessions.resize(campaign + 1);
        frames.sessions[campaign] = stationAndTool(m);
        break;
      case MechanismKind::kCampaignJointZero:  // order: the campaigns after the first
        if (frames.zero_offset_rad.size() <= campaign) {
          frames.zero_offset_rad.resize(campaign + 1, JointVector::Zero(n));
        }
        for (int k = 1; k <= m.order; ++k) {
          frames.zero_offset_rad[static_cast<size_t>(k)](m.joint) +=
              view<mechanism::CampaignJointZero>(m).offset_rad(k);
        }
        break;
      default: break;
    }
  }
  return frames;
}

const StationAndTool* MeasurementFrames::ownFrames(const Measurement& row) const {
  const size_t session = static_cast<size_t>(row.session);
  return session < sessions.size() && sessions[session] ? &*sessions[session] : nullptr;
}

JointVector MeasurementFrames::commanded(const Measurement& row) const {
  const size_t session = static_cast<size_t>(row.session);
  if (session >= zero_offset_rad.size()) return row.q_rad;
  return row.q_rad + zero_offset_rad[session];
}

Pose MeasurementFrames::measured(const Measurement& row, const Pose& X_TipInTracker) const {
  Pose X = X_TipInTracker;
  if (const StationAndTool* own = ownFrames(row)) X = own->X_Station * X * own->X_Tool;
  if (drift != nullptr) X = lie::expSE3(registrationDrift(*drift, static_cast<double>(row.seq))) * X;
  return X;
}

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
  // A pose is a pose_id of one campaign: merged campaigns may use the same ids.
  std::map<std::pair<int, std::string>, int> pose_index;
  for (const Measurement* row : rows) pose_index.emplace(std::pair(row->session, row->pose_id), 0);
  std::vector<int> order(pose_index.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::mt19937_64 rng(kFoldSeed);
  std::shuffle(order.begin(), order.end(), rng);
  int i = 0;
  for (auto& [id, index] : pose_index) index = i++;
  fit.poses = static_cast<int>(pose_index.size());
  for (const Measurement* row : rows) {
    const int p = pose_index.at(std::pair(row->session, row->pose_id));
    fit.start.push_back(fit.count);
    fit.pose.push_back(p);
    fit.fold.push_back(order[static_cast<size_t>(p)] % folds);
    fit.count += row->has_orientation ? 6 : 3;
  }
  return fit;
}

namespace {

// Twists (v, ω) in the first campaign's tracker axes, columns of V, into a campaign's tracker
// axes: the adjoint of its station.
template <typename Columns>
void toStation(const Pose& X_Station, Columns& V) {
  const Mat3 R = X_Station.linear();
  const Eigen::Matrix<double, 3, Eigen::Dynamic> w = R * V.bottomRows(3);
  V.topRows(3) = R * V.topRows(3) + lie::hat(X_Station.translation()) * w;
  V.bottomRows(3) = w;
}

// Row i's weighted residual into r.segment(e, k): measured − modelled at the tip pose X, as the
// row's tracker sees it (MeasurementFrames::measured).
void rowResidual(const FitRows& fit, size_t i, const MeasurementFrames& frames,
                 const Pose& X_modelled, Eigen::Index e, Eigen::VectorXd& r) {
  const Measurement& row = *fit.rows[i];
  const Pose X = frames.measured(row, X_modelled);
  r.segment<3>(e) = fit.w_p * (row.p_TipInTracker_m - X.translation());
  if (row.has_orientation) {
    r.segment<3>(e + 3) =
        fit.w_r * lie::logSO3(row.q_TrackerTip.toRotationMatrix() * X.linear().transpose());
  }
}

// The row functions evaluate the model with its constants (physicalConstants): the same values,
// without its initial poses made again per row.

// Fit rows [begin, end) of an evaluation whose equations start at equation `first` of the fit.
void evaluateRows(const PhysicalModel& model, const FitRows& fit, size_t begin, size_t end,
                  Eigen::Index first, ChainWorkspace& ws, Evaluation& out, size_t offset) {
  const PhysicalConstants constants = physicalConstants(model);
  const MeasurementFrames frames = measurementFramesOf(model);
  for (size_t i = begin; i < end; ++i) {
    const Measurement& row = *fit.rows[i];
    physicalLinkAngles(model, frames.commanded(row), row.wrenchOrZero(), rowTemperature(row),
                       {ws, out.theta_rad[i - offset], out.tau_nm[i - offset]}, {&constants});
    rowResidual(fit, i, frames, tipPose(ws), fit.start[i] - first, out.r);
  }
}

void residualRows(const PhysicalModel& model, const FitRows& fit, size_t begin, size_t end,
                  Eigen::Index first, ChainWorkspace& ws, Eigen::VectorXd& r) {
  const PhysicalConstants constants = physicalConstants(model);
  const MeasurementFrames frames = measurementFramesOf(model);
  JointVector theta, tau;
  for (size_t i = begin; i < end; ++i) {
    const Measurement& row = *fit.rows[i];
    physicalLinkAngles(model, frames.commanded(row), row.wrenchOrZero(), rowTemperature(row),
                       {ws, theta, tau}, {&constants});
    rowResidual(fit, i, frames, tipPose(ws), fit.start[i] - first, r);
  }
}

// Row i's linearisation (its equations from e) at the frames ws holds, r its residual there.
// A campaign's own station turns the twists into its tracker's axes, and its tool moves the point
// whose motion they give (the registration drift, small, is left out).
struct RowLinearisation {
  explicit RowLinearisation(int n) : P(6, 6 * (n + 1)) {}
  Eigen::Matrix<double, 6, Eigen::Dynamic> P;
  Jacobian J;
  void operator()(const KinematicChain& chain, const ChainWorkspace& ws,
                  const MeasurementFrames& frames, const FitRows& fit, size_t i, Eigen::Index e,
                  const Eigen::VectorXd& r, Linearisation& lin) {
    parameterJacobian(chain, ws, P);
    spatialJacobian(chain, ws, J);
    Vec3 p_Tip = tipPose(ws).translation();
    if (const StationAndTool* own = frames.ownFrames(*fit.rows[i])) {
      toStation(own->X_Station, P);
      toStation(own->X_Station, J);
      p_Tip = (own->X_Station * tipPose(ws) * own->X_Tool).translation();
    }
    const Mat3 p_hat = lie::hat(p_Tip);
    // Spatial twists (v, ω) → tip position ṗ = v − p̂ ω and rotation ω (docs/method.md, weighting).
    lin.geometry.middleRows<3>(e) = fit.w_p * (P.topRows<3>() - p_hat * P.bottomRows<3>());
    lin.link_angle.middleRows<3>(e) = fit.w_p * (J.topRows<3>() - p_hat * J.bottomRows<3>());
    if (fit.rows[i]->has_orientation) {
      const Mat3 Jr_inv = lie::rightJacobianInverseSO3(r.segment<3>(e + 3) / fit.w_r);
      lin.geometry.middleRows<3>(e + 3) = fit.w_r * Jr_inv * P.bottomRows<3>();
      lin.link_angle.middleRows<3>(e + 3) = fit.w_r * Jr_inv * J.bottomRows<3>();
    }
  }
};

// Links unscaled: a link scale that varies by row (thermal expansion) makes the geometry's gauge
// directions observable at α·ΔT ≈ 1e-4 of the others, and fits then step along them (a refit
// stalled, profiles took up noise); the Jacobian it leaves out is that small.
void lineariseRows(const PhysicalModel& model, const FitRows& fit, size_t begin, size_t end,
                   Eigen::Index first, const Eigen::VectorXd& r, ChainWorkspace& ws,
                   Linearisation& lin) {
  const PhysicalConstants constants = physicalConstants(model);
  const MeasurementFrames frames = measurementFramesOf(model);
  RowLinearisation row_linearisation(model.chain_Tracker.dof());
  JointVector theta, tau;
  for (size_t i = begin; i < end; ++i) {
    const Measurement& row = *fit.rows[i];
    physicalLinkAngles(model, frames.commanded(row), row.wrenchOrZero(), kUnscaledLinks,
                       {ws, theta, tau}, {&constants});
    row_linearisation(model.chain_Tracker, ws, frames, fit, i, fit.start[i] - first, r, lin);
  }
}

Linearisation sizedLinearisation(const PhysicalModel& model, Eigen::Index equations) {
  const int n = model.chain_Tracker.dof();
  Linearisation lin;
  lin.geometry.resize(equations, 6 * (n + 1));
  lin.link_angle.resize(equations, n);
  return lin;
}

}  // namespace

Evaluation evaluate(const PhysicalModel& model, const FitRows& fit) {
  Evaluation out;
  out.r.resize(fit.count);
  out.theta_rad.resize(fit.rows.size());
  out.tau_nm.resize(fit.rows.size());
  forEachBlock(fit, [&](size_t begin, size_t end, ChainWorkspace& ws) {
    evaluateRows(model, fit, begin, end, 0, ws, out, 0);
  });
  return out;
}

Evaluation evaluate(const PhysicalModel& model, const FitRows& fit, size_t begin, size_t end) {
  const Eigen::Index first = equationOf(fit, begin);
  Evaluation out;
  out.r.resize(equationOf(fit, end) - first);
  out.theta_rad.resize(end - begin);
  out.tau_nm.resize(end - begin);
  ChainWorkspace ws;
  evaluateRows(model, fit, begin, end, first, ws, out, begin);
  return out;
}

Eigen::VectorXd residuals(const PhysicalModel& model, const FitRows& fit) {
  Eigen::VectorXd r(fit.count);
  forEachBlock(fit, [&](size_t begin, size_t end, ChainWorkspace& ws) {
    residualRows(model, fit, begin, end, 0, ws, r);
  });
  return r;
}

Eigen::VectorXd residuals(const PhysicalModel& model, const FitRows& fit, size_t begin,
                          size_t end) {
  const Eigen::Index first = equationOf(fit, begin);
  Eigen::VectorXd r(equationOf(fit, end) - first);
  ChainWorkspace ws;
  residualRows(model, fit, begin, end, first, ws, r);
  return r;
}

Linearisation linearise(const PhysicalModel& model, const FitRows& fit, const Eigen::VectorXd& r) {
  Linearisation lin = sizedLinearisation(model, fit.count);
  forEachBlock(fit, [&](size_t begin, size_t end, ChainWorkspace& ws) {
    lineariseRows(model, fit, begin, end, 0, r, ws, lin);
  });
  return lin;
}

Eigen::MatrixXd differenceColumns(const std::vector<const PhysicalModel*>& models,
                                  const std::vector<double>& steps,
                                  const std::vector<bool>& needed, const FitRows& fit,
                                  size_t begin, size_t end, const Eigen::VectorXd& r0) {
  const Eigen::Index first = equationOf(fit, begin);
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(r0.size(), static_cast<Eigen::Index>(models.size()));
  std::vector<PhysicalConstants> constants;
  std::vector<MeasurementFrames> frames;
  for (const PhysicalModel* model : models) {
    constants.push_back(physicalConstants(*model));
    frames.push_back(measurementFramesOf(*model));
  }
  ChainWorkspace ws;
  JointVector theta, tau;
  Eigen::VectorXd r(6);
  for (size_t i = begin; i < end; ++i) {
    const Measurement& row = *fit.rows[i];
    const Eigen::Index e = fit.start[i] - first, k = fit.equations(i);
    FirstPass first_pass;
    FixedPointStart start;
    start.first_pass = &first_pass;
    for (size_t m = 0; m < models.size(); ++m) {
      if (!needed[m]) continue;
      physicalLinkAngles(*models[m], frames[m].commanded(row), row.wrenchOrZero(),
                         rowTemperature(row), {ws, theta, tau}, {&constants[m], &start});
      rowResidual(fit, i, frames[m], tipPose(ws), 0, r);
      out.block(e, static_cast<Eigen::Index>(m), k, 1) = (r0.segment(e, k) - r.head(k)) / steps[m];
    }
  }
  return out;
}

void evaluateAndLinearise(const PhysicalModel& model, const FitRows& fit, size_t begin,
                          size_t end, Evaluation& evaluation, Linearisation& lin) {
  const Eigen::Index first = equationOf(fit, begin);
  evaluation.r.resize(equationOf(fit, end) - first);
  evaluation.theta_rad.resize(end - begin);
  evaluation.tau_nm.resize(end - begin);
  lin = sizedLinearisation(model, evaluation.r.size());
  const PhysicalConstants constants = physicalConstants(model);
  const MeasurementFrames frames = measurementFramesOf(model);
  RowLinearisation row_linearisation(model.chain_Tracker.dof());
  ChainWorkspace ws;
  JointVector theta, tau;
  for (size_t i = begin; i < end; ++i) {
    const Measurement& row = *fit.rows[i];
    const double temp_c = rowTemperature(row);
    const JointVector q = frames.commanded(row);
    physicalLinkAngles(model, q, row.wrenchOrZero(), temp_c,
                       {ws, evaluation.theta_rad[i - begin], evaluation.tau_nm[i - begin]},
                       {&constants});
    const Eigen::Index e = fit.start[i] - first;
    rowResidual(fit, i, frames, tipPose(ws), e, evaluation.r);
    // Where the model scales no link at the row's temperature, its frames are the unscaled ones.
    if (model.linkLengthScale(temp_c) != 1.0) {
      physicalLinkAngles(model, q, row.wrenchOrZero(), kUnscaledLinks, {ws, theta, tau},
                         {&constants});
    }
    row_linearisation(model.chain_Tracker, ws, frames, fit, i, e, evaluation.r, lin);
  }
}

Linearisation linearise(const PhysicalModel& model, const FitRows& fit, size_t begin, size_t end,
                        const Eigen::VectorXd& r) {
  const Eigen::Index first = equationOf(fit, begin);
  Linearisation lin = sizedLinearisation(model, equationOf(fit, end) - first);
  ChainWorkspace ws;
  lineariseRows(model, fit, begin, end, first, r, ws, lin);
  return lin;
}

}  // namespace stepcal::trainer::diagnosis

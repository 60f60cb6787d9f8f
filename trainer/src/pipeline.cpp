#include "stepcal/trainer/pipeline.hpp"

#include <chrono>
#include <cstdio>
#include <ctime>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <string>

#include <Eigen/Eigenvalues>

#include "stepcal/common/compliance.hpp"
#include "stepcal/common/lie.hpp"

#include "stepcal/common/error.hpp"
#include "stepcal/common/gpr_predictor.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/trainer/registration.hpp"
#include "diagnose/cross_validation.hpp"

namespace stepcal::trainer {
namespace {

PoseModel chainModel(const KinematicChain& chain_Tracker) {
  return [chain_Tracker](const Measurement& row) {
    ChainWorkspace ws;
    forwardKinematics(chain_Tracker, row.q_rad, ws);
    return tipPose(ws);
  };
}

// The model of each session, chosen by the row's session (one session: its model).
PoseModel bySession(std::vector<PoseModel> models) {
  if (models.size() == 1) return std::move(models[0]);
  return [models = std::move(models)](const Measurement& row) {
    return models[static_cast<size_t>(row.session)](row);
  };
}

PoseModel chainModel(const std::vector<SessionFrames>& sessions) {
  std::vector<PoseModel> models;
  for (const SessionFrames& s : sessions) models.push_back(chainModel(s.chain_Tracker));
  return bySession(std::move(models));
}

// Evaluates a method on every row: its per-row errors and its summaries, over every row and,
// when the campaign merges several, over each session's rows.
void evaluate(CalibrationOutcome& out, const std::string& method, const PoseModel& model,
              const Campaign& campaign) {
  std::vector<RowError> errors = rowErrors(model, campaign.rows);
  const std::vector<AccuracySummary> summaries = summarize(method, campaign.rows, errors);
  out.accuracy.insert(out.accuracy.end(), summaries.begin(), summaries.end());
  out.session_accuracy.resize(campaign.sessions.size());
  for (size_t k = 0; k < campaign.sessions.size(); ++k) {
    const CampaignSession& session = campaign.sessions[k];
    const auto first = static_cast<std::ptrdiff_t>(session.first_row);
    const auto last = first + static_cast<std::ptrdiff_t>(session.row_count);
    const std::vector<Measurement> rows(campaign.rows.begin() + first, campaign.rows.begin() + last);
    const std::vector<RowError> own(errors.begin() + first, errors.begin() + last);
    const std::vector<AccuracySummary> mine = summarize(method, rows, own);
    out.session_accuracy[k].insert(out.session_accuracy[k].end(), mine.begin(), mine.end());
  }
  out.row_errors.emplace_back(method, std::move(errors));
}

// Modelled vs measured deflections of several sessions' pairs, per load over all of them.
std::vector<StiffnessValidation> mergedByLoad(const std::vector<std::vector<StiffnessValidation>>& parts) {
  std::map<double, StiffnessValidation> by_load;
  for (const std::vector<StiffnessValidation>& part : parts) {
    for (const StiffnessValidation& v : part) {
      StiffnessValidation& m = by_load[v.load_kg];
      m.load_kg = v.load_kg;
      m.mean_deviation_pct += v.mean_deviation_pct * v.pairs;
      m.mean_deflection_m += v.mean_deflection_m * v.pairs;
      m.max_deviation_pct = std::max(m.max_deviation_pct, v.max_deviation_pct);
      m.pairs += v.pairs;
    }
  }
  std::vector<StiffnessValidation> out;
  for (auto& [load, m] : by_load) {
    m.mean_deviation_pct /= m.pairs;
    m.mean_deflection_m /= m.pairs;
    out.push_back(m);
  }
  return out;
}

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

double rowTemperature(const Measurement& row) {
  return row.temp_c ? *row.temp_c : std::numeric_limits<double>::quiet_NaN();
}

PoseModel physicalPoseModel(PhysicalModel physical) {
  return [physical = std::move(physical)](const Measurement& row) {
    ChainWorkspace ws;
    JointVector theta, tau;
    physicalLinkAngles(physical, row.q_rad, row.wrenchOrZero(), rowTemperature(row),
                       {ws, theta, tau});
    return tipPose(ws);
  };
}

PoseModel withResidual(PoseModel base, const GaussianProcess& gp) {
  return [base = std::move(base), &gp](const Measurement& row) {
    const Pose X = base(row);
    Vec6 twist = gp.predictMean(gprInput(row));
    tipTwistFromGprOutput(gp.parameters(), X.linear(), twist);
    return Pose(X * lie::expSE3(twist));
  };
}

PoseModel withResidual(PoseModel base, const ResidualModel& residual) {
  return residual.taken ? withResidual(std::move(base), residual.gp) : base;
}

namespace {

// A row's payload force ‖f‖, N: the wrench's force as the sensor reads it.
double payloadForce(const Measurement& row) { return row.wrenchOrZero().head<3>().norm(); }

// The rows a residual GP learns from: with orientation and, per payload force, with a load.
std::vector<const Measurement*> residualRows(const std::vector<const Measurement*>& rows,
                                             ResidualTarget target) {
  std::vector<const Measurement*> usable;
  for (const Measurement* row : rows) {
    const bool loaded = row->load_kg > 0.0 && payloadForce(*row) > 0.0;
    if (row->has_orientation && (target == ResidualTarget::kResidual || loaded)) {
      usable.push_back(row);
    }
  }
  return usable;
}

// Whether the GP lowers the held-out error significantly (ResidualModel::taken), in the
// residual's units: row i's held-out residual and target times gain(i).
void judgeResidual(ResidualModel& out, const Eigen::MatrixXd& Y, const Eigen::VectorXd& gain,
                   const Eigen::VectorXd& stated, int folds) {
  const Eigen::RowVectorXd weight = stated.array().square().inverse().matrix().transpose();
  const Eigen::MatrixXd held_out_twist =
      gain.asDiagonal() * out.gp.crossValidationResiduals(folds);
  const Eigen::MatrixXd twist = gain.asDiagonal() * Y;
  const Eigen::VectorXd held_out =
      (held_out_twist.array().square().rowwise() * weight.array()).rowwise().sum();
  const Eigen::VectorXd uncorrected = (twist.array().square().rowwise() * weight.array()).rowwise().sum();
  out.cv_error = held_out.mean();
  out.uncorrected_error = uncorrected.mean();
  out.z_statistic = diagnosis::signedRankZ(
      std::vector<double>(uncorrected.data(), uncorrected.data() + uncorrected.size()),
      std::vector<double>(held_out.data(), held_out.data() + held_out.size()));
  out.taken = out.z_statistic > kGprTakenZ;
}

}  // namespace

ResidualModel fitResidual(const PoseModel& model, const std::vector<const Measurement*>& rows,
                          const std::string& set_name, const TrackerNoise& noise,
                          const CalibrationOptions& options, ResidualTarget target) {
  const bool per_force = target == ResidualTarget::kPerPayloadForce;
  const std::vector<const Measurement*> usable = residualRows(rows, target);
  if (usable.size() < 2) {
    throw InputError("step 3 needs at least 2 " + set_name + " rows with orientation (qw..qz)" +
                     (per_force ? " and a load read by the sensor" : "") +
                     " to learn the 6-D residual");
  }
  const size_t m = std::min(usable.size(), static_cast<size_t>(options.gpr_max_points));
  const Eigen::Index D = gprInput(*usable[0]).size();
  Eigen::MatrixXd X(static_cast<Eigen::Index>(m), D), Y(static_cast<Eigen::Index>(m), 6);
  Eigen::VectorXd gain = Eigen::VectorXd::Ones(static_cast<Eigen::Index>(m));
  double reference_n = 0.0;
  for (size_t i = 0; i < m; ++i) {
    const Measurement& row = *usable[i * usable.size() / m];
    X.row(static_cast<Eigen::Index>(i)) = gprInput(row).transpose();
    const Pose X = model(row);
    Vec6 twist = lie::logSE3(X.inverse() * row.X_TrackerTip());
    if (per_force) {
      twist.head<3>() = X.linear() * twist.head<3>().eval();  // in the tracker's axes (eq. 30a)
      twist.tail<3>() = X.linear() * twist.tail<3>().eval();
      gain(static_cast<Eigen::Index>(i)) = payloadForce(row);
    }
    Y.row(static_cast<Eigen::Index>(i)) = twist.transpose();
  }
  if (per_force) {
    reference_n = gain.mean();
    gain /= reference_n;
    Y = gain.cwiseInverse().asDiagonal() * Y;  // the residual per payload force
  }
  // The twist's noise per output: the tip's position error (v, in tip axes) and its rotation (ω);
  // per payload force, the least a row's target carries (the largest force's).
  Eigen::VectorXd stated(6);
  stated << Eigen::Vector3d::Constant(noise.position_sigma_m),
      Eigen::Vector3d::Constant(noise.orientation_sigma_rad);
  GprOptions gpr = options.gpr;
  if (gpr.output_noise_sigma.size() == 0) gpr.output_noise_sigma = stated;
  stated = gpr.output_noise_sigma;
  if (per_force) gpr.output_noise_sigma = stated / gain.maxCoeff();
  gpr.payload_force_reference_n = reference_n;
  if (gpr.cv_folds < 2) gpr.cv_folds = 10;  // the choice below needs it
  GprFitReport report;
  GaussianProcess gp = GaussianProcess::fit(X, Y, gpr, &report);
  ResidualModel out{std::move(gp), std::move(report), static_cast<int>(m), set_name};
  judgeResidual(out, Y, gain, stated, gpr.cv_folds);
  return out;
}

KinematicChain campaignChain(const Campaign& campaign, int* sensor_frame) {
  const std::string source =
      campaign.directory.empty() ? campaign.robot_file : campaign.directory + "/" + campaign.robot_file;
  std::vector<std::string> attached;
  if (!campaign.sensor_link.empty()) attached.push_back(campaign.sensor_link);
  if (!campaign.flange_link.empty()) attached.push_back(campaign.flange_link);
  KinematicChain chain =
      chainFromUrdf(campaign.urdf_xml, campaign.base_link, campaign.tip_link, attached, source);
  if (!campaign.flange_link.empty()) {
    // The model names its flange by the frame's name, whatever the link's (runtime kFlangeFrame).
    std::vector<AttachedFrame> frames = chain.frames();
    frames.back().name = kFlangeFrameName;
    chain = KinematicChain(chain.joints(), chain.initialPoses(), frames);
  }
  if (chain.dof() != campaign.joint_count) {
    throw InputError("the robot chain from '" + campaign.base_link + "' to '" + campaign.tip_link +
                         "' has " + std::to_string(chain.dof()) +
                         " revolute joints but measurements.csv has q1_deg..q" +
                         std::to_string(campaign.joint_count) + "_deg",
                     source);
  }
  if (sensor_frame) *sensor_frame = campaign.sensor_link.empty() ? -1 : 0;
  return chain;
}

Eigen::VectorXd gprInput(const Measurement& row) {
  Eigen::VectorXd x(row.q_rad.size() + 6);
  x << row.q_rad, row.wrenchOrZero();
  return x;
}

namespace {

// A session's rows among rows.
std::vector<const Measurement*> ofSession(const std::vector<const Measurement*>& rows, int session) {
  std::vector<const Measurement*> out;
  for (const Measurement* row : rows) {
    if (row->session == session) out.push_back(row);
  }
  return out;
}

// A session's stiffness rows and the unloaded geometry rows of their poses: a planned campaign
// (readPoseList) measures each pose once unloaded, for step 1 and as the loads' reference.
std::vector<const Measurement*> stiffnessPairRows(const Campaign& campaign, int session) {
  std::vector<const Measurement*> rows = ofSession(campaign.rowsIn(RowSet::kStiffness), session);
  std::set<std::string> loaded_poses;
  for (const Measurement* row : rows) loaded_poses.insert(row->pose_id);
  for (const Measurement* row : ofSession(campaign.rowsIn(RowSet::kGeometry), session)) {
    if (row->load_kg == 0.0 && loaded_poses.count(row->pose_id) > 0) rows.push_back(row);
  }
  return rows;
}

}  // namespace

namespace {

// The model's accuracy factors (model_file.hpp): the step-1 and step-2 fits' covariances as
// factors and the tracker's stated noise.
AccuracyFactors accuracyFactors(const Campaign& campaign, const CalibrationOutcome& outcome) {
  AccuracyFactors a;
  a.position_noise_m = campaign.tracker.position_sigma_m;
  a.orientation_noise_rad = campaign.tracker.orientation_sigma_rad;
  a.geometry_factor = outcome.poe.covariance_factor;
  if (outcome.has_stiffness && outcome.stiffness.compliance_covariance.size() > 0) {
    // Σ = V Λ Vᵀ = (V √Λ)(V √Λ)ᵀ: a factor of a covariance that may be singular (rigid joints).
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(
        outcome.stiffness.compliance_covariance);
    a.compliance_factor =
        eigen.eigenvectors() * eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
  }
  return a;
}

}  // namespace

CalibrationOutcome calibrateCampaign(const Campaign& campaign, const CalibrationOptions& options) {
  CalibrationOutcome out;
  auto clock = std::chrono::steady_clock::now();
  out.nominal_Base = campaignChain(campaign, &out.sensor_frame);
  const std::vector<const Measurement*> fit = campaign.rowsIn(RowSet::kGeometry);
  const int session_count = campaign.sessionCount();
  std::vector<GeometricSession> sessions;
  for (int k = 0; k < session_count; ++k) {
    sessions.push_back({ofSession(fit, k), campaign.trackerOf(k)});
    if (sessions.back().rows.empty()) {
      throw InputError("no row has set=geometry; step 1 needs unloaded geometry rows to fit on" +
                           std::string(session_count > 1 ? " (and to register this campaign's "
                                                           "tracker in a multi-campaign fit)"
                                                         : ""),
                       campaign.directoryOf(k) + "/" + campaign.measurements_file);
    }
  }
  out.X_TrackerBase_nominal = registerTracker(out.nominal_Base, sessions[0].rows);
  GeometricOptions frames_options = options.geometric;
  frames_options.scope = GeometricScope::kFramesOnly;
  out.frames = calibrateGeometry(out.nominal_Base, sessions, frames_options);
  GeometricOptions poe_options = options.geometric;
  poe_options.scope = GeometricScope::kFullPoe;
  out.poe = calibrateGeometry(out.nominal_Base, sessions, poe_options);
  out.session_differences = testSessionDifferences(out.nominal_Base, sessions, poe_options);
  // A campaign keeps its own value of a joint frame only where the held-out test demands it: a
  // significant difference that removes a practical share of the held-out error (keepsOwnFrame).
  std::vector<int> own_frames;
  for (const SessionDifference& d : out.session_differences) {
    if (d.kept_per_session) own_frames.push_back(d.frame);
  }
  if (!own_frames.empty()) {
    poe_options.own_frames = own_frames;
    out.poe = calibrateGeometry(out.nominal_Base, sessions, poe_options);
  }
  out.seconds_geometry = secondsSince(clock);

  // Step 2 where the campaign has loaded/unloaded pairs and a sensor: one compliance for the
  // robot from every session's pairs, each seen through its own frames.
  clock = std::chrono::steady_clock::now();
  const KinematicChain& chain = out.poe.chain_Tracker;
  std::vector<StiffnessSession> stiffness_sessions;
  size_t pair_count = 0;
  for (int k = 0; k < session_count; ++k) {
    stiffness_sessions.push_back({&out.poe.sessions[static_cast<size_t>(k)].chain_Tracker,
                                  deflectionPairs(stiffnessPairRows(campaign, k)),
                                  campaign.trackerOf(k)});
    pair_count += stiffness_sessions.back().pairs.size();
  }
  JointVector compliance = JointVector::Zero(chain.dof());
  if (pair_count > 0 && out.sensor_frame >= 0) {
    out.stiffness = identifyCompliance(stiffness_sessions, out.sensor_frame, options.stiffness);
    out.has_stiffness = true;
    compliance = out.stiffness.compliance_rad_per_nm;
    std::vector<std::vector<StiffnessValidation>> validation;
    for (int k = 0; k < session_count; ++k) {
      validation.push_back(validateCompliance(
          *stiffness_sessions[static_cast<size_t>(k)].chain_Tracker, out.sensor_frame, compliance,
          deflectionPairs(ofSession(campaign.rowsIn(RowSet::kValidation), k))));
    }
    out.stiffness_validation = session_count == 1 ? validation[0] : mergedByLoad(validation);
  }
  if (session_count > 1) {
    if (out.has_stiffness) {
      out.compliance_differences =
          testComplianceDifferences(stiffness_sessions, out.sensor_frame, out.stiffness);
    } else {
      out.compliance_differences.not_tested =
          out.sensor_frame < 0 ? "the campaigns name no sensor_link" : "no campaign has loaded pairs";
    }
  }
  out.seconds_stiffness = secondsSince(clock);

  // Step 3 on the residual rows (or, lacking them, on the geometry rows step 1 fitted).
  clock = std::chrono::steady_clock::now();
  std::vector<const Measurement*> residual_rows = campaign.rowsIn(RowSet::kResidual);
  std::string residual_set = "residual";
  if (residual_rows.empty()) {
    residual_rows = fit;
    residual_set = "geometry";
  }
  const PoseModel poe_model = chainModel(out.poe.sessions);
  std::vector<PoseModel> physical_sessions;
  for (const SessionFrames& session : out.poe.sessions) {
    PhysicalModel parts;
    parts.chain_Tracker = session.chain_Tracker;
    parts.sensor_frame = out.sensor_frame;
    parts.compliance_rad_per_nm = compliance;
    physical_sessions.push_back(physicalPoseModel(std::move(parts)));
  }
  const PoseModel physical = out.has_stiffness ? bySession(std::move(physical_sessions)) : poe_model;
  out.gpr = fitResidual(physical, residual_rows, residual_set, campaign.tracker, options);
  out.accuracy_factors = accuracyFactors(campaign, out);
  if (!out.gpr->taken) raiseNoiseToResidual(out.accuracy_factors, physical, residual_rows);
  if (out.has_stiffness) {
    out.gpr_baseline = fitResidual(poe_model, residual_rows, residual_set, campaign.tracker, options);
  }
  out.seconds_gpr = secondsSince(clock);

  std::vector<PoseModel> nominal;
  for (const SessionFrames& session : out.poe.sessions) {
    nominal.push_back(chainModel(out.nominal_Base.rerooted(session.X_TrackerBase)));
  }
  evaluate(out, kMethodNominal, bySession(std::move(nominal)), campaign);
  evaluate(out, kMethodFrames, chainModel(out.frames.sessions), campaign);
  evaluate(out, kMethodPoe, poe_model, campaign);
  if (out.has_stiffness) {
    evaluate(out, kMethodPoeStiffness, physical, campaign);
    evaluate(out, kMethodPoeGpr, withResidual(poe_model, *out.gpr_baseline), campaign);
    evaluate(out, kMethodPoeStiffnessGpr, withResidual(physical, *out.gpr), campaign);
  } else {
    evaluate(out, kMethodPoeGpr, withResidual(poe_model, *out.gpr), campaign);
  }
  out.floor_position_m = noiseFloorMean(campaign.tracker.position_sigma_m);
  out.floor_orientation_rad = noiseFloorMean(campaign.tracker.orientation_sigma_rad);
  return out;
}

std::vector<std::pair<std::string, PoseModel>> modelLayers(const CalibratedModel& model) {
  std::vector<std::pair<std::string, PoseModel>> layers;
  PoseModel physical = chainModel(model.chain_Tracker);
  const bool stiffness = model.compliance_rad_per_nm.size() > 0 && model.sensor_frame >= 0;
  const bool extended = !model.mechanisms.empty();
  // An extended model's chain was fitted with its mechanisms: alone it is no model of the robot.
  if (!extended) layers.emplace_back(kMethodPoe, physical);
  if (stiffness || extended) {
    physical = physicalPoseModel(physicalModelOf(model));
    layers.emplace_back(extended ? kMethodExtended : kMethodPoeStiffness, physical);
  }
  if (model.gpr) {
    const Eigen::Index inputs = model.gpr->inputs_normalised.cols();
    const Eigen::Index outputs = model.gpr->alpha.cols();
    if (inputs != model.chain_Tracker.dof() + 6 || outputs != 6) {
      throw InputError("the model's GPR maps " + std::to_string(inputs) + " inputs to " +
                       std::to_string(outputs) + " outputs; expected (q, wrench) to the residual "
                       "twist, " + std::to_string(model.chain_Tracker.dof() + 6) + " to 6");
    }
    auto gpr = std::make_shared<const GprPredictor>(GprPredictor::fromParameters(*model.gpr));
    layers.emplace_back(extended    ? kMethodExtendedGpr
                        : stiffness ? kMethodPoeStiffnessGpr
                                    : kMethodPoeGpr,
                        [physical, gpr](const Measurement& row) {
                          GprPredictor::Workspace workspace = gpr->makeWorkspace();
                          Vec6 residual;
                          gpr->predictInto(gprInput(row).data(), residual.data(), nullptr,
                                           workspace);
                          const Pose X = physical(row);
                          tipTwistFromGprOutput(gpr->parameters(), X.linear(), residual);
                          return Pose(X * lie::expSE3(residual));
                        });
  }
  return layers;
}

std::string campaignHash(const Campaign& campaign) {
  uint64_t h = 1469598103934665603ull;
  auto mix = [&h](const void* data, size_t size) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < size; ++i) {
      h ^= bytes[i];
      h *= 1099511628211ull;
    }
  };
  mix(campaign.urdf_xml.data(), campaign.urdf_xml.size());
  for (const std::string* s : {&campaign.base_link, &campaign.tip_link, &campaign.sensor_link}) {
    mix(s->data(), s->size() + 1);  // the terminator separates the fields
  }
  for (const Measurement& m : campaign.rows) {
    mix(&m.seq, sizeof m.seq);
    mix(m.pose_id.data(), m.pose_id.size() + 1);
    mix(&m.set, sizeof m.set);
    mix(&m.load_kg, sizeof m.load_kg);
    mix(m.q_rad.data(), sizeof(double) * static_cast<size_t>(m.q_rad.size()));
    mix(m.wrench_Sensor.data(), sizeof(double) * 6);
    mix(m.p_TipInTracker_m.data(), sizeof(double) * 3);
    mix(m.q_TrackerTip.coeffs().data(), sizeof(double) * 4);
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}


CalibratedModel modelFromOutcome(const Campaign& campaign, const CalibrationOutcome& outcome) {
  CalibratedModel model;
  model.chain_Tracker = outcome.poe.chain_Tracker;
  model.nominal_Base = outcome.nominal_Base;
  model.X_TrackerBase = outcome.poe.X_TrackerBase;
  model.sensor_frame = outcome.sensor_frame;
  model.gravity_Base = campaign.gravity_in_base.value_or(Vec3(0.0, 0.0, -9.80665));
  if (outcome.has_stiffness) {
    model.compliance_rad_per_nm = outcome.stiffness.compliance_rad_per_nm;
    model.compliance_sigma_rad_per_nm = outcome.stiffness.compliance_sigma_rad_per_nm;
  }
  if (outcome.gpr && outcome.gpr->taken) model.gpr = outcome.gpr->gp.parameters();
  model.accuracy = outcome.accuracy_factors;
  model.provenance.campaign_hash = campaignHash(campaign);
  model.provenance.campaign_path = campaign.directory;
  model.provenance.trainer_version = STEPCAL_VERSION;
  char when[32];
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  std::strftime(when, sizeof when, "%Y-%m-%dT%H:%M:%SZ", &utc);
  model.provenance.created_utc = when;
  for (const AccuracySummary& s : outcome.accuracy) {
    if (s.set != RowSet::kValidation) continue;
    model.provenance.validation.push_back({s.method, s.load_kg, s.rows, s.mean_position_m,
                                           s.max_position_m, s.mean_orientation_rad});
  }
  return model;
}

}  // namespace stepcal::trainer

// The extended model and its gain on the validation rows (search.hpp).
#include <algorithm>
#include <chrono>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "../least_squares.hpp"
#include "search.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/mechanisms/registration_drift.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// A row as the tracker would have measured it standing as it last stood, the extended model's
// tracker frame (X_FittedLast; drift: the found model's, or null: the row as measured). Rows after
// the fit rows were measured by the tracker as it went on standing, which that frame stands for:
// they are taken as measured, so the held-out error here is the one `stepcal validate` gives on
// the model file (one definition; the drift's value at the last fit row gave another).
Measurement withoutDrift(Measurement row, const Mechanism* drift) {
  if (drift == nullptr) return row;
  const double last_fit_seq = view<mechanism::RegistrationDrift>(*drift).lastSeq();
  if (static_cast<double>(row.seq) > last_fit_seq) return row;
  const Pose X_Undrift =
      X_FittedLast(*drift) * lie::expSE3(-registrationDrift(*drift, static_cast<double>(row.seq)));
  row.p_TipInTracker_m = X_Undrift * row.p_TipInTracker_m;
  row.q_TrackerTip = Eigen::Quaterniond(X_Undrift.linear() * row.q_TrackerTip.toRotationMatrix());
  return row;
}

std::vector<Measurement> validationRows(const Campaign& campaign, const Mechanism* drift) {
  std::vector<Measurement> rows;
  for (const Measurement& m : campaign.rows) {
    if (m.set == RowSet::kValidation) rows.push_back(withoutDrift(m, drift));
  }
  return rows;
}

// A row of a later campaign as the first campaign's tracker would have measured it with the first
// campaign's tool, by that campaign's own frames (at the modelled orientation where the row has
// none): the rows the extended model's GPR learns from.
Measurement inFirstCampaignTerms(Measurement row, const MeasurementFrames& frames,
                                 const PoseModel& model) {
  row.q_rad = frames.commanded(row);
  const StationAndTool* own = frames.ownFrames(row);
  if (own == nullptr) return row;
  if (row.has_orientation) {
    const Pose X = own->X_Station.inverse() * row.X_TrackerTip() * own->X_Tool.inverse();
    row.p_TipInTracker_m = X.translation();
    row.q_TrackerTip = Eigen::Quaterniond(X.linear());
  } else {
    row.p_TipInTracker_m = own->X_Station.inverse() * row.p_TipInTracker_m -
                           model(row).linear() * own->X_Tool.translation();
  }
  return row;
}

// Singular values below this fraction of the largest are unobservable. Above step 1's 1e-9: the
// POE's structural redundancies sit at rounding level on a plain chain, but a mechanism that reads
// the chain's frames (an off-axis compliance) lifts two of them to about 3e-8, where a step
// carries no information and its second-order terms run the refit off; the observable directions
// stand at 1e-2 and above (tests/test_diagnose_load_effects.cpp, ...InBlocksLeavesNoLoadWorse).
constexpr double kPinRankTolerance = 1e-6;
// Gauss–Newton steps of the geometry on the unloaded rows: it starts beside its optimum.
constexpr int kPinIterations = 8;
// The F statistic above which the unloaded rows reject the global fit's geometry: far in the
// tail of F(rank, equations − rank) (its 99.9 % point is about 2 for 30 directions and 500
// equations), so a model the data fit is not moved.
constexpr double kPinF = 3.0;

// The geometry alone refitted on rows by Gauss–Newton steps, the rest of the model held; the
// identifiable directions' count in *rank.
PhysicalModel geometryRefitted(PhysicalModel model, const FitRows& rows, int* rank) {
  Eigen::VectorXd r = residuals(model, rows);
  for (int it = 0; it < kPinIterations; ++it) {
    const Eigen::MatrixXd A = linearise(model, rows, r).geometry;
    TallQr system(A.cols());
    system.add(A, r);
    const SvdSolution s = solveReduced(system, kPinRankTolerance);
    *rank = s.rank;
    bool improved = false;
    for (double fraction = 1.0; fraction > 1e-3 && !improved; fraction *= 0.5) {
      PhysicalModel candidate = model;
      candidate.chain_Tracker = model.chain_Tracker.corrected(fraction * s.x);
      const Eigen::VectorXd r_candidate = residuals(candidate, rows);
      if (r_candidate.squaredNorm() < r.squaredNorm()) {
        improved = r.squaredNorm() - r_candidate.squaredNorm() > 1e-6 * r.squaredNorm();
        model = std::move(candidate);
        r = r_candidate;
        if (!improved) return model;
        break;
      }
    }
    if (!improved) break;
  }
  return model;
}

// How far the pinned geometry moves the modelled tip from the found one over the fit rows: the
// position part of the two residuals' difference, unweighted.
void tipShift(const PhysicalModel& found, const PhysicalModel& pinned, const FitRows& fit,
              GeometryPin& pin) {
  const Eigen::VectorXd shift = residuals(found, fit) - residuals(pinned, fit);
  double sum = 0.0;
  for (size_t i = 0; i < fit.rows.size(); ++i) {
    const double d_m = shift.segment(fit.start[i], 3).norm() / fit.w_p;
    sum += d_m * d_m;
    pin.tip_shift_max_m = std::max(pin.tip_shift_max_m, d_m);
  }
  if (!fit.rows.empty()) pin.tip_shift_rms_m = std::sqrt(sum / static_cast<double>(fit.rows.size()));
}

// The paper's step 1 within the extended model: where the unloaded fit rows reject the geometry
// the global fit found on every fit row (a load effect the catalogue cannot explain leaked into
// it), the geometry they alone give, the mechanisms held; the loaded rows' rest is the GPR's.
PhysicalModel pinnedToUnloaded(const PhysicalModel& found, const Search& search,
                               const TrackerNoise& noise, GeometryPin& pin) {
  std::vector<const Measurement*> unloaded;
  for (const Measurement* row : search.fit.rows) {
    if (row->load_kg == 0.0) unloaded.push_back(row);
  }
  pin = GeometryPin();
  pin.unloaded_rows = static_cast<int>(unloaded.size());
  if (unloaded.empty() || unloaded.size() == search.fit.rows.size()) return found;
  const FitRows rows = makeFitRows(unloaded, noise, search.fit.folds);
  const double cost_found = residuals(found, rows).squaredNorm();
  PhysicalModel pinned = geometryRefitted(found, rows, &pin.rank);
  const double cost_pinned = residuals(pinned, rows).squaredNorm();
  const int dof = rows.count - pin.rank;
  pin.tested = pin.rank > 0 && dof > 0 && cost_pinned > 0.0;
  if (!pin.tested) return found;
  pin.f_statistic = ((cost_found - cost_pinned) / pin.rank) / (cost_pinned / dof);
  pin.f_limit = kPinF;
  pin.pinned = pin.f_statistic > kPinF;
  tipShift(found, pinned, search.fit, pin);
  return pin.pinned ? pinned : found;
}

// What the extended model's GPR learns: where its rows carry loads, the residual per payload
// force, so that a load effect outside the catalogue is smooth in its inputs (one linear in the
// payload: a function of the pose alone) and an unloaded row is never moved (docs/method.md
// eq. 30a); rows without loads, the residual itself.
ResidualTarget extendedResidualTarget(const std::vector<const Measurement*>& rows) {
  int loaded = 0;
  for (const Measurement* row : rows) {
    if (row->has_orientation && row->load_kg > 0.0 && row->wrenchOrZero().head<3>().norm() > 0.0) {
      ++loaded;
    }
  }
  return loaded >= 2 ? ResidualTarget::kPerPayloadForce : ResidualTarget::kResidual;
}

// A model of the first campaign's tracker, tool and readings, each row seen from its own
// campaign's.
PoseModel inOwnFrames(PoseModel model, MeasurementFrames frames) {
  frames.drift = nullptr;
  if (frames.sessions.empty() && frames.zero_offset_rad.empty()) return model;
  return [model = std::move(model), frames = std::move(frames)](const Measurement& row) {
    Measurement as_first = row;
    as_first.q_rad = frames.commanded(row);
    return frames.measured(row, model(as_first));
  };
}

// The extended model's measurement noise in its accuracy factors (it keeps the starting model's
// parameter factors): the tracker's, raised to the extended physical model's residual scatter on
// the fit rows its GPR does not take. None taken: every row it would have learned from. A GPR per
// payload force moves no unloaded row and states at a load its own noise and variance, growing
// with the force (its output gain): the unloaded fit rows' scatter, seen as the GPR's rows are
// (asFirst). Raised to the loaded rows' scatter instead, the residual the GPR takes would be
// stated again at every load, the unloaded one included.
void statedNoiseOfExtended(AccuracyFactors& factors, const Campaign& campaign,
                           const ResidualModel& residual, const PoseModel& after,
                           const std::vector<const Measurement*>& gpr_rows,
                           const std::function<Measurement(const Measurement&)>& asFirst) {
  factors.position_noise_m = campaign.tracker.position_sigma_m;
  factors.orientation_noise_rad = campaign.tracker.orientation_sigma_rad;
  if (!residual.taken) {
    raiseNoiseToResidual(factors, after, gpr_rows);
    return;
  }
  if (residual.gp.parameters().payload_force_reference_n <= 0.0) return;
  std::vector<Measurement> unloaded;
  for (const Measurement& row : campaign.rows) {
    const bool loaded = row.load_kg > 0.0 && row.wrenchOrZero().head<3>().norm() > 0.0;
    if (row.set != RowSet::kValidation && !loaded) unloaded.push_back(asFirst(row));
  }
  std::vector<const Measurement*> unloaded_rows;
  for (const Measurement& row : unloaded) unloaded_rows.push_back(&row);
  raiseNoiseToResidual(factors, after, unloaded_rows);
}

/// Each transmission profile's coefficients' covariance as its factor V √Λ (over the eigenvalues
/// above 1e-14 of the largest), for the transmission_error of its joint among `mechanisms` where
/// that holds the coefficients and σ of the fit the covariance is from (else its σ stand alone).
std::vector<ProfileCovarianceFactor> profileFactors(const std::vector<Profile>& profiles,
                                                    const std::vector<Mechanism>& mechanisms) {
  std::vector<ProfileCovarianceFactor> factors;
  for (size_t k = 0; k < mechanisms.size(); ++k) {
    const Mechanism& m = mechanisms[k];
    if (m.kind != MechanismKind::kTransmissionError) continue;
    for (const Profile& p : profiles) {
      const Eigen::MatrixXd& covariance = p.coefficient_covariance;
      if (p.mechanism.joint != m.joint || covariance.rows() != 2 * m.order ||
          p.mechanism.parameters != m.parameters) {
        continue;
      }
      bool its_fit = true;
      for (Eigen::Index i = 0; i < covariance.rows(); ++i) {
        its_fit = its_fit && std::sqrt(std::max(0.0, covariance(i, i))) == m.sigma[size_t(i)];
      }
      if (!its_fit) continue;
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(covariance);
      const Eigen::VectorXd& lambda = eigen.eigenvalues();  // ascending
      Eigen::Index kept = 0;
      while (kept < lambda.size() && lambda(lambda.size() - 1 - kept) > 1e-14 * lambda.maxCoeff()) {
        ++kept;
      }
      factors.push_back({static_cast<uint32_t>(k), eigen.eigenvectors().rightCols(kept) *
                                                       lambda.tail(kept).cwiseSqrt().asDiagonal()});
    }
  }
  return factors;
}

}  // namespace

void extendAndEvaluate(const Campaign& campaign, const CalibratedModel& model,
                       const PhysicalModel& found, Search& search) {
  const DiagnoseOptions& options = search.options;
  Diagnosis& d = search.d;
  const PhysicalModel extended_found = pinnedToUnloaded(found, search, campaign.tracker, d.geometry_pin);
  // The robot's part of what was found: a drift of the tracker is the campaign's, never a
  // correction. The rows the GPR learns from and the validation rows are judged as the tracker
  // would have measured them had it stood as at the last fit row (withoutDrift). Several
  // campaigns' own stations and tools are theirs too: the model's are the first campaign's.
  const Mechanism* drift = nullptr;
  for (const Mechanism& m : extended_found.mechanisms) {
    if (m.kind == MechanismKind::kRegistrationDrift) drift = &m;
  }
  const MeasurementFrames found_frames = measurementFramesOf(extended_found);
  PhysicalModel extended_physical = extended_found;
  auto& mechanisms = extended_physical.mechanisms;
  mechanisms.erase(std::remove_if(mechanisms.begin(), mechanisms.end(),
                                  [](const Mechanism& m) { return isMeasurementOnly(m.kind); }),
                   mechanisms.end());
  // The model's tracker frame is the tracker as it last stood (the one a user measures in next),
  // its base unmoved: the tracker registration and the chain's root move together.
  Pose X_TrackerBase = model.X_TrackerBase;
  if (drift != nullptr) {
    const Pose X_Last = X_FittedLast(*drift);
    KinematicChain& chain = extended_physical.chain_Tracker;
    chain.setInitialPose(0, X_Last * chain.initialPose(0));
    extended_physical.gravity_Tracker = X_Last.linear() * extended_physical.gravity_Tracker;
    X_TrackerBase = X_Last * X_TrackerBase;
  }
  const int n = extended_physical.chain_Tracker.dof();
  auto clock = std::chrono::steady_clock::now();
  CalibratedModel& ext = d.extended_model;
  ext = model;
  ext.chain_Tracker = extended_physical.chain_Tracker;
  ext.X_TrackerBase = X_TrackerBase;
  ext.mechanisms = extended_physical.mechanisms;
  if (ext.accuracy) ext.accuracy->profile_factors = profileFactors(search.model.profiles, ext.mechanisms);
  const bool any_compliance = extended_physical.compliance_rad_per_nm.maxCoeff() > 0.0;
  if (model.compliance_rad_per_nm.size() == n || any_compliance) {
    ext.compliance_rad_per_nm = extended_physical.compliance_rad_per_nm;
    ext.compliance_sigma_rad_per_nm = search.compliance_sigma;
  }
  std::vector<const Measurement*> gpr_rows = campaign.rowsIn(RowSet::kResidual);
  std::string gpr_set = "residual";
  if (gpr_rows.empty()) {
    gpr_rows = campaign.rowsIn(RowSet::kGeometry);
    gpr_set = "geometry";
  }
  const PoseModel after = physicalPoseModel(extended_physical);
  std::vector<Measurement> as_first;
  if (drift != nullptr || !found_frames.sessions.empty() || !found_frames.zero_offset_rad.empty()) {
    for (const Measurement* row : gpr_rows) {
      as_first.push_back(inFirstCampaignTerms(withoutDrift(*row, drift), found_frames, after));
    }
    for (size_t i = 0; i < as_first.size(); ++i) gpr_rows[i] = &as_first[i];
  }
  const ResidualModel residual = fitResidual(after, gpr_rows, gpr_set, campaign.tracker,
                                             options.calibration, extendedResidualTarget(gpr_rows));
  ext.gpr.reset();
  if (residual.taken) ext.gpr = residual.gp.parameters();
  if (ext.accuracy) {
    statedNoiseOfExtended(*ext.accuracy, campaign, residual, after, gpr_rows, [&](const Measurement& row) {
      return inFirstCampaignTerms(withoutDrift(row, drift), found_frames, after);
    });
  }
  d.extended_gpr_rows = residual.training_rows;
  d.extended_gpr_z = residual.z_statistic;
  d.extended_gpr_taken = residual.taken;
  d.seconds_gpr = secondsSince(clock);

  clock = std::chrono::steady_clock::now();
  const std::vector<Measurement> validation = validationRows(campaign, drift);
  d.validation_rows = static_cast<int>(validation.size());
  d.floor_position_m = noiseFloorMean(campaign.tracker.position_sigma_m);
  if (!validation.empty()) {
    // Each model sees a later campaign's rows through its own fit of that campaign's frames.
    PhysicalModel starting;  // the frames alone: the given model's fit of each campaign's
    starting.mechanisms = search.starting_frames;
    const MeasurementFrames before_frames = measurementFramesOf(starting);
    const auto base_layers = modelLayers(model);
    const PoseModel before = inOwnFrames(physicalPoseModel(physicalModelOf(model)), before_frames);
    const bool has_gpr = model.gpr.has_value();
    d.gpr_method = has_gpr ? base_layers.back().first : "";
    const auto s_before = summarize("before", before, validation);
    const auto s_after = summarize(kMethodExtended, inOwnFrames(after, found_frames), validation);
    const auto s_after_gpr = summarize(
        kMethodExtendedGpr, inOwnFrames(withResidual(after, residual), found_frames), validation);
    std::vector<AccuracySummary> s_gpr;
    if (has_gpr) {
      s_gpr = summarize(d.gpr_method, inOwnFrames(base_layers.back().second, before_frames),
                        validation);
    }
    for (size_t g = 0; g < s_before.size(); ++g) {
      GainRow row;
      row.load_kg = s_before[g].load_kg;
      row.rows = s_before[g].rows;
      row.before = s_before[g];
      row.after = s_after[g];
      row.after_gpr = s_after_gpr[g];
      if (has_gpr) row.gpr = s_gpr[g];
      d.gain.push_back(row);
    }
    ext.provenance.validation.clear();
    for (const auto& [method, layer] : modelLayers(ext)) {
      for (const AccuracySummary& s :
           summarize(method, inOwnFrames(layer, found_frames), validation)) {
        ext.provenance.validation.push_back({s.method, s.load_kg, s.rows, s.mean_position_m,
                                             s.max_position_m, s.mean_orientation_rad});
      }
    }
  }
  d.seconds_evaluation = secondsSince(clock);
}

}  // namespace stepcal::trainer::diagnosis

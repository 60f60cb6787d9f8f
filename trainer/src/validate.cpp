#include "stepcal/trainer/validate.hpp"

#include <memory>
#include <string>

#include "diagnose/fit_rows.hpp"
#include "least_squares.hpp"
#include "stepcal/trainer/registration.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/gpr_predictor.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer {
namespace {

constexpr double kRankTolerance = 1e-9;
constexpr int kFrameIterations = 10;

// The tracker registered in closed form to the model's tip positions (the campaign's tracker may
// stand anywhere; gravity turns with it), then Gauss–Newton on the initial poses of the root
// (tracker) and the tip (tool), 12 parameters.
PhysicalModel refitFrames(PhysicalModel model, const diagnosis::FitRows& fit) {
  const int n = model.chain_Tracker.dof();
  {
    std::vector<Vec3> p_model, p_measured;
    ChainWorkspace ws;
    JointVector theta, tau;
    for (const Measurement* row : fit.rows) {
      physicalLinkAngles(model, row->q_rad, row->wrenchOrZero(), rowTemperature(*row), ws, theta,
                         tau);
      p_model.push_back(tipPose(ws).translation());
      p_measured.push_back(row->p_TipInTracker_m);
    }
    const Pose X_NewOld = fitRigidTransform(p_model, p_measured);
    model.chain_Tracker = model.chain_Tracker.rerooted(X_NewOld);
    model.gravity_Tracker = X_NewOld.linear() * model.gravity_Tracker;
  }
  Eigen::VectorXd r = diagnosis::residuals(model, fit);
  double cost = r.squaredNorm();
  for (int it = 0; it < kFrameIterations; ++it) {
    const Eigen::MatrixXd G = diagnosis::linearise(model, fit, r).geometry;
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
      const Eigen::VectorXd r_moved = diagnosis::residuals(moved, fit);
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

PoseModel withGpr(PoseModel physical, const GprParameters& parameters) {
  auto gpr = std::make_shared<const GprPredictor>(GprPredictor::fromParameters(parameters));
  return [physical, gpr](const Measurement& row) {
    GprPredictor::Workspace workspace = gpr->makeWorkspace();
    Vec6 residual;
    gpr->predictInto(gprInput(row).data(), residual.data(), nullptr, workspace);
    return Pose(physical(row) * lie::expSE3(residual));
  };
}

}  // namespace

ValidationResult validateModel(const CalibratedModel& model, const Campaign& campaign,
                               bool refit_frames, const CalibratedModel* coverage_of) {
  const int n = model.chain_Tracker.dof();
  diagnosis::requireJointCount(campaign, n);
  std::vector<const Measurement*> rows;
  for (const Measurement& row : campaign.rows) rows.push_back(&row);
  const diagnosis::FitRows fit = diagnosis::makeFitRows(rows, campaign.tracker, 1);
  const std::vector<std::pair<std::string, PoseModel>> layers = modelLayers(model);

  // The physical model of each layer: the chain alone, then with compliance and mechanisms.
  PhysicalModel chain_only = physicalModelOf(model);
  chain_only.compliance_rad_per_nm.setZero();
  chain_only.mechanisms.clear();
  const PhysicalModel physical = physicalModelOf(model);
  ValidationResult out;
  out.frames_refit = refit_frames;
  std::vector<PoseModel> predictors;
  PoseModel physical_layer;
  for (const auto& [name, layer] : layers) {
    if (!refit_frames) {
      predictors.push_back(layer);
    } else if (name == kMethodPoe) {
      physical_layer = physicalPoseModel(refitFrames(chain_only, fit));
      predictors.push_back(physical_layer);
    } else if (name == kMethodPoeStiffness || name == kMethodExtended) {
      physical_layer = physicalPoseModel(refitFrames(physical, fit));
      predictors.push_back(physical_layer);
    } else {
      // The GPR on its physical layer, the one before it.
      predictors.push_back(withGpr(physical_layer, *model.gpr));
    }
  }
  std::vector<Measurement> all_rows(campaign.rows.begin(), campaign.rows.end()), covered_rows;
  const PhysicalModel covering = coverage_of ? physicalModelOf(*coverage_of) : physical;
  // Covered rows are counted only for a model with profiles (without, every row is covered).
  if (covering.has(MechanismKind::kTransmissionError)) {
    for (const Measurement& row : campaign.rows) {
      if (row.q_rad.size() == covering.chain_Tracker.dof() &&
          jointsOutsideCoverage(covering, row.q_rad) == 0) {
        covered_rows.push_back(row);
      }
    }
  }
  out.rows = static_cast<int>(all_rows.size());
  out.covered_rows = static_cast<int>(covered_rows.size());
  for (size_t l = 0; l < layers.size(); ++l) {
    const std::string name = refit_frames ? layers[l].first + " (frames refit)" : layers[l].first;
    const auto all = summarize(name, predictors[l], all_rows);
    out.all.insert(out.all.end(), all.begin(), all.end());
    if (!covered_rows.empty()) {
      const auto covered = summarize(name + " (covered rows)", predictors[l], covered_rows);
      out.covered.insert(out.covered.end(), covered.begin(), covered.end());
    }
  }
  return out;
}

}  // namespace stepcal::trainer

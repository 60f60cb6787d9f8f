#include "stepcal/trainer/validate.hpp"

#include <memory>
#include <string>

#include "diagnose/session_frames.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/gpr_predictor.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/model_robot.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer {
namespace {

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
  requireCampaignOfModelRobot(model, campaign, "");
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
      const PhysicalModel refit = diagnosis::refitFrames(chain_only, fit);
      out.refit_chain_Tracker = refit.chain_Tracker;  // replaced by the next layer's, if any
      physical_layer = physicalPoseModel(refit);
      predictors.push_back(physical_layer);
    } else if (name == kMethodPoeStiffness || name == kMethodExtended) {
      const PhysicalModel refit = diagnosis::refitFrames(physical, fit);
      out.refit_chain_Tracker = refit.chain_Tracker;
      physical_layer = physicalPoseModel(refit);
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

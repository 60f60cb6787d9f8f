// A model file on another campaign (`stepcal validate`): the accuracy of each of its layers,
// optionally with the tracker and tool frames fitted again for that campaign by the layer's own
// model, on all rows and on the rows inside every transmission profile's coverage.
#pragma once

#include <optional>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/trainer/accuracy.hpp"

namespace stepcal::trainer {

struct ValidationResult {
  std::vector<AccuracySummary> all;      ///< per layer (modelLayers order) and (set, load) group
  std::vector<AccuracySummary> covered;  ///< the same on the covered rows (empty if none)
  int rows = 0;
  int covered_rows = 0;  ///< rows whose joint angles every profile covers (jointsOutsideCoverage)
  bool frames_refit = false;
  /// With frames_refit: the full physical model's chain with the campaign's tracker and tool
  /// frames (what the model's last layer predicts with), for the runtime's bound on these rows.
  std::optional<KinematicChain> refit_chain_Tracker;
};

/// Every layer of the model on the campaign's rows (all sets). With refit_frames, the tracker
/// and tool frames (12 parameters, docs/method.md eq. 7 blocks 0 and n) are fitted again on these
/// rows, by Gauss–Newton with each physical layer's own model (chain; chain with compliance and
/// mechanisms; the GPR layer uses its physical layer's frames), the joint frames kept: for a
/// campaign measured with the tracker or the target moved. Throws InputError when the campaign
/// does not fit the model. coverage_of: the model whose profiles decide which rows are covered
/// (another model's, to compare two models on the same rows; default: this one's).
ValidationResult validateModel(const CalibratedModel& model, const Campaign& campaign,
                               bool refit_frames, const CalibratedModel* coverage_of = nullptr);

}  // namespace stepcal::trainer

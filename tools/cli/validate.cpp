// `stepcal validate`: a model file's accuracy on another campaign's rows.
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/model_robot.hpp"
#include "stepcal/report/report.hpp"
#include "stepcal/trainer/validate.hpp"
#include "bound_coverage.hpp"
#include "subcommands.hpp"

namespace stepcal::cli {
namespace {

struct ValidateArgs {
  std::string model, campaign;
  bool json = false;
  bool refit_frames = false;
  bool bound_coverage = false;  ///< --json: an object with the accuracy and the bound's coverage
  std::string covered_by;  ///< another model whose profiles' coverage counts; empty: none
};

// Accuracy of every layer of a model file (chain, + compliance and mechanisms, + GPR) on a
// campaign's rows, all of them and those every transmission profile covers. With refit_frames,
// the tracker and tool frames are fitted again on the campaign's rows by each layer's model
// (validate.hpp): for a campaign measured with the tracker or the target moved.
void runValidate(const std::string& model_path, const std::string& dir, bool refit_frames,
                 const std::string& covered_by, bool json, bool with_coverage_json) {
  const CalibratedModel model = readModelFile(model_path);
  const Campaign campaign = readCampaign(dir);
  requireCampaignOfModelRobot(model, campaign, model_path);
  std::optional<CalibratedModel> covering;
  if (!covered_by.empty()) covering = readModelFile(covered_by);
  const trainer::ValidationResult v =
      trainer::validateModel(model, campaign, refit_frames, covering ? &*covering : nullptr);
  std::vector<trainer::AccuracySummary> summaries = v.all;
  summaries.insert(summaries.end(), v.covered.begin(), v.covered.end());
  // The runtime's stated bound on the same rows (the model's last layer, frames as refit).
  const std::vector<BoundCoverageRow> coverage =
      boundCoverage(model, campaign, v.refit_chain_Tracker);
  if (json) {
    nlohmann::json out = report::accuracyJson(summaries);
    if (with_coverage_json) {
      out = {{"accuracy", out}, {"bound_coverage", boundCoverageJson(coverage)}};
    }
    std::cout << out.dump(2) << "\n";
  } else {
    std::cout << "model " << model_path << " (campaign " << model.provenance.campaign_path
              << ") on " << dir << ": " << v.rows << " rows";
    if (!v.covered.empty() || v.covered_rows > 0 || covering) {
      std::cout << ", " << v.covered_rows << " inside every transmission profile's coverage";
    }
    std::cout << "\n" << report::formatAccuracyTable(summaries);
    if (!coverage.empty()) std::cout << formatBoundCoverage(coverage);
  }
}

}  // namespace

Subcommand addValidateCommand(CLI::App& app) {
  auto args = std::make_shared<ValidateArgs>();
  ValidateArgs& a = *args;
  CLI::App* validate = app.add_subcommand(
      "validate", "accuracy of a model file on another campaign's rows (e.g. fit on one series, check on another)");
  validate->add_option("model", a.model, "model file")->required();
  validate->add_option("campaign", a.campaign, "campaign folder")->required();
  validate->add_flag("--json", a.json, "print the table as JSON");
  validate->add_flag("--refit-frames", a.refit_frames,
                     "fit the tracker and tool frames again on this campaign (joint frames kept)");
  validate->add_flag("--bound-coverage", a.bound_coverage,
                     "with --json: an object {accuracy, bound_coverage}, the second how many rows "
                     "the runtime's stated 95 % bound holds, per set and load (the text output "
                     "always shows it for a model that states a bound)");
  validate->add_option("--rows-covered-by", a.covered_by,
                       "count as covered the rows this other model's profiles cover (to compare "
                       "two models on the same rows)");
  return {validate, [args] {
            runValidate(args->model, args->campaign, args->refit_frames, args->covered_by,
                        args->json, args->bound_coverage);
          }};
}

}  // namespace stepcal::cli

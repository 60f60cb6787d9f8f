// `stepcal diagnose`: what the physical model gets wrong, the extended model and its gain.
#include <chrono>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "common.hpp"
#include "interrupt_notice.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/model_robot.hpp"
#include "stepcal/report/diagnosis_report.hpp"
#include "stepcal/report/report_html.hpp"
#include "stepcal/trainer/diagnose.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "subcommands.hpp"

namespace stepcal::cli {
namespace {

struct DiagnoseArgs {
  std::vector<std::string> campaign_dirs;
  std::string model;  ///< the model file to diagnose; empty: calibrate the campaigns first
  std::string model_out, report_out;
  bool json = false;
  int gpr_points = trainer::CalibrationOptions{}.gpr_max_points;
};

// Diagnosis of a campaign against its calibrated physical model (calibrated here, or the given
// model file): the named causes, the extended model (written with --out) and its gain.
// Several campaigns: one robot from several tracker stations, diagnosed together (diagnose.hpp).
void runDiagnose(const std::vector<std::string>& dirs, const std::string& model_path,
                 const std::string& model_out, const std::string& report_out, bool json,
                 int gpr_points) {
  trainer::DiagnoseOptions options;
  options.calibration = calibrationOptions(gpr_points);
  InterruptNotice notice(outputs({report_out, model_out}));
  std::vector<Campaign> campaigns;
  for (const std::string& dir : dirs) campaigns.push_back(readCampaign(dir));
  const Campaign campaign = mergeCampaigns(std::move(campaigns));
  const auto start = std::chrono::steady_clock::now();
  CalibratedModel model;
  if (model_path.empty()) {
    model = trainer::modelFromOutcome(campaign,
                                      trainer::calibrateCampaign(campaign, options.calibration));
  } else {
    model = readModelFile(model_path);
    requireCampaignOfModelRobot(model, campaign, model_path);
  }
  const double seconds_calibrate =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const trainer::Diagnosis diagnosis = trainer::diagnose(campaign, model, options);
  if (!report_out.empty()) {
    notice.write(report_out, "report",
                 [&] { writeReport(report_out, report::diagnosisHtml(campaign, diagnosis)); });
  }
  if (!model_out.empty()) {
    notice.write(model_out, "model", [&] { writeModelFile(diagnosis.extended_model, model_out); });
  }
  if (json) {
    std::cout << report::diagnosisJson(diagnosis, seconds_calibrate).dump(2) << "\n";
  } else {
    std::cout << report::formatDiagnosis(diagnosis, seconds_calibrate);
  }
}

}  // namespace

Subcommand addDiagnoseCommand(CLI::App& app) {
  auto args = std::make_shared<DiagnoseArgs>();
  DiagnoseArgs& a = *args;
  CLI::App* diagnose_cmd = app.add_subcommand(
      "diagnose", "name what the physical model gets wrong, extend it and measure the gain");
  diagnose_cmd
      ->add_option("campaign", a.campaign_dirs,
                   "campaign folder (or its campaign.yaml); several: one robot measured from "
                   "several tracker stations, diagnosed together, each campaign with its own "
                   "tracker and tool frames; the extended model takes the first one's")
      ->required();
  diagnose_cmd->add_option("--model", a.model,
                           "model file to diagnose, in the first campaign's tracker frame "
                           "(default: calibrate the campaigns first)");
  diagnose_cmd->add_flag("--json", a.json, "print the diagnosis as JSON");
  diagnose_cmd->add_option("--out", a.model_out, "extended model file to write");
  diagnose_cmd->add_option("--report", a.report_out, "HTML report with the plots to write");
  diagnose_cmd->add_option("--gpr-points", a.gpr_points,
                           kGprPointsHelp + ", of the calibration and of the extended model")
      ->capture_default_str();
  return {diagnose_cmd, [args] {
            runDiagnose(args->campaign_dirs, args->model, args->model_out, args->report_out,
                        args->json, args->gpr_points);
          }};
}

}  // namespace stepcal::cli

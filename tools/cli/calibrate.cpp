#include "calibrate.hpp"

#include <iostream>
#include <memory>

#include "common.hpp"
#include "interrupt_notice.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/report/report.hpp"
#include "stepcal/report/report_html.hpp"
#include "stepcal/report/unexplained_report.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "subcommands.hpp"

namespace stepcal::cli {
namespace {

struct CalibrateArgs {
  std::vector<std::string> campaign_dirs;
  std::string model_out, report_out;
  bool json = false;
  int gpr_points = trainer::CalibrationOptions{}.gpr_max_points;
};

}  // namespace

// One campaign, or several of one robot fitted together (mergeCampaigns): the first one's
// tracker frame and tool are the model's.
void runCalibrate(const std::vector<std::string>& dirs, const std::string& model_out,
                  const std::string& report_out, bool json, int gpr_points) {
  const trainer::CalibrationOptions options = calibrationOptions(gpr_points);
  InterruptNotice notice(outputs({report_out, model_out}));
  std::vector<Campaign> campaigns;
  for (const std::string& dir : dirs) campaigns.push_back(readCampaign(dir));
  const Campaign campaign = mergeCampaigns(std::move(campaigns));
  const trainer::CalibrationOutcome outcome = trainer::calibrateCampaign(campaign, options);
  if (!report_out.empty()) {
    notice.write(report_out, "report",
                 [&] { writeReport(report_out, report::htmlReport(campaign, outcome)); });
  }
  if (!model_out.empty()) {
    notice.write(model_out, "model", [&] {
      writeModelFile(trainer::modelFromOutcome(campaign, outcome), model_out);
    });
  }
  const std::string note = report::residualNote(campaign, outcome);
  if (json) {
    std::cout << report::reportJson(campaign, outcome).dump(2) << "\n";
  } else {
    std::cout << report::formatReport(campaign, outcome);
    if (!note.empty()) std::cout << "\n" << note << "\n";
  }
}

Subcommand addCalibrateCommand(CLI::App& app) {
  auto args = std::make_shared<CalibrateArgs>();
  CalibrateArgs& a = *args;
  CLI::App* calibrate = app.add_subcommand(
      "calibrate",
      "calibrate a campaign and print its accuracy tables; a note when the model leaves more than "
      "3x the stated tracker-noise floor on the validation rows (then try `stepcal diagnose`)");
  calibrate
      ->add_option("campaign", a.campaign_dirs,
                   "campaign folder (or its campaign.yaml); several: one robot measured in several "
                   "sessions (tracker stations, target remounted), fitted together; the model "
                   "takes the first one's tracker frame, tool and the joint frames each campaign "
                   "keeps its own: give first the campaign of the robot as it is now")
      ->required();
  calibrate->add_option("--out", a.model_out, "model file to write");
  calibrate->add_flag("--json", a.json, "print the report as JSON");
  calibrate->add_option("--report", a.report_out, "HTML report with the figures to write");
  calibrate->add_option("--gpr-points", a.gpr_points, kGprPointsHelp)->capture_default_str();
  return {calibrate, [args] {
            runCalibrate(args->campaign_dirs, args->model_out, args->report_out, args->json,
                         args->gpr_points);
          }};
}

}  // namespace stepcal::cli

// `stepcal export urdf`: a model file as the robot's calibrated URDF.
#include <filesystem>
#include <iostream>
#include <memory>
#include <set>
#include <string>

#include "stepcal/common/atomic_file.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/urdf_export.hpp"
#include "stepcal/report/report.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "subcommands.hpp"

namespace stepcal::cli {
namespace {

struct ExportUrdfArgs {
  std::string model, campaign, out;  ///< campaign empty: the model's own, from its provenance
};

// The model's chain as the robot's URDF (urdf_export.hpp), then what a URDF-only user gets
// against the full runtime: the model's validation figures of its poe layer and its last one.
void runExportUrdf(const std::string& model_path, const std::string& campaign_dir,
                   const std::string& out) {
  const CalibratedModel model = readModelFile(model_path);
  std::string dir = campaign_dir;
  if (dir.empty()) {
    dir = model.provenance.campaign_path;
    if (dir.empty() || !std::filesystem::exists(dir)) {
      throw InputError("the model's campaign '" + dir + "' (from its provenance) is not there; "
                       "expected the campaign it was calibrated on, for its robot.urdf, base_link "
                       "and tip_link; hint: pass --campaign DIR",
                       model_path);
    }
  }
  const Campaign campaign = readCampaign(dir);
  const RobotDescription robot{campaign.urdf_xml, campaign.base_link, campaign.tip_link,
                               campaign.directory + "/" + campaign.robot_file};
  const CalibratedUrdf urdf = calibratedUrdf(model, model_path, robot);
  writeFileAtomically(out, urdf.urdf_xml.data(), urdf.urdf_xml.size(), "URDF");
  std::cerr << "wrote " << out << "\n";

  std::cout << "calibrated URDF of " << robot.source << " (" << robot.base_link << " -> "
            << robot.tip_link << ", " << model.chain_Tracker.dof() << " joints): link '"
            << kUrdfWorldLink << "' is the tracker frame, link '" << kUrdfToolLink
            << "' the calibrated " << robot.tip_link << "\n";
  if (!urdf.dropped_links.empty()) {
    std::cout << "left out, not below " << robot.base_link << ":";
    for (const std::string& link : urdf.dropped_links) std::cout << " " << link;
    std::cout << "\n";
  }
  const std::string full = trainer::modelLayers(model).back().first;
  std::cout << "a URDF carries the geometric layer (" << trainer::kMethodPoe
            << ") only; the runtime applies " << full << "\n";
  std::set<double> loads_kg;
  for (const ValidationFigure& v : model.provenance.validation) {
    if (v.method == trainer::kMethodPoe) loads_kg.insert(v.load_kg);
  }
  if (loads_kg.empty()) {
    std::cout << "the model holds no validation figures of " << trainer::kMethodPoe
              << " (its campaign had no validation rows)\n";
    return;
  }
  std::cout << "validation figures at training time (mean / max position mm, mean orientation "
               "deg):\n";
  for (const double load_kg : loads_kg) {
    for (const std::string& method : {std::string(trainer::kMethodPoe), full}) {
      for (const ValidationFigure& v : model.provenance.validation) {
        if (v.method == method && v.load_kg == load_kg) std::cout << report::formatValidationFigure(v);
      }
    }
  }
}

}  // namespace

Subcommand addExportCommand(CLI::App& app) {
  auto args = std::make_shared<ExportUrdfArgs>();
  ExportUrdfArgs& a = *args;
  CLI::App* export_cmd =
      app.add_subcommand("export", "write a model file's contents in another format");
  export_cmd->require_subcommand(1);
  CLI::App* export_urdf = export_cmd->add_subcommand(
      "urdf", "the robot's URDF with the calibrated joint origins and axes, the tracker as link "
              "'world' and the calibrated tip as link 'tool'");
  export_urdf->add_option("model", a.model, "model file")->required();
  export_urdf->add_option("--out", a.out, "URDF file to write")->required();
  export_urdf->add_option("--campaign", a.campaign,
                          "campaign the model was calibrated on, for its robot.urdf, base_link and "
                          "tip_link (default: the model's own, from its provenance)");
  return {export_urdf, [args] { runExportUrdf(args->model, args->campaign, args->out); }};
}

}  // namespace stepcal::cli

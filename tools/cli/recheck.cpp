// `stepcal recheck`: a stored model against a short campaign after a crash, a motor change or a
// re-mastering (trainer/recheck.hpp): what changed, in the operator's words, and the updated
// model written beside the stored one, never over it.
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/model_robot.hpp"
#include "stepcal/trainer/recheck.hpp"
#include "subcommands.hpp"

namespace stepcal::cli {
namespace {

namespace fs = std::filesystem;

struct RecheckArgs {
  std::string model, campaign, out;
  trainer::RecheckOptions options;
};

/// MODEL.stepcal → MODEL.recheck.stepcal beside it.
std::string besideTheModel(const std::string& model_path) {
  fs::path p(model_path);
  const std::string stem = p.extension() == ".stepcal" ? p.stem().string() : p.filename().string();
  return (p.parent_path() / (stem + ".recheck.stepcal")).string();
}

void runRecheck(const RecheckArgs& a) {
  const CalibratedModel model = readModelFile(a.model);
  const Campaign campaign = readCampaign(a.campaign);
  requireCampaignOfModelRobot(model, campaign, a.model);
  const std::string out = a.out.empty() ? besideTheModel(a.model) : a.out;
  std::error_code ec;
  if (fs::equivalent(out, a.model, ec)) {
    throw InputError(
        "--out names the stored model; expected another file (the stored model is "
        "never overwritten)",
        out);
  }
  const trainer::RecheckResult r = trainer::recheckModel(model, campaign, a.options);
  std::cout << "model " << a.model << " re-checked on " << a.campaign << "\n"
            << trainer::recheckVerdict(r);
  writeModelFile(r.updated, out);
  std::cout << "updated model written to " << out << " (the stored one unchanged)\n";
}

}  // namespace

Subcommand addRecheckCommand(CLI::App& app) {
  auto args = std::make_shared<RecheckArgs>();
  RecheckArgs& a = *args;
  CLI::App* recheck = app.add_subcommand(
      "recheck",
      "a stored model against a short campaign: which joint zeros and tool changed (and "
      "compliances, on rows at two loads or more), and the model updated beside it "
      "(docs/cell.md)");
  recheck->add_option("model", a.model, "the stored model file")->required();
  recheck->add_option("campaign", a.campaign, "the re-check campaign folder")->required();
  recheck->add_option("--out", a.out,
                      "updated model file (default: MODEL.recheck.stepcal beside it)");
  recheck->add_flag("--keep-registration", a.options.keep_registration,
                    "the tracker stands where it stood for the model: keep its registration and "
                    "see joint 1's zero");
  recheck->add_flag(
      "--keep-tool", a.options.keep_tool,
      "the target has not been remounted: keep the tool and see the last joint's zero");
  return {recheck, [args] { runRecheck(*args); }};
}

}  // namespace stepcal::cli

// `stepcal import ipa`: a series of the IPA UR10 data set as a campaign (importers/ipa.hpp);
// `stepcal import mapped`: a tracker export and a joint log, as a mapping file says
// (importers/mapped.hpp).
#include <iostream>
#include <memory>
#include <string>

#include "common.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/robots.hpp"
#include "stepcal/importers/ipa.hpp"
#include "stepcal/importers/mapped.hpp"
#include "subcommands.hpp"

namespace stepcal::cli {
namespace {

struct IpaArgs {
  std::string csv, out, robot = "ur10";
  std::string mapping, mapped_out;
  int validation_from_row = -1;  ///< rows from here on become set=validation; -1: none
};

}  // namespace

Subcommand addImportCommand(CLI::App& app) {
  auto args = std::make_shared<IpaArgs>();
  IpaArgs& a = *args;
  CLI::App* import = app.add_subcommand("import", "convert foreign measurements into a campaign");
  import->require_subcommand(1);
  CLI::App* ipa = import->add_subcommand("ipa", "a series of the IPA UR10 data set (ipa-robot-accuracy)");
  ipa->add_option("csv", a.csv, "the series' measurements CSV")->required();
  ipa->add_option("--validation-from-row", a.validation_from_row,
                  "rows from N on (0-based, after the header) become set=validation");
  ipa->add_option("--robot", a.robot,
                  "nominal UR10 description: a URDF file or a shipped robot's name (" +
                      shippedRobotList() + ")")
      ->capture_default_str();
  ipa->add_option("--out", a.out, "campaign folder to write")->required();
  CLI::App* mapped = import->add_subcommand(
      "mapped",
      "a tracker export beside a joint log, columns and units named by a mapping file "
      "(docs/cell.md): joined by row, time stamp or point name; each joint's sign and offset "
      "(q_urdf = sign*q_log + offset); an F/T sensor's wrench from either file");
  mapped->add_option("mapping", a.mapping, "the mapping file (YAML, stepcal-import-mapping/1)")
      ->required();
  mapped->add_option("--out", a.mapped_out, "campaign folder to write")->required();
  // One Subcommand for both: main.cpp sets the help footer on the selecting command's parents.
  ipa->footer(exit_code::kHelpFooter);
  mapped->footer(exit_code::kHelpFooter);
  return {import, [args, mapped] {
            if (*mapped) {
              writeCampaign(importers::importMapped(args->mapping), args->mapped_out);
              std::cerr << "wrote " << args->mapped_out << "\n";
              return;
            }
            writeCampaign(importers::importIpaSeries(args->csv, args->validation_from_row,
                                                     robotDescriptionPath(args->robot)),
                          args->out);
            std::cerr << "wrote " << args->out << "\n";
          }};
}

}  // namespace stepcal::cli

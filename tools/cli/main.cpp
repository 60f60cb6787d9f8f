// stepcal: the offline command line. Every subcommand reads and writes campaign folders
// (campaign-format.md); errors in the user's input end with exit status 2 and one clear line.
// A subcommand is a file of its own (subcommands.hpp).
#include <iostream>
#include <vector>

#include <CLI/CLI.hpp>

#include "stepcal/common/error.hpp"
#include "subcommands.hpp"

int main(int argc, char** argv) {
  using namespace stepcal::cli;
  CLI::App app{"stepcal: stepwise calibration of heavy-duty robots (geometry, compliance, residual)"};
  app.require_subcommand(1);
  // In the order `stepcal --help` lists them.
  const std::vector<Subcommand> subcommands = {
      addSimulateCommand(app),
      addPlanCommand(app),
      addImportCommand(app),
      addCalibrateCommand(app),
      addValidateCommand(app),
      addInspectCommand(app),
      addExportCommand(app),
      addDiagnoseCommand(app),
      addDemoCommand(app),
      addCorrectCommand(app),
  };
  CLI11_PARSE(app, argc, argv);
  try {
    for (const Subcommand& subcommand : subcommands) {
      if (*subcommand.command) subcommand.run();
    }
  } catch (const stepcal::InputError& e) {
    std::cerr << "stepcal: error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

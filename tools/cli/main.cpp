// stepcal: the offline command line. Every subcommand reads and writes campaign folders
// (campaign-format.md); errors in the user's input end with exit status 2 and one clear line.
// A subcommand is a file of its own (subcommands.hpp). Exit statuses: exit_codes.hpp.
#include <iostream>
#include <vector>

#include <CLI/CLI.hpp>

#include "stepcal/common/error.hpp"
#include "stepcal/common/exit_codes.hpp"
#include "subcommands.hpp"

int main(int argc, char** argv) {
  using namespace stepcal::cli;
  namespace exit_code = stepcal::exit_code;
  CLI::App app{"stepcal: stepwise calibration of heavy-duty robots (geometry, compliance, residual)"};
  app.require_subcommand(1);
  app.footer(exit_code::kHelpFooter);
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
      addToolCommand(app),
      addFrameCommand(app),
      addCertifyCommand(app),
      addRecheckCommand(app),
  };
  for (const Subcommand& subcommand : subcommands) {  // `import` as well as `import ipa`
    for (CLI::App* c = subcommand.command; c != nullptr; c = c->get_parent()) {
      c->footer(exit_code::kHelpFooter);
    }
  }
  if (argc <= 1) {  // a usage error, with the usage
    std::cerr << app.help();
    return exit_code::kBadInput;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help is done (0); any other parse error is bad usage, whatever CLI11's own number.
    return app.exit(e) == 0 ? exit_code::kDone : exit_code::kBadInput;
  }
  try {
    for (const Subcommand& subcommand : subcommands) {
      if (*subcommand.command) return subcommand.run();
    }
  } catch (const stepcal::InputError& e) {
    std::cerr << "stepcal: error: " << e.what() << "\n";
    return exit_code::kBadInput;
  }
  return exit_code::kDone;
}

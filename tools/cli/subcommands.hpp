// The subcommands of `stepcal`, one file each (tools/cli/<name>.cpp): each registers its CLI11
// subcommand with its options and says how to run it; main.cpp lists them in the order
// `stepcal --help` shows them.
#pragma once

#include <functional>
#include <type_traits>
#include <utility>

#include <CLI/CLI.hpp>

#include "stepcal/common/exit_codes.hpp"

namespace stepcal::cli {

/// A registered subcommand, run when it is the one given on the command line.
struct Subcommand {
  CLI::App* command;        ///< the subcommand that selects it (`ipa` of `import ipa`)
  std::function<int()> run;  ///< does its work, returns the exit status (exit_codes.hpp); throws
                             ///< InputError on bad input (exit status 2)

  /// work returns its exit status, or nothing when it is all or nothing (done: 0).
  template <typename Work>
  Subcommand(CLI::App* selecting_command, Work work) : command(selecting_command) {
    if constexpr (std::is_void_v<std::invoke_result_t<Work&>>) {
      run = [work = std::move(work)]() mutable {
        work();
        return exit_code::kDone;
      };
    } else {
      run = std::move(work);
    }
  }
};

Subcommand addSimulateCommand(CLI::App& app);   ///< simulate.cpp
Subcommand addPlanCommand(CLI::App& app);       ///< plan.cpp
Subcommand addImportCommand(CLI::App& app);     ///< import.cpp: import ipa, import mapped
Subcommand addCalibrateCommand(CLI::App& app);  ///< calibrate.cpp
Subcommand addValidateCommand(CLI::App& app);   ///< validate.cpp
Subcommand addInspectCommand(CLI::App& app);    ///< inspect.cpp
Subcommand addExportCommand(CLI::App& app);     ///< export.cpp: export urdf
Subcommand addDiagnoseCommand(CLI::App& app);   ///< diagnose.cpp
Subcommand addDemoCommand(CLI::App& app);       ///< demo.cpp
Subcommand addCorrectCommand(CLI::App& app);    ///< correct.cpp
Subcommand addToolCommand(CLI::App& app);       ///< tool.cpp
Subcommand addFrameCommand(CLI::App& app);      ///< frame.cpp
Subcommand addCertifyCommand(CLI::App& app);    ///< certify.cpp
Subcommand addRecheckCommand(CLI::App& app);    ///< recheck.cpp

}  // namespace stepcal::cli

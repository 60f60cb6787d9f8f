// `stepcal correct MODEL PROGRAM --out CORRECTED`: an offline program's targets (poses in a
// chosen frame, or the nominal joint targets of an offline programming tool), each with its
// tool and payload, corrected with a model: joint targets and pre-distorted poses that make the
// real robot reach them, with each line's status, predicted residual and coverage, and a
// summary. The file formats are in docs/runtime.md ("Correcting an offline program").
#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace stepcal::cli {

struct CorrectArgs {
  std::string model, program, out;
  std::string frame = "tracker";    ///< tracker | base | user: the frame of the pose targets
  std::vector<double> user_frame;   ///< --frame user: x y z (mm) qw qx qy qz, in the base frame
  std::vector<double> seed_deg;     ///< the first pose target's seed when the file has none, deg
  std::string truth;                ///< the twin's truth.json: each target run on it too
  bool json = false;                ///< the summary as JSON
};

/// Registers the subcommand on app; its options fill args.
CLI::App* addCorrectCommand(CLI::App& app, CorrectArgs& args);

/// Reads the model and the program, corrects every line, writes args.out (atomically) and prints
/// the summary. Throws InputError naming the file, line and column of bad input.
void runCorrect(const CorrectArgs& args);

}  // namespace stepcal::cli

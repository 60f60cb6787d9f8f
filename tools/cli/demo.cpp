// `stepcal demo`: the paper's IRB4400 campaign simulated, calibrated and its tables printed.
#include <cstdint>
#include <iostream>
#include <memory>
#include <string>

#include "calibrate.hpp"
#include "simulate.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "subcommands.hpp"

namespace stepcal::cli {
namespace {

struct DemoArgs {
  std::string out = "out/demo-campaign";
  uint64_t seed = 1;
};

}  // namespace

Subcommand addDemoCommand(CLI::App& app) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* demo = app.add_subcommand(
      "demo", "the main job: simulate the paper's IRB4400 campaign, calibrate it, print the tables");
  demo->add_option("--out", args->out, "where the simulated campaign goes")->capture_default_str();
  demo->add_option("--seed", args->seed, "random seed of the twin")->capture_default_str();
  return {demo, [args] {
            SimulateArgs paper;
            paper.seed = args->seed;
            paper.out = args->out;
            runSimulate(paper);
            std::cout << "simulated the paper's IRB4400 campaign (seed " << args->seed << ") into "
                      << args->out << "\n\n";
            runCalibrate({args->out}, args->out + "/model.stepcal", args->out + "/report.html",
                         false, trainer::CalibrationOptions{}.gpr_max_points);
          }};
}

}  // namespace stepcal::cli

// The daemon's options (stepcal/service/daemon_options.hpp): the command line by getopt_long, the
// configuration file of the same names, and their errors; the daemon run with a configuration.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "stepcal/common/error.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/service/daemon_options.hpp"
#include "support/command.hpp"
#include "support/files.hpp"
#include "support/input_error.hpp"

namespace stepcal {
namespace {

using service::DaemonArgs;
using service::DaemonCommandLine;
using service::parseDaemonCommandLine;

/// parseDaemonCommandLine of "stepcal-runtime" followed by args.
DaemonCommandLine parse(std::vector<std::string> args) {
  args.insert(args.begin(), "stepcal-runtime");
  std::vector<char*> argv;
  for (std::string& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);
  return parseDaemonCommandLine(int(args.size()), argv.data());
}

TEST(DaemonOptions, CommandLineSetsEveryKindOfValue) {
  const DaemonArgs a = parse({"--model", "m.stepcal", "--budget-us=350", "--max-wrench-age-ms",
                              "12.5", "--sensor", "can:can0", "--sensor-base-id", "0x2A",
                              "--sensor-republish", "", "--realtime"})
                           .args;
  EXPECT_EQ(a.model_path, "m.stepcal");
  EXPECT_EQ(a.budget_us, 350);
  EXPECT_EQ(a.max_wrench_age_ms, 12.5);
  EXPECT_EQ(a.sensor.sensor, "can:can0");
  EXPECT_EQ(a.sensor.base_id, 0x2Au);
  EXPECT_EQ(a.sensor.republish_channel, "");
  EXPECT_TRUE(a.realtime);
  EXPECT_EQ(a.lcm_url, DaemonArgs{}.lcm_url);  // untouched options keep their defaults
  EXPECT_FALSE(parse({"--model", "m", "--realtime=false"}).args.realtime);
}

TEST(DaemonOptions, TheCommandLineOverridesTheConfigurationFileWhateverTheOrder) {
  const test::TempDir dir;
  const std::string conf = (dir.path() / "cell1.conf").string();
  test::writeText(conf,
                  "# cell 1\n\nmodel = /var/lib/stepcal/cell1.stepcal\n  budget-us =  300 \n"
                  "realtime = true\nsensor-base-id = 32\nlcm-url = udpm://239.255.76.67:7667?ttl=0\n");
  const DaemonArgs a = parse({"--budget-us", "150", "--config", conf}).args;
  EXPECT_EQ(a.model_path, "/var/lib/stepcal/cell1.stepcal");
  EXPECT_EQ(a.budget_us, 150);
  EXPECT_TRUE(a.realtime);
  EXPECT_EQ(a.sensor.base_id, 32u);
  EXPECT_EQ(a.lcm_url, "udpm://239.255.76.67:7667?ttl=0");
}

TEST(DaemonOptions, PrintConfigWritesEveryOptionAndReadsBackTheSame) {
  const test::TempDir dir;
  const DaemonArgs given = parse({"--model", "a b.stepcal", "--budget-us", "250", "--sensor",
                                  "can:vcan0", "--sensor-base-id", "0x11", "--sensor-rate-hz",
                                  "500.5", "--realtime", "--sensor-republish", "STEPCAL_W2"})
                               .args;
  const std::string text = service::daemonConfiguration(given);
  const std::string conf = (dir.path() / "printed.conf").string();
  test::writeText(conf, text);
  DaemonArgs read;
  service::readDaemonConfiguration(conf, read);
  EXPECT_EQ(service::daemonConfiguration(read), text);
  EXPECT_EQ(read.model_path, "a b.stepcal");
  EXPECT_EQ(read.sensor.rate_hz, 500.5);
  // Every option of --help is a key of the file.
  const std::string usage = service::daemonUsage();
  for (size_t at = usage.find("\n  --"); at != std::string::npos; at = usage.find("\n  --", at + 1)) {
    const std::string name = usage.substr(at + 5, usage.find_first_of(" \n[", at + 5) - at - 5);
    if (name == "config" || name == "print-config" || name == "help") continue;
    EXPECT_NE(text.find("\n" + name + " = "), std::string::npos) << name;
  }
}

TEST(DaemonOptions, RefusesBadCommandLinesNamingTheOption) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{}, "no model file"},
      {{"--model", "m", "--budget-us", "fast"}, "--budget-us: expected an integer, got 'fast'"},
      {{"--model", "m", "--budget-us", "20 0"}, "--budget-us: expected an integer"},
      {{"--model", "m", "--max-wrench-age-ms", "inf"}, "--max-wrench-age-ms: expected a finite number"},
      {{"--model", "m", "--sensor-base-id", "-1"}, "--sensor-base-id: expected a non-negative integer"},
      {{"--model", "m", "--realtime=yes"}, "--realtime: expected true or false, got 'yes'"},
      {{"--model", "m", "--turbo"}, "unknown option '--turbo'"},
      {{"--model"}, "option '--model' needs a value"},
      {{"--model", "m", "extra"}, "unexpected argument 'extra'"},
  };
  for (const auto& [args, expected] : cases) {
    try {
      parse(args);
      ADD_FAILURE() << "accepted: " << testing::PrintToString(args);
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos)
          << e.what() << " — expected: " << expected;
    }
  }
}

constexpr char kWithNul[] = "model = m\nlcm-url = a\0b\n";

TEST(DaemonOptions, RefusesBadConfigurationFilesNamingFileLineAndKey) {
  const test::TempDir dir;
  const std::string conf = (dir.path() / "cell.conf").string();
  const std::vector<std::pair<std::string, std::pair<int, std::string>>> cases = {
      {"model = m\nbudget-us 200\n", {2, "expected 'key = value', got 'budget-us 200'"}},
      {"model = m\n\nturbo = on\n", {3, "unknown key 'turbo' (expected one of: model, lcm-url"}},
      {"model = m\nbudget-us = 200\nbudget-us = 300\n", {3, "key 'budget-us' given twice (first on line 2)"}},
      {"# x\nrealtime = 1\n", {2, "key 'realtime': expected true or false, got '1'"}},
      {"sensor-rate-hz = 1e3x\n", {1, "key 'sensor-rate-hz': expected a finite number, got '1e3x'"}},
      {"model = m\nconfig = other.conf\n", {2, "unknown key 'config'"}},
      {std::string(kWithNul, sizeof kWithNul - 1), {2, "NUL byte"}},
  };
  for (const auto& [text, where] : cases) {
    test::writeText(conf, text);
    test::expectInputError([&] { parse({"--config", conf}); }, "cell.conf", where.first, "",
                           {where.second});
  }
  test::expectInputError([&] { parse({"--config", (dir.path() / "none.conf").string()}); },
                         "none.conf", 0, "", {"cannot open the configuration file"});
}

TEST(DaemonOptions, TheDaemonRunsFromAConfigurationFileAndExplainsItsOptions) {
  const test::TempDir dir;
  const std::string daemon = std::string(STEPCAL_BIN_DIR) + "/stepcal-runtime";
  test::CommandResult r = test::run(daemon + " --help");
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("--sensor-base-id ID"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(default 0x20)"), std::string::npos) << r.out;

  // The configuration's errors reach the user as one line with the file and line; status 2.
  const std::string conf = (dir.path() / "cell1.conf").string();
  test::writeText(conf, "model = " + (dir.path() / "missing.stepcal").string() + "\nbudget-us = 0\n");
  r = test::run(daemon + " --config " + conf + " --lcm-url memq://");
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("--budget-us must be > 0"), std::string::npos) << r.out;
  test::writeText(conf, "model = x\nbudget-us = soon\n");
  r = test::run(daemon + " --config " + conf);
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("cell1.conf:2: key 'budget-us': expected an integer, got 'soon'"),
            std::string::npos)
      << r.out;
}

}  // namespace
}  // namespace stepcal

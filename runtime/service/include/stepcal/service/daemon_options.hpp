// The options of the daemon stepcal-runtime: one table (daemon_options.cpp), read from the
// command line by glibc's getopt_long and from a configuration file whose keys are the long
// option names (`budget-us = 200`), so that every option can be set either way. Adding an option
// is one line in that table.
#pragma once

#include <string>

#include "stepcal/service/channels.hpp"
#include "stepcal/service/lcm_server.hpp"

namespace stepcal::service {

/// The daemon's default --auth-window-ms (auth.hpp's kDefaultAuthWindowUs).
inline constexpr int kDaemonAuthWindowMs = 2000;

/// What the daemon runs with.
struct DaemonArgs {
  std::string model_path;
  std::string lcm_url = kDefaultLcmUrl;
  int budget_us = 200;
  double max_wrench_age_ms = 20.0;
  SensorArgs sensor;
  bool realtime = false;
  /// The cell key (auth.hpp, docs/runtime.md "Only the cell may talk to it"): empty, none.
  std::string key_file;
  double auth_window_ms = kDaemonAuthWindowMs;
};

/// The outcome of parsing the daemon's arguments.
struct DaemonCommandLine {
  DaemonArgs args;
  bool help = false;          ///< --help: print daemonUsage() and stop
  bool print_config = false;  ///< --print-config: print daemonConfiguration(args) and stop
};

/// Parses the command line: first the configuration file named by --config FILE (if any), then
/// every other option given, which overrides the file. Throws InputError naming the option, or the
/// file, line and key, with what was expected; a missing model path is refused unless --help or
/// --print-config is given.
DaemonCommandLine parseDaemonCommandLine(int argc, char** argv);

/// Reads a configuration file into args (over what args holds): `key = value` lines, `#` starts a
/// comment line, blank lines are skipped; keys are the long option names without "--", each at
/// most once; a flag takes true or false. Throws InputError with the file, line and key.
void readDaemonConfiguration(const std::string& path, DaemonArgs& args);

/// The --help text: every option with its value's form, its default and what it does.
std::string daemonUsage();

/// args as a configuration file: every option, each preceded by its help as a comment.
std::string daemonConfiguration(const DaemonArgs& args);

}  // namespace stepcal::service

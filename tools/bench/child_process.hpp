// The benches' child processes (stepcal-diagnose-stress, stepcal-bench-scale): a command run as
// the user runs it, with its status, wall time and peak memory.
#pragma once

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

extern char** environ;

namespace stepcal::bench {

/// One child's run: its shell-style status (128 + signal when killed, 127 when it could not
/// start), wall time and peak resident memory.
struct ChildRun {
  int status = 0;
  double wall_s = 0.0;
  double max_rss_mb = 0.0;  ///< wait4's ru_maxrss
};

/// Runs argv (argv[0] a path) with stdout and stderr to the given files.
inline ChildRun runChild(const std::vector<std::string>& argv, const std::filesystem::path& out,
                         const std::filesystem::path& err) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  ChildRun r;
  const auto start = std::chrono::steady_clock::now();
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) {
    r.status = 127;
    return r;
  }
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.max_rss_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;  // kB on Linux
  r.status = WIFSIGNALED(status) ? 128 + WTERMSIG(status)
                                 : (WIFEXITED(status) ? WEXITSTATUS(status) : 255);
  return r;
}

/// The stepcal command a bench runs: its own folder's by default. False, with the error on
/// stderr, when it is not an executable.
inline bool stepcalIsExecutable(const char* tool, const std::string& stepcal) {
  if (access(stepcal.c_str(), X_OK) == 0) return true;
  std::cerr << tool << ": error: --stepcal '" << stepcal
            << "' is not an executable; expected the stepcal command (build/bin/stepcal)\n";
  return false;
}

/// The stepcal command beside this executable.
inline std::string stepcalBesideThis() {
  return (std::filesystem::canonical("/proc/self/exe").parent_path() / "stepcal").string();
}

}  // namespace stepcal::bench

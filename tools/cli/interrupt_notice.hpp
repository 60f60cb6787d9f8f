// How `stepcal calibrate` and `stepcal diagnose` end on SIGINT and SIGTERM.
#pragma once

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <deque>
#include <iostream>
#include <string>
#include <vector>

#include "stepcal/common/atomic_file.hpp"

namespace stepcal::cli {

// SIGINT and SIGTERM end a calibration or diagnosis at once (the trainer has no point to stop
// at) by the signal, after one line on stderr saying which output files are as they were. Files
// are written with the signals held (SignalsHeldForWriting) until the line is updated, so it is
// always true: an output is either untouched or completely replaced.
class InterruptNotice {
 public:
  explicit InterruptNotice(std::vector<std::string> outputs) : unchanged_(std::move(outputs)) {
    publish();
    struct sigaction action {};
    action.sa_handler = onSignal;
    action.sa_flags = SA_RESETHAND;  // the raise in onSignal then ends the process
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, nullptr);
    sigaction(SIGTERM, &action, nullptr);
  }
  ~InterruptNotice() {
    ::signal(SIGINT, SIG_DFL);
    ::signal(SIGTERM, SIG_DFL);
    line_.store("");
  }
  InterruptNotice(const InterruptNotice&) = delete;
  InterruptNotice& operator=(const InterruptNotice&) = delete;

  /// Writes one output with the signals held, and the line then counts it as written.
  template <typename Write>
  void write(const std::string& path, const std::string& what, Write&& write_file) {
    const SignalsHeldForWriting held;
    write_file();
    std::cerr << "wrote " << what << " " << path << "\n";
    unchanged_.erase(std::find(unchanged_.begin(), unchanged_.end(), path));
    written_.push_back(path);
    publish();
  }

 private:
  static std::string listed(const std::vector<std::string>& paths) {
    std::string out;
    for (size_t i = 0; i < paths.size(); ++i) {
      out += (i == 0 ? "" : i + 1 == paths.size() ? " and " : ", ") + paths[i];
    }
    return out;
  }

  void publish() {
    std::string line = "stepcal: interrupted";
    if (!written_.empty()) line += "; wrote " + listed(written_);
    if (!unchanged_.empty()) line += "; " + listed(unchanged_) + " unchanged";
    // Every line stays alive: the handler may be printing the previous one.
    lines_.push_back(line + "\n");
    line_.store(lines_.back().c_str());
  }

  static void onSignal(int signal) {
    const char* line = line_.load();
    const ssize_t ignored = ::write(STDERR_FILENO, line, std::strlen(line));
    (void)ignored;  // nothing left to tell if stderr is gone
    ::raise(signal);
  }

  static inline std::atomic<const char*> line_{""};
  std::vector<std::string> unchanged_;
  std::vector<std::string> written_;
  std::deque<std::string> lines_;
};

}  // namespace stepcal::cli

// Nothing lost: a `stepcal calibrate` or `stepcal diagnose` whose output cannot be written (the
// file size limit, ulimit -f) or that is interrupted (SIGINT, SIGTERM) leaves the previous model
// and report byte for byte, no temporary file beside them, and says so.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "stepcal/common/model_file.hpp"
#include "support/command.hpp"
#include "support/files.hpp"

extern char** environ;

namespace stepcal {
namespace {

namespace fs = std::filesystem;
using test::readText;
using test::run;
using test::TempDir;
using test::writeText;

const std::string kStepcal = std::string(STEPCAL_BIN_DIR) + "/stepcal";
const std::string kPreviousModel = "the previous model\n";
const std::string kPreviousReport = "<p>the previous report</p>\n";

class NothingLost : public ::testing::Test {
 protected:
  /// The simulated paper campaign, once for all tests: calibrating it takes half a second or
  /// more, diagnosing it seconds.
  static void SetUpTestSuite() {
    campaign_ = new TempDir;
    ASSERT_EQ(run(kStepcal + " simulate --seed 1 --out " + campaign_->path().string()).status, 0);
  }
  static void TearDownTestSuite() {
    delete campaign_;
    campaign_ = nullptr;
  }

  /// An output folder holding a previous model.stepcal and report.html.
  NothingLost() {
    writeText(model_, kPreviousModel);
    writeText(report_, kPreviousReport);
  }

  static std::string campaign() { return campaign_->path().string(); }

  /// The previous files, byte for byte, and nothing beside them.
  void expectPreviousOutputsAlone() const {
    EXPECT_EQ(readText(model_), kPreviousModel);
    EXPECT_EQ(readText(report_), kPreviousReport);
    EXPECT_EQ(out_.entries(), (std::vector<std::string>{"model.stepcal", "report.html"}));
  }

  static inline TempDir* campaign_ = nullptr;
  TempDir out_;
  const fs::path model_ = out_.path() / "model.stepcal";
  const fs::path report_ = out_.path() / "report.html";
};

// ulimit -f 16: 8 kB at most (dash counts 512-byte blocks), far below a model's 60 kB.
TEST_F(NothingLost, AModelTooLargeForTheFileSizeLimitLeavesThePreviousOne) {
  const test::CommandResult r =
      run("ulimit -f 16 && " + kStepcal + " calibrate " + campaign() + " --out " + model_.string());
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("stepcal: error: " + model_.string() + ": cannot write the model"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("File too large"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("the previous file, if any, is unchanged and the temporary file removed"),
            std::string::npos)
      << r.out;
  expectPreviousOutputsAlone();
}

// The report is written first; when it fails, the model is not touched either.
TEST_F(NothingLost, AReportTooLargeForTheFileSizeLimitLeavesBothPreviousFiles) {
  const test::CommandResult r = run("ulimit -f 16 && " + kStepcal + " calibrate " + campaign() +
                                    " --report " + report_.string() + " --out " + model_.string());
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find(report_.string() + ": cannot write the report"), std::string::npos) << r.out;
  expectPreviousOutputsAlone();
}

struct Interruption {
  const char* command;
  int signal;
};

void PrintTo(const Interruption& i, std::ostream* out) {
  *out << i.command << " " << strsignal(i.signal);
}

class NothingLostInterrupted : public NothingLost,
                               public ::testing::WithParamInterface<Interruption> {};

/// True once the process catches both SIGINT and SIGTERM (its /proc status, field SigCgt).
bool catchesInterrupts(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("SigCgt:", 0) != 0) continue;
    const unsigned long long caught = std::stoull(line.substr(7), nullptr, 16);
    const auto bit = [](int signal) { return 1ull << (signal - 1); };
    return (caught & bit(SIGINT)) && (caught & bit(SIGTERM));
  }
  return false;
}

// The signal is sent as soon as stepcal has installed its handler, long before it would write
// (reading the campaign alone takes milliseconds, calibrating it half a second or more).
// Whenever it arrives, the line stepcal prints must match the files: those it names unchanged
// are the previous ones, the others complete new files (all of them if the run ended first).
TEST_P(NothingLostInterrupted, LeavesThePreviousModelAndReportAndSaysSo) {
  const Interruption& interruption = GetParam();
  const fs::path log = out_.path().parent_path() / (out_.path().filename().string() + ".log");
  const std::vector<std::string> args = {kStepcal,         interruption.command, campaign(),
                                         "--out",          model_.string(),      "--report",
                                         report_.string()};
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t files;
  posix_spawn_file_actions_init(&files);
  posix_spawn_file_actions_addopen(&files, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&files, STDERR_FILENO, log.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = 0;
  ASSERT_EQ(posix_spawn(&pid, kStepcal.c_str(), &files, nullptr, argv.data(), environ), 0);
  posix_spawn_file_actions_destroy(&files);

  // It catches them from its start: polled every millisecond, a run that long cannot end unseen.
  int status = 0;
  while (!catchesInterrupts(pid)) {
    ASSERT_NE(waitpid(pid, &status, WNOHANG), pid)
        << "stepcal ended without ever catching SIGINT and SIGTERM:\n" << readText(log);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_EQ(kill(pid, interruption.signal), 0);
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  const std::string said = readText(log);
  fs::remove(log);

  // "stepcal: interrupted[; wrote A[ and B]][; C[ and D] unchanged]": the files it names as
  // unchanged must be the previous ones, the others complete new files.
  bool model_unchanged = false;
  bool report_unchanged = false;
  if (WIFSIGNALED(status)) {
    EXPECT_EQ(WTERMSIG(status), interruption.signal) << said;
    const size_t at = said.find("stepcal: interrupted");
    ASSERT_NE(at, std::string::npos) << said;
    const std::string line = said.substr(at, said.find('\n', at) - at);
    const bool lists_unchanged = line.size() > 10 && line.substr(line.size() - 10) == " unchanged";
    const auto unchanged = [&](const fs::path& path) {
      const size_t named = line.find(path.string());
      EXPECT_NE(named, std::string::npos) << line;
      return lists_unchanged && named != std::string::npos && named > line.rfind("; ");
    };
    model_unchanged = unchanged(model_);
    report_unchanged = unchanged(report_);
  } else {
    std::cout << "the run ended before the signal; checking its outputs are complete\n";
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << said;
  }
  if (model_unchanged) {
    EXPECT_EQ(readText(model_), kPreviousModel);
  } else {
    EXPECT_NO_THROW(readModelFile(model_.string())) << said;
  }
  if (report_unchanged) {
    EXPECT_EQ(readText(report_), kPreviousReport);
  } else {
    EXPECT_NE(readText(report_).find("</html>"), std::string::npos);
  }
  EXPECT_EQ(out_.entries(), (std::vector<std::string>{"model.stepcal", "report.html"}));
}

INSTANTIATE_TEST_SUITE_P(, NothingLostInterrupted,
                         ::testing::Values(Interruption{"calibrate", SIGINT},
                                           Interruption{"calibrate", SIGTERM},
                                           Interruption{"diagnose", SIGINT},
                                           Interruption{"diagnose", SIGTERM}),
                         [](const auto& info) {
                           return std::string(info.param.command) +
                                  (info.param.signal == SIGINT ? "Sigint" : "Sigterm");
                         });

}  // namespace
}  // namespace stepcal

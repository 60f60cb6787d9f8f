// stepcal-runtime: the real-time daemon beside the robot controller. Answers correction requests
// over LCM with a calibrated model (docs/runtime.md).
//
//   stepcal-runtime [--config FILE] --model MODEL [--lcm-url URL] [--budget-us 200] …
//
// Every option, on the command line or as a key of the --config file: daemon_options.cpp's table
// (`stepcal-runtime --help`).
// One serving thread polls the LCM socket, a signalfd (SIGHUP reload, SIGINT/SIGTERM stop) and a
// 10 Hz timerfd (status). With --sensor can:IFACE the F/T driver polls on its own thread
// (created after --realtime's settings, so it inherits them). Reloads load the new file on their own thread and swap it in through
// the service's ModelHandle, so requests keep being answered meanwhile; a refused file leaves the
// model in service as it is.
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <sys/stat.h>
#include <sys/timerfd.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <string_view>
#include <thread>

#include "stepcal/common/error.hpp"
#include "stepcal/common/exit_codes.hpp"
#include "stepcal/service/auth.hpp"
#include "stepcal/service/channels.hpp"
#include "stepcal/service/daemon_options.hpp"
#include "stepcal/service/lcm_server.hpp"
#include "stepcal/service/realtime.hpp"

namespace {

using namespace stepcal;

constexpr long kStatusPeriodNs = 100'000'000;  // 10 Hz

void logLine(const char* format, ...) __attribute__((format(printf, 1, 2)));
void logLine(const char* format, ...) {
  char line[1024];
  va_list args;
  va_start(args, format);
  std::vsnprintf(line, sizeof line, format, args);
  va_end(args);
  std::fprintf(stderr, "stepcal-runtime: %s\n", line);
}

/// The real-time settings (service::enterRealtime); false, with one line saying what is
/// missing, when the process is not permitted.
bool enterRealtime() {
  const std::string refusal = service::enterRealtime();
  if (refusal.empty()) return true;
  logLine("--realtime: %s; running without real-time settings", refusal.c_str());
  return false;
}

/// Reloads the model file on its own thread (SCHED_OTHER) when asked.
class Reloader {
 public:
  Reloader(service::Service& service, std::string path)
      : service_(service), path_(std::move(path)), wake_fd_(eventfd(0, EFD_CLOEXEC)) {
    if (wake_fd_ < 0) throw InputError(std::string("eventfd: ") + std::strerror(errno));
    thread_ = std::thread([this] { run(); });
  }
  ~Reloader() {
    stop_.store(true);
    wake();
    thread_.join();
    close(wake_fd_);
  }
  Reloader(const Reloader&) = delete;
  Reloader& operator=(const Reloader&) = delete;

  /// Asks for a reload; returns at once (a write to an eventfd).
  void wake() {
    const uint64_t one = 1;
    if (write(wake_fd_, &one, sizeof one) < 0) logLine("reload request lost: %s", std::strerror(errno));
  }

 private:
  void run() {
    sched_param normal{};
    pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
    uint64_t requests = 0;
    while (read(wake_fd_, &requests, sizeof requests) == sizeof requests && !stop_.load()) {
      try {
        service_.reloadFile(path_);
        logLine("reloaded %s: model %016llx in service", path_.c_str(),
                static_cast<unsigned long long>(service_.modelId()));
      } catch (const InputError& e) {
        logLine("reload refused, keeping model %016llx: %s",
                static_cast<unsigned long long>(service_.modelId()), e.what());
      }
    }
  }

  service::Service& service_;
  std::string path_;
  int wake_fd_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// A file descriptor closed on destruction.
class Fd {
 public:
  explicit Fd(int fd, const char* what) : fd_(fd) {
    if (fd_ < 0) throw InputError(std::string(what) + ": " + std::strerror(errno));
  }
  ~Fd() { close(fd_); }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

using service::DaemonArgs;
/// The refusals the service counts, each logged once when it first happens (the status message
/// counts them all).
class RefusalLog {
 public:
  void update(const service::ServiceCounters& c) {
    once(c.old_version, old_version_,
         "refused a request in an older message version (1: correction_request_v1_t, or 2): "
         "this daemon reads correction_request_t version 3; update the client (docs/runtime.md, "
         "Messages); "
         "counted in STEPCAL_STATUS old_version_requests");
    once(c.forged, forged_,
         "dropped a request whose authentication code does not verify (forged, or sent without "
         "the cell key); counted in STEPCAL_STATUS forged_requests");
    once(c.replayed, replayed_,
         "dropped a request whose counter is not fresh (a replay, or a clock off by more than "
         "--auth-window-ms); counted in STEPCAL_STATUS replayed_requests");
  }

 private:
  static void once(int64_t count, bool& logged, const char* line) {
    if (count > 0 && !logged) {
      logLine("%s", line);
      logged = true;
    }
  }
  bool old_version_ = false, forged_ = false, replayed_ = false;
};

/// The systemd credential that carries the cell key (LoadCredential=cell-key:… in the unit).
constexpr const char* kKeyCredential = "cell-key";
/// Its content when the unit found no key file: SetCredential=cell-key:none.
constexpr std::string_view kNoKeyCredential = "none";

/// True when the file at path holds exactly kNoKeyCredential.
bool holdsNoKey(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  std::string content(kNoKeyCredential.size() + 1, '\0');
  file.read(content.data(), std::streamsize(content.size()));
  return file.gcount() == std::streamsize(kNoKeyCredential.size()) &&
         content.compare(0, kNoKeyCredential.size(), kNoKeyCredential) == 0;
}

/// Where the cell key comes from: --key-file when given (the command line or the configuration
/// file: an explicit choice wins), else the credential cell-key when systemd handed one
/// ($CREDENTIALS_DIRECTORY), else none. The credential "none" is the unit's fallback for a cell
/// without a key file (SetCredential=cell-key:none; systemd takes no empty value): no key.
struct KeySource {
  std::string path;    ///< empty: no key
  std::string source;  ///< "--key-file" or "credential cell-key"
};

KeySource keySource(const DaemonArgs& args) {
  if (!args.key_file.empty()) return {args.key_file, "--key-file"};
  const char* credentials = std::getenv("CREDENTIALS_DIRECTORY");
  if (credentials == nullptr || *credentials == '\0') return {};
  const std::string path = std::string(credentials) + "/" + kKeyCredential;
  struct stat st {};
  if (stat(path.c_str(), &st) != 0 || holdsNoKey(path)) return {};
  return {path, std::string("credential ") + kKeyCredential};
}

int serve(const DaemonArgs& args) {
  if (args.budget_us <= 0) throw InputError("--budget-us must be > 0");
  if (!(args.max_wrench_age_ms > 0.0)) throw InputError("--max-wrench-age-ms must be > 0");
  service::ServiceOptions options;
  options.budget_ns = int64_t(args.budget_us) * 1000;
  options.max_wrench_age_ns = int64_t(args.max_wrench_age_ms * 1e6);
  const KeySource key = keySource(args);
  if (!key.path.empty()) {
    if (!(args.auth_window_ms > 0.0)) throw InputError("--auth-window-ms must be > 0");
    options.key = service::CellKey::load(key.path, key.source);
    options.auth_window_us = int64_t(args.auth_window_ms * 1e3);
  }

  // Signals go to the signalfd only; blocked before any thread starts, so every thread inherits it.
  sigset_t signals;
  sigemptyset(&signals);
  for (int s : {SIGHUP, SIGINT, SIGTERM}) sigaddset(&signals, s);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  const Fd signal_fd(signalfd(-1, &signals, SFD_CLOEXEC), "signalfd");

  service::Service service(runtime::RuntimeModel::load(args.model_path), args.model_path, options);
  // Real-time before LCM starts its receive thread, so that it inherits SCHED_FIFO.
  const bool realtime = args.realtime && enterRealtime();
  lcm_t* lcm = lcm_create(args.lcm_url.c_str());
  if (lcm == nullptr) throw InputError("--lcm-url '" + args.lcm_url + "': LCM cannot open it");
  const std::unique_ptr<lcm_t, void (*)(lcm_t*)> lcm_owner(lcm, &lcm_destroy);
  service::LcmServer server(lcm, service);
  const std::unique_ptr<service::WrenchFeed> feed =
      service::makeWrenchFeed(args.sensor, lcm, service);
  Reloader reloader(service, args.model_path);

  const Fd timer_fd(timerfd_create(CLOCK_MONOTONIC, TFD_CLOEXEC), "timerfd");
  const itimerspec period{{0, kStatusPeriodNs}, {0, kStatusPeriodNs}};
  timerfd_settime(timer_fd.get(), 0, &period, nullptr);

  logLine("serving %s (model %016llx) on %s: budget %d us, live wrench %s (max age %g ms), "
          "real-time %s, receive queues %d messages, %s",
          args.model_path.c_str(), static_cast<unsigned long long>(service.modelId()),
          args.lcm_url.c_str(), args.budget_us, feed->describe().c_str(),
          args.max_wrench_age_ms, realtime ? "on" : "off", service::kSubscriptionQueueCapacity,
          key.path.empty()
              ? "no cell key (anyone who reaches the LCM group may send requests and sensor "
                "commands)"
              : ("cell key " + key.path + " (" + key.source +
                 "; requests, replies and sensor commands authenticated)").c_str());
  RefusalLog refusals;

  pollfd fds[3] = {{lcm_get_fileno(lcm), POLLIN, 0},
                   {signal_fd.get(), POLLIN, 0},
                   {timer_fd.get(), POLLIN, 0}};
  for (;;) {
    if (poll(fds, 3, -1) < 0) {
      if (errno == EINTR) continue;
      throw InputError(std::string("poll: ") + std::strerror(errno));
    }
    if (fds[1].revents & POLLIN) {
      signalfd_siginfo info{};
      if (read(signal_fd.get(), &info, sizeof info) != sizeof info) continue;
      if (info.ssi_signo == SIGHUP) {
        reloader.wake();
        continue;
      }
      // Both counts let a test tell requests lost before the daemon from replies lost after it.
      logLine("%s: stopping after %lld requests, %lld replies", strsignal(int(info.ssi_signo)),
              static_cast<long long>(service.counters().requests),
              static_cast<long long>(service.counters().replies));
      return 0;
    }
    if (fds[2].revents & POLLIN) {
      uint64_t expirations = 0;
      if (read(timer_fd.get(), &expirations, sizeof expirations) == sizeof expirations) {
        server.publishStatus(realtime);
        feed->publishStatus();
        refusals.update(service.counters());
      }
    }
    if (fds[0].revents & POLLIN) lcm_handle(lcm);
  }
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const service::DaemonCommandLine command_line = service::parseDaemonCommandLine(argc, argv);
    if (command_line.help) {
      std::fputs(service::daemonUsage().c_str(), stdout);
      return 0;
    }
    if (command_line.print_config) {
      std::fputs(service::daemonConfiguration(command_line.args).c_str(), stdout);
      return 0;
    }
    return serve(command_line.args);
  } catch (const InputError& e) {
    std::fprintf(stderr, "stepcal-runtime: error: %s\n", e.what());
    return exit_code::kBadInput;
  }
}

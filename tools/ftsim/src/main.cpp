// stepcal-ftsim: a simulated ATI Net CAN OEM F/T sensor on a SocketCAN interface, the
// counterpart of stepcal-runtime --sensor can:IFACE (protocol: runtime/netcan.hpp).
//
//   stepcal-ftsim --iface vcan0 [--base-id 0x20] [--wrench fx fy fz mx my mz]
//                 [--truth truth.json [--lcm-url URL]] [--force-sigma-n S] [--moment-sigma-nm S]
//                 [--offset fx fy fz mx my mz] [--seed N] [--drop P] [--corrupt P]
//                 [--status-word W] [--garbage-per-poll N] [--stall-at-s T --stall-for-s D]
//                 [--bus-off-at-s T --bus-off-for-s D] [--faults-at-s T --faults-for-s D]
//                 [--calibration-gain G] [--duration-s S] [--json]
//
// The wrench it feels: --wrench (N, N·m, sensor axes), or with --truth the payload wrench of the
// twin (stepcal simulate's truth.json) at the pose and payload of each robot_state_t received on
// STEPCAL_ROBOT_STATE (echoed on STEPCAL_ROBOT_STATE_APPLIED once felt); noise defaults to the twin's F/T noise then. Faults: per-frame drop and
// corruption probabilities, a status word in every reading, garbage frames, a stall and a bus-off
// (error frames CAN_ERR_BUSOFF, then CAN_ERR_RESTARTED) at given times; --faults-at-s/-for-s
// confine the per-reading faults to a window. Each transition is logged with its Unix time, so
// a test can line it up with the replies it saw. --calibration-gain scales the calibration
// matrix: another calibration of the sensor (what a restart with another one active presents).
// Stops on SIGINT/SIGTERM or after --duration-s, printing its counters.
#include <CLI/CLI.hpp>
#include <poll.h>
#include <signal.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <iostream>
#include <optional>
#include <thread>

#include <lcm/lcm.h>
#include <nlohmann/json.hpp>
#include <stepcal_lcm/robot_state_t.hpp>

#include "stepcal/common/error.hpp"
#include "stepcal/ftsim/simulator.hpp"
#include "stepcal/runtime/ft_sensor.hpp"
#include "stepcal/service/channels.hpp"
#include "stepcal/twin/twin.hpp"

namespace {

using namespace stepcal;
using Clock = std::chrono::steady_clock;

struct Args {
  std::string iface;
  uint32_t base_id = 0x20;
  std::vector<double> wrench, offset;
  std::string truth_path;
  std::string lcm_url = service::kDefaultLcmUrl;
  std::optional<double> force_sigma_n, moment_sigma_nm;
  uint64_t seed = 1;
  double drop = 0.0, corrupt = 0.0;
  uint32_t status_word = 0;
  int garbage_per_poll = 0;
  double stall_at_s = -1.0, stall_for_s = 0.0;
  double bus_off_at_s = -1.0, bus_off_for_s = 0.0;
  double faults_at_s = 0.0, faults_for_s = -1.0;  ///< negative duration: to the end
  double calibration_gain = 1.0;
  double duration_s = 0.0;
  bool json = false;
};

nlohmann::json readJson(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("--truth: cannot read the file", path);
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("--truth: not JSON: ") + e.what(), path);
  }
}

/// Receives robot_state_t, sets the simulator's wrench to the twin's payload wrench there and
/// echoes the state on kRobotStateAppliedChannel: from then on every reading is of that state.
struct StateListener {
  const twin::TwinRobot* truth;
  ftsim::SensorSimulator* simulator;
  lcm_t* lcm;
  int64_t states = 0, undecodable = 0;

  static void onState(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    auto* self = static_cast<StateListener*>(user);
    stepcal_lcm::robot_state_t state{};
    const int size = int(rbuf->data_size);
    if (state.decode(rbuf->data, 0, size) != size) {
      ++self->undecodable;
      return;
    }
    JointVector q(6);
    for (int i = 0; i < 6; ++i) q[i] = state.q_rad[i];
    self->simulator->setWrench(self->truth->sensorWrench(q, state.payload_kg));
    ++self->states;
    lcm_publish(self->lcm, service::kRobotStateAppliedChannel, rbuf->data, rbuf->data_size);
  }
};

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

double unixSeconds() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

/// Whether t lies in [at, at + length); a negative length lasts to the end.
bool inWindow(double t, double at, double length) {
  return t >= at && (length < 0.0 || t < at + length);
}

void logTransition(const char* what, double t) {
  std::fprintf(stderr, "stepcal-ftsim: %s at %.3f s (unix %.6f)\n", what, t, unixSeconds());
}

int run(const Args& args) {
  ftsim::SimulatorOptions options;
  options.base_id = args.base_id;
  options.seed = args.seed;
  std::optional<twin::TwinRobot> truth;
  if (!args.truth_path.empty()) {
    const nlohmann::json truth_json = readJson(args.truth_path);
    truth = twin::TwinRobot::fromTruthJson(truth_json);
    if (truth_json.contains("noise")) {
      // The campaign's F/T noise, so live wrenches are as noisy as the measured ones.
      const nlohmann::json& noise = truth_json.at("noise");
      options.force_sigma_n = noise.value("ft_force_sigma_n", 0.0);
      options.moment_sigma_nm = noise.value("ft_moment_sigma_nm", 0.0);
    }
  }
  if (args.force_sigma_n) options.force_sigma_n = *args.force_sigma_n;
  if (args.moment_sigma_nm) options.moment_sigma_nm = *args.moment_sigma_nm;
  if (!args.offset.empty()) options.offset_Sensor = Vec6(args.offset.data());
  for (float& entry : options.calibration.matrix) entry = float(entry * args.calibration_gain);
  ftsim::SensorSimulator simulator(options);
  if (!args.wrench.empty()) simulator.setWrench(Vec6(args.wrench.data()));
  ftsim::Faults faults;
  const auto setReadingFaults = [&](bool on) {
    faults.drop_probability = on ? args.drop : 0.0;
    faults.corrupt_probability = on ? args.corrupt : 0.0;
    faults.status_word = on ? uint16_t(args.status_word) : uint16_t(0);
    faults.garbage_per_poll = on ? args.garbage_per_poll : 0;
  };
  bool reading_faults = inWindow(0.0, args.faults_at_s, args.faults_for_s);
  setReadingFaults(reading_faults);
  simulator.setFaults(faults);

  // The sensor answers only its own ids; error frames are injected on a socket of their own.
  runtime::CanSocket socket =
      runtime::CanSocket::open(args.iface, {runtime::sensorFilter(args.base_id)}, 0);
  runtime::CanSocket injector = runtime::CanSocket::open(args.iface, {}, 0);

  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  const int signal_fd = signalfd(-1, &signals, SFD_CLOEXEC);

  lcm_t* lcm = nullptr;
  if (truth) {
    lcm = lcm_create(args.lcm_url.c_str());
    if (lcm == nullptr) throw InputError("--lcm-url '" + args.lcm_url + "': LCM cannot open it");
  }
  StateListener listener{truth ? &*truth : nullptr, &simulator, lcm};
  if (truth) {
    lcm_subscribe(lcm, service::kRobotStateChannel, &StateListener::onState, &listener);
  }

  std::atomic<bool> stop{false};
  std::thread server([&] { simulator.serve(socket, stop); });
  std::fprintf(stderr, "stepcal-ftsim: sensor base id 0x%02X on %s (unix %.6f), %s\n",
               args.base_id, args.iface.c_str(), unixSeconds(),
               truth ? ("payload wrench of " + args.truth_path + " at " +
                        service::kRobotStateChannel + " poses").c_str()
                     : "a fixed wrench");
  const Clock::time_point start = Clock::now();
  bool stalled = false, bus_off = false;
  int64_t injected_errors = 0;
  for (;;) {
    pollfd fds[2] = {{signal_fd, POLLIN, 0}, {lcm ? lcm_get_fileno(lcm) : -1, POLLIN, 0}};
    poll(fds, lcm ? 2 : 1, 5);
    if (fds[0].revents & POLLIN) break;
    if (lcm && (fds[1].revents & POLLIN)) lcm_handle(lcm);
    const double t = secondsSince(start);
    if (args.duration_s > 0.0 && t >= args.duration_s) break;
    const bool stall_now = args.stall_at_s >= 0.0 && t >= args.stall_at_s && t < args.stall_at_s + args.stall_for_s;
    if (stall_now != stalled) {
      stalled = stall_now;
      faults.stalled = stalled;
      simulator.setFaults(faults);
      logTransition(stalled ? "stalled" : "answering again", t);
    }
    const bool reading_faults_now = inWindow(t, args.faults_at_s, args.faults_for_s);
    if (reading_faults_now != reading_faults) {
      reading_faults = reading_faults_now;
      setReadingFaults(reading_faults);
      simulator.setFaults(faults);
      logTransition(reading_faults ? "reading faults on" : "reading faults off", t);
    }
    const bool off_now = args.bus_off_at_s >= 0.0 && t >= args.bus_off_at_s && t < args.bus_off_at_s + args.bus_off_for_s;
    if (off_now != bus_off) {
      bus_off = off_now;
      injector.send(ftsim::errorFrame(bus_off ? CAN_ERR_BUSOFF : CAN_ERR_RESTARTED));
      ++injected_errors;
      faults.stalled = bus_off || stalled;  // a bus-off node hears nothing
      simulator.setFaults(faults);
      logTransition(bus_off ? "bus-off" : "bus restarted", t);
    }
  }
  stop.store(true);
  server.join();
  if (lcm) lcm_destroy(lcm);
  const ftsim::SimulatorCounters c = simulator.counters();
  const nlohmann::json report = {{"requests", c.requests},   {"gauge_replies", c.gauge_replies},
                                 {"dropped", c.dropped},     {"corrupted", c.corrupted},
                                 {"garbage", c.garbage},     {"saturated", c.saturated},
                                 {"resets", c.resets},       {"robot_states", listener.states},
                                 {"error_frames", injected_errors}};
  if (args.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    std::printf("stepcal-ftsim: %s\n", report.dump().c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stepcal-ftsim: a simulated ATI Net CAN OEM F/T sensor on a SocketCAN interface"};
  Args args;
  app.add_option("--iface", args.iface, "CAN interface, e.g. vcan0")->required();
  app.add_option("--base-id", args.base_id, "base id, 0 … 0x7F")->capture_default_str();
  app.add_option("--wrench", args.wrench, "fixed wrench felt: fx fy fz (N) mx my mz (N·m)")
      ->expected(6);
  app.add_option("--truth", args.truth_path,
                 "truth.json of a simulated campaign: feel its payload wrench at the poses of "
                 "robot_state_t on STEPCAL_ROBOT_STATE");
  app.add_option("--lcm-url", args.lcm_url, "LCM URL (with --truth)")->capture_default_str();
  app.add_option("--force-sigma-n", args.force_sigma_n, "force noise per axis, 1-σ, N");
  app.add_option("--moment-sigma-nm", args.moment_sigma_nm, "moment noise per axis, 1-σ, N·m");
  app.add_option("--offset", args.offset, "reading with nothing attached (N, N·m)")->expected(6);
  app.add_option("--seed", args.seed, "noise and fault draws")->capture_default_str();
  app.add_option("--drop", args.drop, "probability that a reply frame is lost")->check(CLI::Range(0.0, 1.0));
  app.add_option("--corrupt", args.corrupt, "probability that a reply frame is corrupt")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--status-word", args.status_word, "status word of every reading (0x8020 …)")
      ->check(CLI::Range(0u, 0xFFFFu));
  app.add_option("--garbage-per-poll", args.garbage_per_poll, "random frames before each reply")
      ->check(CLI::Range(0, 100));
  app.add_option("--stall-at-s", args.stall_at_s, "stop answering at this time, s");
  app.add_option("--stall-for-s", args.stall_for_s, "for this long, s");
  app.add_option("--bus-off-at-s", args.bus_off_at_s, "report bus-off at this time, s");
  app.add_option("--bus-off-for-s", args.bus_off_for_s, "then restart after this long, s");
  app.add_option("--faults-at-s", args.faults_at_s,
                 "--drop, --corrupt, --status-word, --garbage-per-poll from this time on, s")
      ->capture_default_str();
  app.add_option("--faults-for-s", args.faults_for_s, "for this long (negative: to the end), s")
      ->capture_default_str();
  app.add_option("--calibration-gain", args.calibration_gain,
                 "calibration matrix = the default one times this: another calibration")
      ->check(CLI::Range(0.01, 100.0))
      ->capture_default_str();
  app.add_option("--duration-s", args.duration_s, "stop after this long (0: on a signal), s");
  app.add_flag("--json", args.json, "counters as JSON");
  CLI11_PARSE(app, argc, argv);
  try {
    if (args.base_id > runtime::netcan::kMaxBaseId) throw InputError("--base-id: expected 0 … 0x7F");
    if (!args.wrench.empty() && !args.truth_path.empty()) {
      throw InputError("--wrench and --truth: give one source of the wrench");
    }
    return run(args);
  } catch (const InputError& e) {
    std::fprintf(stderr, "stepcal-ftsim: error: %s\n", e.what());
    return 2;
  }
}

// stepcal-client --sensor-command: one sensor_command_t (bias, clear-bias, reset) to the daemon's
// CAN sensor. The protocol has no acknowledgement: what the daemon did with the command shows in
// its sensor_status_t (10 Hz), whose counters of refused, forged and replayed commands grow when
// it drops one. The client reads a status before sending and waits for two published after
// (the first may have left before the command was handled): unchanged counters confirm it.
#include <algorithm>
#include <iostream>

#include <stepcal_lcm/sensor_command_t.hpp>
#include <stepcal_lcm/sensor_status_t.hpp>

#include "client.hpp"
#include "stepcal/service/lcm_server.hpp"
#include "stepcal/service/service.hpp"

namespace stepcal::client {
namespace {

using stepcal_lcm::sensor_status_t;

/// The daemon's sensor statuses as they arrive.
struct SensorStatuses {
  std::vector<sensor_status_t> received;
  static void on(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    sensor_status_t status{};
    if (status.decode(rbuf->data, 0, int(rbuf->data_size)) != int(rbuf->data_size)) return;
    static_cast<SensorStatuses*>(user)->received.push_back(std::move(status));
  }
  /// Statuses published after utime_us.
  int after(int64_t utime_us) const {
    return int(std::count_if(received.begin(), received.end(),
                             [&](const sensor_status_t& s) { return s.utime > utime_us; }));
  }
};

/// Handles LCM until `done` holds or `wait` has passed; whether it holds.
template <typename Done>
bool waitFor(lcm_t* lcm, Clock::duration wait, const Done& done) {
  const Clock::time_point until = Clock::now() + wait;
  while (!done() && Clock::now() < until) {
    service::handleLcmUntil(lcm, std::min(until, Clock::now() + std::chrono::milliseconds(20)));
  }
  return done();
}

/// Why the daemon dropped the command, from its counters before and after; empty when it did not.
std::string refusal(const sensor_status_t& before, const sensor_status_t& after) {
  if (after.forged_commands > before.forged_commands) {
    return "its code did not verify (no --key-file, or another key than the daemon's)";
  }
  if (after.replayed_commands > before.replayed_commands) {
    return "its counter was not fresh (a replay, or this host's clock off the daemon's)";
  }
  if (after.refused_commands > before.refused_commands) return "it did not decode or named no known command";
  return {};
}

/// The command's bytes, sealed (in place: its last fields) with the key of --key-file when given.
std::vector<uint8_t> commandBytes(const Args& args, bool& sealed) {
  stepcal_lcm::sensor_command_t command{};
  command.utime = unixMicroseconds();
  command.command = int8_t(1 + choice("--sensor-command", args.sensor_command,
                                      {"bias", "clear-bias", "reset"}));
  std::vector<uint8_t> bytes(size_t(command.getEncodedSize()));
  const int size = command.encode(bytes.data(), 0, int(bytes.size()));
  bytes.resize(size_t(std::max(size, 0)));
  const std::optional<service::CellKey> key = loadKey(args.key_file);
  sealed = key.has_value();
  if (key) service::MessageSigner(*key).seal(bytes.data(), int(bytes.size()));
  return bytes;
}

}  // namespace

int runSensorCommand(const Args& args) {
  bool sealed = false;
  const std::vector<uint8_t> bytes = commandBytes(args, sealed);
  const Lcm lcm(args.lcm_url);
  SensorStatuses statuses;
  lcm_subscription_t* subscription = service::subscribeQueued(
      lcm.get(), service::kSensorStatusChannel, &SensorStatuses::on, &statuses);
  // Statuses come at 10 Hz: wait for at least a second, whatever --timeout-ms.
  const auto wait = std::max<Clock::duration>(
      std::chrono::milliseconds(1000),
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::milli>(args.timeout_ms)));
  const bool had_status = waitFor(lcm.get(), wait, [&] { return !statuses.received.empty(); });
  const sensor_status_t before = had_status ? statuses.received.back() : sensor_status_t{};
  const int64_t sent_us = unixMicroseconds();
  if (lcm_publish(lcm.get(), service::kSensorCommandChannel, bytes.data(), unsigned(bytes.size())) != 0) {
    lcm_unsubscribe(lcm.get(), subscription);
    throw InputError("--sensor-command: LCM could not publish on " +
                     std::string(service::kSensorCommandChannel));
  }
  const std::string sent = "sent " + args.sensor_command + " on " +
                           service::kSensorCommandChannel + (sealed ? " (sealed with the key)" : "");
  const bool answered = had_status && waitFor(lcm.get(), wait, [&] { return statuses.after(sent_us) >= 2; });
  lcm_unsubscribe(lcm.get(), subscription);
  if (!answered) {
    std::cout << sent << "; not confirmed: no sensor status on " << service::kSensorStatusChannel
              << " within " << std::chrono::duration<double, std::milli>(wait).count()
              << " ms" << (had_status ? " after it" : "")
              << " (is stepcal-runtime --sensor can:IFACE running on " << args.lcm_url << "?)\n";
    return exit_code::kNoService;
  }
  const sensor_status_t& after = statuses.received.back();
  if (const std::string why = refusal(before, after); !why.empty()) {
    std::cout << sent << "; REFUSED by the daemon: " << why << "\n";
    return exit_code::kNoService;
  }
  std::cout << sent << "; accepted by the daemon" << (sealed ? " (authenticated)" : "")
            << "; sensor biased: " << (after.biased ? "yes" : "no") << "\n";
  return exit_code::kDone;
}

}  // namespace stepcal::client

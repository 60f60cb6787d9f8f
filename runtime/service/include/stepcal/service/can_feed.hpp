// The live wrench from an ATI Net CAN OEM F/T sensor on a SocketCAN interface (--sensor
// can:IFACE): the driver (runtime/ft_sensor.hpp) polls on its own thread and hands every sample
// to the Service; optionally each sample is also published as wrench_t. Commands (bias, reset)
// arrive as sensor_command_t (with the service's cell key: only authentic, fresh ones); the
// driver's health leaves as sensor_status_t.
#pragma once

#include <atomic>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <lcm/lcm.h>
#include <stepcal_lcm/sensor_status_t.hpp>

#include "stepcal/runtime/ft_sensor.hpp"
#include "stepcal/service/lcm_server.hpp"

namespace stepcal::service {

class CanWrenchFeed final : public WrenchFeed, private runtime::WrenchSink {
 public:
  /// Reads the sensor's identity and calibration over socket (throws InputError naming the
  /// interface and what failed), then starts polling. republish_channel empty: no wrench_t.
  CanWrenchFeed(lcm_t* lcm, runtime::CanSocket socket, const runtime::FtSensorOptions& options,
                std::string republish_channel, Service& service);
  ~CanWrenchFeed() override;

  std::string describe() const override;
  /// Publishes sensor_status_t on kSensorStatusChannel (serving thread).
  void publishStatus() override;
  runtime::FtSensorDriver& driver() noexcept { return driver_; }
  /// sensor_command_t messages that did not decode or named no known command (serving thread).
  int64_t refusedCommands() const noexcept { return refused_commands_; }
  /// With the service's key: commands dropped because their code did not verify, and because
  /// their counter was not fresh (serving thread).
  int64_t forgedCommands() const noexcept { return forged_commands_; }
  int64_t replayedCommands() const noexcept { return replayed_commands_; }

 private:
  /// Driver thread: to the Service, and to LCM when republishing. Allocation-free.
  void publish(const runtime::WrenchSample& sample) noexcept override;
  static void onCommand(const lcm_recv_buf_t* rbuf, const char* channel, void* user);

  lcm_t* lcm_;
  std::string iface_;
  std::string republish_channel_;
  Service& service_;
  runtime::FtSensorDriver driver_;
  lcm_subscription_t* subscription_ = nullptr;
  std::vector<uint8_t> wrench_buffer_;  ///< one encoded wrench_t, sized at construction
  stepcal_lcm::sensor_status_t status_{};
  std::vector<uint8_t> status_buffer_;
  int64_t refused_commands_ = 0;
  int64_t forged_commands_ = 0, replayed_commands_ = 0;
  std::optional<MessageVerifier> verifier_;  ///< with the service's key
  std::thread thread_;
};

/// A CAN_RAW socket on iface for the sensor at base_id: its ids and every error class.
/// Throws InputError naming the interface or the base id.
runtime::CanSocket openSensorSocket(const std::string& iface, uint32_t base_id);

}  // namespace stepcal::service

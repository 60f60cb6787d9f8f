// Binds a Service to an LCM instance: requests in on STEPCAL_REQUEST, replies out on
// STEPCAL_REPLY, status on STEPCAL_STATUS, and the sources of the live wrench (--sensor).
//
// Everything here runs on the thread that calls lcm_handle (the serving thread). Replies are
// encoded into a buffer sized at construction and published as raw bytes, so answering a
// request allocates nothing in this code (what LCM itself does per message is its own).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <lcm/lcm.h>

#include "stepcal/service/channels.hpp"
#include "stepcal/service/service.hpp"

namespace stepcal::service {

/// How many received messages LCM keeps for one subscription until the thread that calls
/// lcm_handle takes them. Beyond it LCM's receive thread drops new messages without a word; its
/// default, 30, is 15 ms of the long run's 2 kHz of requests, less than the stalls of a loaded
/// machine (round trips up to 42 ms measured under ASan, cyclictest wake-ups up to 34 ms). Sized
/// as the longest stall of the serving thread (or a client's) to ride out without a loss, times
/// the highest message rate on one channel it is meant for.
inline constexpr double kLongestStall_s = 1.0;
inline constexpr double kMaxChannelRate_hz = 4000.0;  ///< e.g. four controllers at 1 kHz
/// 4 000 messages; queued ones sit in LCM's ring buffer at their own size (≈ 300 bytes for a
/// request or reply), so at most ≈ 1.2 MB.
inline constexpr int kSubscriptionQueueCapacity = int(kLongestStall_s * kMaxChannelRate_hz);

/// lcm_subscribe, then the subscription's queue capacity set to queue_capacity (> 0: a bound).
/// Every subscription of stepcal-runtime and stepcal-client goes through it. Throws InputError
/// naming the channel when LCM refuses either.
lcm_subscription_t* subscribeQueued(lcm_t* lcm, const char* channel, lcm_msg_handler_t handler,
                                    void* user, int queue_capacity = kSubscriptionQueueCapacity);

/// The steady-clock time at which LCM received a message stamped recv_utime (µs since the
/// epoch, system clock), so that time spent queued inside LCM counts against the budget.
/// Clamped to [now − 1 s, now] against clock steps.
runtime::Clock::time_point receivedAt(int64_t recv_utime) noexcept;

/// Serves requests arriving on an LCM instance while it lives.
class LcmServer {
 public:
  /// Subscribes to kRequestChannel on lcm (not owned; must outlive the server).
  LcmServer(lcm_t* lcm, Service& service);
  ~LcmServer();
  LcmServer(const LcmServer&) = delete;
  LcmServer& operator=(const LcmServer&) = delete;

  /// Publishes service.status(realtime) on kStatusChannel.
  void publishStatus(bool realtime);

 private:
  static void onRequest(const lcm_recv_buf_t* rbuf, const char* channel, void* user);

  lcm_t* lcm_;
  Service& service_;
  lcm_subscription_t* subscription_ = nullptr;
  std::vector<uint8_t> reply_buffer_;
  std::vector<uint8_t> status_buffer_;
};

/// A source of live wrench samples: hands them to a Service (Service::publishWrench) while it
/// lives. The only writer of the service's wrench.
class WrenchFeed {
 public:
  virtual ~WrenchFeed() = default;
  /// For the start-up line, e.g. "lcm:STEPCAL_WRENCH".
  virtual std::string describe() const = 0;
  /// Publishes the source's health, if it has any to tell (serving thread, 10 Hz).
  virtual void publishStatus() {}
};

/// wrench_t messages on an LCM channel, received on the serving thread and stamped with their
/// receive time (receivedAt). Undecodable messages are counted and dropped.
class LcmWrenchFeed final : public WrenchFeed {
 public:
  LcmWrenchFeed(lcm_t* lcm, std::string channel, Service& service);
  ~LcmWrenchFeed() override;
  std::string describe() const override { return "lcm:" + channel_; }
  /// Messages on the channel that did not decode as wrench_t.
  int64_t undecodable() const noexcept { return undecodable_; }

 private:
  static void onWrench(const lcm_recv_buf_t* rbuf, const char* channel, void* user);

  lcm_t* lcm_;
  std::string channel_;
  Service& service_;
  lcm_subscription_t* subscription_ = nullptr;
  int64_t undecodable_ = 0;
};

/// What --sensor and the --sensor-* options of stepcal-runtime say.
struct SensorArgs {
  std::string sensor = "lcm";  ///< "lcm" or "can:IFACE"
  std::string wrench_channel = kWrenchChannel;  ///< lcm: the channel read
  uint32_t base_id = 0x20;     ///< can: the sensor's base id
  double rate_hz = 1000.0;     ///< can: gauge polls per second
  int calibration_index = 0;   ///< can: calibration made active at start-up (−1: keep)
  int bias_samples = 16;       ///< can: readings averaged per bias (tare)
  std::string republish_channel;  ///< can: also publish each sample as wrench_t here ("" none)
};

/// The feed named by args.sensor: "lcm" (wrench_t on wrench_channel) or "can:IFACE" (the ATI
/// Net CAN OEM driver, CanWrenchFeed). Throws InputError naming --sensor for anything else, and
/// the CAN feed's start-up errors.
std::unique_ptr<WrenchFeed> makeWrenchFeed(const SensorArgs& args, lcm_t* lcm, Service& service);

}  // namespace stepcal::service

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

#include "stepcal/service/service.hpp"

namespace stepcal::service {

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

/// The feed named by --sensor: "lcm" (wrench_t on wrench_channel). A CAN sensor ("can:IFACE")
/// will be a feed with its own reader thread; it does not exist yet. Throws InputError naming
/// --sensor for anything else.
std::unique_ptr<WrenchFeed> makeWrenchFeed(const std::string& sensor, lcm_t* lcm,
                                           const std::string& wrench_channel, Service& service);

}  // namespace stepcal::service

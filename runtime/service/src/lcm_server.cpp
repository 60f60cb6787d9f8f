#include "stepcal/service/lcm_server.hpp"

#include <time.h>

#include <algorithm>
#include <utility>

#include <stepcal_lcm/wrench_t.hpp>

#include "stepcal/common/error.hpp"
#include "stepcal/service/can_feed.hpp"
#include "stepcal/service/channels.hpp"

namespace stepcal::service {

using runtime::Clock;

Clock::time_point receivedAt(int64_t recv_utime) noexcept {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  const int64_t now_us = int64_t(now.tv_sec) * 1'000'000 + now.tv_nsec / 1000;
  const int64_t queued_us = std::clamp<int64_t>(now_us - recv_utime, 0, 1'000'000);
  return Clock::now() - std::chrono::microseconds(queued_us);
}

lcm_subscription_t* subscribeQueued(lcm_t* lcm, const char* channel, lcm_msg_handler_t handler,
                                    void* user, int queue_capacity) {
  if (queue_capacity <= 0) {
    throw InputError(std::string("channel ") + channel + ": queue capacity " +
                     std::to_string(queue_capacity) + " must be > 0 (a bound)");
  }
  lcm_subscription_t* subscription = lcm_subscribe(lcm, channel, handler, user);
  if (subscription == nullptr) throw InputError(std::string("cannot subscribe to ") + channel);
  if (lcm_subscription_set_queue_capacity(subscription, queue_capacity) != 0) {
    lcm_unsubscribe(lcm, subscription);
    throw InputError(std::string("channel ") + channel + ": LCM refused a queue capacity of " +
                     std::to_string(queue_capacity));
  }
  return subscription;
}

LcmServer::LcmServer(lcm_t* lcm, Service& service)
    : lcm_(lcm), service_(service), reply_buffer_(size_t(Service::replyBytes())) {
  subscription_ = subscribeQueued(lcm_, kRequestChannel, &LcmServer::onRequest, this);
}

LcmServer::~LcmServer() { lcm_unsubscribe(lcm_, subscription_); }

void LcmServer::onRequest(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  auto* self = static_cast<LcmServer*>(user);
  const int bytes = self->service_.handleRequest(
      rbuf->data, static_cast<int>(rbuf->data_size), receivedAt(rbuf->recv_utime),
      self->reply_buffer_.data(), static_cast<int>(self->reply_buffer_.size()));
  if (bytes > 0) lcm_publish(self->lcm_, kReplyChannel, self->reply_buffer_.data(), unsigned(bytes));
}

void LcmServer::publishStatus(bool realtime) {
  const stepcal_lcm::runtime_status_t& status = service_.status(realtime);
  const int size = status.getEncodedSize();
  if (status_buffer_.size() < size_t(size)) status_buffer_.resize(size_t(size));
  const int bytes = status.encode(status_buffer_.data(), 0, size);
  if (bytes > 0) lcm_publish(lcm_, kStatusChannel, status_buffer_.data(), unsigned(bytes));
}

LcmWrenchFeed::LcmWrenchFeed(lcm_t* lcm, std::string channel, Service& service)
    : lcm_(lcm), channel_(std::move(channel)), service_(service) {
  try {
    subscription_ = subscribeQueued(lcm_, channel_.c_str(), &LcmWrenchFeed::onWrench, this);
  } catch (const InputError& e) {
    throw InputError("--wrench-channel '" + channel_ + "': " + e.what());
  }
}

LcmWrenchFeed::~LcmWrenchFeed() { lcm_unsubscribe(lcm_, subscription_); }

void LcmWrenchFeed::onWrench(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  auto* self = static_cast<LcmWrenchFeed*>(user);
  stepcal_lcm::wrench_t msg;
  const int size = static_cast<int>(rbuf->data_size);
  if (msg.decode(rbuf->data, 0, size) != size) {
    ++self->undecodable_;
    return;
  }
  runtime::WrenchSample sample;
  for (int i = 0; i < 6; ++i) sample.wrench_Sensor[i] = msg.wrench[i];
  sample.stamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                        receivedAt(rbuf->recv_utime).time_since_epoch())
                        .count();
  sample.sensor_status = static_cast<uint32_t>(msg.sensor_status);
  sample.sequence = static_cast<uint64_t>(msg.sequence);
  self->service_.publishWrench(sample);
}

std::unique_ptr<WrenchFeed> makeWrenchFeed(const SensorArgs& args, lcm_t* lcm, Service& service) {
  if (args.sensor == "lcm") return std::make_unique<LcmWrenchFeed>(lcm, args.wrench_channel, service);
  if (args.sensor.rfind("can:", 0) == 0 && args.sensor.size() > 4) {
    runtime::FtSensorOptions options;
    options.base_id = args.base_id;
    options.poll_hz = args.rate_hz;
    options.calibration_index = args.calibration_index;
    options.bias_samples = args.bias_samples;
    return std::make_unique<CanWrenchFeed>(lcm, openSensorSocket(args.sensor.substr(4), args.base_id),
                                           options, args.republish_channel, service);
  }
  throw InputError("--sensor '" + args.sensor +
                   "': expected lcm (wrench_t on --wrench-channel) or can:IFACE (an ATI Net CAN "
                   "OEM sensor on SocketCAN interface IFACE, e.g. can:can0)");
}

}  // namespace stepcal::service

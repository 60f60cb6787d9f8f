#include "stepcal/service/can_feed.hpp"


#include <cstdio>

#include <stepcal_lcm/sensor_command_t.hpp>
#include <stepcal_lcm/wrench_t.hpp>

#include "stepcal/common/error.hpp"
#include "stepcal/service/channels.hpp"

namespace stepcal::service {

runtime::CanSocket openSensorSocket(const std::string& iface, uint32_t base_id) {
  if (base_id > runtime::netcan::kMaxBaseId) {
    throw InputError("--sensor-base-id " + std::to_string(base_id) + ": expected 0 … 127 (0x7F)");
  }
  return runtime::CanSocket::open(iface, {runtime::sensorFilter(base_id)},
                                  runtime::kSensorErrorMask);
}

CanWrenchFeed::CanWrenchFeed(lcm_t* lcm, runtime::CanSocket socket,
                             const runtime::FtSensorOptions& options, std::string republish_channel,
                             Service& service)
    : lcm_(lcm),
      iface_(socket.name()),
      republish_channel_(std::move(republish_channel)),
      service_(service),
      driver_(std::move(socket), options) {
  wrench_buffer_.resize(size_t(stepcal_lcm::wrench_t{}.getEncodedSize()));
  if (service.options().key) {
    verifier_.emplace(*service.options().key, service.options().auth_window_us);
  }
  subscription_ = subscribeQueued(lcm_, kSensorCommandChannel, &CanWrenchFeed::onCommand, this);
  const runtime::FtSensorIdentity& identity = driver_.identity();
  status_.interface_name = iface_;
  status_.base_id = int32_t(options.base_id);
  status_.serial = identity.serial;
  status_.firmware = std::to_string(identity.firmware_major) + "." +
                     std::to_string(identity.firmware_minor) + "." +
                     std::to_string(identity.firmware_build);
  thread_ = std::thread([this] { driver_.run(*this); });
}

CanWrenchFeed::~CanWrenchFeed() {
  driver_.stop();
  thread_.join();
  lcm_unsubscribe(lcm_, subscription_);
}

std::string CanWrenchFeed::describe() const {
  char base[8];
  std::snprintf(base, sizeof base, "0x%02X", driver_.options().base_id);
  return "can:" + iface_ + " (ATI Net CAN OEM, base id " + base + ", serial " +
         driver_.identity().serial + ", firmware " + status_.firmware + ", " +
         std::to_string(int(driver_.options().poll_hz)) + " Hz" +
         (republish_channel_.empty() ? "" : ", republished on " + republish_channel_) + ")";
}

void CanWrenchFeed::publish(const runtime::WrenchSample& sample) noexcept {
  service_.publishWrench(sample);
  if (republish_channel_.empty()) return;
  stepcal_lcm::wrench_t msg{};
  msg.utime = unixMicroseconds();
  msg.stamp_ns = sample.stamp_ns;
  for (int i = 0; i < 6; ++i) msg.wrench[i] = sample.wrench_Sensor[i];
  msg.sensor_status = int32_t(sample.sensor_status);
  msg.sequence = int64_t(sample.sequence);
  const int bytes = msg.encode(wrench_buffer_.data(), 0, int(wrench_buffer_.size()));
  if (bytes > 0) lcm_publish(lcm_, republish_channel_.c_str(), wrench_buffer_.data(), unsigned(bytes));
}

void CanWrenchFeed::onCommand(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  auto* self = static_cast<CanWrenchFeed*>(user);
  stepcal_lcm::sensor_command_t command{};
  const int size = int(rbuf->data_size);
  if (self->verifier_) {
    // A tare while a payload hangs on the sensor would offset every later correction.
    const Verdict verdict = self->verifier_->verify(static_cast<const uint8_t*>(rbuf->data),
                                                    size, unixMicroseconds());
    if (verdict != Verdict::kAuthentic) {
      ++(verdict == Verdict::kForged ? self->forged_commands_ : self->replayed_commands_);
      return;
    }
  }
  if (command.decode(rbuf->data, 0, size) != size) {
    ++self->refused_commands_;
    return;
  }
  switch (command.command) {
    case stepcal_lcm::sensor_command_t::COMMAND_BIAS: self->driver_.requestBias(); break;
    case stepcal_lcm::sensor_command_t::COMMAND_CLEAR_BIAS: self->driver_.clearBias(); break;
    case stepcal_lcm::sensor_command_t::COMMAND_RESET: self->driver_.requestReset(); break;
    default: ++self->refused_commands_; break;
  }
}

void CanWrenchFeed::publishStatus() {
  const runtime::FtSensorCounters c = driver_.counters();
  status_.utime = unixMicroseconds();
  status_.state = int8_t(c.state);
  status_.status_word = c.last_status_word;
  status_.status_text = runtime::netcan::describeStatus(c.last_status_word);
  status_.biased = driver_.biased() ? 1 : 0;
  status_.polls = c.polls;
  status_.samples = c.samples;
  status_.timeouts = c.timeouts;
  status_.critical_status = c.critical_status;
  status_.foreign_id = c.foreign_id;
  status_.bad_length = c.bad_length;
  status_.unknown_opcode = c.unknown_opcode;
  status_.unpaired = c.unpaired;
  status_.late = c.late;
  status_.unexpected_reply = c.unexpected_reply;
  status_.error_frames = c.error_frames;
  status_.bus_off = c.bus_off;
  status_.restarts = c.restarts;
  status_.send_failures = c.send_failures;
  status_.resets = c.resets;
  status_.refused_commands = refused_commands_;
  status_.forged_commands = forged_commands_;
  status_.replayed_commands = replayed_commands_;
  const int size = status_.getEncodedSize();
  if (status_buffer_.size() < size_t(size)) status_buffer_.resize(size_t(size));
  const int bytes = status_.encode(status_buffer_.data(), 0, size);
  if (bytes > 0) lcm_publish(lcm_, kSensorStatusChannel, status_buffer_.data(), unsigned(bytes));
}

}  // namespace stepcal::service

// A SocketCAN CAN_RAW socket, or any datagram socket carrying `struct can_frame` records (a
// socketpair in tests and benchmarks), with kernel receive timestamps.
//
// send and receive allocate nothing, never throw and return a result code: the sensor thread
// runs them in its loop. Opening throws InputError naming the interface and what to do.
#pragma once

#include <linux/can.h>
#include <linux/can/error.h>

#include <cstdint>
#include <string>
#include <vector>

#include "stepcal/runtime/corrector.hpp"

namespace stepcal::runtime {

/// A received frame and when the kernel received it, on runtime::Clock (steady), ns.
struct ReceivedFrame {
  can_frame frame{};
  int64_t stamp_ns = 0;
};

enum class CanIo : uint8_t {
  kOk,
  kTimeout,    ///< nothing arrived before the deadline
  kBusy,       ///< the transmit queue is full (ENOBUFS): the controller is bus-off or the bus jammed
  kDown,       ///< the interface is down (ENETDOWN)
  kClosed,     ///< the other end of an adopted socket closed it (never on CAN)
  kFailed,     ///< any other error (errno kept in lastErrno)
};

class CanSocket {
 public:
  /// Opens CAN_RAW on interface `iface`, receiving only frames that pass `filters` (none: no
  /// data frames) and the error classes in err_mask (CAN_ERR_* bits; CAN_ERR_MASK for all).
  /// Throws InputError naming the interface, the failing call and a hint.
  static CanSocket open(const std::string& iface, const std::vector<can_filter>& filters,
                        can_err_mask_t err_mask);
  /// Takes ownership of a connected SOCK_SEQPACKET / SOCK_DGRAM socket whose records are
  /// struct can_frame (tests, benchmarks). Timestamps come from SO_TIMESTAMPNS as for CAN.
  static CanSocket adopt(int fd, std::string name);

  CanSocket(CanSocket&& other) noexcept;
  CanSocket& operator=(CanSocket&& other) noexcept;
  CanSocket(const CanSocket&) = delete;
  CanSocket& operator=(const CanSocket&) = delete;
  ~CanSocket();

  /// Queues one frame for sending.
  CanIo send(const can_frame& frame) noexcept;
  /// Waits until deadline for one frame. Frames of another size than can_frame are skipped.
  CanIo receive(ReceivedFrame& out, Clock::time_point deadline) noexcept;
  /// The errno of the last kFailed / kBusy / kDown.
  int lastErrno() const noexcept { return last_errno_; }
  int fd() const noexcept { return fd_; }
  const std::string& name() const noexcept { return name_; }

 private:
  CanSocket(int fd, std::string name) noexcept : fd_(fd), name_(std::move(name)) {}
  CanIo ioFailure(int error) noexcept;

  int fd_ = -1;
  std::string name_;
  int last_errno_ = 0;
};

/// runtime::Clock time now, ns.
int64_t steadyNowNs() noexcept;

}  // namespace stepcal::runtime

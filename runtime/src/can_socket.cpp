#include "stepcal/runtime/can_socket.hpp"

#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>

#include "stepcal/common/error.hpp"

namespace stepcal::runtime {

namespace {

int64_t clockNs(clockid_t clock) noexcept {
  timespec now{};
  clock_gettime(clock, &now);
  return int64_t(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

[[noreturn]] void openFailed(const std::string& iface, const std::string& call, int error,
                             const std::string& hint) {
  throw InputError("CAN interface '" + iface + "': " + call + " failed (" + std::strerror(error) +
                   "); " + hint);
}

/// CLOCK_REALTIME − CLOCK_MONOTONIC now, ns: the realtime reading bracketed by two steady ones,
/// retried when a preemption widened the bracket, so the offset is good to a few µs.
int64_t realtimeMinusSteadyNs() noexcept {
  int64_t offset = 0;
  for (int attempt = 0; attempt < 4; ++attempt) {
    const int64_t before = steadyNowNs();
    const int64_t real = clockNs(CLOCK_REALTIME);
    const int64_t after = steadyNowNs();
    offset = real - (before + (after - before) / 2);
    if (after - before < 20'000) break;
  }
  return offset;
}

void enableTimestamps(int fd) noexcept {
  const int on = 1;
  // Without it receive falls back to the time it reads the frame; nothing else changes.
  setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on);
}

}  // namespace

int64_t steadyNowNs() noexcept {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
      .count();
}

CanSocket CanSocket::open(const std::string& iface, const std::vector<can_filter>& filters,
                          can_err_mask_t err_mask) {
  if (iface.empty() || iface.size() >= IFNAMSIZ) {
    throw InputError("CAN interface '" + iface + "': expected a name of 1 to " +
                     std::to_string(IFNAMSIZ - 1) + " characters, e.g. can0 or vcan0");
  }
  const int fd = socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    openFailed(iface, "socket(PF_CAN, SOCK_RAW, CAN_RAW)", errno,
               "this kernel has no SocketCAN (modprobe can can-raw), or run inside "
               "tests/system/vcan_run.sh");
  }
  CanSocket socket(fd, iface);
  ifreq request{};
  std::memcpy(request.ifr_name, iface.c_str(), iface.size() + 1);
  if (ioctl(fd, SIOCGIFINDEX, &request) < 0) {
    openFailed(iface, "SIOCGIFINDEX", errno,
               "no such interface: check `ip link show`, or create a virtual one with "
               "`ip link add dev " + iface + " type vcan && ip link set " + iface + " up`");
  }
  const socklen_t filter_bytes = socklen_t(filters.size() * sizeof(can_filter));
  if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filters.empty() ? nullptr : filters.data(),
                 filter_bytes) < 0) {
    openFailed(iface, "CAN_RAW_FILTER", errno, "the receive filters were refused");
  }
  if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) < 0) {
    openFailed(iface, "CAN_RAW_ERR_FILTER", errno, "error frames cannot be enabled");
  }
  enableTimestamps(fd);
  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = request.ifr_ifindex;
  if (bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) < 0) {
    openFailed(iface, "bind", errno, "is the interface a CAN interface?");
  }
  return socket;
}

CanSocket CanSocket::adopt(int fd, std::string name) {
  STEPCAL_INVARIANT(fd >= 0, "CanSocket::adopt needs an open socket");
  enableTimestamps(fd);
  return CanSocket(fd, std::move(name));
}

CanSocket::CanSocket(CanSocket&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)), name_(std::move(other.name_)),
      last_errno_(other.last_errno_) {}

CanSocket& CanSocket::operator=(CanSocket&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    name_ = std::move(other.name_);
    last_errno_ = other.last_errno_;
  }
  return *this;
}

CanSocket::~CanSocket() {
  if (fd_ >= 0) close(fd_);
}

CanIo CanSocket::ioFailure(int error) noexcept {
  last_errno_ = error;
  if (error == ENOBUFS || error == EAGAIN) return CanIo::kBusy;
  if (error == ENETDOWN) return CanIo::kDown;
  return CanIo::kFailed;
}

CanIo CanSocket::send(const can_frame& frame) noexcept {
  for (;;) {
    const ssize_t sent = ::send(fd_, &frame, sizeof frame, MSG_DONTWAIT | MSG_NOSIGNAL);
    if (sent == ssize_t(sizeof frame)) return CanIo::kOk;
    if (sent < 0 && errno == EINTR) continue;
    return ioFailure(sent < 0 ? errno : EMSGSIZE);
  }
}

CanIo CanSocket::receive(ReceivedFrame& out, Clock::time_point deadline) noexcept {
  for (;;) {
    iovec io{&out.frame, sizeof out.frame};
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec))];
    msghdr message{};
    message.msg_iov = &io;
    message.msg_iovlen = 1;
    message.msg_control = control;
    message.msg_controllen = sizeof control;
    const ssize_t got = recvmsg(fd_, &message, MSG_DONTWAIT);
    if (got < 0) {
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) return ioFailure(errno);
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - Clock::now() + std::chrono::microseconds(999));
      if (left.count() <= 0) return CanIo::kTimeout;
      // poll's resolution is 1 ms; the loop re-checks the deadline after each wake-up.
      pollfd waiting{fd_, POLLIN, 0};
      const int ready = poll(&waiting, 1, int(std::min<int64_t>(left.count(), 1000)));
      if (ready < 0 && errno != EINTR) return ioFailure(errno);
      if (ready == 0 && Clock::now() >= deadline) return CanIo::kTimeout;
      continue;
    }
    if (got == 0) return CanIo::kClosed;  // a socketpair peer's end of file
    if (got != ssize_t(sizeof out.frame) || (message.msg_flags & MSG_TRUNC)) continue;
    const int64_t steady_now = steadyNowNs();
    out.stamp_ns = steady_now;
    for (cmsghdr* c = CMSG_FIRSTHDR(&message); c != nullptr; c = CMSG_NXTHDR(&message, c)) {
      if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SO_TIMESTAMPNS) continue;
      timespec kernel{};
      std::memcpy(&kernel, CMSG_DATA(c), sizeof kernel);
      const int64_t kernel_real_ns = int64_t(kernel.tv_sec) * 1'000'000'000 + kernel.tv_nsec;
      // The kernel stamps with CLOCK_REALTIME; on the steady clock, never later than now.
      const int64_t stamp = kernel_real_ns - realtimeMinusSteadyNs();
      if (stamp <= steady_now && steady_now - stamp < 1'000'000'000) out.stamp_ns = stamp;
    }
    return CanIo::kOk;
  }
}

}  // namespace stepcal::runtime

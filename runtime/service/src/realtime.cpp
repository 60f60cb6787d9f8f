#include "stepcal/service/realtime.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>

namespace stepcal::service {
namespace {

/// Stack touched after mlockall, so the real-time thread never page-faults on it, bytes.
constexpr size_t kPrefaultStackBytes = 512 * 1024;

void prefaultStack() {
  char stack[kPrefaultStackBytes];
  explicit_bzero(stack, sizeof stack);  // never optimised away
}

}  // namespace

std::string enterRealtime() {
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
    return std::string("mlockall failed (") + std::strerror(errno) +
           "): needs CAP_IPC_LOCK or RLIMIT_MEMLOCK large enough (systemd: "
           "LimitMEMLOCK=infinity)";
  }
  sched_param param{};
  param.sched_priority = kRealtimePriority;
  if (const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param)) {
    munlockall();
    const std::string priority = std::to_string(kRealtimePriority);
    return "SCHED_FIFO priority " + priority + " refused (" + std::strerror(error) +
           "): needs CAP_SYS_NICE or RLIMIT_RTPRIO ≥ " + priority + " (systemd: LimitRTPRIO=" +
           priority + ")";
  }
  prefaultStack();
  return "";
}

int pinToLastAllowedCpu(std::string& refusal) {
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (const int error = pthread_getaffinity_np(pthread_self(), sizeof allowed, &allowed)) {
    refusal = std::string("pthread_getaffinity_np: ") + std::strerror(error);
    return -1;
  }
  int cpu = -1;
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (CPU_ISSET(c, &allowed)) cpu = c;
  }
  if (cpu < 0) {
    refusal = "no CPU in the thread's affinity mask";
    return -1;
  }
  cpu_set_t one;
  CPU_ZERO(&one);
  CPU_SET(cpu, &one);
  if (const int error = pthread_setaffinity_np(pthread_self(), sizeof one, &one)) {
    refusal = "pinning to CPU " + std::to_string(cpu) + " refused: " + std::strerror(error);
    return -1;
  }
  return cpu;
}

}  // namespace stepcal::service

// Real-time settings of a process beside the controller: locked memory, SCHED_FIFO, one CPU. Used
// by the daemon (--realtime) and by stepcal-bench (--realtime), so both measure the same set-up.
#pragma once

#include <string>

namespace stepcal::service {

/// SCHED_FIFO priority of the daemon's serving thread and of the bench's timing thread.
constexpr int kRealtimePriority = 80;

/// mlockall, SCHED_FIFO at kRealtimePriority for the calling thread (threads it creates later
/// inherit it) and a prefaulted stack. Returns "" when all took effect; otherwise one line saying
/// what was refused and what permits it, with nothing left changed.
std::string enterRealtime();

/// Pins the calling thread to the last CPU of its allowed set. Returns that CPU, or −1 with
/// `refusal` set to why not.
int pinToLastAllowedCpu(std::string& refusal);

}  // namespace stepcal::service

// LCM channel names and the default URL shared by stepcal-runtime and stepcal-client.
#pragma once

namespace stepcal::service {

inline constexpr const char* kRequestChannel = "STEPCAL_REQUEST";  ///< correction_request_t
inline constexpr const char* kReplyChannel = "STEPCAL_REPLY";      ///< correction_reply_t
inline constexpr const char* kStatusChannel = "STEPCAL_STATUS";    ///< runtime_status_t, 10 Hz
inline constexpr const char* kWrenchChannel = "STEPCAL_WRENCH";    ///< wrench_t (default)
inline constexpr const char* kSensorCommandChannel = "STEPCAL_SENSOR_COMMAND";  ///< sensor_command_t
inline constexpr const char* kSensorStatusChannel = "STEPCAL_SENSOR_STATUS";    ///< sensor_status_t
inline constexpr const char* kRobotStateChannel = "STEPCAL_ROBOT_STATE";  ///< robot_state_t
/// robot_state_t echoed by a simulated sensor once it feels that state (stepcal-ftsim --truth).
inline constexpr const char* kRobotStateAppliedChannel = "STEPCAL_ROBOT_STATE_APPLIED";
inline constexpr const char* kPingChannel = "STEPCAL_PING";  ///< raw bytes, client --ping
inline constexpr const char* kPongChannel = "STEPCAL_PONG";  ///< the same bytes, client --echo

/// Multicast on the loopback only (ttl=0): LCM's own default.
inline constexpr const char* kDefaultLcmUrl = "udpm://239.255.76.67:7667?ttl=0";

}  // namespace stepcal::service

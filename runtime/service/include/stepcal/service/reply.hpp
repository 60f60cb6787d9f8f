// The reply side of the wire contract (lcmtypes/correction_reply_t.lcm, and the frozen
// correction_reply_v1_t a version-1 client can read): encoding for the daemon, decoding for every
// client (stepcal-client, the Python client, tests), beside the request side (request.hpp);
// tests/test_wire.cpp round-trips both. Pure, allocation-free, never throws.
#pragma once

#include <cstdint>

#include <stepcal_lcm/correction_reply_t.hpp>

namespace stepcal::service {

/// Bytes of the larger of an encoded correction_reply_t and correction_reply_v1_t: a buffer of
/// this size holds any reply.
int replyBytes() noexcept;

/// Encodes reply into out[0 .. capacity): its size in bytes, or 0 when capacity is too small.
int encodeReply(const stepcal_lcm::correction_reply_t& reply, uint8_t* out, int capacity) noexcept;

/// Encodes the version-1 BAD_REQUEST refusal of a version-1 request (correction_reply_v1_t: its
/// request_id, utime in µs since the Unix epoch and the model id, nothing else) into
/// out[0 .. capacity): its size in bytes, or 0 when capacity is too small.
int encodeOldVersionRefusal(int64_t request_id, int64_t utime, int64_t model_id, uint8_t* out,
                            int capacity) noexcept;

/// What a message on the reply channel is.
enum class ReplyKind : int8_t {
  kReply = 0,       ///< exactly one correction_reply_t (message version 2)
  kOldVersion = 1,  ///< a correction_reply_v1_t: a daemon that predates message version 2
  kMalformed = 2,   ///< anything else: another type, truncated or too long
};

/// Decodes the bytes of one message on the reply channel: kReply with out filled, or what else it
/// is (out then zeros). Told apart by the LCM fingerprint (the first 8 bytes) before anything is
/// decoded.
ReplyKind decodeReply(const void* data, int size, stepcal_lcm::correction_reply_t& out) noexcept;

}  // namespace stepcal::service

// The reply side of the wire contract (lcmtypes/correction_reply_t.lcm, and the frozen
// correction_reply_v1_t and correction_reply_v2_t older clients can read): encoding for the daemon, decoding for every
// client (stepcal-client, the Python client, tests), beside the request side (request.hpp);
// tests/test_wire.cpp round-trips both. Pure, allocation-free, never throws.
#pragma once

#include <cstdint>

#include <stepcal_lcm/correction_reply_t.hpp>

namespace stepcal::service {

/// Bytes of the largest of an encoded correction_reply_t, correction_reply_v1_t and
/// correction_reply_v2_t: a buffer of this size holds any reply.
int replyBytes() noexcept;

/// Encodes reply into out[0 .. capacity): its size in bytes, or 0 when capacity is too small.
int encodeReply(const stepcal_lcm::correction_reply_t& reply, uint8_t* out, int capacity) noexcept;

/// Encodes the BAD_REQUEST refusal of a request in an older message version (1 or 2, as
/// Request::old_version) in that version's reply (correction_reply_v1_t, correction_reply_v2_t:
/// its request_id, utime in µs since the Unix epoch and the model id; for version 2 its
/// message_version 2; nothing else) into out[0 .. capacity): its size in bytes, or 0 when
/// capacity is too small or the version is neither.
int encodeOldVersionRefusal(int version, int64_t request_id, int64_t utime, int64_t model_id,
                            uint8_t* out, int capacity) noexcept;

/// What a message on the reply channel is.
enum class ReplyKind : int8_t {
  kReply = 0,       ///< exactly one correction_reply_t (message version 3)
  /// a correction_reply_v1_t or correction_reply_v2_t: a daemon that predates message version 3
  /// (which one: oldReplyVersion)
  kOldVersion = 1,
  kMalformed = 2,   ///< anything else: another type, truncated or too long
};

/// Decodes the bytes of one message on the reply channel: kReply with out filled, or what else it
/// is (out then zeros). Told apart by the LCM fingerprint (the first 8 bytes) before anything is
/// decoded.
ReplyKind decodeReply(const void* data, int size, stepcal_lcm::correction_reply_t& out) noexcept;

/// The message version of a reply decodeReply calls kOldVersion (1 or 2, by its fingerprint);
/// 0 for any other bytes.
int oldReplyVersion(const void* data, int size) noexcept;

}  // namespace stepcal::service

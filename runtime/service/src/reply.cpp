#include "stepcal/service/reply.hpp"

#include <algorithm>

#include <stepcal_lcm/correction_reply_v1_t.hpp>
#include <stepcal_lcm/correction_reply_v2_t.hpp>

namespace stepcal::service {
namespace {

using stepcal_lcm::correction_reply_t;
using stepcal_lcm::correction_reply_v1_t;
using stepcal_lcm::correction_reply_v2_t;

constexpr int kFingerprintBytes = 8;

int64_t bigEndian64(const uint8_t* bytes) noexcept {
  uint64_t value = 0;
  for (int i = 0; i < 8; ++i) value = (value << 8) | bytes[i];
  return static_cast<int64_t>(value);
}

}  // namespace

int replyBytes() noexcept {
  static const int bytes =
      std::max({correction_reply_t{}.getEncodedSize(), correction_reply_v1_t{}.getEncodedSize(),
                correction_reply_v2_t{}.getEncodedSize()});
  return bytes;
}

int encodeReply(const correction_reply_t& reply, uint8_t* out, int capacity) noexcept {
  if (out == nullptr) return 0;
  const int bytes = reply.encode(out, 0, capacity);
  return bytes > 0 ? bytes : 0;
}

int encodeOldVersionRefusal(int version, int64_t request_id, int64_t utime, int64_t model_id,
                            uint8_t* out, int capacity) noexcept {
  if (out == nullptr) return 0;
  int bytes = 0;
  if (version == 1) {
    correction_reply_v1_t refusal{};
    refusal.request_id = request_id;
    refusal.utime = utime;
    refusal.status = correction_reply_v1_t::STATUS_BAD_REQUEST;
    refusal.model_id = model_id;
    bytes = refusal.encode(out, 0, capacity);
  } else if (version == correction_reply_v2_t::VERSION) {
    correction_reply_v2_t refusal{};
    refusal.request_id = request_id;
    refusal.message_version = correction_reply_v2_t::VERSION;
    refusal.utime = utime;
    refusal.status = correction_reply_v2_t::STATUS_BAD_REQUEST;
    refusal.model_id = model_id;
    bytes = refusal.encode(out, 0, capacity);
  }
  return bytes > 0 ? bytes : 0;
}

ReplyKind decodeReply(const void* data, int size, correction_reply_t& out) noexcept {
  out = correction_reply_t{};
  if (data == nullptr || size < kFingerprintBytes) return ReplyKind::kMalformed;
  const int64_t fingerprint = bigEndian64(static_cast<const uint8_t*>(data));
  if (oldReplyVersion(data, size) != 0) return ReplyKind::kOldVersion;
  if (fingerprint != correction_reply_t::getHash()) return ReplyKind::kMalformed;
  if (out.decode(data, 0, size) != size) {
    out = correction_reply_t{};
    return ReplyKind::kMalformed;
  }
  return ReplyKind::kReply;
}

int oldReplyVersion(const void* data, int size) noexcept {
  if (data == nullptr || size < kFingerprintBytes) return 0;
  const int64_t fingerprint = bigEndian64(static_cast<const uint8_t*>(data));
  if (fingerprint == correction_reply_v1_t::getHash()) return 1;
  if (fingerprint == correction_reply_v2_t::getHash()) return correction_reply_v2_t::VERSION;
  return 0;
}

}  // namespace stepcal::service

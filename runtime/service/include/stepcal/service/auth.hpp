// Only the cell may talk to the daemon: a shared key per cell (--key-file), and on requests,
// replies and sensor commands a message authentication code and a counter against replay.
//
// The code is libsodium's crypto_auth (HMAC-SHA-512-256, 32 bytes) under the cell's 32-byte key;
// no cryptography is written here. A message's last three fields are its authentication (the
// .lcm files): auth_sender (int64, the sender's id, random per process), auth_counter (int64,
// µs since the Unix epoch, at least the sender's previous + 1) and auth_mac (32 bytes, the code
// of every byte of the encoded message before it, the LCM fingerprint included). So both sides
// work on the encoded bytes: MessageSigner writes the three fields into them, MessageVerifier
// reads them there, before the message is decoded.
//
// A verified message is fresh when its counter lies within ±window of the receiver's clock and
// above the last counter seen from its sender: a replayed message (a copy of a genuine one) is
// refused, within the window by the per-sender counter and after it by the clock. Senders are
// remembered in a fixed table (kMaxSenders), so verifying allocates nothing.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include <sodium.h>

namespace stepcal::service {

/// Bytes of a cell key (crypto_auth_KEYBYTES).
inline constexpr int kKeyBytes = 32;
/// Bytes of the authentication fields at the end of a message: sender, counter, code.
inline constexpr int kAuthBytes = 8 + 8 + 32;
/// How far a message's counter may lie from the receiver's clock, µs (--auth-window-ms).
inline constexpr int64_t kDefaultAuthWindowUs = 2'000'000;

/// The cell's shared key, read from a file that only its owner may read or write.
class CellKey {
 public:
  /// Reads path: a regular file of exactly kKeyBytes bytes whose mode gives the group and others
  /// nothing (0600 or 0400). Throws InputError naming the file, what is wrong and how to make a
  /// key (`head -c 32 /dev/urandom > FILE && chmod 600 FILE`); one it may not read, naming the
  /// user this process runs as and the file's owner. source: where the path came from, the
  /// messages' prefix ("--key-file", "credential cell-key").
  static CellKey load(const std::string& path, const std::string& source = "--key-file");
  /// A key from bytes (tests).
  static CellKey fromBytes(const std::array<uint8_t, kKeyBytes>& bytes);
  ~CellKey();
  CellKey(const CellKey& other);
  CellKey& operator=(const CellKey& other);

  const uint8_t* data() const noexcept { return key_.data(); }

 private:
  CellKey() = default;
  std::array<uint8_t, kKeyBytes> key_{};
};

/// Signs one sender's messages.
class MessageSigner {
 public:
  /// A random sender id (libsodium's randombytes).
  explicit MessageSigner(const CellKey& key);
  int64_t sender() const noexcept { return sender_; }
  /// Writes the sender id, the next counter and the code into the last kAuthBytes of an encoded
  /// message of `size` bytes (≥ kAuthBytes). Allocation-free.
  void seal(uint8_t* bytes, int size) noexcept;

 private:
  crypto_auth_hmacsha512256_state keyed_;  ///< the HMAC's state after the key
  int64_t sender_ = 0;
  int64_t counter_ = 0;
};

/// Outcome of verifying one message.
enum class Verdict : int8_t {
  kAuthentic = 0,  ///< the code verifies and the counter is fresh
  kForged = 1,     ///< too short, or the code does not verify (another key, none, a change)
  kReplayed = 2,   ///< the code verifies but the counter is not fresh
};

/// Verifies messages from any number of senders of one cell.
class MessageVerifier {
 public:
  /// Senders remembered at once: more, each sending within the window, and the newest is
  /// refused as kReplayed until one falls silent for a window.
  static constexpr int kMaxSenders = 64;

  MessageVerifier(const CellKey& key, int64_t window_us = kDefaultAuthWindowUs);
  /// The verdict on an encoded message of `size` bytes whose last kAuthBytes are its
  /// authentication, received at now_us (µs since the Unix epoch). Remembers the counter of an
  /// authentic one. Allocation-free.
  Verdict verify(const uint8_t* bytes, int size, int64_t now_us) noexcept;
  int64_t windowUs() const noexcept { return window_us_; }

 private:
  struct Sender {
    int64_t id = 0;
    int64_t last_counter = 0;
    bool used = false;
  };
  crypto_auth_hmacsha512256_state keyed_;
  int64_t window_us_;
  std::array<Sender, kMaxSenders> senders_{};
};

}  // namespace stepcal::service

#include "stepcal/service/auth.hpp"

#include <fcntl.h>
#include <pwd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "stepcal/common/error.hpp"
#include "stepcal/service/service.hpp"

namespace stepcal::service {
namespace {

constexpr int kMacBytes = crypto_auth_hmacsha512256_BYTES;
static_assert(kMacBytes == 32 && crypto_auth_hmacsha512256_KEYBYTES == kKeyBytes,
              "the messages' auth_mac[32] and the key file's 32 bytes are libsodium's sizes");

const char* const kKeyHint =
    "make one per cell with `head -c 32 /dev/urandom > FILE && chmod 600 FILE` and give every "
    "host of the cell a copy";

/// libsodium initialised once (thread-safe, idempotent); aborts if it cannot be.
void initSodium() {
  static const bool ready = sodium_init() >= 0;
  STEPCAL_INVARIANT(ready, "libsodium failed to initialise (sodium_init)");
}

void putBigEndian64(uint8_t* out, int64_t value) noexcept {
  const auto v = static_cast<uint64_t>(value);
  for (int i = 0; i < 8; ++i) out[i] = uint8_t(v >> (56 - 8 * i));
}

int64_t bigEndian64(const uint8_t* bytes) noexcept {
  uint64_t value = 0;
  for (int i = 0; i < 8; ++i) value = (value << 8) | bytes[i];
  return static_cast<int64_t>(value);
}

void keyedState(const CellKey& key, crypto_auth_hmacsha512256_state& state) {
  initSodium();
  crypto_auth_hmacsha512256_init(&state, key.data(), size_t(kKeyBytes));
}

/// The code of bytes[0, size) from the keyed state (copied: the state is reused).
void codeOf(const crypto_auth_hmacsha512256_state& keyed, const uint8_t* bytes, int size,
            uint8_t* mac) noexcept {
  crypto_auth_hmacsha512256_state state = keyed;
  crypto_auth_hmacsha512256_update(&state, bytes, static_cast<unsigned long long>(size));
  crypto_auth_hmacsha512256_final(&state, mac);
  sodium_memzero(&state, sizeof state);
}

/// A user's name, or "uid N" when the user database has none.
std::string userName(uid_t uid) {
  const passwd* user = getpwuid(uid);
  return user != nullptr ? std::string(user->pw_name) : "uid " + std::to_string(uid);
}

/// Why this process may not read the key at path: who it runs as, who owns the file, the fix.
std::string permissionDenied(const std::string& path, const std::string& source) {
  struct stat st {};
  const std::string owner =
      stat(path.c_str(), &st) == 0 ? " (owner " + userName(st.st_uid) + ")" : "";
  return source + ": permission denied: user " + userName(geteuid()) + " may not read the cell key" +
         owner + "; keep it root:root 0600 and let systemd hand it to the daemon as the credential "
         "cell-key (LoadCredential=cell-key:" + path + ", as stepcal-runtime@.service does for "
         "/etc/stepcal/NAME.key; docs/runtime.md), with key-file empty, or run as a user who may "
         "read it";
}

}  // namespace

CellKey CellKey::load(const std::string& path, const std::string& source) {
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
  if (fd < 0 && errno == EACCES) throw InputError(permissionDenied(path, source), path);
  if (fd < 0) {
    throw InputError(source + ": cannot open the cell key: " + std::strerror(errno) + "; " +
                         kKeyHint,
                     path);
  }
  struct FdCloser {
    int fd;
    ~FdCloser() { close(fd); }
  } closer{fd};
  struct stat st {};
  if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    throw InputError(source + ": not a regular file; " + kKeyHint, path);
  }
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", unsigned(st.st_mode & 07777));
    throw InputError(source + ": mode " + mode +
                         " lets the group or others at the cell key; expected 0600 or 0400 "
                         "(chmod 600 on it, and make a new key if others may have read it)",
                     path);
  }
  if (st.st_size != kKeyBytes) {
    throw InputError(source + ": " + std::to_string(st.st_size) + " bytes; expected exactly " +
                         std::to_string(kKeyBytes) + " random bytes; " + kKeyHint,
                     path);
  }
  CellKey key;
  if (read(fd, key.key_.data(), key.key_.size()) != kKeyBytes) {
    throw InputError(source + ": cannot read the cell key: " + std::strerror(errno),
                     path);
  }
  return key;
}

CellKey CellKey::fromBytes(const std::array<uint8_t, kKeyBytes>& bytes) {
  CellKey key;
  key.key_ = bytes;
  return key;
}

CellKey::~CellKey() { sodium_memzero(key_.data(), key_.size()); }
CellKey::CellKey(const CellKey& other) : key_(other.key_) {}
CellKey& CellKey::operator=(const CellKey& other) {
  key_ = other.key_;
  return *this;
}

MessageSigner::MessageSigner(const CellKey& key) {
  keyedState(key, keyed_);
  randombytes_buf(&sender_, sizeof sender_);
}

void MessageSigner::seal(uint8_t* bytes, int size) noexcept {
  STEPCAL_INVARIANT(size >= kAuthBytes, "a sealed message ends in its authentication fields");
  counter_ = std::max(counter_ + 1, unixMicroseconds());
  uint8_t* auth = bytes + size - kAuthBytes;
  putBigEndian64(auth, sender_);
  putBigEndian64(auth + 8, counter_);
  codeOf(keyed_, bytes, size - kMacBytes, auth + 16);
}

MessageVerifier::MessageVerifier(const CellKey& key, int64_t window_us) : window_us_(window_us) {
  STEPCAL_INVARIANT(window_us > 0, "the counter window is positive");
  keyedState(key, keyed_);
}

Verdict MessageVerifier::verify(const uint8_t* bytes, int size, int64_t now_us) noexcept {
  if (bytes == nullptr || size < kAuthBytes) return Verdict::kForged;
  const uint8_t* auth = bytes + size - kAuthBytes;
  uint8_t mac[kMacBytes];
  codeOf(keyed_, bytes, size - kMacBytes, mac);
  if (crypto_verify_32(mac, auth + 16) != 0) return Verdict::kForged;
  const int64_t id = bigEndian64(auth), counter = bigEndian64(auth + 8);
  // Outside the window: stale (a replay after the window) or from a clock far off.
  if (counter < now_us - window_us_ || counter > now_us + window_us_) return Verdict::kReplayed;
  Sender* free_slot = nullptr;
  for (Sender& s : senders_) {
    if (s.used && s.id == id) {
      if (counter <= s.last_counter) return Verdict::kReplayed;
      s.last_counter = counter;
      return Verdict::kAuthentic;
    }
    // A sender silent for a window is forgotten: the clock refuses its older counters.
    if (free_slot == nullptr && (!s.used || s.last_counter < now_us - window_us_)) free_slot = &s;
  }
  if (free_slot == nullptr) return Verdict::kReplayed;
  *free_slot = Sender{id, counter, true};
  return Verdict::kAuthentic;
}

}  // namespace stepcal::service

// Atomic file replacement (atomic_file.hpp).
#include "stepcal/common/atomic_file.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <ctime>
#include <filesystem>
#include <system_error>
#include <utility>

#include "stepcal/common/error.hpp"

namespace stepcal {
namespace {

std::string systemMessage(int error) { return std::system_category().message(error); }

/// Owns a temporary file: closes it, and removes it unless it was renamed into place.
class TemporaryFile {
 public:
  TemporaryFile(std::string path, int fd) : path_(std::move(path)), fd_(fd) {}
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;
  ~TemporaryFile() {
    if (fd_ >= 0) ::close(fd_);
    if (!renamed_) ::unlink(path_.c_str());
  }
  int fd() const { return fd_; }
  const std::string& path() const { return path_; }
  /// Closes the descriptor; returns 0 or the errno.
  int close() {
    const int rc = ::close(fd_);
    fd_ = -1;
    return rc == 0 ? 0 : errno;
  }
  void markRenamed() { renamed_ = true; }

 private:
  std::string path_;
  int fd_;
  bool renamed_ = false;
};

/// What to do about a failed write, for the errors a user can act on.
std::string hintFor(int error) {
  if (error == ENOSPC || error == EDQUOT) return "; hint: free space on that file system";
  if (error == EFBIG) return "; hint: raise the file size limit (ulimit -f)";
  if (error == EACCES || error == EPERM || error == EROFS) {
    return "; hint: write where you have write permission";
  }
  return "";
}

}  // namespace

SignalsHeldForWriting::SignalsHeldForWriting() {
  sigset_t held;
  sigemptyset(&held);
  for (const int signal : {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGXFSZ}) sigaddset(&held, signal);
  pthread_sigmask(SIG_BLOCK, &held, &previous_);
}

SignalsHeldForWriting::~SignalsHeldForWriting() {
  sigset_t file_size;
  sigemptyset(&file_size);
  sigaddset(&file_size, SIGXFSZ);
  const timespec now{0, 0};
  while (sigtimedwait(&file_size, nullptr, &now) == SIGXFSZ) {
  }
  pthread_sigmask(SIG_SETMASK, &previous_, nullptr);
}

void writeFileAtomically(const std::string& path, const void* data, size_t size,
                         const std::string& what) {
  struct stat existing {};
  if (::stat(path.c_str(), &existing) == 0 && S_ISDIR(existing.st_mode)) {
    throw InputError("is a folder; expected the path of the " + what + " file to write", path);
  }
  const SignalsHeldForWriting held;  // declared first: released after the temporary is gone
  const auto bytes = static_cast<const char*>(data);
  std::string pattern = path + ".tmp-XXXXXX";
  const int fd = ::mkstemp(pattern.data());
  if (fd < 0) {
    const int error = errno;
    throw InputError("cannot write the " + what + ": no temporary file beside it (" +
                         systemMessage(error) +
                         "); expected an existing, writable folder; the previous file, if any, "
                         "is unchanged" + hintFor(error),
                     path);
  }
  TemporaryFile tmp(pattern, fd);
  const auto fail = [&](const std::string& step, int error) {
    throw InputError("cannot write the " + what + ": " + step + " " + tmp.path() + " failed (" +
                         systemMessage(error) +
                         "); the previous file, if any, is unchanged and the temporary file "
                         "removed" + hintFor(error),
                     path);
  };
  // mkstemp creates 0600; a model is meant to be read by the runtime's user too.
  if (::fchmod(tmp.fd(), 0644) != 0) fail("fchmod of", errno);
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(tmp.fd(), bytes + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) fail("writing", errno);
    done += size_t(n);
  }
  if (::fsync(tmp.fd()) != 0) fail("fsync of", errno);
  if (const int error = tmp.close(); error != 0) fail("closing", error);
  if (::rename(tmp.path().c_str(), path.c_str()) != 0) fail("renaming", errno);
  tmp.markRenamed();
  // The rename itself is durable only once the folder is synced.
  std::string folder = std::filesystem::path(path).parent_path().string();
  if (folder.empty()) folder = ".";
  const int dir = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY);
  const int rc = dir < 0 ? -1 : ::fsync(dir);
  const int error = errno;
  if (dir >= 0) ::close(dir);
  if (rc != 0) {
    throw InputError("the " + what + " was written, but syncing its folder " + folder +
                         " failed (" + systemMessage(error) +
                         "); expected a folder that can be synced, else the new file may not "
                         "survive a power loss",
                     path);
  }
}

}  // namespace stepcal

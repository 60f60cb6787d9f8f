// Replacing a file so that a reader sees the old contents or the new, never a part, and so that a
// failed or interrupted write leaves the old file as it was.
#pragma once

#include <signal.h>

#include <cstddef>
#include <string>

namespace stepcal {

/// While alive, the calling thread holds back SIGINT, SIGTERM, SIGHUP and SIGQUIT: they act when
/// it ends (the previous signal mask is restored), so a write it spans is never cut in half. It
/// also holds SIGXFSZ and drops it at the end: a write past the file size limit (ulimit -f) then
/// fails with EFBIG, which the writer reports, instead of ending the process.
class SignalsHeldForWriting {
 public:
  SignalsHeldForWriting();
  ~SignalsHeldForWriting();
  SignalsHeldForWriting(const SignalsHeldForWriting&) = delete;
  SignalsHeldForWriting& operator=(const SignalsHeldForWriting&) = delete;

 private:
  sigset_t previous_;
};

/// Replaces the file at path by size bytes: a temporary file beside it (mode 0644) is written,
/// fsync'ed and renamed over path, then the folder is fsync'ed; signals are held throughout
/// (SignalsHeldForWriting). On any failure (no space, file size limit, I/O error) the temporary
/// file is removed and path stays as it was; the InputError names path, what failed and says
/// so. `what` names the contents in messages ("model", "report").
void writeFileAtomically(const std::string& path, const void* data, size_t size,
                         const std::string& what);

}  // namespace stepcal

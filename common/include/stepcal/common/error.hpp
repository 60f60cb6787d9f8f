// Error reporting: bad user input becomes InputError; broken invariants abort.
#pragma once

#include <stdexcept>
#include <string>

namespace stepcal {

/// Bad user input found at load time. what() reads
/// "<file>:<line>: column '<column>': <message>" with the parts that are known.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message, std::string file = {}, int line = 0,
                      std::string column = {});
  const std::string& file() const noexcept { return file_; }
  int line() const noexcept { return line_; }
  const std::string& column() const noexcept { return column_; }

 private:
  std::string file_;
  int line_ = 0;
  std::string column_;
};

/// Aborts with a message when an internal invariant fails (a bug, never bad input).
[[noreturn]] void invariantFailed(const char* condition, const char* file, int line,
                                  const char* message) noexcept;

}  // namespace stepcal

#define STEPCAL_INVARIANT(cond, msg)                                      \
  do {                                                                    \
    if (!(cond)) ::stepcal::invariantFailed(#cond, __FILE__, __LINE__, msg); \
  } while (0)

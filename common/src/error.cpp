#include "stepcal/common/error.hpp"

#include <cstdio>
#include <cstdlib>

namespace stepcal {
namespace {

std::string composeMessage(const std::string& message, const std::string& file, int line,
                           const std::string& column) {
  std::string out;
  if (!file.empty()) {
    out += file;
    if (line > 0) out += ":" + std::to_string(line);
    out += ": ";
  }
  if (!column.empty()) out += "column '" + column + "': ";
  return out + message;
}

}  // namespace

InputError::InputError(const std::string& message, std::string file, int line, std::string column)
    : std::runtime_error(composeMessage(message, file, line, column)),
      file_(std::move(file)),
      line_(line),
      column_(std::move(column)) {}

void invariantFailed(const char* condition, const char* file, int line,
                     const char* message) noexcept {
  std::fprintf(stderr, "stepcal: internal invariant violated at %s:%d: (%s) %s\n", file, line,
               condition, message);
  std::abort();
}

}  // namespace stepcal

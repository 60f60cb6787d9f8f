// printf into a std::string of whatever length it needs, for the CLI's renderings.
#pragma once

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <string>

namespace stepcal::report {

inline std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
inline std::string format(const char* fmt, ...) {
  va_list args, args_copy;
  va_start(args, fmt);
  va_copy(args_copy, args);
  const int length = std::vsnprintf(nullptr, 0, fmt, args);
  va_end(args);
  std::string out(static_cast<size_t>(std::max(length, 0)) + 1, '\0');
  std::vsnprintf(out.data(), out.size(), fmt, args_copy);
  va_end(args_copy);
  out.pop_back();
  return out;
}

}  // namespace stepcal::report

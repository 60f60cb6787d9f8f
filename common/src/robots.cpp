// Where the shipped robot descriptions are (see robots.hpp).
#include "stepcal/common/robots.hpp"

#include <cstdlib>
#include <filesystem>
#include <system_error>

namespace stepcal {

std::string shippedRobotsDir() {
  if (const char* dir = std::getenv("STEPCAL_ROBOTS_DIR"); dir != nullptr && *dir != '\0') {
    return dir;
  }
  std::error_code error;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", error);
  if (!error) {
    const std::filesystem::path installed =
        exe.parent_path().parent_path() / STEPCAL_INSTALL_ROBOTS_SUBDIR;
    if (std::filesystem::is_directory(installed, error)) return installed.string();
  }
  return STEPCAL_SOURCE_ROBOTS_DIR;
}

}  // namespace stepcal

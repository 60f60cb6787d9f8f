#include "stepcal/common/robots.hpp"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <system_error>

#include "stepcal/common/error.hpp"

namespace stepcal {
namespace {

namespace fs = std::filesystem;

constexpr const char* kExtension = ".urdf";

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool isReadableFile(const fs::path& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

std::string listed(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out.empty() ? "none" : out;
}

}  // namespace

std::vector<std::string> robotSearchFolders() {
  std::vector<std::string> folders;
  if (const char* env = std::getenv(kRobotsDirEnv); env != nullptr && *env != '\0') {
    folders.emplace_back(env);
  }
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    folders.push_back((exe.parent_path().parent_path() / "share" / "stepcal" / "robots").string());
  }
  return folders;
}

std::vector<std::string> shippedRobots() {
  std::vector<std::string> names;
  for (const std::string& folder : robotSearchFolders()) {
    std::error_code ec;
    for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
      const std::string file = it->path().filename().string();
      if (endsWith(file, kExtension) && isReadableFile(it->path())) {
        names.push_back(file.substr(0, file.size() - std::string(kExtension).size()));
      }
    }
  }
  std::sort(names.begin(), names.end());
  names.erase(std::unique(names.begin(), names.end()), names.end());
  return names;
}

bool isRobotPath(const std::string& robot) {
  return robot.find('/') != std::string::npos || endsWith(robot, kExtension);
}

std::string robotDescriptionPath(const std::string& robot) {
  if (robot.empty()) {
    throw InputError("--robot is empty; expected a URDF file or the name of a shipped robot (" +
                     listed(shippedRobots()) + ")");
  }
  if (isRobotPath(robot)) {
    std::error_code ec;
    if (fs::is_directory(robot, ec)) {
      throw InputError("--robot '" + robot + "': is a folder; expected a URDF file");
    }
    if (!isReadableFile(robot)) {
      throw InputError("--robot '" + robot + "': no such file; expected a URDF file (a path "
                       "containing '/' or ending in .urdf) or the name of a shipped robot (" +
                       listed(shippedRobots()) + ")");
    }
    return robot;
  }
  const std::vector<std::string> folders = robotSearchFolders();
  for (const std::string& folder : folders) {
    const fs::path candidate = fs::path(folder) / (robot + kExtension);
    if (isReadableFile(candidate)) return candidate.string();
  }
  throw InputError("--robot '" + robot + "': no shipped robot of that name in " +
                   listed(folders) + "; expected one of " + listed(shippedRobots()) +
                   " or a URDF file (hint: ./" + robot + kExtension + " for a file here; " +
                   kRobotsDirEnv + " names another folder of robots)");
}

}  // namespace stepcal

// Inputs of the file-reading fuzz targets: one fuzz input holds two files split at its first NUL
// byte, which a target writes into a scratch folder before calling the reader, because the
// readers take paths (a campaign.yaml names the files beside it, the IPA importer reads the
// transform beside the series).
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <system_error>
#include <utility>

namespace stepcal::fuzz {

/// The input before and after its first NUL byte (all of it and "" when it has none).
inline std::pair<std::string, std::string> splitAtFirstNul(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const size_t nul = text.find('\0');
  if (nul == std::string::npos) return {text, ""};
  return {text.substr(0, nul), text.substr(nul + 1)};
}

/// This process's folder in the system's temporary folder (fuzz.sh points TMPDIR at /dev/shm),
/// the same for every input, removed when the fuzzer exits normally.
class ScratchFolder {
 public:
  ScratchFolder()
      : path_(std::filesystem::temp_directory_path() /
              ("stepcal-fuzz-" + std::to_string(::getpid()))) {
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchFolder() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchFolder(const ScratchFolder&) = delete;
  ScratchFolder& operator=(const ScratchFolder&) = delete;

  /// Replaces the file name in the folder by text; aborts (a harness failure, not a finding)
  /// when it cannot.
  std::filesystem::path write(const std::string& name, const std::string& text) const {
    const std::filesystem::path path = path_ / name;
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << text;
    out.close();
    if (!out) std::abort();
    return path;
  }
  /// The whole file name in the folder; aborts when it cannot be read.
  std::string read(const std::string& name) const {
    std::ifstream in(path_ / name, std::ios::binary);
    if (!in) std::abort();
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace stepcal::fuzz

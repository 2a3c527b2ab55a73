// A per-process scratch folder for a test program, removed when the program exits.
#pragma once
#include <unistd.h>

#include <filesystem>
#include <string>

namespace mm::test {

// One folder per (program, prefix): <tmp>/<prefix>_<pid>. The prefix of the first call wins.
inline const std::filesystem::path& scratch_dir(const std::string& prefix) {
  static const struct Dir {
    std::filesystem::path path;
    explicit Dir(const std::string& p)
        : path(std::filesystem::temp_directory_path() / (p + "_" + std::to_string(::getpid()))) {
      std::filesystem::create_directories(path);
    }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  } dir(prefix);
  return dir.path;
}

}  // namespace mm::test

// A per-process scratch folder for the meshio tests, removed when the test program exits.
#pragma once
#include <unistd.h>

#include <filesystem>
#include <string>

namespace mm::test {

inline const std::filesystem::path& meshio_temp_dir() {
  static const struct Dir {
    std::filesystem::path path;
    Dir() : path(std::filesystem::temp_directory_path() / ("mm_meshio_test_" + std::to_string(::getpid()))) {
      std::filesystem::create_directories(path);
    }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  } dir;
  return dir.path;
}

}  // namespace mm::test

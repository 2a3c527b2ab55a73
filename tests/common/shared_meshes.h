// Locating the real test meshes in ../shared/data/meshes.
// A clone without ../shared cannot run these tests: they say so plainly and skip, except under
// CI (CI=true), where the meshes are always present and their absence is a failure.
#pragma once
#include <gtest/gtest.h>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace mm::test {

inline std::filesystem::path shared_meshes_dir() { return MESHMARK_SHARED_MESHES; }

inline std::string shared_mesh(const std::string& name) {
  return (shared_meshes_dir() / name).string();
}

inline bool shared_meshes_present() {
  return std::filesystem::exists(shared_meshes_dir() / "fandisk_quads.off");
}

}  // namespace mm::test

// Use at the top of a test body that reads the shared meshes.
#define MM_REQUIRE_SHARED_MESHES()                                                        \
  do {                                                                                    \
    if (!mm::test::shared_meshes_present()) {                                             \
      const char* ci = std::getenv("CI");                                                 \
      if (ci && std::string(ci) == "true")                                                \
        FAIL() << "shared meshes absent at " << mm::test::shared_meshes_dir();            \
      GTEST_SKIP() << "shared meshes absent at " << mm::test::shared_meshes_dir()         \
                   << ": clone with ../shared beside this repository to run this test";   \
    }                                                                                     \
  } while (0)

// What the format tests share: a small mixed mesh, reading a file whole, and the check that a
// damaged file is refused with an InputError naming it and the reason.
#pragma once
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "meshio/read_mesh.h"

namespace mm::test {

// A quad and a triangle sharing an edge, coordinates that float32 rounds.
inline Mesh quad_and_triangle() {
  Mesh m;
  m.points.resize(5, 3);
  m.points << 0, 0, 0, 10.1, 0, 0, 10.1, 20.3, 0, 0, 20.3, 0, 5, 30.7, 1.25;
  m.faces = {{0, 1, 2, 3}, {3, 2, 4}};
  return m;
}

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

// Writes `bytes` to dir/name and expects read_mesh to refuse it naming the file and `why`.
inline void expect_refused(const std::filesystem::path& dir, const std::string& bytes, const std::string& name,
                           const std::string& why) {
  const std::filesystem::path p = dir / name;
  std::ofstream(p, std::ios::binary) << bytes;
  try {
    read_mesh(p.string());
    ADD_FAILURE() << name << " was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), p.string());
    EXPECT_NE(e.reason().find(why), std::string::npos) << name << ": " << e.what();
  }
}

}  // namespace mm::test

// The corpus in tests/data/broken (made by make_broken.py, listed in EXPECTED.tsv): each file
// is refused with an InputError naming the file and the specific reason, never a crash.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <cstring>
#include <map>
#include <random>
#include <set>

#include "meshio/read_mesh.h"
#include "meshio/repair_manifold.h"

namespace {

namespace fs = std::filesystem;
const fs::path kDir = fs::path(MESHMARK_SOURCE_DIR) / "tests" / "data" / "broken";

std::map<std::string, std::string> expected() {
  std::map<std::string, std::string> out;
  std::ifstream in(kDir / "EXPECTED.tsv");
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    auto tab = line.find('\t');
    out[line.substr(0, tab)] = line.substr(tab + 1);
  }
  return out;
}

TEST(BrokenFiles, EveryFileGivesItsSpecificError) {
  auto cases = expected();
  ASSERT_GE(cases.size(), 25u);
  for (const auto& [name, reason] : cases) {
    SCOPED_TRACE(name);
    std::string path = (kDir / name).string();
    ASSERT_TRUE(fs::exists(path));
    try {
      mm::read_mesh(path);
      ADD_FAILURE() << "read without error";
    } catch (const mm::InputError& e) {
      EXPECT_EQ(e.source(), path);
      EXPECT_NE(e.reason().find(reason), std::string::npos) << "reason was: " << e.reason();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos);
    }
    EXPECT_THROW(mm::read_mesh_manifold(path), mm::InputError);
  }
}

TEST(BrokenFiles, EveryFileInTheFolderIsListed) {
  auto cases = expected();
  for (const auto& e : fs::directory_iterator(kDir)) {
    std::string name = e.path().filename().string();
    if (name == "EXPECTED.tsv" || name == "make_broken.py") continue;
    EXPECT_TRUE(cases.count(name)) << name << " has no expected error";
  }
}

// Every prefix of a valid file is either read (a shorter valid file) or refused cleanly.
TEST(BrokenFiles, EveryTruncationOfValidFilesIsHandled) {
  const std::map<std::string, std::string> valid = {
      {"off", "OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n"},
      {"obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n"},
      {"ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
              "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"},
      {"stl", "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
              "endloop\nendfacet\nendsolid s\n"},
  };
  for (const auto& [fmt, text] : valid) {
    EXPECT_NO_THROW(mm::parse_mesh(text, fmt, "whole." + fmt));
    int refused = 0;
    for (size_t n = 0; n < text.size(); ++n) {
      try {
        mm::parse_mesh(std::string_view(text).substr(0, n), fmt, "prefix");
      } catch (const mm::InputError& e) {
        ++refused;
        EXPECT_EQ(e.source(), "prefix");
      }
    }
    // Only cuts inside the last number or keyword can still parse.
    EXPECT_GE(refused, static_cast<int>(text.size()) - 12) << fmt;
  }
}

}  // namespace

namespace {

std::string binary_stl_two_triangles() {
  std::string s(80, 'x');
  auto put32 = [&](uint32_t u) { for (int k = 0; k < 4; ++k) s += static_cast<char>(u >> (8 * k) & 0xff); };
  auto putf = [&](float f) { uint32_t u; std::memcpy(&u, &f, 4); put32(u); };
  put32(2);
  const float tri[2][9] = {{0, 0, 0, 1, 0, 0, 1, 1, 0}, {0, 0, 0, 1, 1, 0, 0, 1, 0}};
  for (const auto& t : tri) {
    for (int k = 0; k < 3; ++k) putf(k == 2 ? 1.f : 0.f);
    for (float f : t) putf(f);
    s += std::string(2, '\0');
  }
  return s;
}

std::string binary_ply_quad() {
  std::string s = "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty double x\nproperty double y\n"
                  "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  for (double d : {0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.}) s.append(reinterpret_cast<const char*>(&d), 8);
  s += '\x04';
  for (int32_t i : {0, 1, 2, 3}) s.append(reinterpret_cast<const char*>(&i), 4);
  return s;
}

// Hostile bytes: random flips, insertions, deletions and cuts of valid files. The readers must
// either read the result or throw InputError: no other exception, no crash (run under the Asan
// build type to also catch memory errors).
TEST(BrokenFiles, RandomlyMutatedFilesGiveInputErrorOrAMesh) {
  const std::vector<std::pair<std::string, std::string>> seeds = {
      {"off", "OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n"},
      {"obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf -4 -2 -1\n"},
      {"ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
              "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"},
      {"ply", binary_ply_quad()},
      {"stl", "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
              "endloop\nendfacet\nendsolid s\n"},
      {"stl", binary_stl_two_triangles()},
  };
  std::mt19937 rng(2024);
  const char interesting[] = {'0', '9', '-', 'e', '.', ' ', '\n', '/', '\0', '\xff', 'n', 'i'};
  for (const auto& [fmt, valid] : seeds) {
    ASSERT_NO_THROW(mm::parse_mesh(valid, fmt, "seed")) << fmt;
    int read = 0, refused = 0;
    for (int trial = 0; trial < 3000; ++trial) {
      std::string s = valid;
      int edits = 1 + static_cast<int>(rng() % 4);
      for (int e = 0; e < edits && !s.empty(); ++e) {
        size_t at = rng() % s.size();
        switch (rng() % 5) {
          case 0: s[at] = static_cast<char>(rng() & 0xff); break;
          case 1: s[at] = interesting[rng() % sizeof interesting]; break;
          case 2: s.insert(at, 1, interesting[rng() % sizeof interesting]); break;
          case 3: s.erase(at, 1 + rng() % 4); break;
          case 4: s.resize(at); break;
        }
      }
      try {
        mm::Mesh m = mm::parse_mesh(s, fmt, "mutant");
        ++read;
        for (const auto& f : m.faces) {
          ASSERT_GE(f.size(), 3u);
          for (int v : f) ASSERT_TRUE(v >= 0 && v < m.num_vertices());
        }
        ASSERT_TRUE(m.points.allFinite());
      } catch (const mm::InputError& e) {
        ++refused;
        ASSERT_EQ(e.source(), "mutant");
        ASSERT_FALSE(e.reason().empty());
      }
    }
    EXPECT_GT(refused, 500) << fmt;  // the mutations do break files
    EXPECT_GT(read, 0) << fmt;       // and some are still valid meshes
  }
}

}  // namespace

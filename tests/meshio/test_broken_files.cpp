// The corpus in tests/data/broken (made by make_broken.py, listed in EXPECTED.tsv): each file
// is refused with an InputError naming the file and the specific reason, never a crash.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
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

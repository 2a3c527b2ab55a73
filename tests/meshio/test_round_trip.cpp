// write_mesh then read_mesh gives back identical positions and faces in every format.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <random>

#include "common/shared_meshes.h"
#include "meshio/read_mesh.h"
#include "common/temp_dir.h"

namespace {

namespace fs = std::filesystem;

fs::path temp_dir() {
  return mm::test::scratch_dir("mm_meshio_test");
}

// A mixed quad/triangle strip with coordinates no float can hold exactly.
mm::Mesh mixed_mesh() {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(-1e3, 1e3);
  mm::Mesh m;
  const int cols = 6;
  m.points.resize(2 * cols, 3);
  for (int i = 0; i < 2 * cols; ++i) m.points.row(i) << u(rng), u(rng) / 7.0, u(rng) * 1e-9;
  for (int c = 0; c + 1 < cols; ++c) {
    if (c % 2 == 0) {
      m.faces.push_back({c, c + 1, cols + c + 1, cols + c});
    } else {
      m.faces.push_back({c, c + 1, cols + c + 1});
      m.faces.push_back({c, cols + c + 1, cols + c});
    }
  }
  return m;
}

void expect_identical(const mm::Mesh& a, const mm::Mesh& b) {
  ASSERT_EQ(a.num_vertices(), b.num_vertices());
  for (int i = 0; i < a.num_vertices(); ++i)
    for (int k = 0; k < 3; ++k) ASSERT_EQ(a.points(i, k), b.points(i, k)) << "vertex " << i;
  EXPECT_EQ(a.faces, b.faces);
}

TEST(RoundTrip, TextFormatsAreExact) {
  mm::Mesh m = mixed_mesh();
  for (const char* ext : {".obj", ".off", ".ply", ".OFF"}) {
    SCOPED_TRACE(ext);
    std::string p = (temp_dir() / (std::string("mixed") + ext)).string();
    mm::write_mesh(m, p);
    expect_identical(m, mm::read_mesh(p));
  }
}

TEST(RoundTrip, StlIsExactForFloatCoordinates) {
  // STL stores float32 triangles: positions survive exactly when they are floats, and welding
  // numbers vertices by first appearance, which this mesh's face order already follows.
  mm::Mesh m = mixed_mesh();
  for (int i = 0; i < m.num_vertices(); ++i)
    for (int k = 0; k < 3; ++k) m.points(i, k) = static_cast<float>(m.points(i, k));
  mm::Mesh tri;
  tri.points = m.points;
  for (const auto& f : m.faces)
    for (size_t k = 1; k + 1 < f.size(); ++k) tri.faces.push_back({f[0], f[k], f[k + 1]});
  std::string p = (temp_dir() / "mixed.stl").string();
  mm::write_mesh(m, p);  // quads are fan-triangulated on write
  mm::Mesh back = mm::read_mesh(p);
  ASSERT_EQ(back.num_vertices(), m.num_vertices());
  // Map read-back vertices to the originals by position (all positions are distinct).
  std::vector<int> map(static_cast<size_t>(back.num_vertices()), -1);
  for (int i = 0; i < back.num_vertices(); ++i)
    for (int j = 0; j < m.num_vertices(); ++j)
      if (back.points.row(i) == m.points.row(j)) map[static_cast<size_t>(i)] = j;
  for (int i = 0; i < back.num_vertices(); ++i) ASSERT_GE(map[static_cast<size_t>(i)], 0);
  ASSERT_EQ(back.faces.size(), tri.faces.size());
  for (size_t f = 0; f < tri.faces.size(); ++f)
    for (size_t k = 0; k < 3; ++k) EXPECT_EQ(map[static_cast<size_t>(back.faces[f][k])], tri.faces[f][k]);
}

TEST(RoundTrip, SharedFandiskQuadsInEveryTextFormat) {
  MM_REQUIRE_SHARED_MESHES();
  mm::Mesh m = mm::read_mesh(mm::test::shared_mesh("fandisk_quads.off"));
  for (const char* ext : {".obj", ".off", ".ply"}) {
    SCOPED_TRACE(ext);
    std::string p = (temp_dir() / (std::string("fandisk_quads") + ext)).string();
    mm::write_mesh(m, p);
    expect_identical(m, mm::read_mesh(p));
  }
}

TEST(RoundTrip, SharedStlRewrittenAsStlIsIdentical) {
  MM_REQUIRE_SHARED_MESHES();
  mm::Mesh m = mm::read_mesh(mm::test::shared_mesh("abc7.stl"));
  std::string p = (temp_dir() / "abc7.stl").string();
  mm::write_mesh(m, p);
  expect_identical(m, mm::read_mesh(p));
}

TEST(RoundTrip, OverwriteIsAtomicAndLeavesNoTemporaryFiles) {
  fs::path dir = temp_dir() / "atomic";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::string p = (dir / "part.off").string();
  mm::Mesh m = mixed_mesh();
  mm::write_mesh(m, p);
  m.points(0, 0) = 42.0;
  mm::write_mesh(m, p);
  EXPECT_EQ(mm::read_mesh(p).points(0, 0), 42.0);
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    (void)e;
    ++files;
  }
  EXPECT_EQ(files, 1);
}

TEST(RoundTrip, WriteErrorsNameThePathAndLeaveNothing) {
  mm::Mesh m = mixed_mesh();
  try {
    mm::write_mesh(m, "/nonexistent-dir/part.off");
    FAIL() << "no exception";
  } catch (const mm::InputError& e) {
    EXPECT_EQ(e.source(), "/nonexistent-dir/part.off");
    EXPECT_NE(e.reason().find("cannot create temporary file"), std::string::npos);
  }
  fs::path dir = temp_dir() / "invalid";
  fs::remove_all(dir);
  fs::create_directories(dir);
  mm::Mesh bad = m;
  bad.faces.push_back({0, 1, 99});
  EXPECT_THROW(mm::write_mesh(bad, (dir / "bad.obj").string()), mm::InputError);
  bad = m;
  bad.points(2, 1) = std::nan("");
  EXPECT_THROW(mm::write_mesh(bad, (dir / "bad.ply").string()), mm::InputError);
  EXPECT_THROW(mm::write_mesh(m, (dir / "bad.xyz").string()), mm::InputError);
  EXPECT_TRUE(fs::is_empty(dir));
}

}  // namespace

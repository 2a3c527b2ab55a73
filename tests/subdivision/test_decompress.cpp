// Decompression helpers: level choice for a triangle budget, triangulation for STL.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "subdivision/decompress.h"
#include "subdivision/subdivide.h"
#include "subdivision/test_meshes.h"

namespace mm {
namespace {

Mesh mixed_with_pentagon() {
  // Pentagonal prism with one side quad split into two triangles: pentagons, quads, triangles.
  std::vector<std::array<double, 3>> p;
  for (int z = 0; z < 2; ++z)
    for (int k = 0; k < 5; ++k) p.push_back({std::cos(2 * M_PI * k / 5), std::sin(2 * M_PI * k / 5), 1.0 * z});
  std::vector<std::vector<int>> f{{4, 3, 2, 1, 0}, {5, 6, 7, 8, 9}, {0, 1, 6}, {0, 6, 5}};
  for (int k = 1; k < 5; ++k) f.push_back({k, (k + 1) % 5, 5 + (k + 1) % 5, 5 + k});
  return mm::test::make_mesh(p, f);
}

TEST(Decompress, TriangleCountFormulaMatchesRealCount) {
  const Mesh m = mixed_with_pentagon();
  for (int level = 0; level <= 3; ++level)
    EXPECT_EQ(subdivided_triangle_count(m, level), triangle_count(triangulate(subdivide(m, level))))
        << "level " << level;
}

TEST(Decompress, ChoosesSmallestLevelReachingTarget) {
  const Mesh m = mixed_with_pentagon();
  const long long t1 = subdivided_triangle_count(m, 1), t2 = subdivided_triangle_count(m, 2);
  EXPECT_EQ(level_for_triangle_count(m, 1), 0);
  EXPECT_EQ(level_for_triangle_count(m, t1), 1);
  EXPECT_EQ(level_for_triangle_count(m, t1 + 1), 2);
  EXPECT_EQ(level_for_triangle_count(m, t2), 2);
  EXPECT_EQ(level_for_triangle_count(m, 1LL << 40, 4), 4);  // capped
  const Mesh d = decompress_to_triangle_count(m, t1 + 1);
  EXPECT_EQ(triangle_count(d), t2);
  EXPECT_EQ(decompress_to_level(m, 2).faces, d.faces);
  EXPECT_THROW(level_for_triangle_count(m, 10, -1), std::invalid_argument);
}

TEST(Decompress, LevelChoiceStaysWithinTheSizeLimit) {
  const Mesh big = mm::test::grid(300, 300);  // 180k triangles after triangulation
  const int level = level_for_triangle_count(big, 1LL << 40, 6);
  EXPECT_EQ(level, 2);  // level 3 would be 11.5M triangles
  EXPECT_LE(subdivided_triangle_count(big, level), 2 * kMaxRefinedVertices);
}

TEST(Decompress, TriangulateKeepsShapeAndOrientation) {
  const Mesh q = subdivide(mm::test::cube(), 2);
  const Mesh t = triangulate(q);
  EXPECT_EQ(t.num_faces(), 2 * q.num_faces());
  EXPECT_EQ(t.points, q.points);
  for (const auto& f : t.faces) ASSERT_EQ(f.size(), 3u);
  // Each triangle's normal points outwards like its quad's (the cube is centred at the origin).
  for (const auto& f : t.faces) {
    Eigen::Vector3d a = t.points.row(f[0]), b = t.points.row(f[1]), c = t.points.row(f[2]);
    EXPECT_GT((b - a).cross(c - a).dot((a + b + c) / 3.0), 0.0);
  }
  Mesh bad = q;
  bad.faces[0][0] = 99999;
  EXPECT_THROW(triangulate(bad), InputError);
}

}  // namespace
}  // namespace mm

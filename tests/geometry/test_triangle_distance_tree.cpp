// TriangleDistanceTree must give CGAL's AABB tree numbers bit for bit (the quality reports and
// compress's tolerance decisions were made with CGAL's): queries near, on and far from the
// surfaces of a curved CAD part and of a subdivided control mesh, with and without hints; and
// the triangle a query names (triangle_of) is one at the distance it reports; and within() (a
// tolerance check's question) never says yes for a radius below the distance.
#include <gtest/gtest.h>

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <Eigen/Geometry>
#include <cstring>
#include <random>

#include "common/shared_meshes.h"
#include "meshio/read_mesh.h"
#include "quality/surface_distance.h"
#include "geometry/triangle_distance_tree.h"

namespace {

using K = CGAL::Simple_cartesian<double>;
using TriangleIt = std::vector<K::Triangle_3>::const_iterator;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, CGAL::AABB_triangle_primitive<K, TriangleIt>>>;

std::vector<std::array<Eigen::Vector3d, 3>> corners(const mm::Mesh& m) {
  std::vector<std::array<Eigen::Vector3d, 3>> out;
  for (const auto& f : m.faces)
    for (size_t k = 1; k + 1 < f.size(); ++k) {
      std::array<Eigen::Vector3d, 3> t{m.points.row(f[0]).transpose(), m.points.row(f[k]).transpose(),
                                       m.points.row(f[k + 1]).transpose()};
      if ((t[1] - t[0]).cross(t[2] - t[0]).norm() > 0) out.push_back(t);
    }
  return out;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Queries: surface samples pushed off along random directions by 0 to 10 % of the diagonal
// (most near the surface, where ties between neighbouring triangles happen), the vertices
// themselves and points far outside.
void expect_cgal_numbers(const mm::Mesh& mesh, const mm::Mesh& query_surface, int count) {
  const auto tris = corners(mesh);
  std::vector<K::Triangle_3> cgal;
  for (const auto& t : tris)
    cgal.emplace_back(K::Point_3(t[0].x(), t[0].y(), t[0].z()), K::Point_3(t[1].x(), t[1].y(), t[1].z()),
                      K::Point_3(t[2].x(), t[2].y(), t[2].z()));
  Tree reference(cgal.begin(), cgal.end());
  reference.accelerate_distance_queries();
  const mm::TriangleDistanceTree tree(tris);
  const double diag = (mesh.points.colwise().maxCoeff() - mesh.points.colwise().minCoeff()).norm();
  auto points = mm::sample_surface(query_surface, count, 7, true);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (size_t k = 0; k < points.size(); k += 3) {
    const double scale = (k % 9 == 0 ? 0.1 : k % 9 == 3 ? 0.001 : 0.0) * diag;
    points[k] += scale * Eigen::Vector3d(u(rng), u(rng), u(rng));
  }
  for (int k = 0; k < 20; ++k) points.push_back(Eigen::Vector3d(u(rng), u(rng), u(rng)) * 3 * diag);
  int hint = -1, mismatches = 0, misnamed = 0, wrong_within = 0;
  for (size_t k = 0; k < points.size(); ++k) {
    const auto& p = points[k];
    const double expected = reference.squared_distance(K::Point_3(p.x(), p.y(), p.z()));
    // Hints: the previous answer, none, or an arbitrary triangle far away.
    int h = k % 5 == 4 ? -1 : k % 5 == 3 ? static_cast<int>(k % tris.size()) : hint;
    const double got = tree.squared_distance(p, h);
    if (k % 5 < 3) hint = h;
    if (!same_bits(got, expected) && ++mismatches <= 5)
      ADD_FAILURE() << "query " << k << " (" << p.transpose() << "): " << got << " vs CGAL " << expected;
    // The triangle it names is one at that distance (as CGAL measures a triangle: its first
    // vertex or the projection, whichever is closer).
    const K::Point_3 q(p.x(), p.y(), p.z());
    const K::Triangle_3& named = cgal[static_cast<size_t>(tree.triangle_of(h))];
    const double own = std::min(K::Compute_squared_distance_3()(q, named.vertex(0)),
                                K::Compute_squared_distance_3()(q, K::Construct_projected_point_3()(named, q)));
    if (!same_bits(own, got) && ++misnamed <= 5)
      ADD_FAILURE() << "query " << k << ": the triangle named is at " << own << ", not " << got;
    // within(): never true for a radius below the distance, always true for one clearly above
    // it (a millionth of the diagonal, far above the rounding slack), whatever the hint.
    const double d = std::sqrt(expected);
    for (const double r : {0.5 * d, d * (1 - 1e-9), d + 1e-6 * diag, 1.5 * d + 1e-3 * diag}) {
      int wh = k % 3 == 0 ? -1 : k % 3 == 1 ? h : static_cast<int>((7 * k) % tris.size());
      const bool in = tree.within(p, r, wh);
      if (in && !(expected <= r * r) && ++wrong_within <= 5)
        ADD_FAILURE() << "query " << k << ": within(" << r << ") for a distance of " << d;
      if (!in && r >= d + 1e-6 * diag && ++wrong_within <= 5)
        ADD_FAILURE() << "query " << k << ": not within(" << r << ") for a distance of " << d;
      // The hint it leaves names a triangle within the radius.
      if (in) {
        const K::Triangle_3& found = cgal[static_cast<size_t>(tree.triangle_of(wh))];
        const double at = K::Compute_squared_distance_3()(q, K::Construct_projected_point_3()(found, q));
        if (!(std::sqrt(at) <= r) && ++wrong_within <= 5)
          ADD_FAILURE() << "query " << k << ": within(" << r << ") found a triangle at " << std::sqrt(at);
      }
    }
  }
  EXPECT_EQ(mismatches, 0) << "of " << points.size() << " queries";
  EXPECT_EQ(misnamed, 0) << "of " << points.size() << " queries";
  EXPECT_EQ(wrong_within, 0) << "of " << points.size() << " queries";
  EXPECT_THROW(tree.triangle_of(-1), std::out_of_range);
  EXPECT_THROW(tree.triangle_of(static_cast<int>(tris.size())), std::out_of_range);
}

TEST(TriangleDistanceTree, CgalNumbersOnAPart) {
  MM_REQUIRE_SHARED_MESHES();
  const mm::Mesh part = mm::read_mesh(mm::test::shared_mesh("fandisk.off"));
  expect_cgal_numbers(part, part, 20000);
}

TEST(TriangleDistanceTree, CgalNumbersOnASubdividedSurface) {
  MM_REQUIRE_SHARED_MESHES();
  // A coarse control mesh's level-3 surface against the part and the other way round: the two
  // directions of compress's dense check.
  const mm::Mesh part = mm::read_mesh(mm::test::shared_mesh("fandisk.off"));
  const mm::Mesh quads = mm::read_mesh(mm::test::shared_mesh("fandisk_quads.off"));
  expect_cgal_numbers(quads, part, 20000);
  expect_cgal_numbers(part, quads, 20000);
}

// A query whose closest point is a corner several triangles share, as their first corner, ties
// exactly: the answer names the first of them in the constructor's list, wherever the search
// starts (coordinate_slack charges a sample's error to that triangle's corners, and queries its
// samples in any order).
TEST(TriangleDistanceTree, EquallyCloseTrianglesGiveTheFirstInTheList) {
  using V = Eigen::Vector3d;
  std::vector<std::array<V, 3>> tris;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(2.0, 9.0);
  // Far triangles around, so the tied ones fall into different leaves.
  for (int k = 0; k < 60; ++k) {
    const V a(u(rng), u(rng), u(rng));
    tris.push_back({a, V(a + V(0.5, 0, 0)), V(a + V(0, 0.5, 0))});
  }
  // Three triangles with the origin as their first corner, in the positive octant.
  const std::vector<std::size_t> tied{41, 7, 23};
  const V ex(1, 0, 0), ey(0, 1, 0), ez(0, 0, 1), o(0, 0, 0);
  tris[tied[0]] = {o, ex, ey};
  tris[tied[1]] = {o, ey, ez};
  tris[tied[2]] = {o, ez, ex};
  const mm::TriangleDistanceTree tree(tris);
  const V q(-1, -1, -1);  // nearest to the origin, at squared distance 3 from all three
  for (int start = -1; start < static_cast<int>(tris.size()); ++start) {
    int hint = start;
    EXPECT_EQ(tree.squared_distance(q, hint), 3.0) << start;
    EXPECT_EQ(tree.triangle_of(hint), 7) << "search started at position " << start;
  }
}

TEST(TriangleDistanceTree, RejectsNoTriangles) {
  EXPECT_THROW(mm::TriangleDistanceTree({}), std::invalid_argument);
}

// A tree on another tree's layout (the same triangles, moved: a control polyhedron's stream at
// another grid) answers every query exactly as a tree laid out for its own corners; a layout
// for another count of triangles is refused.
TEST(TriangleDistanceTree, OnAnotherTreesLayoutTheAnswersAreTheSame) {
  using V = Eigen::Vector3d;
  // A wavy sheet of 2 x 40 x 40 triangles, then every vertex moved by up to half a cell.
  const int n = 41;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<V> grid, moved;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      grid.emplace_back(i, j, 3 * std::sin(0.3 * i) * std::cos(0.2 * j));
      moved.push_back(grid.back() + 0.5 * V(u(rng), u(rng), u(rng)));
    }
  const auto sheet = [n](const std::vector<V>& p) {
    std::vector<std::array<V, 3>> tris;
    for (int i = 0; i + 1 < n; ++i)
      for (int j = 0; j + 1 < n; ++j) {
        const int a = i * n + j, b = a + 1, c = a + n, d = c + 1;
        tris.push_back({p[a], p[b], p[d]});
        tris.push_back({p[a], p[d], p[c]});
      }
    return tris;
  };
  const mm::TriangleDistanceTree first(sheet(grid));
  const mm::TriangleDistanceTree own(sheet(moved)), reused(sheet(moved), first.layout());
  EXPECT_EQ(reused.layout(), first.layout());
  int differ = 0, within_differ = 0;
  int h_own = -1, h_reused = -1;
  for (int k = 0; k < 20000; ++k) {
    const V q(40 * (u(rng) + 1) / 2, 40 * (u(rng) + 1) / 2, 4 * u(rng));
    const double a = own.squared_distance(q, h_own), b = reused.squared_distance(q, h_reused);
    if ((!same_bits(a, b) || own.triangle_of(h_own) != reused.triangle_of(h_reused)) && ++differ <= 5)
      ADD_FAILURE() << "query " << k << ": " << a << " vs " << b << " on the reused layout";
    const double r = std::sqrt(a) * (k % 2 == 0 ? 0.999 : 1.001);
    int w1 = -1, w2 = -1;
    if (own.within(q, r, w1) != reused.within(q, r, w2)) ++within_differ;
  }
  EXPECT_EQ(differ, 0);
  EXPECT_EQ(within_differ, 0);
  auto fewer = sheet(moved);
  fewer.pop_back();
  EXPECT_THROW(mm::TriangleDistanceTree(fewer, first.layout()), std::invalid_argument);
}

}  // namespace

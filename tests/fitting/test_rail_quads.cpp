// Rail quads: which triangle pairs become quads, and why they are worth it (a wall between two
// crease rings does not sag with quads, and compress() needs fewer vertices for a cylinder).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include "fitting/compress.h"
#include "fitting/rail_quads.h"
#include "quality/surface_distance.h"
#include "subdivision/subdivide.h"
#include "test_control_meshes.h"

namespace {

using mm::test::count_quads;
using mm::test::cylinder;
using mm::test::expect_oriented;

// Per vertex: 1 when it lies on a crease edge (the rims).
std::vector<char> crease_vertices(const mm::Mesh& m) {
  std::vector<char> on(static_cast<size_t>(m.num_vertices()), 0);
  for (auto [a, b] : m.creases) on[static_cast<size_t>(a)] = on[static_cast<size_t>(b)] = 1;
  return on;
}

// Radius in the xy plane of the refined vertices strictly between the rims, and of those on them.
struct Radii {
  double wall_min = 1e300, wall_max = 0, rim_min = 1e300, rim_max = 0;
};
Radii refined_radii(const mm::Mesh& control, double height) {
  const mm::SubdivisionOperator op = mm::build_subdivision(control, 3);
  const mm::Points p = op.S * control.points;
  const std::vector<char> on_rim = crease_vertices(op.refined);
  Radii r;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    const double rad = std::hypot(p(i, 0), p(i, 1)), z = p(i, 2);
    if (on_rim[i]) {
      r.rim_min = std::min(r.rim_min, rad);
      r.rim_max = std::max(r.rim_max, rad);
    } else if (z > 1e-9 && z < height - 1e-9) {
      r.wall_min = std::min(r.wall_min, rad);
      r.wall_max = std::max(r.wall_max, rad);
    }
  }
  return r;
}

TEST(RailQuads, PairsTheWallBetweenTwoCreaseRimsAndNothingElse) {
  const mm::Mesh tri = cylinder(8, 1, 1.0, 0.5, true);
  const mm::Mesh q = mm::pair_rail_quads(tri);
  EXPECT_EQ(count_quads(q), 8);
  EXPECT_EQ(q.num_faces(), 8 + 16);  // 8 wall quads, 16 cap triangles untouched
  EXPECT_EQ(q.points, tri.points);
  EXPECT_EQ(q.creases, tri.creases);
  expect_oriented(q, true);
  // Every quad has two rim edges: one on each ring.
  const std::set<std::pair<int, int>> creases(q.creases.begin(), q.creases.end());
  for (const auto& f : q.faces) {
    if (f.size() != 4) continue;
    int rails = 0;
    for (int k = 0; k < 4; ++k)
      rails += creases.count({std::min(f[k], f[(k + 1) % 4]), std::max(f[k], f[(k + 1) % 4])}) > 0;
    EXPECT_EQ(rails, 2);
  }
}

TEST(RailQuads, LeavesStripsWithoutTwoCreaseRailsAsTriangles) {
  // No creases: nothing is a rail.
  EXPECT_EQ(count_quads(mm::pair_rail_quads(cylinder(8, 1, 1.0, 0.5, false))), 0);
  // Two rows: each pair has one rim edge and one edge in the middle row, not two rails.
  EXPECT_EQ(count_quads(mm::pair_rail_quads(cylinder(8, 2, 1.0, 0.5, true))), 0);
}

TEST(RailQuads, RejectsConcaveAndSkewedCells) {
  // A flat pair across edge 0-2 whose quad 0-1-2-3 would be concave at 2; rails 0-1 and 2-3.
  mm::Mesh m;
  m.points.resize(4, 3);
  m.points << 0, 0, 0, 1, 0, 0, 0.2, 0.2, 0, 0, 1, 0;
  m.faces = {{0, 1, 2}, {0, 2, 3}};
  m.creases = {{0, 1}, {2, 3}};
  EXPECT_EQ(count_quads(mm::pair_rail_quads(m)), 0);
  // The same pair as a square is paired, with both triangles' orientation.
  m.points.row(2) << 1, 1, 0;
  const mm::Mesh q = mm::pair_rail_quads(m);
  ASSERT_EQ(count_quads(q), 1);
  expect_oriented(q, false);
  // Folded up along the diagonal by 78 degrees: not paired.
  m.points.row(3) << 0, 0.3, 1;
  EXPECT_EQ(count_quads(mm::pair_rail_quads(m, 60.0)), 0);
}

TEST(RailQuads, QuadWallIsTheRuledSurfaceBetweenTheRimCurves) {
  // Catmull-Clark on a one-quad-high strip between two crease curves is the ruled surface
  // between their cubic B-splines: with the rims' vertices one above the other, every wall point
  // lies straight above a rim point.
  const mm::Mesh quads = mm::pair_rail_quads(cylinder(8, 1, 1.0, 0.5, true));
  ASSERT_EQ(count_quads(quads), 8);
  const mm::SubdivisionOperator op = mm::build_subdivision(quads, 3);
  const mm::Points p = op.S * quads.points;
  const std::vector<char> on_rim = crease_vertices(op.refined);
  int wall = 0;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    if (on_rim[i] || p(i, 2) < 1e-9 || p(i, 2) > 0.5 - 1e-9) continue;
    ++wall;
    double nearest = 1e300;
    for (Eigen::Index j = 0; j < p.rows(); ++j)
      if (on_rim[j]) nearest = std::min(nearest, std::hypot(p(i, 0) - p(j, 0), p(i, 1) - p(j, 1)));
    EXPECT_LT(nearest, 1e-12) << "wall vertex " << i;
  }
  EXPECT_GT(wall, 0);
}

TEST(RailQuads, QuadWallSagsLessThanTrianglesBetweenOffsetRims) {
  // Rims offset by half a vertex step, as decimation leaves them: both walls sag towards the
  // chords, the triangles' (whose diagonals span farther) about three times as much.
  const mm::Mesh tri = cylinder(8, 1, 1.0, 0.5, true, 0.5);
  const Radii quads = refined_radii(mm::pair_rail_quads(tri), 0.5);
  const Radii tris = refined_radii(tri, 0.5);
  EXPECT_DOUBLE_EQ(quads.rim_min, tris.rim_min);
  const double quad_sag = quads.rim_min - quads.wall_min, tri_sag = tris.rim_min - tris.wall_min;
  EXPECT_GT(quad_sag, 0);
  EXPECT_LT(quad_sag, 0.5 * tri_sag);
}

// The rounds `meshmark compress` runs before its coarsening (cold, every one at the full level):
// they meet the tolerance by the dense measurement. (The protect path's first round, coarse, is
// steered by its better variant, the quads here; its triangles, fitted again from there, meet
// the tolerance at 24 vertices.)
TEST(RailQuads, CompressNeedsFewerVerticesForACylinder) {
  const mm::Mesh part = cylinder(96, 6, 1.0, 0.2, false);  // a disc, like abc7
  mm::CompressOptions with;
  with.coarsen = true;
  with.verify = [&part, &with](const mm::Mesh& control) {
    return mm::decoded_distance(part, control, 3).hausdorff_relative() <= with.tolerance;
  };
  mm::CompressOptions without = with;
  without.rail_quads = false;
  std::shared_ptr<const mm::CompressState> state;
  const mm::CompressResult q = mm::compress_rounds(part, with, "cylinder", state);
  const mm::CompressResult t = mm::compress_rounds(part, without, "cylinder", state);
  ASSERT_TRUE(q.tolerance_met);
  ASSERT_TRUE(t.tolerance_met);
  EXPECT_LT(q.control.num_vertices(), t.control.num_vertices());
  // A round fits the quads only where its triangles missed: the quads met the tolerance at a
  // vertex count where the triangles did not.
  int with_quads = 0;
  for (const auto& c : q.candidates) {
    if (count_quads(c.control) == 0) continue;
    ++with_quads;
    for (const auto& d : q.candidates) {
      if (count_quads(d.control) == 0) {
        EXPECT_NE(d.control.num_vertices(), c.control.num_vertices());
      }
    }
  }
  EXPECT_GT(with_quads, 0);
  for (const auto& c : t.candidates) EXPECT_EQ(count_quads(c.control), 0);
}

}  // namespace

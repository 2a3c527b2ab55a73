// Coarsening a fitted control polyhedron: the half-edge collapse that keeps the crease network
// (fitting/collapse_control.h) and compress()'s use of it (CompressOptions::coarsen).
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <set>

#include "fitting/collapse_control.h"
#include "fitting/compress.h"
#include "fitting/rail_quads.h"
#include "quality/surface_distance.h"
#include "samples/flanged_cylinder.h"
#include "test_control_meshes.h"

namespace {

using mm::test::count_quads;
using mm::test::cylinder;
using mm::test::expect_oriented;

mm::Mesh octahedron() {
  mm::Mesh m;
  m.points.resize(6, 3);
  m.points << 0, 0, 1, 0, 0, -1, 1, 0, 0, 0, 1, 0, -1, 0, 0, 0, -1, 0;
  m.faces = {{0, 2, 3}, {0, 3, 4}, {0, 4, 5}, {0, 5, 2}, {1, 3, 2}, {1, 4, 3}, {1, 5, 4}, {1, 2, 5}};
  return m;
}

// Crease edges per vertex.
std::map<int, int> crease_degree(const mm::Mesh& m) {
  std::map<int, int> d;
  for (auto [a, b] : m.creases) ++d[a], ++d[b];
  return d;
}

TEST(CollapseControl, SmoothVertexGoesOntoItsNeighbour) {
  const mm::Mesh m = octahedron();
  const auto c = mm::collapse_control_vertex(m, 0, 2);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->num_vertices(), 5);
  EXPECT_EQ(c->num_faces(), 6);  // the two faces on edge (0, 2) are gone
  expect_oriented(*c, true);
  // The others keep their positions, one row up; the former vertex 2 (now 1) stays where it was.
  for (int w = 1; w < 6; ++w) EXPECT_TRUE(c->points.row(w - 1) == m.points.row(w)) << w;
  // A bipyramid has nothing left to give: below five vertices there is no closed surface to fit.
  for (int v = 0; v < 5; ++v)
    for (int t = 0; t < 5; ++t) EXPECT_FALSE(mm::collapse_control_vertex(*c, v, t));
}

TEST(CollapseControl, ACreaseShortensOnlyAlongItself) {
  const mm::Mesh m = cylinder(8, 2, 1.0, 0.5, true);  // rims: rows 0 and 2, 16 crease edges
  EXPECT_FALSE(mm::collapse_control_vertex(m, 1, 9));  // off the rim: the crease would bend
  const auto c = mm::collapse_control_vertex(m, 1, 2);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->num_vertices(), m.num_vertices() - 1);
  EXPECT_EQ(c->num_faces(), m.num_faces() - 2);
  expect_oriented(*c, true);
  ASSERT_EQ(c->creases.size(), 15u);
  // Both rims are still closed loops: every rim vertex on exactly two crease edges.
  const auto degree = crease_degree(*c);
  EXPECT_EQ(degree.size(), 15u);
  for (auto [v, d] : degree) EXPECT_EQ(d, 2) << v;
  EXPECT_TRUE(std::is_sorted(c->creases.begin(), c->creases.end()));
  // A smooth wall vertex may go onto a rim vertex; the creases stay as they were.
  const auto wall = mm::collapse_control_vertex(m, 9, 1);
  ASSERT_TRUE(wall);
  EXPECT_EQ(wall->creases.size(), 16u);
  for (auto [v, d] : crease_degree(*wall)) EXPECT_EQ(d, 2) << v;
}

TEST(CollapseControl, RefusesCornersAndOpenBoundaries) {
  mm::Mesh m = cylinder(8, 2, 1.0, 0.5, true);
  m.corners = {1};
  EXPECT_FALSE(mm::collapse_control_vertex(m, 1, 2));
  EXPECT_TRUE(mm::collapse_control_vertex(m, 2, 3));
  // Without its bottom cap the bottom rim is an open boundary: its vertices stay.
  mm::Mesh open = cylinder(8, 2, 1.0, 0.5, false);
  const int bottom = 3 * 8;
  open.faces.erase(std::remove_if(open.faces.begin(), open.faces.end(),
                                  [bottom](const std::vector<int>& f) { return f[0] == bottom; }),
                   open.faces.end());
  EXPECT_FALSE(mm::collapse_control_vertex(open, 1, 2));
  EXPECT_TRUE(mm::collapse_control_vertex(open, 9, 1));  // an inner vertex may go onto the boundary
}

TEST(CollapseControl, AQuadOnTheEdgeLosesTheVertexAndBecomesATriangle) {
  const mm::Mesh q = mm::pair_rail_quads(cylinder(8, 1, 1.0, 0.5, true));
  ASSERT_EQ(count_quads(q), 8);
  const auto c = mm::collapse_control_vertex(q, 1, 2);
  ASSERT_TRUE(c);
  EXPECT_EQ(count_quads(*c), 7);
  EXPECT_EQ(c->num_faces(), q.num_faces() - 1);  // the cap triangle on (1, 2) goes, the quad stays as a triangle
  expect_oriented(*c, true);
  for (const auto& f : c->faces) EXPECT_EQ(std::set<int>(f.begin(), f.end()).size(), f.size());
}

// Coarsening removes control vertices from the rounds' polyhedron while the caller's dense
// measurement keeps the tolerance, never below the first round's count; every candidate it hands
// on meets the tolerance. (Against the rounds it starts from, cold and unweighted: the protect
// path's reweighted rounds, without coarsening, end at 66 vertices here, fewer than its 74.)
TEST(Coarsen, FewerVerticesWithinTheTolerance) {
  const mm::Mesh part = mm::samples::flanged_cylinder();
  mm::CompressOptions o;
  o.verify = [&part, &o](const mm::Mesh& control) {
    return mm::decoded_distance(part, control, o.levels).hausdorff_relative() <= o.tolerance;
  };
  o.coarsen = true;
  std::shared_ptr<const mm::CompressState> state;
  const mm::CompressResult plain = mm::compress_rounds(part, o, "flanged_cylinder", state);
  const mm::CompressResult coarse = mm::compress(part, o, "flanged_cylinder");
  ASSERT_TRUE(plain.tolerance_met);
  ASSERT_TRUE(coarse.tolerance_met);
  EXPECT_LT(coarse.control.num_vertices(), plain.control.num_vertices());
  EXPECT_GE(coarse.control.num_vertices(), std::max(24, coarse.corners + coarse.patches + 16));
  EXPECT_EQ(coarse.control.corners.size(), plain.control.corners.size());
  ASSERT_FALSE(coarse.candidates.empty());
  EXPECT_EQ(coarse.candidates.front().control.num_vertices(), coarse.control.num_vertices());
  for (const auto& c : coarse.candidates)
    EXPECT_LE(mm::decoded_distance(part, c.control, o.levels).hausdorff_relative(), o.tolerance)
        << c.control.num_vertices();
  const mm::CompressResult again = mm::compress(part, o, "flanged_cylinder");
  EXPECT_TRUE(again.control.points == coarse.control.points);
  EXPECT_EQ(again.control.faces, coarse.control.faces);
}

// The two steps a caller comparing crease angles uses: the rounds, then the coarsening of the
// angle it picks, give compress()'s results bit for bit, the rounds' without coarsening and the
// coarsening's with it; the state is reusable (coarsening twice gives the same).
TEST(Coarsen, RoundsThenCoarseningAreCompressInTwoSteps) {
  const mm::Mesh part = mm::samples::flanged_cylinder();
  mm::CompressOptions o;
  o.verify = [&part, &o](const mm::Mesh& control) {
    return mm::decoded_distance(part, control, o.levels).hausdorff_relative() <= o.tolerance;
  };
  o.coarsen = true;
  std::shared_ptr<const mm::CompressState> state;
  const mm::CompressResult rounds = mm::compress_rounds(part, o, "flanged_cylinder", state);
  ASSERT_NE(state, nullptr);
  const mm::CompressResult coarse = mm::coarsen_rounds(*state);
  const auto same = [](const mm::CompressResult& a, const mm::CompressResult& b) {
    ASSERT_EQ(a.candidates.size(), b.candidates.size());
    for (size_t k = 0; k < a.candidates.size(); ++k) {
      EXPECT_TRUE(a.candidates[k].control.points == b.candidates[k].control.points) << k;
      EXPECT_EQ(a.candidates[k].control.faces, b.candidates[k].control.faces) << k;
      EXPECT_EQ(a.candidates[k].stats.hausdorff, b.candidates[k].stats.hausdorff) << k;
    }
    EXPECT_TRUE(a.control.points == b.control.points);
    EXPECT_EQ(a.control.creases, b.control.creases);
    EXPECT_EQ(a.rounds, b.rounds);
    EXPECT_EQ(a.tolerance_met, b.tolerance_met);
  };
  same(coarse, mm::compress(part, o, "flanged_cylinder"));
  same(mm::coarsen_rounds(*state), coarse);
  EXPECT_LT(coarse.control.num_vertices(), rounds.control.num_vertices());
  // Without coarsening the rounds are compress()'s result, and they start warm.
  o.coarsen = false;
  std::shared_ptr<const mm::CompressState> warm_state;
  same(mm::compress_rounds(part, o, "flanged_cylinder", warm_state), mm::compress(part, o, "flanged_cylinder"));
}

}  // namespace

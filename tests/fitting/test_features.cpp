// Sharp features, segmentation and the feature-preserving control polyhedron.
#include <map>
#include <set>

#include "common/shared_meshes.h"
#include "fitting/control_polyhedron.h"
#include "fitting/segmentation.h"
#include "fitting/sharp_features.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"

namespace {

// A unit cube whose faces are each split into an n x n grid of triangles (so it has interior
// vertices to decimate and crease vertices between the corners).
mm::Mesh grid_cube(int n) {
  mm::Mesh m;
  std::vector<Eigen::Vector3d> pts;
  auto add_face = [&](const Eigen::Vector3d& o, const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
    int base = static_cast<int>(pts.size());
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) pts.push_back(o + u * (double(i) / n) + v * (double(j) / n));
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        int a = base + j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
        m.faces.push_back({a, b, d});
        m.faces.push_back({a, d, c});
      }
  };
  using V = Eigen::Vector3d;
  add_face(V(0, 0, 0), V(0, 1, 0), V(1, 0, 0));  // z = 0, normal -z
  add_face(V(0, 0, 1), V(1, 0, 0), V(0, 1, 0));  // z = 1
  add_face(V(0, 0, 0), V(1, 0, 0), V(0, 0, 1));  // y = 0
  add_face(V(0, 1, 0), V(0, 0, 1), V(1, 0, 0));  // y = 1
  add_face(V(0, 0, 0), V(0, 0, 1), V(0, 1, 0));  // x = 0
  add_face(V(1, 0, 0), V(0, 1, 0), V(0, 0, 1));  // x = 1
  // Weld coincident grid points so the cube is one closed surface.
  std::vector<int> remap(pts.size());
  std::vector<Eigen::Vector3d> unique;
  for (size_t i = 0; i < pts.size(); ++i) {
    int found = -1;
    for (size_t k = 0; k < unique.size(); ++k)
      if ((unique[k] - pts[i]).norm() < 1e-9) found = static_cast<int>(k);
    if (found < 0) {
      found = static_cast<int>(unique.size());
      unique.push_back(pts[i]);
    }
    remap[i] = found;
  }
  for (auto& f : m.faces)
    for (auto& v : f) v = remap[v];
  m.points.resize(static_cast<Eigen::Index>(unique.size()), 3);
  for (size_t k = 0; k < unique.size(); ++k) m.points.row(static_cast<Eigen::Index>(k)) = unique[k];
  return m;
}

mm::Mesh normalized(mm::Mesh m) {
  mm::apply(mm::unit_box_normalization(m.points), m.points);
  return m;
}

}  // namespace

TEST(Features, CubeHasTwelveCreasesAndEightCorners) {
  auto cube = grid_cube(1);
  ASSERT_EQ(cube.num_vertices(), 8);
  auto f = mm::detect_features(cube);
  EXPECT_EQ(f.sharp_edges.size(), 12u);  // the face diagonals are flat, not sharp
  EXPECT_EQ(f.corners.size(), 8u);
  EXPECT_EQ(f.boundary_edges, 0);
}

TEST(Features, GridCubeCreaseVerticesAreNotCorners) {
  auto cube = grid_cube(4);
  auto f = mm::detect_features(cube);
  EXPECT_EQ(f.sharp_edges.size(), 12u * 4);
  EXPECT_EQ(f.corners.size(), 8u);
  auto s = mm::segment(cube, f);
  EXPECT_EQ(s.num_patches, 6);
  ASSERT_EQ(s.polylines.size(), 12u);
  for (const auto& line : s.polylines) EXPECT_EQ(line.size(), 5u);
}

TEST(Features, AngleThresholdIsRespected) {
  auto cube = grid_cube(2);
  mm::FeatureOptions strict;
  strict.angle_degrees = 95;  // cube edges are 90 degrees: none is sharp
  auto f = mm::detect_features(cube, strict);
  EXPECT_TRUE(f.sharp_edges.empty());
  EXPECT_TRUE(f.corners.empty());
}

TEST(Features, Fandisk) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("fandisk.off"));
  auto f = mm::detect_features(m);
  // Fandisk is closed; its crease network has a few hundred edges and a few dozen corners.
  EXPECT_EQ(f.boundary_edges, 0);
  EXPECT_GT(f.sharp_edges.size(), 500u);
  EXPECT_LT(f.sharp_edges.size(), 1000u);
  EXPECT_GE(f.corners.size(), 15u);
  EXPECT_LE(f.corners.size(), 40u);
  auto s = mm::segment(m, f);
  EXPECT_GE(s.num_patches, 8);
  // Every sharp edge lies on exactly one polyline.
  size_t edges_on_lines = 0;
  for (const auto& line : s.polylines) edges_on_lines += line.size() - 1;
  EXPECT_EQ(edges_on_lines, f.sharp_edges.size());
}

TEST(Features, HemisphereBoundaryIsAFeatureLoop) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("hemisphere.off"));
  auto f = mm::detect_features(m);
  EXPECT_GT(f.boundary_edges, 0);
  EXPECT_EQ(f.sharp_edges.size(), static_cast<size_t>(f.boundary_edges));  // smooth otherwise
  auto s = mm::segment(m, f);
  EXPECT_EQ(s.num_patches, 1);
  ASSERT_EQ(s.polylines.size(), 1u);
  EXPECT_EQ(s.polylines[0].front(), s.polylines[0].back());  // closed loop
}

namespace {

// Every edge of the control mesh has exactly two faces (closed input) or at most two (open).
void expect_manifold(const mm::Mesh& c, bool closed) {
  std::map<std::pair<int, int>, int> count;
  for (const auto& f : c.faces)
    for (size_t k = 0; k < f.size(); ++k) {
      int a = f[k], b = f[(k + 1) % f.size()];
      ASSERT_NE(a, b);
      ++count[{std::min(a, b), std::max(a, b)}];
    }
  for (const auto& [e, n] : count) {
    if (closed) EXPECT_EQ(n, 2) << e.first << "-" << e.second;
    else EXPECT_LE(n, 2);
  }
}

}  // namespace

TEST(ControlPolyhedron, GridCubeKeepsItsCreaseNetwork) {
  auto cube = normalized(grid_cube(6));
  auto f = mm::detect_features(cube);
  auto s = mm::segment(cube, f);
  mm::ControlOptions o;
  o.target_vertices = 8;
  auto c = mm::build_control_polyhedron(cube, f, s, o);
  expect_manifold(c.mesh, true);
  // Corners stay and the creases shrink to the 12 cube edges: the mesh is the cube itself.
  EXPECT_EQ(c.mesh.num_vertices(), 8);
  EXPECT_EQ(c.mesh.corners.size(), 8u);
  EXPECT_EQ(c.mesh.creases.size(), 12u);
  // Asking for one interior vertex per crease polyline keeps 12 more vertices on the edges.
  o.min_open_chain_interior = 1;
  auto c1 = mm::build_control_polyhedron(cube, f, s, o);
  expect_manifold(c1.mesh, true);
  EXPECT_EQ(c1.mesh.num_vertices(), 20);
  EXPECT_EQ(c1.mesh.creases.size(), 24u);
  // Every crease lies on a cube edge: its two ends share two coordinates in {0, 1}.
  for (auto [a, b] : c.mesh.creases) {
    Eigen::Vector3d pa = c.mesh.points.row(a), pb = c.mesh.points.row(b);
    int on_box_planes = 0;
    for (int k = 0; k < 3; ++k) {
      bool at0 = std::abs(pa[k]) < 1e-12 && std::abs(pb[k]) < 1e-12;
      bool at1 = std::abs(pa[k] - 1) < 1e-12 && std::abs(pb[k] - 1) < 1e-12;
      on_box_planes += at0 || at1;
    }
    EXPECT_EQ(on_box_planes, 2);
  }
  // Vertices started on input vertices.
  for (int v = 0; v < c.mesh.num_vertices(); ++v)
    EXPECT_TRUE(c.mesh.points.row(v).isApprox(cube.points.row(c.source[v])));
}

// A thin plate (1 x 1 x 0.02): its side walls are strips between two creases, and a coarse
// control mesh needs long thin triangles there. The aspect-ratio guard exempts triangles whose
// corners all lie on creases; guarding them too (the behaviour before) keeps dozens of vertices
// along the rims.
TEST(ControlPolyhedron, ThinStripsBetweenCreasesDecimate) {
  auto plate = grid_cube(8);
  plate.points.col(2) *= 0.02;
  plate = normalized(plate);
  auto f = mm::detect_features(plate);
  ASSERT_EQ(f.corners.size(), 8u);
  auto s = mm::segment(plate, f);
  mm::ControlOptions o;
  o.target_vertices = 8;
  auto c = mm::build_control_polyhedron(plate, f, s, o);
  expect_manifold(c.mesh, true);
  EXPECT_EQ(c.mesh.num_vertices(), 8);
  EXPECT_EQ(c.mesh.creases.size(), 12u);
  o.aspect_ratio_on_feature_triangles = true;
  auto guarded = mm::build_control_polyhedron(plate, f, s, o);
  expect_manifold(guarded.mesh, true);
  EXPECT_GT(guarded.mesh.num_vertices(), 24);
}

TEST(ControlPolyhedron, FandiskCreasesFollowSharpEdges) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = normalized(mm::read_mesh(mm::test::shared_mesh("fandisk.off")));
  auto f = mm::detect_features(m);
  auto s = mm::segment(m, f);
  mm::ControlOptions o;
  o.target_vertices = 100;
  auto c = mm::build_control_polyhedron(m, f, s, o);
  expect_manifold(c.mesh, true);
  EXPECT_LE(c.mesh.num_vertices(), 100);
  // Corners survive (they are locked); crease ends (darts, one crease edge) are not tagged.
  std::set<int> feature_corners(f.corners.begin(), f.corners.end());
  std::set<int> tagged;
  for (int v : c.mesh.corners) {
    EXPECT_TRUE(feature_corners.count(c.source[v]));
    tagged.insert(c.source[v]);
  }
  for (int v : f.corners) {
    if (f.sharp_valence[v] >= 2) {
      EXPECT_TRUE(tagged.count(v)) << "corner " << v << " lost";
    }
  }
  // Each crease joins two vertices of the same input polyline (it shortcuts along it).
  std::map<int, std::set<int>> lines_of;
  for (size_t l = 0; l < s.polylines.size(); ++l)
    for (int v : s.polylines[l]) lines_of[v].insert(static_cast<int>(l));
  ASSERT_FALSE(c.mesh.creases.empty());
  for (auto [a, b] : c.mesh.creases) {
    const auto &la = lines_of[c.source[a]], &lb = lines_of[c.source[b]];
    bool shared = false;
    for (int l : la) shared = shared || lb.count(l);
    EXPECT_TRUE(shared) << "crease " << a << "-" << b << " leaves the feature network";
  }
}

TEST(Features, ShortDanglingFragmentsAreDropped) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("blade.stl"));  // remeshed: noisy crease bits
  mm::FeatureOptions all;
  all.min_crease_edges = 0;
  auto raw = mm::detect_features(m, all);
  auto pruned = mm::detect_features(m);
  EXPECT_LT(pruned.sharp_edges.size(), raw.sharp_edges.size());
  // Whatever survives is a subset of the raw sharp edges...
  std::set<std::pair<int, int>> raw_set(raw.sharp_edges.begin(), raw.sharp_edges.end());
  for (const auto& e : pruned.sharp_edges) EXPECT_TRUE(raw_set.count(e));
  // ...and no isolated chain shorter than 3 edges is left.
  auto s = mm::segment(m, pruned);
  for (const auto& line : s.polylines) {
    bool open_both = pruned.sharp_valence[line.front()] == 1 && pruned.sharp_valence[line.back()] == 1;
    if (open_both) {
      EXPECT_GE(line.size(), 4u);
    }
  }
}

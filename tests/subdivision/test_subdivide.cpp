// Properties of the quad/triangle operator that hold on any mesh, in particular mixed ones where no
// oracle exists: watertightness, vertex counts, affine invariance, planarity, straight creases,
// smoothing, and clean rejection of bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "common/shared_meshes.h"
#include "meshio/read_mesh.h"
#include "subdivision/subdivide.h"
#include "subdivision/test_meshes.h"

namespace mm {
namespace {

using mm::test::cube;
using mm::test::grid;
using mm::test::jittered;
using mm::test::make_mesh;
using mm::test::tetrahedron;

// Each undirected edge used by exactly two faces, once in each direction.
::testing::AssertionResult watertight(const Mesh& m) {
  std::map<std::pair<int, int>, int> directed;
  for (const auto& f : m.faces)
    for (size_t k = 0; k < f.size(); ++k) ++directed[{f[k], f[(k + 1) % f.size()]}];
  for (const auto& [e, n] : directed) {
    if (n != 1) return ::testing::AssertionFailure() << "directed edge used " << n << " times";
    if (!directed.count({e.second, e.first}))
      return ::testing::AssertionFailure() << "edge " << e.first << "-" << e.second << " has no twin";
  }
  return ::testing::AssertionSuccess();
}

// A closed mixed mesh: a cube with its top face replaced by four triangles around an apex.
Mesh mixed_house() {
  Mesh m = cube();
  m.faces.erase(m.faces.begin() + 1);  // top {4,5,6,7}
  m.points.conservativeResize(9, 3);
  m.points.row(8) << 0, 0, 2;
  for (auto [a, b] : std::vector<std::pair<int, int>>{{4, 5}, {5, 6}, {6, 7}, {7, 4}}) m.faces.push_back({a, b, 8});
  return jittered(m, 0.03);
}

double max_dihedral_degrees(const Mesh& m) {
  std::map<std::pair<int, int>, std::vector<Eigen::Vector3d>> normals;
  for (const auto& f : m.faces) {
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    const int s = static_cast<int>(f.size());
    for (int k = 0; k < s; ++k)
      n += Eigen::Vector3d(m.points.row(f[k])).cross(Eigen::Vector3d(m.points.row(f[(k + 1) % s])));
    n.normalize();
    for (int k = 0; k < s; ++k)
      normals[{std::min(f[k], f[(k + 1) % s]), std::max(f[k], f[(k + 1) % s])}].push_back(n);
  }
  double worst = 0;
  for (const auto& [e, ns] : normals)
    if (ns.size() == 2) worst = std::max(worst, std::acos(std::clamp(ns[0].dot(ns[1]), -1.0, 1.0)));
  return worst * 180.0 / M_PI;
}

TEST(Subdivision, LevelZeroIsIdentity) {
  const Mesh m = mixed_house();
  const SubdivisionOperator op = build_subdivision(m, 0);
  EXPECT_EQ(op.refined.faces, m.faces);
  EXPECT_EQ((op.refined.points - m.points).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_TRUE(op.steps.empty());
}

TEST(Subdivision, MixedMeshIsWatertightWithExpectedCounts) {
  Mesh m = mixed_house();
  ASSERT_TRUE(watertight(m));
  for (int level = 1; level <= 3; ++level) {
    const Mesh prev = subdivide(m, level - 1);
    const SubdivisionOperator op = build_subdivision(m, level);
    EXPECT_TRUE(watertight(op.refined)) << "level " << level;
    int quads = 0, tris = 0;
    for (const auto& f : prev.faces) (f.size() == 3 ? tris : quads)++;
    const int edges = static_cast<int>(unique_edges(prev).size());
    // V' = V + (non-triangle faces) + E; triangles give 4 triangles, quads 4 quads.
    EXPECT_EQ(op.refined.num_vertices(), prev.num_vertices() + quads + edges);
    EXPECT_EQ(op.refined.num_faces(), 4 * (tris + quads));
    // Euler characteristic of a sphere is kept.
    EXPECT_EQ(op.refined.num_vertices() - static_cast<int>(unique_edges(op.refined).size()) +
                  op.refined.num_faces(), 2);
  }
}

TEST(Subdivision, VertexCountsFromTopologyMatchTheOperators) {
  // Triangles, quads, a pentagon, open sheets, a non-manifold vertex (two triangles sharing only
  // a vertex): the counts a caller uses to tell a mesh's level before building that level.
  Mesh pentagon = make_mesh({{0, 0, 0}, {1, 0, 0}, {1.3, 1, 0}, {0.5, 1.6, 0}, {-0.3, 1, 0}, {0.5, 0.7, 1}},
                            {{0, 1, 2, 3, 4}, {0, 5, 1}, {1, 5, 2}, {2, 5, 3}, {3, 5, 4}, {4, 5, 0}});
  Mesh open = mixed_house();
  open.faces.erase(open.faces.begin() + 1);
  const Mesh bowtie = make_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}}, {{0, 1, 2}, {0, 3, 4}});
  for (const Mesh& m : {tetrahedron(), cube(), mixed_house(), grid(3, 2), test::triangulated(grid(2, 2)), pentagon, open, bowtie}) {
    const std::vector<long long> counts = subdivision_vertex_counts(m, 4);
    ASSERT_EQ(counts.size(), 5u);
    for (int level = 0; level <= 4; ++level)
      EXPECT_EQ(counts[static_cast<size_t>(level)], build_subdivision(m, level).S.rows()) << "level " << level;
  }
  Mesh bad = cube();
  bad.faces[0][0] = 99;
  EXPECT_THROW(subdivision_vertex_counts(bad, 2), InputError);
  EXPECT_THROW(subdivision_vertex_counts(cube(), kMaxSubdivisionLevels + 1), std::invalid_argument);
}

TEST(Subdivision, RowsSumToOneAndAreConvex) {
  Mesh m = mixed_house();
  m.creases = {{0, 1}, {1, 2}, {2, 3}};
  m.corners = {8};
  const SubdivisionOperator op = build_subdivision(m, 3);
  for (int r = 0; r < op.S.rows(); ++r) {
    double sum = 0, neg = 0;
    for (SparseOperator::InnerIterator it(op.S, r); it; ++it) {
      sum += it.value();
      neg = std::min(neg, it.value());
    }
    ASSERT_NEAR(sum, 1.0, 1e-12) << "row " << r;
    // All rules here (no valence-2 Catmull-Clark vertex) have non-negative weights.
    ASSERT_GE(neg, 0.0) << "row " << r;
  }
  // Tagged corners do not move; steps compose to S.
  EXPECT_EQ(op.refined.points.row(8), m.points.row(8));
  const Points via_steps = apply_subdivision(op, m.points);
  EXPECT_LT((via_steps - op.refined.points).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Subdivision, DirectEvaluationEqualsOperator) {
  // subdivide() evaluates the same rules on the points level by level, without matrices.
  Mesh m = mixed_house();
  m.creases = {{0, 1}, {1, 2}, {4, 8}};
  m.corners = {3};
  std::vector<Mesh> meshes{m, jittered(grid(3, 3), 0.1), jittered(cube(), 0.1)};
  meshes.back().faces[0] = {0, 3, 2};  // open cube with a triangle, a quad-less vertex, boundary
  for (const Mesh& x : meshes)
    for (int level = 0; level <= 3; ++level) {
      const SubdivisionOperator op = build_subdivision(x, level);
      const Mesh d = subdivide(x, level);
      EXPECT_EQ(d.faces, op.refined.faces);
      EXPECT_EQ(d.creases, op.refined.creases);
      EXPECT_EQ(d.corners, op.refined.corners);
      EXPECT_LT((d.points - op.S * x.points).cwiseAbs().maxCoeff(), 1e-12) << "level " << level;
    }
}

TEST(Subdivision, PlanarMixedInputStaysPlanar) {
  // Grid with alternate quads split into triangles, in a tilted plane.
  Mesh g = grid(5, 4);
  Mesh m = g;
  m.faces.clear();
  for (size_t i = 0; i < g.faces.size(); ++i) {
    const auto& f = g.faces[i];
    if (i % 3 == 1) {
      m.faces.push_back({f[0], f[1], f[2]});
      m.faces.push_back({f[0], f[2], f[3]});
    } else {
      m.faces.push_back(f);
    }
  }
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  const Eigen::Vector3d n = Eigen::Vector3d(0.3, -0.5, 1.0).normalized();
  for (int i = 0; i < m.num_vertices(); ++i) {
    Eigen::Vector3d p(m.points(i, 0) + u(rng), m.points(i, 1) + u(rng), 0);
    p -= n * (n.dot(p) - 0.7);  // project onto the plane n.x = 0.7
    m.points.row(i) = p.transpose();
  }
  const Mesh r = subdivide(m, 3);
  double off = 0;
  for (int i = 0; i < r.num_vertices(); ++i) off = std::max(off, std::abs(n.dot(Eigen::Vector3d(r.points.row(i))) - 0.7));
  EXPECT_LT(off, 1e-12);
}

TEST(Subdivision, StraightCreaseStaysStraight) {
  // A folded mixed sheet: the fold line y = 2 is a crease polyline (x = 0..4) with corners at both
  // ends (boundary + crease). Refined crease vertices must stay on the line.
  Mesh g = grid(4, 4);
  Mesh m = g;
  m.faces.clear();
  for (size_t i = 0; i < g.faces.size(); ++i) {
    const auto& f = g.faces[i];
    if (i % 2) {
      m.faces.push_back({f[0], f[1], f[3]});
      m.faces.push_back({f[1], f[2], f[3]});
    } else {
      m.faces.push_back(f);
    }
  }
  for (int i = 0; i < m.num_vertices(); ++i) m.points(i, 2) = std::abs(m.points(i, 1) - 2.0) * 0.8;
  for (int i = 0; i < 4; ++i) m.creases.emplace_back(10 + i, 11 + i);  // row y = 2 is vertices 10..14
  m.points(12, 0) += 0.3;  // uneven spacing along the line, still on it
  const SubdivisionOperator op = build_subdivision(m, 3);
  ASSERT_EQ(op.refined.creases.size(), 4u * 8u);
  for (const auto& [a, b] : op.refined.creases)
    for (int v : {a, b}) {
      EXPECT_NEAR(op.refined.points(v, 1), 2.0, 1e-12);
      EXPECT_NEAR(op.refined.points(v, 2), 0.0, 1e-12);
      EXPECT_GE(op.refined.points(v, 0), -1e-12);
      EXPECT_LE(op.refined.points(v, 0), 4.0 + 1e-12);
    }
  // Ends of the polyline are on the boundary: corners, so they stay put.
  EXPECT_EQ(op.refined.points.row(10), m.points.row(10));
  EXPECT_EQ(op.refined.points.row(14), m.points.row(14));
}

TEST(Subdivision, MixedSurfaceGetsSmoother) {
  // Tangent continuity: the largest angle between neighbouring faces must shrink geometrically
  // with the level (by the subdominant eigenvalue at the worst vertex), towards 0.
  const Mesh m = mixed_house();
  std::vector<double> a;
  for (int level = 1; level <= 6; ++level) a.push_back(max_dihedral_degrees(subdivide(m, level)));
  std::printf("[smooth] mixed house max dihedral by level 1..6:");
  for (double x : a) std::printf(" %.2f", x);
  std::printf(" degrees\n");
  for (size_t k = 2; k < a.size(); ++k) EXPECT_LT(a[k], 0.8 * a[k - 1]) << "level " << k + 1;
  EXPECT_LT(a.back(), 5.0);
}

TEST(Subdivision, ChamferCubeMixedSanity) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh m = read_mesh(mm::test::shared_mesh("chamfer-cube.off"));
  int tris = 0;
  for (const auto& f : m.faces) tris += f.size() == 3;
  ASSERT_GT(tris, 0);
  ASSERT_LT(tris, m.num_faces());
  const SubdivisionOperator op = build_subdivision(m, 3);
  EXPECT_TRUE(watertight(op.refined));
  for (int r = 0; r < op.S.rows(); ++r) ASSERT_NEAR(op.S.row(r).sum(), 1.0, 1e-12);
  // Symmetric input, symmetric output: the mesh is centred, so the refined centroid stays ~0.
  EXPECT_LT(op.refined.points.colwise().mean().cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT(max_dihedral_degrees(subdivide(m, 4)), 0.6 * max_dihedral_degrees(subdivide(m, 2)));
}

TEST(Subdivision, CreasesAndCornersAreCarried) {
  Mesh m = cube();
  m.creases = {{4, 5}, {5, 6}};
  m.corners = {0, 0, 3};
  const Mesh r = subdivide(m, 2);
  EXPECT_EQ(r.creases.size(), 8u);
  EXPECT_EQ(r.corners, (std::vector<int>{0, 3}));
  for (const auto& [a, b] : r.creases) EXPECT_LT(a, b);
}

// The fit's entry point: the same S as build_subdivision, and the refined mesh's faces (fanned),
// creases and boundary edges as flat lists. An open mixed mesh with a pentagon and creases.
TEST(Subdivision, OperatorWithFlatTopologyMatchesBuildSubdivision) {
  Mesh open_house = mixed_house();  // the cube's top replaced by a pyramid; then its bottom removed
  open_house.faces.erase(open_house.faces.begin());
  open_house.creases = {{4, 5}, {5, 8}};
  Mesh pentagon = make_mesh({{0, 0, 0}, {2, 0, 0}, {3, 1, 0}, {1, 2, 0}, {-1, 1, 0}, {1, 1, 1}},
                            {{0, 1, 2, 3, 4}, {0, 5, 1}, {1, 5, 2}, {2, 5, 3}, {3, 5, 4}, {4, 5, 0}});
  pentagon.creases = {{0, 1}};
  const std::vector<Mesh> meshes{open_house, pentagon, cube()};
  for (size_t i = 0; i < meshes.size(); ++i)
    for (int level = 0; level <= 3; ++level) {
      const Mesh& m = meshes[i];
      RefinedTopology t;
      const SparseOperator S = subdivision_operator(m, level, t);
      const SubdivisionOperator op = build_subdivision(m, level);
      ASSERT_EQ(S.rows(), op.S.rows()) << "level " << level;
      ASSERT_EQ(S.nonZeros(), op.S.nonZeros());
      EXPECT_TRUE(std::equal(S.outerIndexPtr(), S.outerIndexPtr() + S.rows() + 1, op.S.outerIndexPtr()));
      EXPECT_TRUE(std::equal(S.innerIndexPtr(), S.innerIndexPtr() + S.nonZeros(), op.S.innerIndexPtr()));
      EXPECT_TRUE(std::equal(S.valuePtr(), S.valuePtr() + S.nonZeros(), op.S.valuePtr()));
      std::vector<std::array<int, 3>> fans;
      std::map<std::pair<int, int>, int> uses;
      for (const auto& f : op.refined.faces) {
        for (size_t k = 1; k + 1 < f.size(); ++k) fans.push_back({f[0], f[k], f[k + 1]});
        for (size_t k = 0; k < f.size(); ++k) ++uses[{std::min(f[k], f[(k + 1) % f.size()]), std::max(f[k], f[(k + 1) % f.size()])}];
      }
      EXPECT_EQ(t.triangles, fans);
      EXPECT_EQ(t.creases, op.refined.creases);
      std::vector<std::pair<int, int>> boundary;
      for (const auto& [e, n] : uses)
        if (n == 1) boundary.push_back(e);
      std::sort(t.boundary.begin(), t.boundary.end());
      EXPECT_EQ(t.boundary, boundary);
      if (i == 0) {
        EXPECT_FALSE(boundary.empty()) << "the open mesh has a boundary at level " << level;
      }
    }
}

TEST(Subdivision, NonManifoldVertexIsKeptFixed) {
  // Two tetrahedra touching at one vertex: manifold edges, a non-manifold vertex.
  Mesh a = tetrahedron(), m = tetrahedron();
  m.points.conservativeResize(7, 3);
  for (int i = 1; i < 4; ++i) m.points.row(3 + i) = -a.points.row(i) + 2 * a.points.row(0);
  for (const auto& f : a.faces) {
    std::vector<int> g;
    for (int v : f) g.push_back(v == 0 ? 0 : v + 3);
    std::reverse(g.begin(), g.end());
    m.faces.push_back(g);
  }
  const Mesh r = subdivide(m, 2);
  EXPECT_EQ(r.points.row(0), m.points.row(0));
  EXPECT_TRUE(watertight(r));
}

void expect_input_error(const Mesh& m, const std::string& fragment) {
  try {
    build_subdivision(m, 1);
    ADD_FAILURE() << "no error for: " << fragment;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(Subdivision, RejectsBadInput) {
  Mesh m = tetrahedron();
  m.faces[1][2] = 4;
  expect_input_error(m, "out of range");
  m = tetrahedron();
  m.faces[1][2] = -1;
  expect_input_error(m, "out of range");
  m = tetrahedron();
  m.faces[1] = {0, 1};
  expect_input_error(m, "fewer than 3");
  m = tetrahedron();
  m.faces[1] = {0, 3, 3};
  expect_input_error(m, "repeats vertex");
  m = tetrahedron();
  m.faces.push_back({0, 1, 2});
  expect_input_error(m, "");  // duplicate face: same direction or >2 faces
  m = tetrahedron();
  m.points.conservativeResize(5, 3);
  m.points.row(4) << 3, 3, 3;
  m.faces.push_back({0, 2, 4});  // third face on edge 0-2 (0-2 is used by faces 0 and 2)
  m.faces.push_back({2, 1, 4});
  expect_input_error(m, "non-manifold edge");
  m = tetrahedron();
  std::reverse(m.faces[3].begin(), m.faces[3].end());
  expect_input_error(m, "same direction");
  m = tetrahedron();
  m.creases = {{0, 0}};
  expect_input_error(m, "crease");
  m = cube();
  m.creases = {{0, 6}};
  expect_input_error(m, "not an edge");
  m = tetrahedron();
  m.corners = {9};
  expect_input_error(m, "corner");
  m = tetrahedron();
  m.points(2, 1) = std::nan("");
  expect_input_error(m, "non-finite");
  m = tetrahedron();
  m.faces.clear();
  expect_input_error(m, "no faces");
  EXPECT_THROW(build_subdivision(tetrahedron(), -1), std::invalid_argument);
  EXPECT_THROW(build_subdivision(tetrahedron(), kMaxSubdivisionLevels + 1), std::invalid_argument);
  Mesh big = grid(300, 300);  // 90k quads: level 8 would be ~6e9 vertices
  EXPECT_THROW(build_subdivision(big, 8), std::invalid_argument);
  const SubdivisionOperator op = build_subdivision(tetrahedron(), 1);
  EXPECT_THROW(apply_subdivision(op, Points(3, 3)), std::invalid_argument);
}

TEST(Subdivision, HighValenceFanAndHugePolygon) {
  // A disk of 20000 triangles around one vertex: checks are linear in the valence, so this
  // stays cheap (a quadratic check would take ~1e9 steps).
  const int k = 20000;
  Mesh fan;
  fan.points.resize(k + 1, 3);
  fan.points.row(k) << 0, 0, 0;
  std::vector<int> ring;
  for (int i = 0; i < k; ++i) {
    fan.points.row(i) << std::cos(2 * M_PI * i / k), std::sin(2 * M_PI * i / k), 0.0;
    fan.faces.push_back({k, i, (i + 1) % k});
    ring.push_back(i);
  }
  const Mesh r = subdivide(fan, 2);
  EXPECT_EQ(r.num_faces(), 16 * k);
  EXPECT_NEAR(r.points(k, 2), 0.0, 1e-12);
  EXPECT_EQ(build_subdivision(fan, 1).S.rows(), 3 * k + 1);  // vertices + spokes + rim edges
  // Composing S for level 2 would put the centre's 20001-term row into ~4e4 rows: refused.
  EXPECT_THROW(build_subdivision(fan, 2), std::invalid_argument);
  // Polygons make dense rows (every corner in the face point): a 2000-gon is fine, a 20000-gon
  // (2 * 4e8 operator entries) is refused before anything is allocated.
  Mesh polygon = fan;
  polygon.faces = {std::vector<int>(ring.begin(), ring.begin() + 2000)};
  EXPECT_EQ(subdivide(polygon, 1).num_faces(), 2000);  // one quad per corner
  polygon.faces = {ring};
  EXPECT_THROW(subdivide(polygon, 1), InputError);
}

TEST(Subdivision, RandomTopologyNeverCrashes) {
  // Seeded random polygon soups (bad indices, repeats, non-manifold edges, flips, creases on
  // non-edges): every one is either subdivided into a watertight-or-open valid mesh or rejected
  // with InputError. Run under the Asan build to catch memory errors.
  std::mt19937 rng(12345);
  int accepted = 0, rejected = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int nv = 3 + static_cast<int>(rng() % 12);
    Mesh m;
    m.points = Points::Random(nv, 3);
    const int nf = 1 + static_cast<int>(rng() % 10);
    for (int f = 0; f < nf; ++f) {
      std::vector<int> face(2 + rng() % 4);
      for (int& v : face) v = static_cast<int>(rng() % (nv + 1)) - (trial % 17 == 0 ? 1 : 0);
      m.faces.push_back(face);
    }
    if (trial % 2 == 0) {
      // A valid mixed sheet with random faces removed (still valid, possibly disconnected or with
      // non-manifold vertices), random creases on its edges, and sometimes one corrupted index.
      m = mixed_house();
      for (int k = static_cast<int>(rng() % 4); k > 0; --k) m.faces.erase(m.faces.begin() + rng() % m.faces.size());
      const auto edges = unique_edges(m);
      for (int k = static_cast<int>(rng() % 4); k > 0; --k) m.creases.push_back(edges[rng() % edges.size()]);
      if (rng() % 3 == 0) m.faces[rng() % m.faces.size()][0] = static_cast<int>(rng() % 12) - 1;
    }
    if (rng() % 3 == 0) m.creases.emplace_back(static_cast<int>(rng() % nv), static_cast<int>(rng() % nv));
    if (rng() % 4 == 0) m.corners.push_back(static_cast<int>(rng() % (m.num_vertices() + 1)));
    try {
      const SubdivisionOperator op = build_subdivision(m, 2);
      ++accepted;
      for (int r = 0; r < op.S.rows(); ++r) ASSERT_NEAR(op.S.row(r).sum(), 1.0, 1e-12);
      for (const auto& f : op.refined.faces)
        for (int v : f) ASSERT_TRUE(v >= 0 && v < op.refined.num_vertices());
    } catch (const InputError&) {
      ++rejected;
    }
  }
  std::printf("[random] %d accepted, %d rejected\n", accepted, rejected);
  EXPECT_GT(accepted, 10);
  EXPECT_GT(rejected, 10);
}

TEST(SubdivideLinear, SplitsAtMidpointsAndMovesNoVertex) {
  for (const Mesh& m : {tetrahedron(), cube()}) {
    const Mesh s = subdivide_linear(m, 1);
    EXPECT_EQ(s.num_faces(), 4 * m.num_faces());
    EXPECT_TRUE(s.creases.empty() && s.corners.empty());
    EXPECT_EQ(s.points.topRows(m.num_vertices()), m.points);
    // Every new vertex is an edge's midpoint or (on a quad) its face's centre.
    std::vector<Eigen::RowVector3d> allowed;
    for (const auto& [a, b] : unique_edges(m)) allowed.push_back(0.5 * (m.points.row(a) + m.points.row(b)));
    for (const auto& f : m.faces) {
      Eigen::RowVector3d c = Eigen::RowVector3d::Zero();
      for (int v : f) c += m.points.row(v);
      if (f.size() == 4) allowed.push_back(c / 4.0);
    }
    for (int v = m.num_vertices(); v < s.num_vertices(); ++v)
      EXPECT_TRUE(std::any_of(allowed.begin(), allowed.end(),
                              [&](const Eigen::RowVector3d& p) { return (p - s.points.row(v)).norm() < 1e-12; }))
          << "vertex " << v;
    EXPECT_EQ(s.num_vertices(), m.num_vertices() + static_cast<int>(allowed.size()));
  }
}

}  // namespace
}  // namespace mm

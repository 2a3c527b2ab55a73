// Non-manifold input (bowties, edges with 3-4 faces, touching solids, flipped faces, random
// soups) becomes manifold by duplicating vertices: no face lost, every face accepted by
// OpenMesh's halfedge PolyMesh.
#include <gtest/gtest.h>

#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <algorithm>
#include <array>
#include <random>

#include "meshio/repair_manifold.h"

namespace {

mm::Mesh make(int n, std::vector<std::vector<int>> faces) {
  mm::Mesh m;
  m.points.resize(n, 3);
  for (int i = 0; i < n; ++i) m.points.row(i) << i, i * i % 7, i % 3;  // positions are irrelevant
  m.faces = std::move(faces);
  return m;
}

// Faces OpenMesh refuses when the mesh is built face by face.
int openmesh_rejected_faces(const mm::Mesh& m) {
  OpenMesh::PolyMesh_ArrayKernelT<> om;
  std::vector<OpenMesh::VertexHandle> vh;
  for (int i = 0; i < m.num_vertices(); ++i)
    vh.push_back(om.add_vertex({float(m.points(i, 0)), float(m.points(i, 1)), float(m.points(i, 2))}));
  int rejected = 0;
  for (const auto& f : m.faces) {
    std::vector<OpenMesh::VertexHandle> h;
    for (int v : f) h.push_back(vh[static_cast<size_t>(v)]);
    if (!om.add_face(h).is_valid()) ++rejected;
  }
  return rejected;
}

// Repairs and checks the invariants; returns the report.
mm::ManifoldRepair repair_and_check(const mm::Mesh& input) {
  mm::Mesh m = input;
  mm::ManifoldRepair r = mm::repair_manifold(m);
  EXPECT_EQ(m.num_faces(), input.num_faces());
  EXPECT_EQ(m.num_vertices(), input.num_vertices() + r.vertices_duplicated);
  EXPECT_EQ(r.original_vertex.size(), static_cast<size_t>(m.num_vertices()));
  for (int i = 0; i < input.num_vertices(); ++i) EXPECT_EQ(r.original_vertex[static_cast<size_t>(i)], i);
  for (int i = 0; i < m.num_vertices(); ++i)
    EXPECT_EQ(m.points.row(i), input.points.row(r.original_vertex[static_cast<size_t>(i)]));
  for (size_t f = 0; f < m.faces.size(); ++f) {
    EXPECT_EQ(m.faces[f].size(), input.faces[f].size());
    if (m.faces[f].size() != input.faces[f].size()) continue;
    for (size_t k = 0; k < m.faces[f].size(); ++k)
      EXPECT_EQ(r.original_vertex[static_cast<size_t>(m.faces[f][k])], input.faces[f][k]);
  }
  mm::ManifoldRepair after = mm::check_manifold(m);
  EXPECT_EQ(after.complex_edges, 0);
  EXPECT_EQ(after.complex_vertices, 0);
  EXPECT_EQ(openmesh_rejected_faces(m), 0);
  // Repair is idempotent.
  mm::Mesh again = m;
  EXPECT_EQ(mm::repair_manifold(again).vertices_duplicated, 0);
  return r;
}

TEST(RepairManifold, ManifoldMeshIsUnchanged) {
  // A closed tetrahedron.
  mm::Mesh tet = make(4, {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}});
  auto r = repair_and_check(tet);
  EXPECT_EQ(r.vertices_duplicated, 0);
  EXPECT_EQ(r.complex_edges, 0);
  EXPECT_EQ(r.complex_vertices, 0);
}

TEST(RepairManifold, Bowtie) {
  mm::Mesh m = make(5, {{0, 1, 2}, {0, 3, 4}});
  EXPECT_EQ(mm::check_manifold(m).complex_vertices, 1);
  auto r = repair_and_check(m);
  EXPECT_EQ(r.complex_vertices, 1);
  EXPECT_EQ(r.vertices_duplicated, 1);
}

TEST(RepairManifold, ThreeFacesOnOneEdge) {
  mm::Mesh m = make(5, {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}});
  EXPECT_GT(openmesh_rejected_faces(m), 0);  // what the repair is for
  auto r = repair_and_check(m);
  EXPECT_EQ(r.complex_edges, 1);
  // The edge is cut: each endpoint ends up in 3 separate fans.
  EXPECT_EQ(r.vertices_duplicated, 4);
}

TEST(RepairManifold, TwoTetrahedraSharingAnEdge) {
  // Closed solids touching along edge 0-1 (4 faces on it): each solid keeps its own copy.
  mm::Mesh m = make(6, {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2},
                        {0, 4, 1}, {0, 1, 5}, {1, 4, 5}, {0, 5, 4}});
  auto r = repair_and_check(m);
  EXPECT_EQ(r.complex_edges, 1);
  EXPECT_EQ(r.vertices_duplicated, 2);
}

TEST(RepairManifold, TwoCubesSharingACorner) {
  mm::Mesh m;
  m.points.resize(15, 3);
  for (int i = 0; i < 8; ++i) m.points.row(i) << (i & 1), (i >> 1 & 1), (i >> 2 & 1);
  for (int i = 1; i < 8; ++i) m.points.row(7 + i) << -(i & 1), -(i >> 1 & 1), -(i >> 2 & 1);
  auto cube = [](std::array<int, 8> v) {
    return std::vector<std::vector<int>>{{v[0], v[2], v[3], v[1]}, {v[4], v[5], v[7], v[6]},
                                         {v[0], v[1], v[5], v[4]}, {v[2], v[6], v[7], v[3]},
                                         {v[0], v[4], v[6], v[2]}, {v[1], v[3], v[7], v[5]}};
  };
  m.faces = cube({0, 1, 2, 3, 4, 5, 6, 7});
  // The second cube is mirrored through the shared corner 0, so its faces are reversed.
  for (auto f : cube({0, 8, 9, 10, 11, 12, 13, 14})) {
    std::reverse(f.begin(), f.end());
    m.faces.push_back(f);
  }
  auto r = repair_and_check(m);
  EXPECT_EQ(r.complex_edges, 0);
  EXPECT_EQ(r.complex_vertices, 1);
  EXPECT_EQ(r.vertices_duplicated, 1);
}

TEST(RepairManifold, FacesWithInconsistentOrientation) {
  // Both faces run 0 -> 1: a halfedge structure cannot hold them glued.
  mm::Mesh m = make(4, {{0, 1, 2}, {0, 1, 3}});
  EXPECT_GT(openmesh_rejected_faces(m), 0);
  auto r = repair_and_check(m);
  EXPECT_EQ(r.complex_edges, 1);
  EXPECT_EQ(r.vertices_duplicated, 2);
}

TEST(RepairManifold, MoebiusStrip) {
  // A closed strip with a half twist: no consistent orientation exists, so it must be cut.
  const int n = 6;
  std::vector<std::vector<int>> faces;
  for (int i = 0; i < n; ++i) {
    int a = i, b = i + n, c = (i + 1) % n, d = (i + 1) % n + n;
    if (i == n - 1) std::swap(c, d);  // the twist
    faces.push_back({a, c, d, b});
  }
  auto r = repair_and_check(make(2 * n, faces));
  EXPECT_GT(r.vertices_duplicated, 0);
}

TEST(RepairManifold, RandomTriangleSoupsLoseNoFace) {
  for (unsigned seed = 1; seed <= 40; ++seed) {
    SCOPED_TRACE(seed);
    std::mt19937 rng(seed);
    int nv = 5 + static_cast<int>(rng() % 30);
    std::uniform_int_distribution<int> pick(0, nv - 1);
    std::vector<std::vector<int>> faces;
    int nf = 1 + static_cast<int>(rng() % 120);
    while (static_cast<int>(faces.size()) < nf) {
      int a = pick(rng), b = pick(rng), c = pick(rng);
      if (a != b && b != c && a != c) faces.push_back({a, b, c});
    }
    repair_and_check(make(nv, faces));
  }
}

TEST(RepairManifold, RejectsDegenerateFaces) {
  mm::Mesh m = make(3, {{0, 1, 1}});
  EXPECT_THROW(mm::repair_manifold(m), std::invalid_argument);
}

}  // namespace

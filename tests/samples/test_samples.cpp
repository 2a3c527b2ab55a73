// The sample parts are closed, manifold, consistently outward oriented, of the expected genus
// and volume, well tessellated, and bit-for-bit deterministic.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <cmath>
#include <filesystem>
#include <map>
#include <unistd.h>

#include "meshio/read_mesh.h"
#include "meshio/repair_manifold.h"
#include "samples/part_family.h"
#include "samples/samples.h"

namespace {

using mm::samples::SamplePart;

double signed_volume(const mm::Mesh& m) {
  double v = 0;
  for (const auto& f : m.faces)
    for (size_t k = 1; k + 1 < f.size(); ++k) {
      Eigen::Vector3d a = m.points.row(f[0]), b = m.points.row(f[k]), c = m.points.row(f[k + 1]);
      v += a.dot(b.cross(c)) / 6.0;
    }
  return v;
}

// Every undirected edge has exactly two faces that use it in opposite directions.
void expect_closed_oriented(const mm::Mesh& m) {
  std::map<std::pair<int, int>, int> directed;
  for (const auto& f : m.faces)
    for (size_t k = 0; k < f.size(); ++k) ++directed[{f[k], f[(k + 1) % f.size()]}];
  for (const auto& [e, count] : directed) {
    ASSERT_EQ(count, 1) << "edge " << e.first << "-" << e.second << " used twice in one direction";
    ASSERT_EQ(directed.count({e.second, e.first}), 1u) << "boundary edge " << e.first << "-" << e.second;
  }
  auto r = mm::check_manifold(m);
  EXPECT_EQ(r.complex_edges, 0);
  EXPECT_EQ(r.complex_vertices, 0);
  // A halfedge structure takes every face and has no boundary.
  OpenMesh::PolyMesh_ArrayKernelT<> om;
  std::vector<OpenMesh::VertexHandle> vh;
  for (int i = 0; i < m.num_vertices(); ++i)
    vh.push_back(om.add_vertex({float(m.points(i, 0)), float(m.points(i, 1)), float(m.points(i, 2))}));
  for (const auto& f : m.faces) {
    std::vector<OpenMesh::VertexHandle> h;
    for (int v : f) h.push_back(vh[static_cast<size_t>(v)]);
    ASSERT_TRUE(om.add_face(h).is_valid());
  }
  for (auto v : om.vertices()) EXPECT_FALSE(om.is_boundary(v));
}

// Watertight: no two vertices at the same place (a crack would show as a duplicate).
void expect_distinct_positions(const mm::Mesh& m) {
  std::map<std::array<double, 3>, int> seen;
  for (int i = 0; i < m.num_vertices(); ++i) {
    auto [it, inserted] = seen.insert({{m.points(i, 0), m.points(i, 1), m.points(i, 2)}, i});
    EXPECT_TRUE(inserted) << "vertices " << it->second << " and " << i << " coincide";
  }
}

int euler_characteristic(const mm::Mesh& m) {
  return m.num_vertices() - static_cast<int>(mm::unique_edges(m).size()) + m.num_faces();
}

// Longest over shortest edge of each face: no slivers.
double worst_edge_ratio(const mm::Mesh& m) {
  double worst = 0;
  for (const auto& f : m.faces) {
    double lo = 1e300, hi = 0;
    for (size_t k = 0; k < f.size(); ++k) {
      double l = (m.points.row(f[k]) - m.points.row(f[(k + 1) % f.size()])).norm();
      lo = std::min(lo, l);
      hi = std::max(hi, l);
    }
    worst = std::max(worst, hi / lo);
  }
  return worst;
}

TEST(Samples, ClosedManifoldWatertightWellShaped) {
  for (const auto& part : mm::samples::sample_parts()) {
    SCOPED_TRACE(part.name);
    const mm::Mesh& m = part.mesh;
    EXPECT_GE(m.num_vertices(), 200);
    EXPECT_LE(m.num_vertices(), 5000);
    expect_closed_oriented(m);
    expect_distinct_positions(m);
    EXPECT_GT(signed_volume(m), 0);
    EXPECT_LT(worst_edge_ratio(m), 4.0);
  }
}

TEST(Samples, GenusMatchesTheShape) {
  // chi = 2 - 2 genus: the block is a ball, the tube a torus, a plate with 4 holes genus 4.
  EXPECT_EQ(euler_characteristic(mm::samples::chamfered_block()), 2);
  EXPECT_EQ(euler_characteristic(mm::samples::flanged_cylinder()), 0);
  EXPECT_EQ(euler_characteristic(mm::samples::plate_with_holes()), 2 - 2 * 4);
  mm::samples::PlateWithHoles one;
  one.holes = {{1, 1}};
  EXPECT_EQ(euler_characteristic(mm::samples::plate_with_holes(one)), 0);
}

TEST(Samples, ChamferedBlockVolume) {
  mm::samples::ChamferedBlock p;
  const double X = p.size_x, Y = p.size_y, Z = p.size_z, c = p.chamfer;
  // Box minus 12 edge prisms (cross-section c^2/2) minus 8 corner cubes' worth of 5c^3/6.
  double expected = X * Y * Z - c * c / 2 * (4 * (X + Y + Z) - 24 * c) - 8 * 5 * c * c * c / 6;
  EXPECT_NEAR(signed_volume(mm::samples::chamfered_block(p)), expected, 1e-9 * expected);
  // Sharp features: flat faces stay flat, so the bounding box is the block.
  mm::Mesh m = mm::samples::chamfered_block(p);
  Eigen::RowVector3d hi = m.points.colwise().maxCoeff(), lo = m.points.colwise().minCoeff();
  EXPECT_TRUE(hi == Eigen::RowVector3d(X, Y, Z)) << hi;
  EXPECT_TRUE(lo == Eigen::RowVector3d(0, 0, 0)) << lo;
}

TEST(Samples, PlateVolumeIsPlateMinusPolygonalHoles) {
  mm::samples::PlateWithHoles p;
  const int n = 4 * p.segments_per_side;
  double hole = n / 2.0 * p.hole_radius * p.hole_radius * std::sin(2 * M_PI / n);
  double area = p.cells_x * p.cells_y * p.cell * p.cell - static_cast<double>(p.holes.size()) * hole;
  EXPECT_NEAR(signed_volume(mm::samples::plate_with_holes(p)), area * p.thickness, 1e-9 * area * p.thickness);
}

TEST(Samples, FlangedCylinderVolumeIsTheRevolvedPolygon) {
  mm::samples::FlangedCylinder p;
  // Cross-sections are regular N-gon annuli: area = k (r_out^2 - r_in^2).
  const double k = p.sectors / 2.0 * std::sin(2 * M_PI / p.sectors);
  const double a = p.tube_radius, b = p.tube_radius - p.top_chamfer, rb2 = p.bore_radius * p.bore_radius;
  double expected = k * ((p.flange_radius * p.flange_radius - rb2) * p.flange_thickness +
                         (a * a - rb2) * (p.height - p.top_chamfer - p.flange_thickness) +
                         p.top_chamfer * ((a * a + a * b + b * b) / 3 - rb2));
  EXPECT_NEAR(signed_volume(mm::samples::flanged_cylinder(p)), expected, 1e-9 * expected);
}

TEST(Samples, Deterministic) {
  auto first = mm::samples::sample_parts();
  auto second = mm::samples::sample_parts();
  ASSERT_EQ(first.size(), 3u);
  for (size_t i = 0; i < first.size(); ++i) {
    EXPECT_EQ(first[i].name, second[i].name);
    EXPECT_TRUE(first[i].mesh.points == second[i].mesh.points);
    EXPECT_EQ(first[i].mesh.faces, second[i].mesh.faces);
  }
}

TEST(Samples, FamilyMembersAreValidDistinctAndDeterministic) {
  for (const auto& base : mm::samples::sample_parts()) {
    SCOPED_TRACE(base.name);
    const auto zero = mm::samples::sample_variant(base.name, 0);
    EXPECT_TRUE(zero.mesh.points == base.mesh.points);
    int differ = 0;
    for (std::uint64_t v = 1; v <= 40; ++v) {
      SCOPED_TRACE(v);
      const auto m = mm::samples::sample_variant(base.name, v);
      const auto again = mm::samples::sample_variant(base.name, v);
      ASSERT_TRUE(m.mesh.points == again.mesh.points);
      ASSERT_EQ(m.mesh.faces, again.mesh.faces);
      expect_closed_oriented(m.mesh);
      EXPECT_GT(signed_volume(m.mesh), 0);
      EXPECT_LT(worst_edge_ratio(m.mesh), 4.0);
      if (m.mesh.points.rows() != base.mesh.points.rows() || !(m.mesh.points == base.mesh.points)) ++differ;
    }
    EXPECT_GE(differ, 30);  // a few members may draw the default dimensions
  }
  // The sequence is the generator's own, the same on every platform: the benchmark's parts stay put.
  EXPECT_EQ(mm::samples::sample_variant("plate_with_holes", 1).mesh.num_vertices(), 3602);
  EXPECT_EQ(mm::samples::sample_variant("chamfered_block", 2).mesh.num_vertices(), 394);
  EXPECT_THROW(mm::samples::sample_variant("teapot", 1), std::invalid_argument);
}

TEST(Samples, SurviveWriteAndReadBack) {
  auto dir = std::filesystem::temp_directory_path() / ("mm_samples_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (const auto& part : mm::samples::sample_parts()) {
    SCOPED_TRACE(part.name);
    std::string path = (dir / (part.name + ".off")).string();
    mm::write_mesh(part.mesh, path);
    mm::Mesh back = mm::read_mesh(path);
    EXPECT_TRUE(back.points == part.mesh.points);
    EXPECT_EQ(back.faces, part.mesh.faces);
  }
  std::filesystem::remove_all(dir);
}

TEST(Samples, InvalidParametersAreRefused) {
  mm::samples::ChamferedBlock b;
  b.chamfer = 15;
  EXPECT_THROW(mm::samples::chamfered_block(b), std::invalid_argument);
  mm::samples::PlateWithHoles p;
  p.hole_radius = 11;
  EXPECT_THROW(mm::samples::plate_with_holes(p), std::invalid_argument);
  p = {};
  p.holes = {{5, 0}};
  EXPECT_THROW(mm::samples::plate_with_holes(p), std::invalid_argument);
  mm::samples::FlangedCylinder f;
  f.flange_radius = 10;
  EXPECT_THROW(mm::samples::flanged_cylinder(f), std::invalid_argument);
}

}  // namespace

// SurfaceFootprint: the cells a surface passes through, and how much of a suspect lies in them.
#include <gtest/gtest.h>

#include "geometry/surface_footprint.h"
#include "samples/chamfered_block.h"

namespace {

// A 4 x 2 x 1 box of twelve large triangles: its facets cross many cells without a vertex in them.
mm::Mesh box() {
  mm::Mesh m;
  m.points.resize(8, 3);
  for (int i = 0; i < 8; ++i) m.points.row(i) << 4.0 * (i & 1), 2.0 * ((i >> 1) & 1), 1.0 * ((i >> 2) & 1);
  m.faces = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
             {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  return m;
}

// Points of a mesh with one triangle per point (enough for a probe: vertices and centroids).
mm::Mesh points_mesh(const std::vector<Eigen::Vector3d>& pts) {
  mm::Mesh m;
  m.points.resize(static_cast<Eigen::Index>(3 * pts.size()), 3);
  for (size_t i = 0; i < pts.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      m.points.row(static_cast<Eigen::Index>(3 * i + k)) = pts[i].transpose();
      m.faces.push_back({static_cast<int>(3 * i), static_cast<int>(3 * i + 1), static_cast<int>(3 * i + 2)});
    }
  return m;
}

}  // namespace

TEST(SurfaceFootprint, MarksEveryCellALargeFacetCrosses) {
  const mm::SurfaceFootprint f = mm::surface_footprint(box(), 32);
  EXPECT_EQ(f.dims[0], 33);
  EXPECT_EQ(f.dims[1], 17);
  EXPECT_EQ(f.dims[2], 9);
  // Points all over the top facet, far from its vertices, lie in its own cells.
  std::vector<Eigen::Vector3d> top;
  for (int i = 1; i < 40; ++i)
    for (int j = 1; j < 20; ++j) top.emplace_back(0.1 * i, 0.1 * j, 1.0);
  const mm::FootprintProbe probe = mm::footprint_probe(points_mesh(top));
  EXPECT_EQ(mm::covered_fraction(f, probe, 0), 1.0);
  // The box is hollow: its middle is not surface.
  const mm::FootprintProbe inside = mm::footprint_probe(points_mesh({{0.5, 1, 0.5}, {2, 1, 0.5}, {3.5, 1, 0.5}}));
  EXPECT_EQ(mm::covered_fraction(f, inside), 0.0);
}

TEST(SurfaceFootprint, ASuspectSpanningAFewCellsIsHeldByNone) {
  const mm::SurfaceFootprint f = mm::surface_footprint(box(), 32);  // cells of 0.125
  std::vector<Eigen::Vector3d> small, wider;
  for (int i = 0; i < 10; ++i) small.emplace_back(1 + 0.05 * i, 1.0, 1.0), wider.emplace_back(1 + 0.15 * i, 1.0, 1.0);
  EXPECT_EQ(mm::covered_fraction(f, mm::footprint_probe(points_mesh(small))), 0.0);  // 0.45: under 8 cells
  EXPECT_EQ(mm::covered_fraction(f, mm::footprint_probe(points_mesh(small)), 1, 2), 1.0);
  EXPECT_EQ(mm::covered_fraction(f, mm::footprint_probe(points_mesh(wider))), 1.0);  // 1.35: 10.8 cells
}

TEST(SurfaceFootprint, ANeighbouringCellAbsorbsNoiseButNotAShift) {
  const mm::SurfaceFootprint f = mm::surface_footprint(box(), 32);  // cells of 0.125
  // Under the top facet, away from the side facets: 0.1 below it lies in the next cell down,
  // 0.3 below it two cells down.
  std::vector<Eigen::Vector3d> near, shifted;
  for (int i = 5; i < 36; ++i) near.emplace_back(0.1 * i, 1.0, 0.9), shifted.emplace_back(0.1 * i, 1.0, 0.7);
  EXPECT_EQ(mm::covered_fraction(f, mm::footprint_probe(points_mesh(near))), 1.0);
  EXPECT_EQ(mm::covered_fraction(f, mm::footprint_probe(points_mesh(near)), 0), 0.0);
  EXPECT_EQ(mm::covered_fraction(f, mm::footprint_probe(points_mesh(shifted))), 0.0);
  // Outside the box by more than a cell: rejected whole.
  std::vector<Eigen::Vector3d> beyond = near;
  beyond.emplace_back(4.5, 1.0, 1.0);
  EXPECT_EQ(mm::covered_fraction(f, mm::footprint_probe(points_mesh(beyond))), 0.0);
}

// The faces of a mesh whose vertices all lie at x <= cut, and those vertices (a crop).
mm::Mesh keep_below_x(const mm::Mesh& m, double cut) {
  mm::Mesh out;
  std::vector<int> index(static_cast<size_t>(m.num_vertices()), -1);
  std::vector<Eigen::RowVector3d> kept;
  for (const auto& f : m.faces) {
    bool in = true;
    for (int v : f) in = in && m.points(v, 0) <= cut;
    if (!in) continue;
    std::vector<int> g;
    for (int v : f) {
      if (index[static_cast<size_t>(v)] < 0) index[static_cast<size_t>(v)] = static_cast<int>(kept.size()), kept.push_back(m.points.row(v));
      g.push_back(index[static_cast<size_t>(v)]);
    }
    out.faces.push_back(g);
  }
  out.points.resize(static_cast<Eigen::Index>(kept.size()), 3);
  for (size_t i = 0; i < kept.size(); ++i) out.points.row(static_cast<Eigen::Index>(i)) = kept[i];
  return out;
}

TEST(SurfaceFootprint, RegionAgreementRanksThePartACropCameFromAndTiesPartsAlikeThere) {
  auto block = [](double x, double z) {
    mm::samples::ChamferedBlock p;
    p.size_x = x, p.size_y = 30, p.size_z = z;
    return mm::samples::chamfered_block(p);
  };
  const mm::Mesh part = block(40, 20), longer = block(60, 20), taller = block(40, 30);
  const mm::Mesh half = keep_below_x(part, 20);
  const double own = mm::region_agreement(mm::surface_footprint(part), half);
  const double alike = mm::region_agreement(mm::surface_footprint(longer), half);
  const double unlike = mm::region_agreement(mm::surface_footprint(taller), half);
  EXPECT_GT(own, 0.9);
  EXPECT_NEAR(alike, own, 0.05);  // identical over the crop's region: only a mark tells them apart
  EXPECT_LT(unlike, own - 0.2);   // its top face is elsewhere, its walls run on past the crop's top
  // Both footprints hold the crop: covered_fraction alone cannot rank them.
  const mm::FootprintProbe probe = mm::footprint_probe(half);
  EXPECT_GT(mm::covered_fraction(mm::surface_footprint(taller), probe, 0), 0.6);
  EXPECT_EQ(mm::region_agreement(mm::SurfaceFootprint{}, half), 0.0);
  EXPECT_EQ(mm::region_agreement(mm::surface_footprint(part), mm::Mesh{}), 0.0);
}

TEST(SurfaceFootprint, SurvivesItsJsonAndRefusesMalformedJson) {
  const mm::SurfaceFootprint f = mm::surface_footprint(box(), 16);
  const mm::SurfaceFootprint g = mm::SurfaceFootprint::from_json(f.to_json());
  EXPECT_EQ(g.lo, f.lo);
  EXPECT_EQ(g.cell, f.cell);
  for (int a = 0; a < 3; ++a) EXPECT_EQ(g.dims[a], f.dims[a]);
  EXPECT_EQ(g.occupied, f.occupied);
  EXPECT_THROW(mm::SurfaceFootprint::from_json("{\"lo\": [0, 0, 0]}"), mm::InputError);
  EXPECT_THROW(mm::SurfaceFootprint::from_json(R"({"lo":[0,0,0],"cell":1,"dims":[2,2,2],"cells":"zz"})"),
               mm::InputError);
  EXPECT_THROW(mm::SurfaceFootprint::from_json(R"({"lo":[0,0,0],"cell":1,"dims":[2,2,2],"cells":"f"})"),
               mm::InputError);
  EXPECT_THROW(mm::SurfaceFootprint::from_json(R"({"lo":[0,0,0],"cell":-1,"dims":[2,2,2],"cells":"ff"})"),
               mm::InputError);
  EXPECT_THROW(mm::SurfaceFootprint::from_json(R"({"lo":[0,0,0],"cell":1,"dims":[5000,2,2],"cells":""})"),
               mm::InputError);
}

TEST(SurfaceFootprint, IsEmptyForAnEmptyOrDegenerateMesh) {
  EXPECT_TRUE(mm::surface_footprint(mm::Mesh{}).empty());
  const mm::FootprintProbe probe = mm::footprint_probe(box());
  EXPECT_EQ(mm::covered_fraction(mm::SurfaceFootprint{}, probe), 0.0);
  EXPECT_EQ(mm::covered_fraction(mm::surface_footprint(box()), mm::FootprintProbe{}), 0.0);
}

// Oracle comparison with OpenSubdiv 3.5: on all-triangle meshes our operator must equal
// OpenSubdiv's Loop scheme, on all-quad (and n-gon) meshes its Catmull-Clark scheme, with the same
// infinitely sharp creases, corners and boundaries (VTX_BOUNDARY_EDGE_ONLY), row for row.
#include <gtest/gtest.h>

#include <opensubdiv/far/stencilTableFactory.h>
#include <opensubdiv/far/topologyDescriptor.h>

#include <cstdio>
#include <memory>

#include "common/shared_meshes.h"
#include "meshio/read_mesh.h"
#include "subdivision/subdivide.h"
#include "subdivision/test_meshes.h"

namespace mm {
namespace {

using namespace OpenSubdiv;
using mm::test::cube;
using mm::test::grid;
using mm::test::jittered;
using mm::test::octahedron;
using mm::test::quadrangulated;
using mm::test::sharp_edges;
using mm::test::tetrahedron;
using mm::test::triangulated;

struct Oracle {
  std::vector<std::vector<int>> faces;
  SparseOperator S;
};

Oracle opensubdiv_refine(const Mesh& m, Sdc::SchemeType scheme, int levels) {
  std::vector<int> counts, indices, crease_pairs;
  for (const auto& f : m.faces) {
    counts.push_back(static_cast<int>(f.size()));
    indices.insert(indices.end(), f.begin(), f.end());
  }
  for (const auto& [a, b] : m.creases) crease_pairs.insert(crease_pairs.end(), {a, b});
  std::vector<float> crease_w(m.creases.size(), Sdc::Crease::SHARPNESS_INFINITE);
  std::vector<float> corner_w(m.corners.size(), Sdc::Crease::SHARPNESS_INFINITE);

  Far::TopologyDescriptor d;
  d.numVertices = m.num_vertices();
  d.numFaces = static_cast<int>(counts.size());
  d.numVertsPerFace = counts.data();
  d.vertIndicesPerFace = indices.data();
  d.numCreases = static_cast<int>(m.creases.size());
  d.creaseVertexIndexPairs = crease_pairs.data();
  d.creaseWeights = crease_w.data();
  d.numCorners = static_cast<int>(m.corners.size());
  d.cornerVertexIndices = m.corners.data();
  d.cornerWeights = corner_w.data();

  Sdc::Options options;
  options.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_ONLY);
  using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
  std::unique_ptr<Far::TopologyRefiner> refiner(Factory::Create(d, Factory::Options(scheme, options)));
  if (!refiner) throw std::runtime_error("OpenSubdiv rejected the mesh");
  Far::TopologyRefiner::UniformOptions uo(levels);
  uo.fullTopologyInLastLevel = true;
  refiner->RefineUniform(uo);

  Oracle o;
  const auto& last = refiner->GetLevel(levels);
  for (int f = 0; f < last.GetNumFaces(); ++f) {
    auto fv = last.GetFaceVertices(f);
    o.faces.emplace_back(fv.begin(), fv.end());
  }
  Far::StencilTableFactoryReal<double>::Options so;
  so.generateIntermediateLevels = false;
  so.generateOffsets = true;
  so.maxLevel = levels;
  std::unique_ptr<const Far::StencilTableReal<double>> table(
      Far::StencilTableFactoryReal<double>::Create(*refiner, so));
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < table->GetNumStencils(); ++i) {
    auto s = table->GetStencil(i);
    for (int k = 0; k < s.GetSize(); ++k) t.emplace_back(i, s.GetVertexIndices()[k], s.GetWeights()[k]);
  }
  o.S.resize(table->GetNumStencils(), m.num_vertices());
  o.S.setFromTriplets(t.begin(), t.end());
  return o;
}

// Compares our operator with OpenSubdiv's for levels 1..max_level; returns the largest error.
double compare_with_opensubdiv(const Mesh& m, Sdc::SchemeType scheme, int max_level, const char* name) {
  double worst = 0.0;
  for (int level = 1; level <= max_level; ++level) {
    SCOPED_TRACE(std::string(name) + " level " + std::to_string(level));
    const SubdivisionOperator op = build_subdivision(m, level);
    const Oracle o = opensubdiv_refine(m, scheme, level);
    EXPECT_EQ(op.refined.faces, o.faces) << "refined topology or numbering differs";
    EXPECT_EQ(op.S.rows(), o.S.rows());
    if (op.S.rows() != o.S.rows()) return 1e300;
    const double err = SparseOperator(op.S - o.S).coeffs().cwiseAbs().maxCoeff();
    const Points ours = op.refined.points, theirs = o.S * m.points;
    const double perr = std::max((ours - theirs).cwiseAbs().maxCoeff(),
                                 (subdivide(m, level).points - theirs).cwiseAbs().maxCoeff());
    EXPECT_LT(err, 1e-9) << "operator differs from OpenSubdiv";
    EXPECT_LT(perr, 1e-9) << "refined points differ from OpenSubdiv";
    worst = std::max({worst, err, perr});
  }
  std::printf("[oracle] %-34s %s levels 1..%d: max |S - S_osd| and |P - P_osd| = %.3g\n", name,
              scheme == Sdc::SCHEME_LOOP ? "Loop  " : "Catmark", max_level, worst);
  return worst;
}

TEST(SubdivisionOracle, TetrahedronLoop) {
  compare_with_opensubdiv(jittered(tetrahedron(), 0.1), Sdc::SCHEME_LOOP, 3, "tetrahedron");
}

TEST(SubdivisionOracle, OctahedronLoopWithCreasesAndCorner) {
  Mesh m = jittered(octahedron(), 0.1);
  compare_with_opensubdiv(m, Sdc::SCHEME_LOOP, 3, "octahedron");
  m.creases = {{0, 2}, {1, 2}, {0, 3}, {1, 3}};  // equator loop
  compare_with_opensubdiv(m, Sdc::SCHEME_LOOP, 3, "octahedron equator crease");
  m.creases = {{0, 4}, {4, 1}};  // crease polyline with dart ends
  m.corners = {5};
  compare_with_opensubdiv(m, Sdc::SCHEME_LOOP, 3, "octahedron dart crease + corner");
}

TEST(SubdivisionOracle, CubeAllEdgesCreased) {
  Mesh m = jittered(cube(), 0.05);
  m.creases = unique_edges(m);
  ASSERT_EQ(m.creases.size(), 12u);
  compare_with_opensubdiv(m, Sdc::SCHEME_CATMARK, 3, "cube 12 creases");
}

TEST(SubdivisionOracle, CubeSomeCreasesAndCorner) {
  Mesh m = jittered(cube(), 0.05);
  compare_with_opensubdiv(m, Sdc::SCHEME_CATMARK, 3, "cube smooth");
  m.creases = {{4, 5}, {5, 6}, {6, 7}, {4, 7}, {0, 1}};  // top loop and one dart edge
  m.corners = {2};
  compare_with_opensubdiv(m, Sdc::SCHEME_CATMARK, 3, "cube some creases + corner");
  compare_with_opensubdiv(triangulated(m), Sdc::SCHEME_LOOP, 3, "triangulated cube creases");
}

TEST(SubdivisionOracle, OpenGridBoundary) {
  Mesh m = jittered(grid(4, 3), 0.1);
  compare_with_opensubdiv(m, Sdc::SCHEME_CATMARK, 3, "open quad grid");
  compare_with_opensubdiv(triangulated(m), Sdc::SCHEME_LOOP, 3, "open triangle grid");
  m.creases = {{6, 7}, {7, 8}, {1, 6}};  // interior crease meeting the boundary: a corner there
  compare_with_opensubdiv(m, Sdc::SCHEME_CATMARK, 3, "open quad grid + crease");
  compare_with_opensubdiv(triangulated(m), Sdc::SCHEME_LOOP, 3, "open triangle grid + crease");
}

TEST(SubdivisionOracle, PolygonsWithMoreThanFourSidesCatmark) {
  // Pentagonal prism: two pentagons and five quads; OpenSubdiv's Catmark splits n-gons the same way.
  std::vector<std::array<double, 3>> p;
  for (int z = 0; z < 2; ++z)
    for (int k = 0; k < 5; ++k)
      p.push_back({std::cos(2 * M_PI * k / 5), std::sin(2 * M_PI * k / 5), 1.5 * z});
  std::vector<std::vector<int>> f{{4, 3, 2, 1, 0}, {5, 6, 7, 8, 9}};
  for (int k = 0; k < 5; ++k) f.push_back({k, (k + 1) % 5, 5 + (k + 1) % 5, 5 + k});
  Mesh m = jittered(mm::test::make_mesh(p, f), 0.05);
  compare_with_opensubdiv(m, Sdc::SCHEME_CATMARK, 3, "pentagonal prism");
  m.creases = {{0, 1}, {1, 2}, {2, 3}, {3, 4}, {0, 4}};
  compare_with_opensubdiv(m, Sdc::SCHEME_CATMARK, 3, "pentagonal prism + crease");
}

TEST(SubdivisionOracle, ChamferCubeVariants) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh m = read_mesh(mm::test::shared_mesh("chamfer-cube.off"));
  Mesh tri = triangulated(m);
  compare_with_opensubdiv(tri, Sdc::SCHEME_LOOP, 3, "chamfer-cube triangulated");
  tri.creases = sharp_edges(tri, 30.0);
  ASSERT_FALSE(tri.creases.empty());
  compare_with_opensubdiv(tri, Sdc::SCHEME_LOOP, 3, "chamfer-cube triangulated + creases");
  Mesh quad = quadrangulated(m);
  compare_with_opensubdiv(quad, Sdc::SCHEME_CATMARK, 3, "chamfer-cube quadrangulated");
  Mesh mc = m;
  mc.creases = sharp_edges(m, 30.0);
  compare_with_opensubdiv(quadrangulated(mc), Sdc::SCHEME_CATMARK, 3, "chamfer-cube quadrangulated + creases");
}

TEST(SubdivisionOracle, FandiskQuads) {
  MM_REQUIRE_SHARED_MESHES();
  Mesh m = read_mesh(mm::test::shared_mesh("fandisk_quads.off"));
  for (const auto& f : m.faces) ASSERT_EQ(f.size(), 4u) << "fandisk_quads.off is expected to be all quads";
  compare_with_opensubdiv(m, Sdc::SCHEME_CATMARK, 3, "fandisk_quads");
  m.creases = sharp_edges(m, 40.0);
  ASSERT_GT(m.creases.size(), 20u);
  compare_with_opensubdiv(m, Sdc::SCHEME_CATMARK, 3, "fandisk_quads + sharp creases");
}

TEST(SubdivisionOracle, SphereLow) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh m = read_mesh(mm::test::shared_mesh("sphere_low.off"));
  compare_with_opensubdiv(m, Sdc::SCHEME_LOOP, 3, "sphere_low");
}

TEST(SubdivisionOracle, HemisphereBoundary) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh m = read_mesh(mm::test::shared_mesh("hemisphere.off"));
  compare_with_opensubdiv(m, Sdc::SCHEME_LOOP, 3, "hemisphere (boundary)");
}

}  // namespace
}  // namespace mm

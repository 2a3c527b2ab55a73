// Resynchronisation of suspects to the original control polyhedron: exact recovery from
// subdivided copies (in order, shuffled, moved, triangulated), noise averaging, the polyhedron as
// the codec hands it back, and clear failures.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <numeric>
#include <random>
#include <thread>

#include "common/shared_meshes.h"
#include "common/shuffled_mesh.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"
#include "fitting/compress.h"
#include "geometry/closest_point.h"
#include "registration/align_similarity.h"
#include "registration/resynchronize.h"
#include "subdivision/decompress.h"
#include "subdivision/subdivide.h"

namespace {

using mm::Mesh;
using mm::Points;
using mm::test::shuffled;

Mesh fandisk_quads() {
  Mesh m = mm::read_mesh(mm::test::shared_mesh("fandisk_quads.off"));
  mm::apply(mm::unit_box_normalization(m.points), m.points);
  return m;
}

// One context for the whole suite: building it is the expensive, once-per-asset part.
const mm::ResyncContext& context() {
  static const mm::ResyncContext ctx(fandisk_quads(), 3);
  return ctx;
}

double max_error(const Points& a, const Points& b) { return (a - b).rowwise().norm().maxCoeff(); }

mm::Similarity some_similarity() {
  mm::Similarity s;
  s.scale = 25.4;
  s.rotation = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  s.translation = Eigen::RowVector3d(120, -40, 7.5);
  return s;
}

}  // namespace

TEST(Resync, SubdividedCopiesGiveTheControlPointsBack) {
  MM_REQUIRE_SHARED_MESHES();
  const auto& ctx = context();
  for (int level = 1; level <= 3; ++level) {
    const Mesh suspect = mm::subdivide(ctx.control(), level);
    const auto r = mm::resynchronize(ctx, suspect);
    EXPECT_EQ(r.method, "subdivided");
    EXPECT_EQ(r.level, level);
    EXPECT_FALSE(r.order_recovered);
    EXPECT_FALSE(r.resubdivided) << "level " << level;
    EXPECT_LT(max_error(r.points, ctx.control().points), 1e-11) << "level " << level;
    EXPECT_LT(r.residual_rms, 1e-12);
  }
}

TEST(Resync, TriangulatedSubdividedCopyKeepsItsOrder) {
  MM_REQUIRE_SHARED_MESHES();
  const auto& ctx = context();
  const Mesh suspect = mm::triangulate(mm::subdivide(ctx.control(), 2));
  const auto r = mm::resynchronize(ctx, suspect);
  EXPECT_EQ(r.method, "subdivided");
  EXPECT_EQ(r.level, 2);
  EXPECT_FALSE(r.order_recovered);
  EXPECT_LT(max_error(r.points, ctx.control().points), 1e-11);
}

TEST(Resync, ShuffledSubdividedCopyIsMatchedByNearestNeighbour) {
  MM_REQUIRE_SHARED_MESHES();
  const auto& ctx = context();
  const Mesh suspect = shuffled(mm::subdivide(ctx.control(), 2), 11);
  const auto r = mm::resynchronize(ctx, suspect);
  EXPECT_EQ(r.method, "subdivided");
  EXPECT_EQ(r.level, 2);
  EXPECT_TRUE(r.order_recovered);
  EXPECT_EQ(r.matched_fraction, 1.0);
  EXPECT_LT(max_error(r.points, ctx.control().points), 1e-11);
}

// A marked copy that was only renumbered (welded STL) is in the original's frame: recovered
// exactly there, not through a similarity fitted to its pairs, which would take in the mark's
// lowest frequencies (here a uniform 0.1 % growth, as part of the mark).
TEST(Resync, RenumberedMarkedCopyIsRecoveredInTheOriginalsFrame) {
  MM_REQUIRE_SHARED_MESHES();
  const auto& ctx = context();
  Mesh marked = ctx.control();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-2e-4, 2e-4);
  for (Eigen::Index i = 0; i < marked.points.rows(); ++i)
    for (int a = 0; a < 3; ++a) marked.points(i, a) = marked.points(i, a) * 1.001 + u(rng);
  const Mesh suspect = shuffled(mm::subdivide(marked, 2), 13);
  const auto r = mm::resynchronize(ctx, suspect);
  EXPECT_EQ(r.method, "subdivided");
  EXPECT_TRUE(r.order_recovered);
  EXPECT_EQ(r.matched_fraction, 1.0);
  EXPECT_EQ(r.to_control_frame.scale, 1.0);
  EXPECT_LT(max_error(r.points, marked.points), 1e-9);
}

TEST(Resync, MovedShuffledCopyIsAlignedBack) {
  MM_REQUIRE_SHARED_MESHES();
  const auto& ctx = context();
  const auto s = some_similarity();
  Mesh suspect = shuffled(mm::subdivide(ctx.control(), 2), 12);
  suspect.points = s.apply(suspect.points);
  const auto r = mm::resynchronize(ctx, suspect);
  EXPECT_EQ(r.method, "subdivided");
  EXPECT_TRUE(r.order_recovered);
  EXPECT_LT(max_error(r.points, ctx.control().points), 1e-10);
  EXPECT_NEAR(r.to_control_frame.scale, 1 / s.scale, 1e-12);
  EXPECT_LT((r.to_control_frame.after(s).rotation - Eigen::Matrix3d::Identity()).norm(), 1e-10);
}

// A part that is round about an axis (abc6, a flanged ring) fixes a turn about that axis only
// up to its symmetry: the alignment's closest-point fit settles anywhere along it, and no vertex
// pairs with its own. A welded copy turned 30 degrees about z and rescaled (as `meshmark attack
// similarity` makes them) is paired after a search over turns about the axis.
TEST(Resync, TurnedCopyOfARoundPartIsPairedAfterATurnSearch) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh control = mm::compress(mm::read_mesh(mm::test::shared_mesh("abc6.stl"))).control;
  const mm::ResyncContext ctx(control, 3);
  for (double degrees : {30.0, 90.0}) {
    mm::Similarity s;
    s.scale = 2.5;
    s.rotation = Eigen::AngleAxisd(degrees * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    s.translation = Eigen::RowVector3d(3, -1, 2);
    Mesh suspect = shuffled(mm::subdivide(control, 3), 17);
    suspect.points = s.apply(suspect.points);
    const auto r = mm::resynchronize(ctx, suspect);
    EXPECT_EQ(r.method, "subdivided") << degrees;
    EXPECT_TRUE(r.order_recovered) << degrees;
    EXPECT_EQ(r.matched_fraction, 1.0) << degrees;
    EXPECT_LT(max_error(r.points, control.points), 1e-9) << degrees;
  }
}

TEST(Resync, MovedCopyInOrderIsAlignedBack) {
  MM_REQUIRE_SHARED_MESHES();
  const auto& ctx = context();
  const auto s = some_similarity();
  Mesh suspect = mm::subdivide(ctx.control(), 3);
  suspect.points = s.apply(suspect.points);
  const auto r = mm::resynchronize(ctx, suspect);
  EXPECT_EQ(r.level, 3);
  EXPECT_LT(max_error(r.points, ctx.control().points), 1e-10);
}

// Points on a surface, turned by 2 degrees and shifted by 1 % of the box: point-to-plane ICP puts
// them back within a few rounds, where point-to-point ICP, pairing each point with the nearest
// surface point rather than sliding along it, is still far off after as many.
TEST(Resync, PointToPlaneIcpSettlesOnTheSurfaceInAFewRounds) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh surface = mm::subdivide(fandisk_quads(), 1);
  const auto tris = mm::triangle_list(surface);
  const mm::TriangleIndex index(surface.points, tris);
  Points on(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t t = 0; t < tris.size(); ++t)
    on.row(static_cast<Eigen::Index>(t)) =
        (surface.points.row(tris[t][0]) + surface.points.row(tris[t][1]) + surface.points.row(tris[t][2])) / 3;
  mm::Similarity motion;
  motion.rotation = Eigen::AngleAxisd(2 * M_PI / 180, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  motion.translation = Eigen::RowVector3d(0.01, -0.005, 0.008);
  const Points moving = motion.apply(on);
  const mm::ClosestOnSurface on_surface = [&](const Eigen::Vector3d& q, Eigen::Index) {
    const mm::TriangleHit h = index.closest(q);
    const auto& t = tris[static_cast<std::size_t>(h.triangle)];
    const Eigen::Vector3d p0 = surface.points.row(t[0]), p1 = surface.points.row(t[1]), p2 = surface.points.row(t[2]);
    return mm::SurfacePoint{h.point, (p1 - p0).cross(p2 - p0).normalized()};
  };
  mm::IcpOptions o;
  o.trim_fraction = 0;
  const mm::IcpResult plane = mm::icp_rigid_point_to_plane(moving, on_surface, mm::Similarity(), o);
  EXPECT_LE(plane.iterations, 10);
  EXPECT_EQ(plane.transform.scale, 1);
  EXPECT_LT(max_error(plane.transform.apply(moving), on), 1e-6);
  EXPECT_LT(plane.rms, 1e-7);

  const mm::ClosestPoint nearest = [&](const Eigen::Vector3d& q, Eigen::Index) { return index.closest(q).point; };
  o.keep_scale = true;
  const mm::IcpResult point = mm::icp_similarity(moving, nearest, Points(), mm::Similarity(), o, plane.iterations);
  EXPECT_GT(max_error(point.transform.apply(moving), on), 100 * max_error(plane.transform.apply(moving), on));
}

TEST(Resync, PolyhedronWithReorderedFaces) {
  MM_REQUIRE_SHARED_MESHES();
  const auto& ctx = context();
  Mesh suspect = ctx.control();
  std::mt19937_64 rng(3);
  for (auto& f : suspect.faces) std::rotate(f.begin(), f.begin() + static_cast<long>(rng() % f.size()), f.end());
  std::shuffle(suspect.faces.begin(), suspect.faces.end(), rng);
  const auto r = mm::resynchronize(ctx, suspect);
  EXPECT_EQ(r.method, "polyhedron");
  EXPECT_EQ(r.level, 0);
  EXPECT_FALSE(r.order_recovered);
  EXPECT_LT(max_error(r.points, ctx.control().points), 1e-12);

  const auto q = mm::resynchronize(ctx, shuffled(ctx.control(), 5));
  EXPECT_EQ(q.method, "polyhedron");
  EXPECT_TRUE(q.order_recovered);
  EXPECT_LT(max_error(q.points, ctx.control().points), 1e-12);
}

TEST(Resync, NoiseIsAveragedOverTheRefinedVertices) {
  MM_REQUIRE_SHARED_MESHES();
  const auto& ctx = context();
  const double sigma = 1e-3;  // unit-box units: 1/1000 of the part
  Mesh suspect = mm::subdivide(ctx.control(), 3);
  std::mt19937_64 rng(21);
  std::normal_distribution<double> noise(0.0, sigma);
  for (Eigen::Index i = 0; i < suspect.points.rows(); ++i)
    for (int c = 0; c < 3; ++c) suspect.points(i, c) += noise(rng);
  const auto r = mm::resynchronize(ctx, suspect);
  EXPECT_EQ(r.level, 3);
  const double rms = std::sqrt((r.points - ctx.control().points).rowwise().squaredNorm().mean());
  // Least squares gives each control point the noise variance sigma^2 (S^T S)^-1_ii per axis:
  // far below sigma where many refined vertices see a control point, less so at corners, where
  // S is a smoothing (ill-conditioned) map.
  const auto& S = ctx.subdivision(3).S;
  const Eigen::SparseMatrix<double> StS = Eigen::SparseMatrix<double>(S.transpose()) * S;
  const Eigen::MatrixXd inv = Eigen::MatrixXd(StS).inverse();
  const double expected = sigma * std::sqrt(3.0 * inv.diagonal().mean());
  EXPECT_NEAR(rms, expected, 0.15 * expected);
  EXPECT_LT(rms, 0.7 * sigma * std::sqrt(3.0));
  EXPECT_NEAR(r.residual_rms * ctx.diagonal(), sigma * std::sqrt(3.0), 0.2 * sigma * std::sqrt(3.0));
}

TEST(Resync, UnusableSuspectsAreRejectedByName) {
  MM_REQUIRE_SHARED_MESHES();
  const auto& ctx = context();
  mm::ResyncOptions o;
  o.source = "leak.stl";
  EXPECT_THROW(mm::resynchronize(ctx, Mesh{}, o), mm::InputError);
  Mesh nan = mm::subdivide(ctx.control(), 1);
  nan.points(5, 1) = std::numeric_limits<double>::quiet_NaN();
  try {
    mm::resynchronize(ctx, nan, o);
    FAIL() << "non-finite suspect accepted";
  } catch (const mm::InputError& e) {
    EXPECT_EQ(e.source(), "leak.stl");
    EXPECT_NE(std::string(e.what()).find("non-finite"), std::string::npos);
  }
  Mesh bad = mm::subdivide(ctx.control(), 1);
  bad.faces[0][0] = bad.num_vertices();
  EXPECT_THROW(mm::resynchronize(ctx, bad, o), mm::InputError);
}

TEST(Resync, OneContextServesSeveralThreads) {
  MM_REQUIRE_SHARED_MESHES();
  const auto& ctx = context();
  const Mesh in_order = mm::subdivide(ctx.control(), 2);
  const Mesh reordered = shuffled(in_order, 4);
  const auto expected_a = mm::resynchronize(ctx, in_order);
  const auto expected_b = mm::resynchronize(ctx, reordered);
  mm::Resynchronized a, b;
  std::thread ta([&] { a = mm::resynchronize(ctx, in_order); });
  std::thread tb([&] { b = mm::resynchronize(ctx, reordered); });
  ta.join();
  tb.join();
  // Deterministic and unaffected by a concurrent query on the same context: bit for bit.
  EXPECT_EQ(a.points, expected_a.points);
  EXPECT_EQ(b.points, expected_b.points);
  EXPECT_EQ(b.to_control_frame.rotation, expected_b.to_control_frame.rotation);
}

TEST(Resync, UnrelatedShapeFallsToTheSurfaceFit) {
  MM_REQUIRE_SHARED_MESHES();
  const auto& ctx = context();
  const Mesh sphere = mm::read_mesh(mm::test::shared_mesh("sphere_low.off"));
  mm::ResyncOptions o;
  o.suspect_samples = 2000;  // enough to see it does not fit, and fast
  o.alignment_samples = 1000;
  o.icp.probe_points = 500;
  const auto r = mm::resynchronize(ctx, sphere, o);
  std::printf("  sphere: residual %.2e matched %.3f\n", r.residual_rms, r.matched_fraction);
  EXPECT_EQ(r.method, "surface-fit");
  EXPECT_EQ(r.points.rows(), ctx.control().num_vertices());
  EXPECT_TRUE(r.points.allFinite());
  // Nothing like the part: the fit cannot explain it (a decimated copy of the part leaves 1e-5).
  EXPECT_GT(r.residual_rms, 1e-4);
}

// Normalisation into the unit bounding box and back.
#include <gtest/gtest.h>

#include <random>

#include "common/shared_meshes.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"

namespace {

void expect_unit_box(const mm::Points& p) {
  Eigen::Vector3d lo = p.colwise().minCoeff().transpose(), hi = p.colwise().maxCoeff().transpose();
  EXPECT_NEAR(lo.minCoeff(), 0.0, 1e-15);
  EXPECT_NEAR(lo.maxCoeff(), 0.0, 1e-15);
  EXPECT_NEAR((hi - lo).maxCoeff(), 1.0, 1e-15);
}

TEST(Normalize, RandomPointsRoundTrip) {
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> u(-50, 300);
  mm::Points p(200, 3);
  for (int i = 0; i < p.rows(); ++i) p.row(i) << u(rng), u(rng) * 0.01, u(rng) + 1e4;
  mm::Points q = p;
  mm::Normalization n = mm::unit_box_normalization(q);
  mm::apply(n, q);
  expect_unit_box(q);
  // Proportions are kept: one scale for all axes.
  EXPECT_NEAR((q.row(1) - q.row(0)).norm() / (p.row(1) - p.row(0)).norm(), n.scale, 1e-12);
  mm::undo(n, q);
  EXPECT_LT((q - p).cwiseAbs().maxCoeff() / p.cwiseAbs().maxCoeff(), 1e-15);
}

TEST(Normalize, SharedMeshesOfVeryDifferentScales) {
  MM_REQUIRE_SHARED_MESHES();
  for (const char* f : {"abc6.stl", "fandisk.off", "bracket-3.stl"}) {
    SCOPED_TRACE(f);
    mm::Mesh m = mm::read_mesh(mm::test::shared_mesh(f));
    mm::Points q = m.points;
    mm::Normalization n = mm::unit_box_normalization(q);
    mm::apply(n, q);
    expect_unit_box(q);
    mm::undo(n, q);
    double extent = (m.points.colwise().maxCoeff() - m.points.colwise().minCoeff()).maxCoeff();
    EXPECT_LT((q - m.points).cwiseAbs().maxCoeff(), 1e-14 * std::max(1.0, extent + m.points.cwiseAbs().maxCoeff()));
  }
}

TEST(Normalize, DegenerateBoxIsRefused) {
  mm::Points p(3, 3);
  p.setConstant(2.5);
  EXPECT_THROW(mm::unit_box_normalization(p), std::invalid_argument);
}

}  // namespace

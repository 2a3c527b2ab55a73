#include <gtest/gtest.h>

#include <cmath>

#include "compression/coordinate_slack.h"
#include "quality/surface_distance.h"
#include "subdivision/decompress.h"

namespace {

// A flat n x n quad grid in the plane z = 0, boundary creased (the subdivision keeps it flat).
mm::Mesh flat_grid(int n) {
  mm::Mesh m;
  m.points.resize(n * n, 3);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) m.points.row(j * n + i) << i, j, 0;
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) m.faces.push_back({j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i});
  return m;
}

// flat_grid(9) tilted about y (z = x / 2), and its surface at `level` with each vertex lifted
// along the tilted normal by lift(x, y).
template <class Lift>
void tilted_grid(int level, Lift lift, mm::Mesh& control, mm::Mesh& part) {
  control = flat_grid(9);
  for (int v = 0; v < control.num_vertices(); ++v) control.points(v, 2) = 0.5 * control.points(v, 0);
  part = mm::decompress_to_level(control, level);
  const Eigen::RowVector3d normal = Eigen::RowVector3d(-0.5, 0, 1).normalized();
  for (int r = 0; r < part.num_vertices(); ++r) part.points.row(r) += lift(part.points(r, 0), part.points(r, 1)) * normal;
}

}  // namespace

// Against its own surface, a flat grid may slide freely in its plane (no refined vertex depends
// on x or y) and move across it by the whole tolerance.
TEST(CoordinateSlack, FlatSurfaceSlidesFreelyInItsPlane) {
  const mm::Mesh control = flat_grid(5);
  const mm::Mesh part = mm::decompress_to_level(control, 2);
  const auto slack = mm::coordinate_slack(part, control, 2, 0.01);
  ASSERT_EQ(slack.size(), 3u * 25);
  for (int v = 0; v < 25; ++v) {
    EXPECT_GE(slack[3 * v], 1e29) << v;
    EXPECT_GE(slack[3 * v + 1], 1e29) << v;
    EXPECT_NEAR(slack[3 * v + 2], 0.01, 1e-9) << v;
  }
}

// A part lifted by d leaves tolerance - d across the plane; one lifted beyond the tolerance
// leaves nothing (never negative).
TEST(CoordinateSlack, ErrorUsesUpTheSlack) {
  const mm::Mesh control = flat_grid(4);
  mm::Mesh part = mm::decompress_to_level(control, 2);
  part.points.col(2).array() += 0.004;
  auto slack = mm::coordinate_slack(part, control, 2, 0.01);
  for (int v = 0; v < 16; ++v) EXPECT_NEAR(slack[3 * v + 2], 0.006, 1e-9) << v;
  part.points.col(2).array() += 0.01;
  slack = mm::coordinate_slack(part, control, 2, 0.01);
  for (int v = 0; v < 16; ++v) EXPECT_EQ(slack[3 * v + 2], 0.0) << v;
}

// A local bump in the part is charged to the control vertices whose surface is near it: they
// lose their slack, far ones keep it. A tilted grid: every axis then has a normal component,
// which divides the slack by |n_x| + |n_y| + |n_z|.
TEST(CoordinateSlack, LocalErrorIsLocalAndTiltDividesTheSlack) {
  // The part's vertices near control vertex (1, 1) lifted along the normal.
  mm::Mesh control, part;
  tilted_grid(2, [](double x, double y) { return (x - 1) * (x - 1) + (y - 1) * (y - 1) < 0.25 ? 0.02 : 0.0; },
              control, part);
  const double tol = 0.05;
  const auto slack = mm::coordinate_slack(part, control, 2, tol);
  const double l1 = (0.5 + 1) / std::sqrt(1.25);
  const int near = 1 * 9 + 1, far = 7 * 9 + 7;
  EXPECT_LT(slack[3 * near + 2], (tol - 0.015) / l1);
  EXPECT_NEAR(slack[3 * far + 2], tol / l1, 1e-9);
  EXPECT_NEAR(slack[3 * far], tol / l1, 1e-9);
  EXPECT_GE(slack[3 * far + 1], 1e29);  // the tilt is about y: y still slides freely
}

// Asked only which slacks are at most c, it gives those exactly as the whole computation does and
// the others as larger; from c = 0 (a repair's first question) to one where nothing is skipped.
TEST(CoordinateSlack, SlacksUpToALimitAreExactAndTheOthersLarger) {
  // A smooth bump whose height goes from 0.06 (beyond the tolerance) to nothing.
  mm::Mesh control, part;
  tilted_grid(3, [](double x, double y) { return 0.06 * std::exp(-((x - 3) * (x - 3) + (y - 4) * (y - 4)) / 4); },
              control, part);
  const double tol = 0.05;
  mm::SamplingParams params;
  params.samples = 20000;
  const mm::MeasuredSurface measured(part, params);
  const auto all = mm::coordinate_slack(measured, control, 2, tol, params);
  for (double c : {0.0, 0.002, 0.01, 0.02}) {
    const auto some = mm::coordinate_slack(measured, control, 2, tol, params, c);
    ASSERT_EQ(some.size(), all.size());
    int exact = 0, skipped = 0;
    for (std::size_t i = 0; i < all.size(); ++i) {
      if (all[i] <= c) {
        EXPECT_EQ(some[i], all[i]) << "c " << c << " coordinate " << i;
        ++exact;
      } else {
        EXPECT_GT(some[i], c) << "c " << c << " coordinate " << i;
        skipped += some[i] != all[i];
      }
    }
    EXPECT_GT(exact, 0) << c;
    if (tol - 3 * c > 0) {
      EXPECT_GT(skipped, 0) << c;  // near samples were not measured
    }
  }
}

TEST(CoordinateSlack, PartWithoutAreaIsRefused) {
  const mm::Mesh control = flat_grid(3);
  mm::Mesh part = control;
  part.points.setZero();
  EXPECT_THROW(mm::coordinate_slack(part, control, 1, 0.01), mm::InputError);
}

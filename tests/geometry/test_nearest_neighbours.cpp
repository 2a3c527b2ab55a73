// PointTree against brute force: random, flat and clustered sets, queries inside and far outside.
#include <gtest/gtest.h>

#include <random>

#include "geometry/nearest_neighbours.h"

namespace {

int brute(const mm::Points& p, const Eigen::Vector3d& q) {
  int best = -1;
  double d = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    const double e = (p.row(i).transpose() - q).squaredNorm();
    if (e < d) d = e, best = static_cast<int>(i);
  }
  return best;
}

void check(const mm::Points& p, std::uint64_t seed, double spread) {
  const mm::PointTree tree(p);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-spread, spread);
  for (int k = 0; k < 500; ++k) {
    const Eigen::Vector3d q(u(rng), u(rng), u(rng));
    double d2 = 0;
    const int i = tree.nearest(q, &d2);
    ASSERT_EQ(i, brute(p, q)) << "query " << q.transpose();
    EXPECT_EQ(d2, (p.row(i).transpose() - q).squaredNorm());
  }
}

}  // namespace

TEST(PointTree, MatchesBruteForce) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(0, 1);
  mm::Points cube(2000, 3), flat(2000, 3), line(300, 3), clustered(1000, 3);
  for (int i = 0; i < 2000; ++i) {
    cube.row(i) << u(rng), u(rng), u(rng);
    flat.row(i) << u(rng), u(rng), 0.0;
  }
  for (int i = 0; i < 300; ++i) line.row(i) << u(rng), 0.0, 0.0;
  for (int i = 0; i < 1000; ++i) clustered.row(i) << (i % 2 ? 100.0 : 0.0) + 1e-3 * u(rng), 1e-3 * u(rng), 1e-3 * u(rng);
  check(cube, 2, 1.5);     // inside and around
  check(cube, 3, 100.0);   // mostly far outside
  check(flat, 4, 1.2);
  check(line, 5, 2.0);
  check(clustered, 6, 120.0);
  EXPECT_EQ(mm::PointTree(mm::Points(0, 3)).nearest(Eigen::Vector3d::Zero()), -1);
}

// Ties go to the lowest index however the tree splits: an integer lattice with every point twice,
// queried at the lattice's midpoints, where up to eight points (sixteen with the copies) are
// equally near.
TEST(PointTree, TiesGoToTheLowestIndex) {
  mm::Points lattice(2 * 216, 3);
  for (int copy = 0, i = 0; copy < 2; ++copy)
    for (int x = 5; x >= 0; --x)  // descending, so the lowest index is not the first in space
      for (int y = 0; y < 6; ++y)
        for (int z = 0; z < 6; ++z, ++i) lattice.row(i) << x, y, z;
  const mm::PointTree tree(lattice);
  for (double x = -0.5; x <= 6; x += 0.5)
    for (double y = -0.5; y <= 6; y += 0.5)
      for (double z = -0.5; z <= 6; z += 0.5) {
        const Eigen::Vector3d q(x, y, z);
        ASSERT_EQ(tree.nearest(q), brute(lattice, q)) << q.transpose();
        ASSERT_LT(tree.nearest(q), 216) << "a first copy is as near as its second";
      }
}

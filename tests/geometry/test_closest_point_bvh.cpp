// The fit's own BVH must give exactly the closest distance a brute-force scan gives, before and
// after its points move (refit), with and without a start hint: a wrong box bound or a skipped
// child would show up as a larger distance here.
#include <gtest/gtest.h>

#include <random>

#include "geometry/closest_point_bvh.h"

namespace mm {
namespace {

double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                               const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Dense sampling is not exact; use the textbook region test (Ericson, RTCD 5.1.5).
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return (p - a).norm();
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return (p - b).norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return (p - c).norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  const double denom = 1 / (va + vb + vc);
  return (p - (a + ab * vb * denom + ac * vc * denom)).norm();
}

double point_segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                              const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

// A wavy grid surface (many near-ties, like a subdivided surface) with jittered points.
struct Soup {
  Points points;
  std::vector<std::array<int, 3>> triangles;
  std::vector<std::pair<int, int>> segments;
};

Soup wavy_grid(int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> jitter(-0.2, 0.2);
  Soup s;
  s.points.resize(n * n, 3);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      s.points.row(i * n + j) << i + jitter(rng), j + jitter(rng), std::sin(0.5 * i) * std::cos(0.3 * j);
  for (int i = 0; i + 1 < n; ++i)
    for (int j = 0; j + 1 < n; ++j) {
      const int v = i * n + j;
      s.triangles.push_back({v, v + 1, v + n + 1});
      s.triangles.push_back({v, v + n + 1, v + n});
      s.segments.emplace_back(v, v + 1);
      s.segments.emplace_back(v, v + n);
    }
  return s;
}

void expect_matches_brute_force(const Soup& s, const TriangleBvh& tri, const SegmentBvh& seg,
                                std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-3, 23), h(-4, 4);
  std::uniform_int_distribution<int> pick_tri(0, static_cast<int>(s.triangles.size()) - 1);
  std::uniform_int_distribution<int> pick_seg(0, static_cast<int>(s.segments.size()) - 1);
  for (int k = 0; k < 500; ++k) {
    const Eigen::Vector3d q(u(rng), u(rng), h(rng));
    double best_t = 1e300, best_s = 1e300;
    for (const auto& t : s.triangles)
      best_t = std::min(best_t, point_triangle_distance(q, s.points.row(t[0]), s.points.row(t[1]),
                                                        s.points.row(t[2])));
    for (const auto& e : s.segments)
      best_s = std::min(best_s, point_segment_distance(q, s.points.row(e.first), s.points.row(e.second)));
    const TriangleHit a = tri.closest(q), b = tri.closest(q, pick_tri(rng));
    EXPECT_NEAR(a.distance, best_t, 1e-9) << "query " << k;
    EXPECT_NEAR(b.distance, best_t, 1e-9) << "query " << k << " (hinted)";
    EXPECT_NEAR((a.point - q).norm(), a.distance, 1e-9);
    const auto& t = s.triangles[static_cast<size_t>(a.triangle)];
    const Eigen::Vector3d from_bary = a.barycentric[0] * s.points.row(t[0]).transpose() +
                                      a.barycentric[1] * s.points.row(t[1]).transpose() +
                                      a.barycentric[2] * s.points.row(t[2]).transpose();
    EXPECT_NEAR((from_bary - a.point).norm(), 0, 1e-9);
    const SegmentHit c = seg.closest(q), d = seg.closest(q, pick_seg(rng));
    EXPECT_NEAR(c.distance, best_s, 1e-9) << "query " << k;
    EXPECT_NEAR(d.distance, best_s, 1e-9) << "query " << k << " (hinted)";
  }
}

TEST(ClosestPointBvh, MatchesBruteForceBeforeAndAfterRefit) {
  std::mt19937 rng(20261201);
  Soup s = wavy_grid(21, rng);
  TriangleBvh tri(s.points, s.triangles);
  SegmentBvh seg(s.points, s.segments);
  expect_matches_brute_force(s, tri, seg, rng);

  // Move every point (far more than the fit's per-iteration moves): the refitted boxes must
  // still bound their triangles, or queries would miss the true answer.
  std::normal_distribution<double> move(0, 0.7);
  for (int i = 0; i < s.points.rows(); ++i) s.points.row(i) += Eigen::RowVector3d(move(rng), move(rng), move(rng));
  tri.refit(s.points);
  seg.refit(s.points);
  expect_matches_brute_force(s, tri, seg, rng);
}

// The fit orders its queries by their hints' leaf positions: every triangle needs its own one.
TEST(ClosestPointBvh, LeafPositionsNumberTheTrianglesOnce) {
  std::mt19937 rng(20261203);
  const Soup s = wavy_grid(17, rng);
  const TriangleBvh tri(s.points, s.triangles);
  ASSERT_EQ(tri.size(), static_cast<int>(s.triangles.size()));
  std::vector<int> seen(s.triangles.size(), 0);
  for (int t = 0; t < tri.size(); ++t) {
    const int at = tri.leaf_position(t);
    ASSERT_GE(at, 0);
    ASSERT_LT(at, tri.size());
    ++seen[static_cast<size_t>(at)];
  }
  for (int n : seen) EXPECT_EQ(n, 1);
}

TEST(ClosestPointBvh, DegenerateTrianglesAreNeverReported) {
  Points p(4, 3);
  p << 0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0;
  // Triangle 0 is a zero-area sliver along the x axis; triangle 1 is regular.
  TriangleBvh tri(p, {{0, 1, 2}, {0, 1, 3}});
  const TriangleHit hit = tri.closest(Eigen::Vector3d(1.5, -1, 0));
  EXPECT_EQ(hit.triangle, 1);
  TriangleBvh only_degenerate(p, {{0, 1, 2}});
  EXPECT_TRUE(only_degenerate.empty());
}

}  // namespace
}  // namespace mm

#include <gtest/gtest.h>

#include <random>
#include <set>

#include "geometry/bvh_layout.h"

namespace {

// Clustered centroids with repeated ones (median splits and ties) and small boxes around them.
void random_primitives(int n, std::vector<Eigen::Vector3d>& centroid, std::vector<Eigen::AlignedBox3d>& box) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d p(u(rng), u(rng) * 0.1, i % 7 == 0 ? 0.5 : u(rng));
    if (i % 11 == 0 && i > 0) p = centroid.back();
    centroid.push_back(p);
    const double below = 0.01 * u(rng), above = 0.01 * u(rng);
    box.emplace_back(p - Eigen::Vector3d::Constant(below), p + Eigen::Vector3d::Constant(above));
  }
}

std::uint64_t fingerprint(const mm::BvhLayout& l) {
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a over the nodes and the order
  const auto mix = [&](long long v) { h = (h ^ static_cast<std::uint64_t>(v)) * 1099511628211ull; };
  for (const auto& nd : l.nodes) mix(nd.first), mix(nd.count);
  for (int o : l.order) mix(o);
  return h;
}

}  // namespace

// Every primitive in exactly one leaf of at most leaf_size, children after their parent.
TEST(BvhLayout, LeavesHoldEveryPrimitiveOnce) {
  std::vector<Eigen::Vector3d> c;
  std::vector<Eigen::AlignedBox3d> b;
  random_primitives(5000, c, b);
  const mm::BvhLayout l = mm::binned_sah_layout(c, b, 4);
  ASSERT_EQ(l.order.size(), c.size());
  std::multiset<int> seen;
  for (std::size_t i = 0; i < l.nodes.size(); ++i) {
    const auto& nd = l.nodes[i];
    if (nd.count > 0) {
      EXPECT_LE(nd.count, 4);
      for (int k = nd.first; k < nd.first + nd.count; ++k) seen.insert(l.order[static_cast<std::size_t>(k)]);
    } else {
      EXPECT_GT(nd.first, static_cast<int>(i) + 1);  // the right child after the left one
    }
  }
  EXPECT_EQ(seen.size(), c.size());
  for (int t = 0; t < static_cast<int>(c.size()); ++t) EXPECT_EQ(seen.count(t), 1u) << t;
}

// The layout decides which of equally close triangles a fit's closest-point search reports, so a
// compress run's result depends on it: these are the layouts of stop 16's build (an index array
// partitioned in place), which the build over a primitive array reproduces. A change here changes
// streams, and must be deliberate.
TEST(BvhLayout, SameLayoutsAsTheIndexArrayBuild) {
  const std::vector<std::pair<int, std::uint64_t>> expected{{1, 12195993322297192280ull},
                                                            {5, 8822151941644486353ull},
                                                            {1000, 13659734523430840754ull},
                                                            {30000, 14105792520097517627ull}};
  for (const auto& [n, hash] : expected) {
    std::vector<Eigen::Vector3d> c;
    std::vector<Eigen::AlignedBox3d> b;
    random_primitives(n, c, b);
    EXPECT_EQ(fingerprint(mm::binned_sah_layout(c, b, 4)), hash) << n << " primitives";
  }
}

#include "quality/bvh_layout.h"

#include <algorithm>
#include <limits>
#include <numeric>

namespace mm {
namespace {

// Half the surface area of a box (the heuristic's probability of a visit, up to a factor).
double area(const Eigen::AlignedBox3d& b) {
  if (b.isEmpty()) return 0;
  const Eigen::Vector3d e = b.sizes();
  return e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
}

struct Builder {
  const std::vector<Eigen::Vector3d>& centroid;
  const std::vector<Eigen::AlignedBox3d>& box;
  int leaf_size;
  BvhLayout out;
  std::vector<int> bin;  // each primitive's bin in the current split

  int build(int begin, int end, int depth) {
    std::vector<int>& order = out.order;
    const int index = static_cast<int>(out.nodes.size());
    out.nodes.push_back(BvhLayout::Node{});
    if (end - begin <= leaf_size) {
      out.nodes[static_cast<size_t>(index)] = {begin, end - begin};
      return index;
    }
    Eigen::Vector3d lo = centroid[static_cast<size_t>(order[static_cast<size_t>(begin)])], hi = lo;
    for (int k = begin + 1; k < end; ++k) {
      lo = lo.cwiseMin(centroid[static_cast<size_t>(order[static_cast<size_t>(k)])]);
      hi = hi.cwiseMax(centroid[static_cast<size_t>(order[static_cast<size_t>(k)])]);
    }
    constexpr int kBins = 12;
    int axis = 0;
    (hi - lo).maxCoeff(&axis);
    const double extent = hi[axis] - lo[axis];
    int best_bin = -1;
    if (extent > 0) {
      Eigen::AlignedBox3d bins[kBins];
      int counts[kBins] = {};
      for (int k = begin; k < end; ++k) {
        const int t = order[static_cast<size_t>(k)];
        const int b = std::min(kBins - 1, static_cast<int>(kBins * (centroid[static_cast<size_t>(t)][axis] - lo[axis]) / extent));
        bin[static_cast<size_t>(t)] = b;  // for the partition below
        ++counts[b];
        bins[b].extend(box[static_cast<size_t>(t)]);
      }
      double right_area[kBins];
      int right_count[kBins];
      Eigen::AlignedBox3d acc;
      int cnt = 0;
      for (int b = kBins - 1; b > 0; --b) {
        acc.extend(bins[b]);
        cnt += counts[b];
        right_area[b] = area(acc);
        right_count[b] = cnt;
      }
      acc.setEmpty();
      cnt = 0;
      double best_cost = std::numeric_limits<double>::infinity();
      for (int b = 0; b + 1 < kBins; ++b) {
        acc.extend(bins[b]);
        cnt += counts[b];
        if (cnt == 0 || right_count[b + 1] == 0) continue;
        const double cost = area(acc) * cnt + right_area[b + 1] * right_count[b + 1];
        if (cost < best_cost) best_cost = cost, best_bin = b;
      }
    }
    int mid = begin + (end - begin) / 2;
    if (best_bin >= 0 && depth < 48) {
      mid = static_cast<int>(std::partition(order.begin() + begin, order.begin() + end,
                                            [&](int t) { return bin[static_cast<size_t>(t)] <= best_bin; }) -
                             order.begin());
    } else {
      std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end, [&](int x, int y) {
        const double cx = centroid[static_cast<size_t>(x)][axis], cy = centroid[static_cast<size_t>(y)][axis];
        return cx < cy || (cx == cy && x < y);
      });
    }
    build(begin, mid, depth + 1);
    const int right = build(mid, end, depth + 1);
    out.nodes[static_cast<size_t>(index)] = {right, 0};
    return index;
  }
};

}  // namespace

BvhLayout binned_sah_layout(const std::vector<Eigen::Vector3d>& centroid,
                            const std::vector<Eigen::AlignedBox3d>& box, int leaf_size) {
  const int n = static_cast<int>(centroid.size());
  Builder b{centroid, box, std::max(1, leaf_size), {}, std::vector<int>(static_cast<size_t>(n))};
  b.out.order.resize(static_cast<size_t>(n));
  std::iota(b.out.order.begin(), b.out.order.end(), 0);
  b.out.nodes.reserve(static_cast<size_t>(2 * (n / b.leaf_size + 1)));
  if (n > 0) b.build(0, n, 0);
  return std::move(b.out);
}

}  // namespace mm

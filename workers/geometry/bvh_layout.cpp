#include "geometry/bvh_layout.h"

#include <algorithm>
#include <limits>

namespace mm {
namespace {

// Half the surface area of a box (the heuristic's probability of a visit, up to a factor).
double area(const Eigen::AlignedBox3d& b) {
  if (b.isEmpty()) return 0;
  const Eigen::Vector3d e = b.sizes();
  return e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
}

// A primitive as the build reads it. The build permutes these in place, in leaf order, instead
// of an index array into the caller's centroids and boxes: each level then reads them in order,
// not scattered (a 75,000-triangle subdivided surface's build did a random read per primitive
// and level). std::partition and std::nth_element permute by their comparisons alone, so the
// layout is the one the index array gave.
struct Prim {
  Eigen::Vector3d centroid;
  Eigen::AlignedBox3d box;
  int id;
  int bin;  // its bin in the current split
};

struct Builder {
  std::vector<Prim> prims;
  int leaf_size;
  BvhLayout out;

  int build(int begin, int end, int depth) {
    const int index = static_cast<int>(out.nodes.size());
    out.nodes.push_back(BvhLayout::Node{});
    if (end - begin <= leaf_size) {
      out.nodes[static_cast<size_t>(index)] = {begin, end - begin};
      return index;
    }
    const auto first = prims.begin() + begin, last = prims.begin() + end;
    Eigen::Vector3d lo = first->centroid, hi = lo;
    for (auto it = first + 1; it != last; ++it) {
      lo = lo.cwiseMin(it->centroid);
      hi = hi.cwiseMax(it->centroid);
    }
    constexpr int kBins = 12;
    int axis = 0;
    (hi - lo).maxCoeff(&axis);
    const double extent = hi[axis] - lo[axis];
    int best_bin = -1;
    if (extent > 0) {
      Eigen::AlignedBox3d bins[kBins];
      int counts[kBins] = {};
      for (auto it = first; it != last; ++it) {
        const int b = std::min(kBins - 1, static_cast<int>(kBins * (it->centroid[axis] - lo[axis]) / extent));
        it->bin = b;  // for the partition below
        ++counts[b];
        bins[b].extend(it->box);
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
      mid = static_cast<int>(std::partition(first, last, [&](const Prim& t) { return t.bin <= best_bin; }) -
                             prims.begin());
    } else {
      std::nth_element(first, prims.begin() + mid, last, [&](const Prim& x, const Prim& y) {
        const double cx = x.centroid[axis], cy = y.centroid[axis];
        return cx < cy || (cx == cy && x.id < y.id);
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
  Builder b{std::vector<Prim>(static_cast<size_t>(n)), std::max(1, leaf_size), {}};
  for (int t = 0; t < n; ++t)
    b.prims[static_cast<size_t>(t)] = Prim{centroid[static_cast<size_t>(t)], box[static_cast<size_t>(t)], t, 0};
  b.out.nodes.reserve(static_cast<size_t>(2 * (n / b.leaf_size + 1)));
  if (n > 0) b.build(0, n, 0);
  b.out.order.resize(static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) b.out.order[static_cast<size_t>(k)] = b.prims[static_cast<size_t>(k)].id;
  return std::move(b.out);
}

}  // namespace mm

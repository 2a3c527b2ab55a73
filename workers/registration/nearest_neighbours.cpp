#include "registration/nearest_neighbours.h"

#include <algorithm>
#include <limits>
#include <numeric>

namespace mm {
namespace {

constexpr int kLeafSize = 16;

// Squared distance from p to a box. Each axis's gap is at most that of any point in the box
// (rounding is monotone), so this never exceeds a contained point's squared distance as
// nearest() computes it: a box is skipped only when none of its points can tie the best.
double box_distance2(const double* lo, const double* hi, const double* p) {
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double e = std::max(std::max(lo[k] - p[k], p[k] - hi[k]), 0.0);
    d2 += e * e;
  }
  return d2;
}

}  // namespace

PointTree::PointTree(const Points& points) {
  const int n = static_cast<int>(points.rows());
  if (n == 0) return;
  index_.resize(static_cast<size_t>(n));
  std::iota(index_.begin(), index_.end(), 0);
  nodes_.reserve(static_cast<size_t>(4 * (n / kLeafSize + 1)));
  // Depth first, left before right, so a node's left child is the next one.
  struct Pending {
    int begin, end, parent;  // parent: the node whose right child this is (-1: none)
  };
  std::vector<Pending> stack{{0, n, -1}};
  while (!stack.empty()) {
    const Pending w = stack.back();
    stack.pop_back();
    const int at = static_cast<int>(nodes_.size());
    if (w.parent >= 0) nodes_[static_cast<size_t>(w.parent)].right = at;
    Node nd;
    nd.begin = w.begin, nd.end = w.end, nd.right = -1;
    for (int k = 0; k < 3; ++k) {
      nd.lo[k] = std::numeric_limits<double>::infinity();
      nd.hi[k] = -std::numeric_limits<double>::infinity();
    }
    for (int j = w.begin; j < w.end; ++j)
      for (int k = 0; k < 3; ++k) {
        const double x = points(index_[static_cast<size_t>(j)], k);
        nd.lo[k] = std::min(nd.lo[k], x);
        nd.hi[k] = std::max(nd.hi[k], x);
      }
    nodes_.push_back(nd);
    if (w.end - w.begin <= kLeafSize) continue;
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (nd.hi[k] - nd.lo[k] > nd.hi[axis] - nd.lo[axis]) axis = k;
    const int mid = w.begin + (w.end - w.begin) / 2;
    // Ties by index, so the split depends on the points alone.
    std::nth_element(index_.begin() + w.begin, index_.begin() + mid, index_.begin() + w.end, [&](int a, int b) {
      const double xa = points(a, axis), xb = points(b, axis);
      return xa < xb || (xa == xb && a < b);
    });
    // Right pushed first: popped after the whole left subtree.
    nodes_.back().right = 0;  // an inner node; set when the right child is made
    stack.push_back({mid, w.end, at});
    stack.push_back({w.begin, mid, -1});
  }
  nodes_.shrink_to_fit();
  xyz_.resize(static_cast<size_t>(3 * n));
  slot_.resize(static_cast<size_t>(n));
  for (int j = 0; j < n; ++j) {
    slot_[static_cast<size_t>(index_[static_cast<size_t>(j)])] = j;
    for (int k = 0; k < 3; ++k) xyz_[static_cast<size_t>(3 * j + k)] = points(index_[static_cast<size_t>(j)], k);
  }
}

int PointTree::nearest(const Eigen::Vector3d& q, double* squared_distance) const {
  int best = -1;
  double best_d = std::numeric_limits<double>::infinity();
  if (nodes_.empty()) {
    if (squared_distance) *squared_distance = best_d;
    return best;
  }
  const double p[3] = {q.x(), q.y(), q.z()};
  struct Entry {
    int node;
    double d2;
  };
  Entry stack[128];  // median splits: depth about log2(n / kLeafSize) + 1
  int top = 0;
  stack[top++] = {0, box_distance2(nodes_[0].lo, nodes_[0].hi, p)};
  while (top > 0) {
    const Entry e = stack[--top];
    // Not skipped at an equal distance: a point there may tie the best with a lower index.
    if (e.d2 > best_d) continue;
    const Node& nd = nodes_[static_cast<size_t>(e.node)];
    if (nd.right < 0) {
      for (int j = nd.begin; j < nd.end; ++j) {
        const double* x = &xyz_[static_cast<size_t>(3 * j)];
        const double dx = x[0] - p[0], dy = x[1] - p[1], dz = x[2] - p[2];
        const double d = dx * dx + dy * dy + dz * dz;
        const int i = index_[static_cast<size_t>(j)];
        if (d < best_d || (d == best_d && i < best)) best_d = d, best = i;
      }
      continue;
    }
    const int l = e.node + 1, r = nd.right;
    const Node& ln = nodes_[static_cast<size_t>(l)];
    const Node& rn = nodes_[static_cast<size_t>(r)];
    const double dl = box_distance2(ln.lo, ln.hi, p), dr = box_distance2(rn.lo, rn.hi, p);
    // The nearer child on top: its points lower the bound for the other.
    if (dl <= dr) {
      if (dr <= best_d) stack[top++] = {r, dr};
      if (dl <= best_d) stack[top++] = {l, dl};
    } else {
      if (dl <= best_d) stack[top++] = {l, dl};
      if (dr <= best_d) stack[top++] = {r, dr};
    }
  }
  if (squared_distance) *squared_distance = best_d;
  return best;
}

std::size_t PointTree::memory_bytes() const {
  return xyz_.capacity() * sizeof(double) + (index_.capacity() + slot_.capacity()) * sizeof(int) +
         nodes_.capacity() * sizeof(Node);
}

}  // namespace mm

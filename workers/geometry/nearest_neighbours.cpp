#include "geometry/nearest_neighbours.h"

#include <algorithm>
#include <limits>
#include <numeric>

namespace mm {
namespace {

constexpr int kLeafSize = 16;

}  // namespace

PointTree::PointTree(const Points& points) {
  const int n = static_cast<int>(points.rows());
  if (n == 0) return;
  index_.resize(static_cast<size_t>(n));
  std::iota(index_.begin(), index_.end(), 0);
  nodes_.reserve(static_cast<size_t>(4 * (n / kLeafSize + 1)));
  const auto box_of = [&](int begin, int end, double* lo, double* hi) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::numeric_limits<double>::infinity();
      hi[k] = -std::numeric_limits<double>::infinity();
    }
    for (int j = begin; j < end; ++j)
      for (int k = 0; k < 3; ++k) {
        const double x = points(index_[static_cast<size_t>(j)], k);
        lo[k] = std::min(lo[k], x);
        hi[k] = std::max(hi[k], x);
      }
  };
  box_of(0, n, root_lo_, root_hi_);
  // Depth first, left before right, so a node's left child is the next one.
  struct Pending {
    int begin, end, parent;  // parent: the node whose right child this is (-1: none)
    double lo[3], hi[3];     // the range's box
  };
  std::vector<Pending> stack(1);
  stack[0].begin = 0, stack[0].end = n, stack[0].parent = -1;
  std::copy(root_lo_, root_lo_ + 3, stack[0].lo);
  std::copy(root_hi_, root_hi_ + 3, stack[0].hi);
  while (!stack.empty()) {
    const Pending w = stack.back();
    stack.pop_back();
    const int at = static_cast<int>(nodes_.size());
    if (w.parent >= 0) nodes_[static_cast<size_t>(w.parent)].right = at;
    nodes_.emplace_back();
    Node& nd = nodes_.back();
    nd.begin = w.begin, nd.end = w.end, nd.right = -1;
    if (w.end - w.begin <= kLeafSize) continue;
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (w.hi[k] - w.lo[k] > w.hi[axis] - w.lo[axis]) axis = k;
    const int mid = w.begin + (w.end - w.begin) / 2;
    // Ties by index, so the split depends on the points alone.
    std::nth_element(index_.begin() + w.begin, index_.begin() + mid, index_.begin() + w.end, [&](int a, int b) {
      const double xa = points(a, axis), xb = points(b, axis);
      return xa < xb || (xa == xb && a < b);
    });
    Pending left{w.begin, mid, -1, {}, {}}, right{mid, w.end, at, {}, {}};
    box_of(left.begin, left.end, left.lo, left.hi);
    box_of(right.begin, right.end, right.lo, right.hi);
    for (int k = 0; k < 3; ++k) {
      nd.children.lo[k][0] = left.lo[k], nd.children.lo[k][1] = right.lo[k];
      nd.children.hi[k][0] = left.hi[k], nd.children.hi[k][1] = right.hi[k];
    }
    nd.right = 0;  // an inner node; set when the right child is made
    // Right pushed first: popped after the whole left subtree.
    stack.push_back(right);
    stack.push_back(left);
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
  BvhStackEntry stack[128];  // median splits: depth about log2(n / kLeafSize) + 1
  int top = 0;
  stack[top++] = {0, box_distance2(root_lo_, root_hi_, p)};
  while (top > 0) {
    const BvhStackEntry e = stack[--top];
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
    double dl, dr;
    child_box_distances(nd.children, p, dl, dr);
    // Not farther than the best: a point at an equal distance may have a lower index.
    push_nearer_child_last(stack, top, l, dl, r, dr, [best_d](double d) { return d <= best_d; });
  }
  if (squared_distance) *squared_distance = best_d;
  return best;
}

std::size_t PointTree::memory_bytes() const {
  return xyz_.capacity() * sizeof(double) + (index_.capacity() + slot_.capacity()) * sizeof(int) +
         nodes_.capacity() * sizeof(Node);
}

}  // namespace mm

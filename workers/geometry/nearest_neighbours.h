// Exact nearest-neighbour queries on a fixed point set, for matching a suspect's vertices to an
// original's when their order was lost: a k-d tree (median splits on the widest side, a box per
// node), whose queries cost about the same near the points as far from them. A uniform grid did
// before; its cells suit points filling a volume, not a surface, and a far query (a moved copy's
// alignment) scanned every empty cell on the way (docs/registration.md).
#pragma once
#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "meshio/mesh.h"
#include "geometry/bvh_layout.h"

namespace mm {

class PointTree {
 public:
  // Keeps a copy of the points (in its own order).
  explicit PointTree(const Points& points);
  int size() const { return static_cast<int>(index_.size()); }
  // Point i of those given.
  Eigen::Vector3d point(int i) const {
    const double* x = &xyz_[3 * static_cast<size_t>(slot_[static_cast<size_t>(i)])];
    return {x[0], x[1], x[2]};
  }
  // Index of the nearest point (ties: lowest index) and its squared distance; -1 when empty.
  int nearest(const Eigen::Vector3d& q, double* squared_distance = nullptr) const;
  // Heap bytes held (the copy of the points and the tree), for callers that budget memory.
  std::size_t memory_bytes() const;

 private:
  struct Node {
    BvhChildBoxes children;  // inner nodes: the children's boxes, side by side
    int begin, end;          // its points: xyz_[3 * k ...] for k in [begin, end)
    int right;               // inner nodes: the right child (the left one is next); leaves: -1
  };
  double root_lo_[3] = {0, 0, 0}, root_hi_[3] = {0, 0, 0};
  std::vector<double> xyz_;  // the points in leaf order, packed
  std::vector<int> index_;   // leaf order -> index given
  std::vector<int> slot_;    // index given -> leaf order
  std::vector<Node> nodes_;  // pre-order
};

}  // namespace mm

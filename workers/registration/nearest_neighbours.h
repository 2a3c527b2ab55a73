// Exact nearest-neighbour queries on a fixed point set (uniform grid of cells in compressed
// row form), for matching a suspect's vertices to an original's when their order was lost.
#pragma once
#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "meshio/mesh.h"

namespace mm {

class PointGrid {
 public:
  // Keeps a copy of the points; cells hold about two points on average.
  explicit PointGrid(Points points);
  int size() const { return static_cast<int>(points_.rows()); }
  const Points& points() const { return points_; }
  // Index of the nearest point (ties: lowest index) and its squared distance; -1 when empty.
  // Queries far outside the points' box cost no more than those inside.
  int nearest(const Eigen::Vector3d& q, double* squared_distance = nullptr) const;
  // Heap bytes held (the copy of the points and the cell lists), for callers that budget memory.
  std::size_t memory_bytes() const;

 private:
  Points points_;
  Eigen::Vector3d lo_ = Eigen::Vector3d::Zero(), hi_ = Eigen::Vector3d::Zero();
  double cell_ = 1;
  Eigen::Vector3i dims_ = Eigen::Vector3i::Ones();
  std::vector<int> start_, index_;  // cell c holds index_[start_[c] .. start_[c + 1])
};

}  // namespace mm

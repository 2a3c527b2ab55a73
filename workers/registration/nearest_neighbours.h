// Exact nearest-neighbour queries on a fixed point set (uniform hash grid), for matching a
// suspect's vertices to an original's when their order was lost.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <unordered_map>
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
  int nearest(const Eigen::Vector3d& q, double* squared_distance = nullptr) const;

 private:
  Eigen::Vector3i cell_of(const Eigen::Vector3d& q) const;
  static std::int64_t key(const Eigen::Vector3i& c);
  Points points_;
  Eigen::Vector3d lo_ = Eigen::Vector3d::Zero();
  double cell_ = 1;
  int max_ring_ = 1;
  Eigen::Vector3i hi_cell_ = Eigen::Vector3i::Zero();
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

}  // namespace mm

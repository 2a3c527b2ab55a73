#include "registration/nearest_neighbours.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace mm {

PointGrid::PointGrid(Points points) : points_(std::move(points)) {
  if (points_.rows() == 0) return;
  lo_ = points_.colwise().minCoeff().transpose();
  const Eigen::Vector3d hi = points_.colwise().maxCoeff().transpose();
  const Eigen::Vector3d ext = hi - lo_;
  const double side = ext.maxCoeff();
  // Flat or thin sets: the volume of the non-degenerate extent decides the cell size.
  const double floor_side = std::max(side * 1e-3, 1e-300);
  const double volume = ext.cwiseMax(floor_side).prod();
  cell_ = std::cbrt(volume * 2.0 / static_cast<double>(points_.rows()));
  cell_ = std::max(cell_, floor_side);
  if (!(cell_ > 0) || !std::isfinite(cell_)) cell_ = 1;
  max_ring_ = static_cast<int>(std::ceil(side / cell_)) + 2;
  hi_cell_ = cell_of(hi);
  for (Eigen::Index i = 0; i < points_.rows(); ++i)
    cells_[key(cell_of(points_.row(i).transpose()))].push_back(static_cast<int>(i));
}

Eigen::Vector3i PointGrid::cell_of(const Eigen::Vector3d& q) const {
  Eigen::Vector3d f = ((q - lo_) / cell_).array().floor();
  f = f.cwiseMax(-1e6).cwiseMin(1e6);
  return f.cast<int>();
}

std::int64_t PointGrid::key(const Eigen::Vector3i& c) {
  return (std::int64_t(c[0]) * 73856093) ^ (std::int64_t(c[1]) * 19349663) ^
         (std::int64_t(c[2]) * 83492791);
}

int PointGrid::nearest(const Eigen::Vector3d& q, double* squared_distance) const {
  int best = -1;
  double best_d = std::numeric_limits<double>::infinity();
  if (points_.rows() == 0) return best;
  const Eigen::Vector3i c = cell_of(q);
  // A query far outside the grid: the ring search would be long, a linear scan is exact.
  const int outside = std::max({0, (-c).maxCoeff(), (c - hi_cell_).maxCoeff()});
  if (outside > 4) {
    for (Eigen::Index i = 0; i < points_.rows(); ++i) {
      const double d = (points_.row(i).transpose() - q).squaredNorm();
      if (d < best_d) best_d = d, best = static_cast<int>(i);
    }
  } else {
    for (int ring = 0; ring <= max_ring_ + outside; ++ring) {
      for (int dx = -ring; dx <= ring; ++dx)
        for (int dy = -ring; dy <= ring; ++dy)
          for (int dz = -ring; dz <= ring; ++dz) {
            if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != ring) continue;
            auto it = cells_.find(key(c + Eigen::Vector3i(dx, dy, dz)));
            if (it == cells_.end()) continue;
            for (int i : it->second) {
              const double d = (points_.row(i).transpose() - q).squaredNorm();
              if (d < best_d || (d == best_d && i < best)) best_d = d, best = i;
            }
          }
      // Everything outside ring r is at least r * cell away from q's cell.
      if (best >= 0 && std::sqrt(best_d) <= ring * cell_) break;
    }
  }
  if (squared_distance) *squared_distance = best_d;
  return best;
}

}  // namespace mm

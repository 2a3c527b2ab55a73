#include "registration/nearest_neighbours.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace mm {

PointGrid::PointGrid(Points points) : points_(std::move(points)) {
  const Eigen::Index n = points_.rows();
  if (n == 0) return;
  lo_ = points_.colwise().minCoeff().transpose();
  hi_ = points_.colwise().maxCoeff().transpose();
  const Eigen::Vector3d ext = hi_ - lo_;
  const double side = ext.maxCoeff();
  // Flat or thin sets: the volume of the non-degenerate extent decides the cell size.
  const double floor_side = std::max(side * 1e-3, 1e-300);
  const double volume = ext.cwiseMax(floor_side).prod();
  cell_ = std::max(std::cbrt(volume * 2.0 / static_cast<double>(n)), floor_side);
  if (!(cell_ > 0) || !std::isfinite(cell_)) cell_ = 1;
  // Rounding up every axis can multiply the cell count on thin sets: grow cells until bounded.
  for (;;) {
    for (int a = 0; a < 3; ++a) dims_[a] = static_cast<int>(std::floor(ext[a] / cell_)) + 1;
    if (static_cast<double>(dims_[0]) * dims_[1] * dims_[2] <= 4.0 * static_cast<double>(n) + 64) break;
    cell_ *= 1.25;
  }
  const auto cell_index = [&](Eigen::Index i) {
    Eigen::Vector3i c;
    for (int a = 0; a < 3; ++a)
      c[a] = std::clamp(static_cast<int>(std::floor((points_(i, a) - lo_[a]) / cell_)), 0, dims_[a] - 1);
    return (c[0] * dims_[1] + c[1]) * dims_[2] + c[2];
  };
  const int cells = dims_[0] * dims_[1] * dims_[2];
  start_.assign(static_cast<size_t>(cells) + 1, 0);
  std::vector<int> of(static_cast<size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) ++start_[(of[i] = cell_index(i)) + 1];
  for (int c = 0; c < cells; ++c) start_[c + 1] += start_[c];
  index_.resize(static_cast<size_t>(n));
  std::vector<int> fill(start_.begin(), start_.end() - 1);
  for (Eigen::Index i = 0; i < n; ++i) index_[fill[of[i]]++] = static_cast<int>(i);
}

int PointGrid::nearest(const Eigen::Vector3d& q, double* squared_distance) const {
  int best = -1;
  double best_d = std::numeric_limits<double>::infinity();
  if (points_.rows() == 0) return best;
  // Project q onto the points' box: for every point p in the box,
  // |q - p|^2 >= |q - q'|^2 + |q' - p|^2, so rings around q' bound the distances from q too.
  const Eigen::Vector3d qp = q.cwiseMax(lo_).cwiseMin(hi_);
  const double outside2 = (q - qp).squaredNorm();
  Eigen::Vector3i c;
  for (int a = 0; a < 3; ++a)
    c[a] = std::clamp(static_cast<int>(std::floor((qp[a] - lo_[a]) / cell_)), 0, dims_[a] - 1);
  const int max_ring = dims_.maxCoeff();
  for (int ring = 0; ring <= max_ring; ++ring) {
    const int x0 = std::max(0, c[0] - ring), x1 = std::min(dims_[0] - 1, c[0] + ring);
    const int y0 = std::max(0, c[1] - ring), y1 = std::min(dims_[1] - 1, c[1] + ring);
    const int z0 = std::max(0, c[2] - ring), z1 = std::min(dims_[2] - 1, c[2] + ring);
    for (int x = x0; x <= x1; ++x)
      for (int y = y0; y <= y1; ++y) {
        const bool x_or_y_on_ring = std::abs(x - c[0]) == ring || std::abs(y - c[1]) == ring;
        // Only the ring's shell: inner cells were searched before.
        for (int z = z0; z <= z1; z += (x_or_y_on_ring || z1 == z0) ? 1 : std::max(1, z1 - z0)) {
          if (!x_or_y_on_ring && std::abs(z - c[2]) != ring) continue;
          const int cell = (x * dims_[1] + y) * dims_[2] + z;
          for (int k = start_[cell]; k < start_[cell + 1]; ++k) {
            const int i = index_[k];
            const double d = (points_.row(i).transpose() - q).squaredNorm();
            if (d < best_d || (d == best_d && i < best)) best_d = d, best = i;
          }
        }
      }
    // Cells beyond this ring are at least ring * cell away from q' (q' is inside its cell).
    const double reach = ring * cell_;
    if (best >= 0 && best_d <= outside2 + reach * reach) break;
  }
  if (squared_distance) *squared_distance = best_d;
  return best;
}

std::size_t PointGrid::memory_bytes() const {
  return static_cast<std::size_t>(points_.size()) * sizeof(double) +
         (start_.capacity() + index_.capacity()) * sizeof(int);
}

}  // namespace mm

#include "meshio/normalize.h"

#include <stdexcept>

namespace mm {

Normalization unit_box_normalization(const Points& points) {
  Normalization n;
  if (points.rows() == 0) return n;
  Eigen::Vector3d lo = points.colwise().minCoeff().transpose();
  Eigen::Vector3d hi = points.colwise().maxCoeff().transpose();
  double side = (hi - lo).maxCoeff();
  if (!(side > 0)) throw std::invalid_argument("degenerate bounding box: all points coincide");
  n.offset = lo;
  n.scale = 1.0 / side;
  return n;
}

void apply(const Normalization& n, Points& points) {
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    points.row(i) = n.apply(points.row(i).transpose()).transpose();
}

void undo(const Normalization& n, Points& points) {
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    points.row(i) = n.undo(points.row(i).transpose()).transpose();
}

}  // namespace mm

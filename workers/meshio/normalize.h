// The paper normalises every object into the unit bounding box before processing.
// The transform is kept so results can be mapped back to the part's own units.
#pragma once
#include <Eigen/Core>

#include "meshio/mesh.h"

namespace mm {

// p_normalized = (p - offset) * scale; the largest box side becomes 1, the box min goes to 0.
struct Normalization {
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  double scale = 1.0;
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return (p - offset) * scale; }
  Eigen::Vector3d undo(const Eigen::Vector3d& q) const { return q / scale + offset; }
};

Normalization unit_box_normalization(const Points& points);
void apply(const Normalization& n, Points& points);
void undo(const Normalization& n, Points& points);

}  // namespace mm

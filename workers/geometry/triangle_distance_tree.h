// Squared distances from points to a fixed set of triangles, with exactly the numbers of CGAL's
// AABB tree (AABB_tree::squared_distance after accelerate_distance_queries(), which the quality
// code used before): the same projection (CGAL's Construct_projected_point_3) and the same
// starting point (the nearest first vertex of a triangle), so reports and compress decisions
// stay bit for bit what they were. What is faster: a tree with a binned surface-area split and a
// box per triangle (most triangles in a visited leaf are skipped before projecting), and a
// query can start from the triangle that answered the previous, nearby query instead of a
// kd-tree search (samples come in triangle order).
#pragma once
#include <Eigen/Core>
#include <array>
#include <memory>
#include <vector>

#include "geometry/bvh_layout.h"

namespace mm {

class TriangleDistanceTree {
 public:
  // Triangles as corner triples (at least one; degenerate ones should be left out by the caller,
  // as CGAL's tree was given them).
  explicit TriangleDistanceTree(const std::vector<std::array<Eigen::Vector3d, 3>>& triangles);
  // The same on the layout of another tree over as many triangles (layout()): its boxes are
  // computed for these corners, its split kept. Every answer is the same as with the tree's own
  // layout (a distance is the minimum over all triangles, ties go to the first in the list);
  // only the work per query may differ. For surfaces that differ by small moves of the same
  // triangles (a control polyhedron's streams at several grids), the split costs more than the
  // queries of a rejected candidate. Throws std::invalid_argument when the counts differ.
  TriangleDistanceTree(const std::vector<std::array<Eigen::Vector3d, 3>>& triangles,
                       std::shared_ptr<const BvhLayout> layout);
  std::shared_ptr<const BvhLayout> layout() const;
  ~TriangleDistanceTree();
  TriangleDistanceTree(const TriangleDistanceTree&) = delete;
  TriangleDistanceTree& operator=(const TriangleDistanceTree&) = delete;
  // Squared distance from q to the triangles. `hint` (in/out): where the previous query's answer
  // was, to start from (-1 or any out-of-range value: nowhere); an opaque position, not the
  // triangle's index. The answer does not depend on it.
  double squared_distance(const Eigen::Vector3d& q, int& hint) const;
  // Whether squared_distance(q) is certainly at most r * r: true when some triangle lies within r
  // less the rounding slack the tree allows between its cheap distance and CGAL's (so a distance
  // within a few ulps of r gives false, and the caller measures it). Stops at the first such
  // triangle, `hint`'s first: a tolerance check then costs one triangle per sample near the
  // surface instead of a search for the closest. `hint` as for squared_distance (a triangle found
  // within r afterwards, not necessarily the closest).
  bool within(const Eigen::Vector3d& q, double r, int& hint) const;
  // The index (in the constructor's list) of the triangle a query's `hint` names afterwards: the
  // closest one (of equally close ones, the first in the constructor's list, whatever the hint).
  int triangle_of(int hint) const;
  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace mm

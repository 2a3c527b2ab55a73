// Closest points on triangles and segments whose vertices move while the primitives stay the
// same: a bounding volume hierarchy built once and refitted (boxes recomputed bottom-up, the
// tree kept) after the points move. The fit queries its moving subdivided surface and creases in
// every iteration and the target in every round; CGAL's AABB trees (closest_point.h) have to be
// rebuilt for every move and need a kd-tree search to start a query without a hint, which was a
// third of compress()'s instructions. Answers are exact closest points (up to rounding); which
// primitive reports a point shared by several (an edge, a vertex) is the first one found.
#pragma once
#include <Eigen/Core>
#include <array>
#include <memory>
#include <utility>
#include <vector>

#include "geometry/closest_point.h"
#include "meshio/mesh.h"

namespace mm {

class TriangleBvh {
 public:
  // Triangles as vertex index triples into `points`. Degenerate triangles (zero area) are never
  // reported; they may become regular after a refit and are then found.
  TriangleBvh(const Points& points, std::vector<std::array<int, 3>> triangles);
  ~TriangleBvh();
  TriangleBvh(const TriangleBvh&) = delete;
  TriangleBvh& operator=(const TriangleBvh&) = delete;
  // The same triangles over moved points (at least as many rows as the largest index).
  void refit(const Points& points);
  // No triangle with a non-zero area.
  bool empty() const;
  TriangleHit closest(const Eigen::Vector3d& q) const { return closest(q, -1); }
  // The same, starting from a triangle near the answer (a previous answer): its distance bounds
  // the search from the start. Any index is accepted (-1: none); the answer depends on it only
  // through ties.
  TriangleHit closest(const Eigen::Vector3d& q, int start_triangle) const;
  const std::array<int, 3>& triangle(int t) const { return triangles_[static_cast<size_t>(t)]; }
  int size() const { return static_cast<int>(triangles_.size()); }
  // Where triangle t sits in the tree's leaf order (0..size()-1): queries made in this order
  // of their answers' triangles walk the tree's memory in step (no answer changes).
  int leaf_position(int t) const;
  struct Impl;

 private:
  std::vector<std::array<int, 3>> triangles_;
  std::unique_ptr<Impl> impl_;
};

class SegmentBvh {
 public:
  // Segments as vertex index pairs into `points`; zero-length ones are never reported.
  SegmentBvh(const Points& points, std::vector<std::pair<int, int>> segments);
  ~SegmentBvh();
  SegmentBvh(const SegmentBvh&) = delete;
  SegmentBvh& operator=(const SegmentBvh&) = delete;
  void refit(const Points& points);
  bool empty() const;
  SegmentHit closest(const Eigen::Vector3d& q) const { return closest(q, -1); }
  SegmentHit closest(const Eigen::Vector3d& q, int start_segment) const;
  const std::pair<int, int>& segment(int s) const { return segments_[static_cast<size_t>(s)]; }
  struct Impl;

 private:
  std::vector<std::pair<int, int>> segments_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mm

// Closest-point answers on triangles and segments (which primitive was hit and where on it, so a
// hit can be expressed in the primitive's vertices), and a triangle index for fixed triangle sets
// (registration, evidence), on the fit's bounding volume hierarchy (closest_point_bvh.h).
#pragma once
#include <Eigen/Core>
#include <array>
#include <memory>
#include <vector>

#include "meshio/mesh.h"

namespace mm {

struct TriangleHit {
  int triangle = -1;              // index into the triangles given to the index
  Eigen::Vector3d point;          // closest point
  Eigen::Vector3d barycentric;    // weights of the triangle's three vertices
  double distance = 0;
};

struct SegmentHit {
  int segment = -1;
  Eigen::Vector3d point;
  double t = 0;                   // point = (1 - t) * a + t * b
  double distance = 0;
};

class TriangleIndex {
 public:
  // Triangles as vertex index triples into `points`; degenerate ones are never reported.
  TriangleIndex(const Points& points, std::vector<std::array<int, 3>> triangles);
  ~TriangleIndex();
  TriangleIndex(const TriangleIndex&) = delete;
  TriangleIndex& operator=(const TriangleIndex&) = delete;
  bool empty() const;
  TriangleHit closest(const Eigen::Vector3d& q) const;
  // The same, starting from a triangle near the answer (a previous answer; -1: none): much
  // faster when queries move little, and the answer changes only among ties.
  TriangleHit closest(const Eigen::Vector3d& q, int start_triangle) const;
  const std::array<int, 3>& triangle(int t) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Closest points for numbered queries that move little between calls (ICP rounds): each number
// remembers its last answer as the next query's hint. Answers are those of TriangleIndex::closest.
class HintedClosest {
 public:
  explicit HintedClosest(const TriangleIndex& index) : index_(index) {}
  TriangleHit closest(const Eigen::Vector3d& q, Eigen::Index number);

 private:
  const TriangleIndex& index_;
  std::vector<int> hints_;  // per number, the triangle of its last answer (-1: none yet)
};

// Fan triangulation of every face (triangles and quads alike), as index triples.
std::vector<std::array<int, 3>> triangle_list(const Mesh& mesh);

}  // namespace mm

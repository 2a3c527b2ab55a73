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

// A previous answer near the query, to start from (much faster when queries move little).
struct TriangleHint {
  int triangle = -1;
  Eigen::Vector3d point;  // must lie on that triangle (current positions)
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
  TriangleHit closest(const Eigen::Vector3d& q, const TriangleHint& hint) const;
  const std::array<int, 3>& triangle(int t) const { return triangles_[t]; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<std::array<int, 3>> triangles_;
};

// Closest points for numbered queries that move little between calls (ICP rounds): each number
// remembers its last answer as the next query's hint. Answers are those of TriangleIndex::closest.
class HintedClosest {
 public:
  explicit HintedClosest(const TriangleIndex& index) : index_(index) {}
  TriangleHit closest(const Eigen::Vector3d& q, Eigen::Index number);

 private:
  const TriangleIndex& index_;
  std::vector<TriangleHint> hints_;
};

// Fan triangulation of every face (triangles and quads alike), as index triples.
std::vector<std::array<int, 3>> triangle_list(const Mesh& mesh);

}  // namespace mm

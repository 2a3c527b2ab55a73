// Stam & Loop quad/triangle subdivision with infinitely sharp creases and corners (Loop rules on
// triangles, Catmull-Clark on quads), as a sparse linear operator built once per topology:
// refined points = S * control points. Same operator for every customer copy of an asset.
#pragma once
#include <Eigen/Sparse>

#include "meshio/mesh.h"

namespace mm {

struct SubdivisionOperator {
  Eigen::SparseMatrix<double, Eigen::RowMajor> S;  // refined_vertices x control_vertices
  Mesh refined;  // topology after `levels` steps (points = S * control points), creases carried
};

SubdivisionOperator build_subdivision(const Mesh& control, int levels);

// Convenience: the refined mesh with positions.
Mesh subdivide(const Mesh& control, int levels);

}  // namespace mm

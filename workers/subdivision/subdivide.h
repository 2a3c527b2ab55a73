// Stam & Loop quad/triangle subdivision with infinitely sharp creases and corners (Loop rules on
// triangles, Catmull-Clark on quads), as a sparse linear operator built once per topology:
// refined points = S * control points. Same operator for every customer copy of an asset.
//
// Rules, weights and vertex ordering: docs/subdivision.md. In short, each step numbers the
// refined vertices [children of vertices (same index as the parent), face points of non-triangle
// faces (face order), edge points (edge order)], exactly as OpenSubdiv 3.5 numbers its uniform
// refinement levels, so on all-triangle (all-quad) meshes S equals OpenSubdiv's Loop
// (Catmull-Clark) stencils row for row. Boundary edges act as infinitely sharp creases
// (OpenSubdiv's VTX_BOUNDARY_EDGE_ONLY). Polygons with more than 4 sides get a Catmull-Clark
// split in their first step. Non-manifold edges, inconsistent orientation and bad indices are
// rejected with mm::InputError; non-manifold vertices (several fans) are kept fixed as corners.
#pragma once
#include <Eigen/Sparse>
#include <array>
#include <utility>
#include <vector>

#include "meshio/mesh.h"

namespace mm {

using SparseOperator = Eigen::SparseMatrix<double, Eigen::RowMajor>;

struct SubdivisionOperator {
  SparseOperator S;  // refined_vertices x control_vertices
  Mesh refined;      // topology after `levels` steps (points = S * control points), creases carried
  // One matrix per step (steps[k] maps level k to level k+1), S = steps[L-1] * ... * steps[0].
  // Applying the steps one after another is several times cheaper than applying S.
  std::vector<SparseOperator> steps;
};

// Largest accepted number of steps and refined vertices (a guard against over-allocation).
constexpr int kMaxSubdivisionLevels = 8;
constexpr long long kMaxRefinedVertices = 5'000'000;
constexpr long long kMaxOperatorTerms = 100'000'000;  // products summed while composing S

// Throws mm::InputError (source "subdivision control mesh") for out-of-range indices, faces with
// fewer than 3 or repeated vertices, edges shared by more than two faces or traversed twice in the
// same direction, creases that are not edges, corners out of range, non-finite points;
// std::invalid_argument for levels outside [0, kMaxSubdivisionLevels] or a too large result
// (refined vertices, or terms while composing S around very high-valence vertices).
SubdivisionOperator build_subdivision(const Mesh& control, int levels);

// The refined topology as flat lists, for a caller that positions the refined vertices itself
// (the fit): no per-face vectors, no refined points.
struct RefinedTopology {
  std::vector<std::array<int, 3>> triangles;  // faces fanned from their first corner, in face order
  std::vector<std::pair<int, int>> creases;   // as SubdivisionOperator::refined.creases
  std::vector<std::pair<int, int>> boundary;  // edges of one face only, (min, max), in edge order
};

// S of build_subdivision(control, levels) (the same matrix) and the refined topology, without
// the refined Mesh, its points and the steps. Same errors.
SparseOperator subdivision_operator(const Mesh& control, int levels, RefinedTopology& topology);

// Vertex counts of levels 0..levels (element L: rows of build_subdivision(control, L).S) from
// the topology alone, without building anything: a caller can tell which level a mesh could be
// before paying for that level. Same InputErrors as build_subdivision (the topology is checked);
// counts beyond kMaxRefinedVertices are not exact (the caller would be refused the level anyway).
std::vector<long long> subdivision_vertex_counts(const Mesh& control, int levels);

// Refined positions for new control points of the same topology (faster than op.S * points).
Points apply_subdivision(const SubdivisionOperator& op, const Points& control_points);

// The refined mesh with positions, for decompression: evaluates the same rules on the points
// level by level without forming S (equal to build_subdivision(...).refined up to rounding).
// Same errors as build_subdivision except the limit on S.
Mesh subdivide(const Mesh& control, int levels);

// Splits every triangle and quad into four at its edges' midpoints (and the quad's centre),
// `levels` times: the same surface, four times the faces per level, no vertex moved. The result
// has no crease tags. Same errors as subdivide.
Mesh subdivide_linear(Mesh mesh, int levels);

}  // namespace mm

// Decompression: a control polyhedron refined to a display level, or to the smallest level that
// reaches a requested triangle count, and triangulation for formats that only hold triangles (STL).
#pragma once
#include "meshio/mesh.h"

namespace mm {

// Triangles the mesh would have after triangulate(): a triangle counts 1, an n-gon n - 2.
long long triangle_count(const Mesh& mesh);

// Triangles after `levels` steps of subdivide() and triangulate(), computed from the topology only.
long long subdivided_triangle_count(const Mesh& control, int levels);

// Smallest level in [0, max_level] whose triangulated result has at least `target_triangles`
// triangles (max_level when none does, or a lower level when the next one would exceed
// about 2 * kMaxRefinedVertices triangles).
int level_for_triangle_count(const Mesh& control, long long target_triangles, int max_level = 6);

// The subdivided mesh (triangles and quads) at `levels`.
Mesh decompress_to_level(const Mesh& control, int levels);

// The subdivided mesh at level_for_triangle_count(control, target_triangles, max_level).
Mesh decompress_to_triangle_count(const Mesh& control, long long target_triangles, int max_level = 6);

// Quads split along their shorter diagonal (the flatter choice), other polygons fanned from their
// first vertex. Vertices, creases and corners are kept.
Mesh triangulate(const Mesh& mesh);

}  // namespace mm

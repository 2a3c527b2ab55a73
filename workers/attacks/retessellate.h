// Attacks that give the surface a new connectivity, as a leaker's mesh tool does: isotropic
// remeshing, simplification, re-extraction of a new surface around the part (a modelling tool's
// voxel remesh). (A midpoint split is subdivision's subdivide_linear.) Lengths are relative to the bounding-box diagonal. The input is
// triangulated first; the results are triangle meshes. Deterministic: CGAL's algorithms use no
// randomness here, so the same input gives the same mesh.
#pragma once
#include "meshio/mesh.h"

namespace mm::attacks {

// CGAL::Polygon_mesh_processing::isotropic_remeshing to edges of `edge_length` x diagonal,
// `iterations` rounds, sharp edges (dihedral angle above 60 degrees) kept as constraints as a CAD
// tool would. Throws InputError("remesh", reason) for a mesh CGAL cannot take (not a polygon mesh).
Mesh remesh_isotropic(const Mesh& mesh, double edge_length, int iterations = 3);

// CGAL's edge-collapse simplification (Lindstrom-Turk placement and cost) until `keep_fraction`
// of the edges remain, keep_fraction in (0, 1].
Mesh simplify_edges(const Mesh& mesh, double keep_fraction);

// CGAL::alpha_wrap_3: a watertight surface around the part, alpha and offset x diagonal (CGAL
// 5.5's defaults for a close wrap: offset alpha / 30).
Mesh alpha_wrap(const Mesh& mesh, double alpha, double offset);

}  // namespace mm::attacks

// Half-edge collapse on a control polyhedron (triangles and quads) that keeps its crease
// network: the step by which compress() coarsens a polyhedron that already meets the tolerance.
//
// Why on the control mesh and not on the part: the refinement rounds decimate the part afresh
// for every vertex count, so which count meets the tolerance varies by 10-20 % with the path
// the decimation takes. Removing one control vertex at a time from a fitted polyhedron, and
// fitting again, searches the counts below the rounds' smallest one from a solution that is
// already close.
#pragma once
#include <optional>

#include "meshio/mesh.h"

namespace mm {

// Removes vertex `v` by moving it onto its neighbour `t` (t keeps its position); the faces on
// edge (v, t) go (a quad on it loses v and becomes a triangle), and v's other faces take t.
// Crease edges of v become t's. Refused (nullopt)
// when the result would change the crease network or the surface's topology:
// - v is a corner, lies on an open boundary, or has a crease count other than 0 or 2;
// - v is on a crease and (v, t) is not one of its crease edges (a crease may only shorten
//   along itself);
// - the link condition fails (v and t share a neighbour that is not opposite edge (v, t)), or
//   fewer than five vertices would remain;
// - a face of v turns by more than 90 degrees when v moves onto t (the fit starts from a
//   folded surface otherwise);
// - a face around v is neither a triangle nor a quad, or a quad holds v and t opposite.
// Indices above v move down by one; creases and corners are renumbered and stay sorted.
std::optional<Mesh> collapse_control_vertex(const Mesh& control, int v, int t);

}  // namespace mm

// Rail quads: triangle pairs of a control polyhedron that span a strip between two crease
// curves (an extrusion or cylinder wall, a cone, a step) merged into quads.
//
// Why: on a strip whose two rails are creases every vertex lies on a rail, and where the rails'
// vertices are offset (as decimation leaves them) Loop's rules pull the strip's interior
// towards the chords of its long diagonals: a round wall sags and needs many rail vertices to
// stay within tolerance. Catmull-Clark on a one-quad-high strip between two crease curves is
// exactly the ruled surface between the two cubic B-spline rails: it sags only by the rails'
// offset, a third of the triangles' at half a step (tests/fitting/test_rail_quads.cpp).
#pragma once
#include "meshio/mesh.h"

namespace mm {

// Merges triangle pairs across a non-crease edge into a quad when two opposite edges of the
// quad are creases, the two triangles fold by at most `max_fold_degrees`, and the quad is a
// strip cell (convex, corners of 30-150 degrees, rails within 45 degrees of parallel). A triangle joins
// at most one quad; candidates are taken flattest first (ties by vertex indices), so the result
// is deterministic. Vertices, creases and corners are unchanged; other faces are kept as they
// are. Orientation is kept: the quad follows both triangles' vertex order.
Mesh pair_rail_quads(const Mesh& control, double max_fold_degrees = 60.0);

}  // namespace mm

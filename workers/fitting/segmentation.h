// Segmentation into surface patches bounded by sharp edges, and the boundary network: the sharp
// edges chained into polylines that run from corner to corner (or around closed loops).
// The paper segments into near-constant-curvature patches [15]; on CAD parts the sharp-edge
// network is the dominant part of that boundary, and it is what the control polyhedron's creases
// must follow, so the patches here are the regions enclosed by it.
#pragma once
#include <vector>

#include "fitting/sharp_features.h"
#include "meshio/mesh.h"

namespace mm {

struct Segmentation {
  std::vector<int> face_patch;  // per face: patch id in [0, num_patches)
  int num_patches = 0;
  // Boundary network: vertex chains along sharp edges. An open chain starts and ends at corners;
  // a closed loop (no corner on it) repeats its first vertex at the end.
  std::vector<std::vector<int>> polylines;
};

Segmentation segment(const Mesh& mesh, const Features& features);

}  // namespace mm

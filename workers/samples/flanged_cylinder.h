// A tube with a flange at its base: bore, tube wall, flange disc, and a 45-degree chamfer on
// the tube's top outer edge; a surface of revolution with sharp circular feature edges.
#pragma once
#include "meshio/mesh.h"

namespace mm::samples {

struct FlangedCylinder {
  double bore_radius = 8, tube_radius = 12, flange_radius = 22;  // mm
  double flange_thickness = 5, height = 30, top_chamfer = 1.5;
  int sectors = 48;            // angular divisions
  double edge_length = 2.5;    // target profile segment length
};

// Closed, manifold, outward-oriented quad mesh, axis along z, base at z = 0.
Mesh flanged_cylinder(const FlangedCylinder& p = {});

}  // namespace mm::samples

// A rectangular block with every one of its 12 edges chamfered at 45 degrees: 6 flat faces,
// 12 chamfer strips, 8 corner triangles, all meeting at sharp edges (the classic
// chamfer-cube, refined into a regular grid of about edge_length).
#pragma once
#include "meshio/mesh.h"

namespace mm::samples {

struct ChamferedBlock {
  double size_x = 40, size_y = 30, size_z = 20;  // mm
  double chamfer = 4;                            // leg length of each chamfer
  double edge_length = 2.5;                      // target tessellation
};

// Closed, manifold, outward-oriented quads and triangles; the box spans [0, size].
Mesh chamfered_block(const ChamferedBlock& p = {});

}  // namespace mm::samples

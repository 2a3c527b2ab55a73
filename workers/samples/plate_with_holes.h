// A flat rectangular plate with cylindrical through-holes: a grid of square cells, some with a
// hole in the middle. Each holed cell is meshed as rings of quads blending the hole circle into
// the cell square, so elements stay well shaped; the 2D layout is extruded to the thickness.
// Sharp features: the plate's outline, its top and bottom rims, both rims of every hole.
#pragma once
#include <utility>
#include <vector>

#include "meshio/mesh.h"

namespace mm::samples {

struct PlateWithHoles {
  int cells_x = 3, cells_y = 2;
  double cell = 20;              // mm, square cell side
  double hole_radius = 5;        // < cell / 2
  double thickness = 6;
  int segments_per_side = 8;     // cell side divisions (even); a hole gets 4x as many
  int rings = 3;                 // quad rings between hole and cell square
  int layers = 2;                // divisions through the thickness
  std::vector<std::pair<int, int>> holes = {{0, 0}, {2, 0}, {0, 1}, {2, 1}};  // (cx, cy)
};

// Closed, manifold, outward-oriented quad mesh; the plate spans [0, cells*cell] x [0, thickness].
Mesh plate_with_holes(const PlateWithHoles& p = {});

}  // namespace mm::samples

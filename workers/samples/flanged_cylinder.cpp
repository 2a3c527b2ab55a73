#include "samples/flanged_cylinder.h"

#include <stdexcept>

#include "samples/shape_building.h"

namespace mm::samples {

Mesh flanged_cylinder(const FlangedCylinder& p) {
  if (!(0 < p.bore_radius && p.bore_radius + p.top_chamfer < p.tube_radius && p.tube_radius < p.flange_radius &&
        0 < p.flange_thickness && p.flange_thickness + p.top_chamfer < p.height && p.top_chamfer > 0 &&
        p.sectors >= 3 && p.edge_length > 0))
    throw std::invalid_argument("flanged_cylinder: invalid dimensions");
  // Counter-clockwise in the (r, z) plane: along the base outwards, up the flange rim, in over
  // the flange top, up the tube, across the chamfer and the top, down the bore.
  std::vector<Eigen::Vector2d> profile = {
      {p.bore_radius, 0},
      {p.flange_radius, 0},
      {p.flange_radius, p.flange_thickness},
      {p.tube_radius, p.flange_thickness},
      {p.tube_radius, p.height - p.top_chamfer},
      {p.tube_radius - p.top_chamfer, p.height},
      {p.bore_radius, p.height},
  };
  return revolve(subdivide_polygon(profile, p.edge_length), p.sectors);
}

}  // namespace mm::samples

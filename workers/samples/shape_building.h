// Building blocks for the sample parts: refine a coarse polygon mesh into a regular grid,
// extrude a 2D region, revolve a profile. Each gives closed, consistently oriented meshes
// when its input is closed (refine) or a simple region / closed profile (extrude, revolve).
#pragma once
#include <Eigen/Core>
#include <functional>
#include <vector>

#include "meshio/mesh.h"

namespace mm::samples {

// Splits every coarse edge into segments(a, b) equal parts (must be symmetric in a, b), each
// quad into an n x m grid and each triangle into k^2 triangles. Quads need equal counts on
// opposite edges and triangles equal counts on all three; edge points are shared by the faces
// on both sides, so a closed input stays closed and manifold.
Mesh refine(const Mesh& coarse, const std::function<int(int, int)>& segments);

// A planar region: 2D points and counter-clockwise faces (holes are boundary loops).
struct Region {
  std::vector<Eigen::Vector2d> points;
  std::vector<std::vector<int>> faces;
};

// Prism over the region from z = 0 to z = height, side walls split into `layers` rows.
// Outward orientation: top along +z, bottom reversed, walls facing away from the region.
Mesh extrude(const Region& region, double height, int layers);

// Surface of revolution of a closed profile polygon in the (r, z) half-plane (r > 0,
// counter-clockwise with r as x and z as y) around the z axis, in `sectors` angular steps.
Mesh revolve(const std::vector<Eigen::Vector2d>& profile, int sectors);

// Splits each profile segment into pieces no longer than edge_length (the corners stay).
std::vector<Eigen::Vector2d> subdivide_polygon(const std::vector<Eigen::Vector2d>& polygon, double edge_length);

}  // namespace mm::samples

// Software picture of a mesh: orthographic view, flat shading with a fixed light, optional wire
// edges and red crease edges. Used for the pictures of an original part, its control polyhedron
// with creases, and the decoded surface.
#pragma once
#include <Eigen/Core>
#include <optional>
#include <vector>

#include "meshio/mesh.h"
#include "render/image.h"

namespace mm {

struct Camera {
  // Direction towards the camera as seen from the object's centre, in degrees around the up axis
  // and above the horizontal plane.
  double azimuth_deg = 35, elevation_deg = 25;
  int up_axis = 2;     // 0 = x, 1 = y, 2 = z is up
  double zoom = 1.0;   // 1 fits the framing sphere into the image with a small margin
  // Framing sphere (centre, radius). When absent the mesh's bounding box sphere is used; give it
  // explicitly to draw several meshes of the same part with identical framing.
  std::optional<std::pair<Eigen::Vector3d, double>> frame;
};

struct RenderOptions {
  int width = 800, height = 600;
  Rgb background = colours::white;
  Rgb surface = {175, 190, 215};
  std::vector<Rgb> face_colours;  // one per face (a heat map) instead of `surface`; else ignored
  bool draw_wire = false;       // every polygon edge in dark grey
  bool draw_creases = true;     // mesh.creases in red, two pixels wide
  bool draw_corners = false;    // mesh.corners as small red squares
  Rgb wire = {60, 60, 60};
  Rgb crease = colours::red;
};

// Framing sphere of a mesh: bounding box centre and half diagonal.
std::pair<Eigen::Vector3d, double> bounding_sphere(const Mesh& mesh);

// Renders the mesh. Faces with out-of-range indices or fewer than 3 vertices, and crease or corner
// indices out of range, throw InputError("render", reason); an empty mesh gives an empty picture.
Image render_mesh(const Mesh& mesh, const Camera& camera = {}, const RenderOptions& options = {});

}  // namespace mm

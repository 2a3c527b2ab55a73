#include "render/render_mesh.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <string>

namespace mm {

std::pair<Eigen::Vector3d, double> bounding_sphere(const Mesh& mesh) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    const Eigen::Vector3d p = mesh.points.row(i).transpose();
    if (!p.allFinite()) continue;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  if (!(lo.array() <= hi.array()).all()) return {Eigen::Vector3d::Zero(), 1.0};
  const double r = 0.5 * (hi - lo).norm();
  return {0.5 * (lo + hi), r > 0 ? r : 1.0};
}

namespace {

void validate(const Mesh& mesh) {
  const int n = mesh.num_vertices();
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    if (mesh.faces[f].size() < 3)
      throw InputError("render", "face " + std::to_string(f) + " has fewer than 3 vertices");
    for (int v : mesh.faces[f])
      if (v < 0 || v >= n)
        throw InputError("render", "face " + std::to_string(f) + " has vertex index " +
                                       std::to_string(v) + " out of range");
  }
  for (const auto& [a, b] : mesh.creases)
    if (a < 0 || b < 0 || a >= n || b >= n)
      throw InputError("render", "crease index out of range");
  for (int c : mesh.corners)
    if (c < 0 || c >= n) throw InputError("render", "corner index out of range");
}

}  // namespace

Image render_mesh(const Mesh& mesh, const Camera& camera, const RenderOptions& options) {
  validate(mesh);
  Image img(options.width, options.height, options.background);
  if (mesh.num_vertices() == 0) return img;

  // View basis: `eye` points from the object towards the camera.
  const int up_axis = std::clamp(camera.up_axis, 0, 2);
  Eigen::Vector3d up = Eigen::Vector3d::Unit(up_axis);
  const Eigen::Vector3d a1 = Eigen::Vector3d::Unit((up_axis + 1) % 3);
  const Eigen::Vector3d a2 = Eigen::Vector3d::Unit((up_axis + 2) % 3);
  const double az = camera.azimuth_deg * M_PI / 180, el = camera.elevation_deg * M_PI / 180;
  const Eigen::Vector3d eye =
      (std::cos(el) * (std::cos(az) * a1 + std::sin(az) * a2) + std::sin(el) * up).normalized();
  const Eigen::Vector3d forward = -eye;
  if (std::abs(forward.dot(up)) > 0.999) up = a2;  // looking straight down or up
  const Eigen::Vector3d right = forward.cross(up).normalized();
  const Eigen::Vector3d view_up = right.cross(forward);

  const auto [centre, radius] = camera.frame ? *camera.frame : bounding_sphere(mesh);
  const double scale = std::max(camera.zoom, 1e-6) * 0.5 *
                       std::min(options.width, options.height) * 0.92 / std::max(radius, 1e-300);

  // Screen coordinates in pixels; depth in the same pixel units so biases are in pixels.
  const int n = mesh.num_vertices();
  std::vector<ScreenPoint> screen(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d d = mesh.points.row(i).transpose() - centre;
    screen[i] = {0.5 * options.width + d.dot(right) * scale,
                 0.5 * options.height - d.dot(view_up) * scale, d.dot(forward) * scale};
  }

  // Light from the viewer's upper left, two-sided so inconsistently oriented faces still shade.
  const Eigen::Vector3d light = (-0.45 * right + 0.55 * view_up + 1.0 * eye).normalized();
  const bool per_face = options.face_colours.size() == mesh.faces.size();
  for (size_t fi = 0; fi < mesh.faces.size(); ++fi) {
    const auto& f = mesh.faces[fi];
    const Rgb base = per_face ? options.face_colours[fi] : options.surface;
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // Newell's method: robust for polygons
    for (size_t k = 0; k < f.size(); ++k) {
      const Eigen::Vector3d p = mesh.points.row(f[k]).transpose();
      const Eigen::Vector3d q = mesh.points.row(f[(k + 1) % f.size()]).transpose();
      normal += p.cross(q);
    }
    const double len = normal.norm();
    if (!(len > 0) || !std::isfinite(len)) continue;
    const double shade = 0.25 + 0.75 * std::abs(normal.dot(light) / len);
    const Rgb c{static_cast<std::uint8_t>(std::min(255.0, base.r * shade)),
                static_cast<std::uint8_t>(std::min(255.0, base.g * shade)),
                static_cast<std::uint8_t>(std::min(255.0, base.b * shade))};
    for (size_t k = 1; k + 1 < f.size(); ++k)
      img.fill_triangle(screen[f[0]], screen[f[k]], screen[f[k + 1]], c);
  }

  const double bias = 2.0;  // pixels of depth: edges on visible faces win over their own face
  if (options.draw_wire)
    for (const auto& [a, b] : unique_edges(mesh))
      img.draw_line_depth(screen[a], screen[b], options.wire, bias);
  if (options.draw_creases)
    for (const auto& [a, b] : mesh.creases)
      img.draw_line_depth(screen[a], screen[b], options.crease, bias, 2);
  if (options.draw_corners)
    for (int c : mesh.corners) {
      const ScreenPoint& s = screen[c];
      img.draw_line_depth({s.x - 2, s.y, s.z}, {s.x + 2, s.y, s.z}, options.crease, bias, 5);
    }
  return img;
}

}  // namespace mm

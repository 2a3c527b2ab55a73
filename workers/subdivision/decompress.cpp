#include "subdivision/decompress.h"

#include <stdexcept>
#include <string>

#include "subdivision/subdivide.h"

namespace mm {

long long triangle_count(const Mesh& mesh) {
  long long n = 0;
  for (const auto& f : mesh.faces) n += f.size() >= 3 ? static_cast<long long>(f.size()) - 2 : 0;
  return n;
}

long long subdivided_triangle_count(const Mesh& control, int levels) {
  if (levels < 0) throw std::invalid_argument("subdivision levels must be >= 0");
  if (levels == 0) return triangle_count(control);
  // After one step a triangle gives 4 triangles and an n-gon n quads; then each face gives 4.
  long long tris = 0, quads = 0;
  for (const auto& f : control.faces) (f.size() == 3 ? tris += 4 : quads += static_cast<long long>(f.size()));
  long long total = tris + 2 * quads;
  for (int k = 1; k < levels; ++k) {
    if (total > (1LL << 56)) return total;  // saturate: far beyond anything we could build
    total *= 4;
  }
  return total;
}

int level_for_triangle_count(const Mesh& control, long long target_triangles, int max_level) {
  if (max_level < 0 || max_level > kMaxSubdivisionLevels)
    throw std::invalid_argument("max_level must be in [0, " + std::to_string(kMaxSubdivisionLevels) + "]");
  for (int level = 0; level < max_level; ++level) {
    if (subdivided_triangle_count(control, level) >= target_triangles) return level;
    // A closed triangle mesh has about twice as many triangles as vertices: never pick a level
    // that subdivide() would refuse for its size.
    if (subdivided_triangle_count(control, level + 1) > 2 * kMaxRefinedVertices) return level;
  }
  return max_level;
}

Mesh decompress_to_level(const Mesh& control, int levels) { return subdivide(control, levels); }

Mesh decompress_to_triangle_count(const Mesh& control, long long target_triangles, int max_level) {
  return subdivide(control, level_for_triangle_count(control, target_triangles, max_level));
}

Mesh triangulate(const Mesh& mesh) {
  Mesh out;
  out.points = mesh.points;
  out.creases = mesh.creases;
  out.corners = mesh.corners;
  out.faces.reserve(static_cast<size_t>(triangle_count(mesh)));
  const int n = mesh.num_vertices();
  for (size_t fi = 0; fi < mesh.faces.size(); ++fi) {
    const auto& f = mesh.faces[fi];
    for (int v : f)
      if (v < 0 || v >= n)
        throw InputError("triangulate", "face " + std::to_string(fi) + " has vertex index " +
                                            std::to_string(v) + " out of range");
    if (f.size() < 3) throw InputError("triangulate", "face " + std::to_string(fi) + " has fewer than 3 vertices");
    if (f.size() == 4) {
      const double d02 = (mesh.points.row(f[0]) - mesh.points.row(f[2])).squaredNorm();
      const double d13 = (mesh.points.row(f[1]) - mesh.points.row(f[3])).squaredNorm();
      if (d13 < d02) {
        out.faces.push_back({f[0], f[1], f[3]});
        out.faces.push_back({f[1], f[2], f[3]});
      } else {
        out.faces.push_back({f[0], f[1], f[2]});
        out.faces.push_back({f[0], f[2], f[3]});
      }
    } else {
      for (size_t k = 1; k + 1 < f.size(); ++k) out.faces.push_back({f[0], f[k], f[k + 1]});
    }
  }
  return out;
}

}  // namespace mm

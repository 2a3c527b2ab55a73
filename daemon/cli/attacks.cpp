#include "cli/attacks.h"

#include <cmath>
#include <numeric>
#include <random>

#include "subdivision/subdivide.h"

namespace mm::cli {

double largest_side(const Points& points) {
  if (points.rows() == 0) return 0;
  return (points.colwise().maxCoeff() - points.colwise().minCoeff()).maxCoeff();
}

void add_uniform_noise(Points& points, double amplitude, std::uint64_t seed) {
  const double a = amplitude * largest_side(points);
  std::mt19937_64 rng(seed);
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    for (int k = 0; k < 3; ++k) {
      const double u = static_cast<double>(rng() >> 11) * 0x1.0p-53;  // [0, 1)
      points(i, k) += a * (2 * u - 1);
    }
}

void apply_similarity(Points& points, double scale, double rotate_degrees, const Eigen::Vector3d& shift) {
  const double side = largest_side(points);
  const double t = rotate_degrees * M_PI / 180.0, c = std::cos(t), s = std::sin(t);
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const double x = points(i, 0), y = points(i, 1), z = points(i, 2);
    points(i, 0) = scale * (c * x - s * y) + shift.x() * side;
    points(i, 1) = scale * (s * x + c * y) + shift.y() * side;
    points(i, 2) = scale * z + shift.z() * side;
  }
}

Mesh subdivide_linear(Mesh mesh, int levels) {
  for (int level = 0; level < levels; ++level) {
    // Crease edge points are midpoints, corners stay, a quad's face point is its centre.
    mesh.creases = unique_edges(mesh);
    mesh.corners.resize(static_cast<std::size_t>(mesh.num_vertices()));
    std::iota(mesh.corners.begin(), mesh.corners.end(), 0);
    mesh = subdivide(mesh, 1);
  }
  mesh.creases.clear();
  mesh.corners.clear();
  return mesh;
}

}  // namespace mm::cli

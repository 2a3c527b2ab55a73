#include "attacks/perturb.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <string>

namespace mm::attacks {
namespace {

// Uniform in [0, n) by rejection, the same on every standard library (std::uniform_int_distribution
// is not).
std::size_t uniform_below(std::mt19937_64& rng, std::size_t n) {
  const std::uint64_t limit = UINT64_MAX - UINT64_MAX % n;
  std::uint64_t x;
  do x = rng();
  while (x >= limit);
  return static_cast<std::size_t>(x % n);
}

}  // namespace

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

void quantize_coordinates(Points& points, int bits) {
  if (bits < 1 || bits > 30) throw std::invalid_argument("quantize_coordinates: bits outside [1, 30]");
  if (points.rows() == 0) return;
  const Eigen::RowVector3d low = points.colwise().minCoeff();
  const double side = largest_side(points);
  if (side <= 0) return;
  const double cells = std::ldexp(1.0, bits), step = side / cells;
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    for (int k = 0; k < 3; ++k) {
      const double q = std::min(std::floor((points(i, k) - low[k]) / step), cells - 1);
      points(i, k) = low[k] + (q + 0.5) * step;
    }
}

UmbrellaSmoother::UmbrellaSmoother(const Mesh& connectivity)
    : offsets_(static_cast<std::size_t>(connectivity.num_vertices()) + 1, 0) {
  const auto edges = unique_edges(connectivity);
  for (const auto& [i, j] : edges) ++offsets_[static_cast<std::size_t>(i) + 1], ++offsets_[static_cast<std::size_t>(j) + 1];
  for (std::size_t v = 1; v < offsets_.size(); ++v) offsets_[v] += offsets_[v - 1];
  neighbours_.resize(static_cast<std::size_t>(offsets_.back()));
  std::vector<int> fill(offsets_.begin(), offsets_.end() - 1);
  for (const auto& [i, j] : edges) {
    neighbours_[static_cast<std::size_t>(fill[static_cast<std::size_t>(i)]++)] = j;
    neighbours_[static_cast<std::size_t>(fill[static_cast<std::size_t>(j)]++)] = i;
  }
}

void UmbrellaSmoother::step(Points& points, double lambda) const {
  Points next = points;
  for (Eigen::Index v = 0; v + 1 < static_cast<Eigen::Index>(offsets_.size()); ++v) {
    const int begin = offsets_[static_cast<std::size_t>(v)], end = offsets_[static_cast<std::size_t>(v) + 1];
    if (begin == end) continue;
    Eigen::RowVector3d mean = Eigen::RowVector3d::Zero();
    for (int k = begin; k < end; ++k) mean += points.row(neighbours_[static_cast<std::size_t>(k)]);
    mean /= static_cast<double>(end - begin);
    next.row(v) = points.row(v) + lambda * (mean - points.row(v));
  }
  points = std::move(next);
}

void smooth_laplacian(Mesh& mesh, int iterations, double lambda) {
  if (!(lambda > 0 && lambda <= 1) || iterations < 0)
    throw std::invalid_argument("smooth_laplacian: lambda outside (0, 1] or negative iterations");
  const UmbrellaSmoother smoother(mesh);
  for (int it = 0; it < iterations; ++it) smoother.step(mesh.points, lambda);
}

void shuffle_order(Mesh& mesh, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const auto n = static_cast<std::size_t>(mesh.num_vertices());
  std::vector<int> new_index(n);
  std::iota(new_index.begin(), new_index.end(), 0);
  for (std::size_t i = n; i > 1; --i) std::swap(new_index[i - 1], new_index[uniform_below(rng, i)]);
  Points moved(mesh.points.rows(), 3);
  for (std::size_t v = 0; v < n; ++v) moved.row(new_index[v]) = mesh.points.row(static_cast<Eigen::Index>(v));
  mesh.points = std::move(moved);
  for (auto& face : mesh.faces) {
    for (int& v : face) v = new_index[static_cast<std::size_t>(v)];
    std::rotate(face.begin(), face.begin() + static_cast<std::ptrdiff_t>(uniform_below(rng, face.size())), face.end());
  }
  for (std::size_t i = mesh.faces.size(); i > 1; --i) std::swap(mesh.faces[i - 1], mesh.faces[uniform_below(rng, i)]);
  for (auto& [i, j] : mesh.creases) {
    i = new_index[static_cast<std::size_t>(i)];
    j = new_index[static_cast<std::size_t>(j)];
    if (i > j) std::swap(i, j);
  }
  std::sort(mesh.creases.begin(), mesh.creases.end());
  for (int& c : mesh.corners) c = new_index[static_cast<std::size_t>(c)];
  std::sort(mesh.corners.begin(), mesh.corners.end());
}

Mesh average_copies(const std::vector<Mesh>& copies, const std::vector<std::string>& names) {
  if (copies.empty()) throw std::invalid_argument("average_copies: no copies");
  Mesh mean = copies.front();
  for (std::size_t c = 1; c < copies.size(); ++c) {
    const Mesh& m = copies[c];
    const std::string name = c < names.size() ? names[c] : "copy " + std::to_string(c + 1);
    if (m.num_vertices() != mean.num_vertices() || m.faces != copies.front().faces)
      throw InputError(name, "cannot be averaged with the first copy: " + std::to_string(m.num_vertices()) +
                                 " vertices and " + std::to_string(m.num_faces()) + " faces against " +
                                 std::to_string(mean.num_vertices()) + " and " + std::to_string(mean.num_faces()) +
                                 " (copies must share their connectivity)");
    mean.points += m.points;
  }
  mean.points /= static_cast<double>(copies.size());
  return mean;
}

}  // namespace mm::attacks

#include "quality/surface_distance.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "quality/triangle_distance_tree.h"
#include "subdivision/decompress.h"

namespace mm {
namespace {

struct Tri {
  Eigen::Vector3d a, b, c;
  double area;
};

// Fan triangles of positive area; degenerate ones add nothing to a surface and would only
// trouble the closest-point queries.
std::vector<Tri> triangles(const Mesh& mesh) {
  const int n = mesh.num_vertices();
  if (!mesh.points.allFinite()) throw InputError("quality", "mesh has non-finite coordinates");
  std::vector<Tri> out;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& face = mesh.faces[f];
    for (int v : face)
      if (v < 0 || v >= n)
        throw InputError("quality", "face " + std::to_string(f) + " has a vertex index out of range");
    for (std::size_t k = 1; k + 1 < face.size(); ++k) {
      Tri t{mesh.points.row(face[0]).transpose(), mesh.points.row(face[k]).transpose(),
            mesh.points.row(face[k + 1]).transpose(), 0};
      t.area = 0.5 * (t.b - t.a).cross(t.c - t.a).norm();
      if (t.area > 0) out.push_back(t);
    }
  }
  if (out.empty()) throw InputError("quality", "mesh has no face of positive area");
  return out;
}

// Portable uniform [0, 1): the standard distributions differ between library versions.
double uniform(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

double diagonal_of(const Mesh& mesh) {
  if (mesh.num_vertices() == 0) return 0;
  return (mesh.points.colwise().maxCoeff() - mesh.points.colwise().minCoeff()).norm();
}

}  // namespace

std::vector<Eigen::Vector3d> sample_surface(const Mesh& mesh, int samples, std::uint64_t seed,
                                            bool include_vertices) {
  const std::vector<Tri> tris = triangles(mesh);
  std::mt19937_64 rng(seed);
  std::vector<Eigen::Vector3d> out;
  const std::size_t count = static_cast<std::size_t>(std::max(samples, 0));
  out.reserve(count + (include_vertices ? mesh.num_vertices() : 0));
  double total = 0;
  for (const Tri& t : tris) total += t.area;
  // Systematic sampling: sample k sits at cumulative area (k + u0) / count * total, so every
  // triangle gets its area's share of samples to within one.
  const double u0 = uniform(rng);
  double cumulative = 0;
  std::size_t k = 0;
  for (const Tri& t : tris) {
    cumulative += t.area;
    while (k < count && (static_cast<double>(k) + u0) / static_cast<double>(count) * total < cumulative) {
      double r1 = uniform(rng), r2 = uniform(rng);
      if (r1 + r2 > 1) {
        r1 = 1 - r1;
        r2 = 1 - r2;
      }
      out.push_back(t.a + r1 * (t.b - t.a) + r2 * (t.c - t.a));
      ++k;
    }
  }
  for (; k < count; ++k) out.push_back(tris.back().c);  // rounding leftovers, if any
  if (include_vertices) {
    std::vector<char> used(mesh.num_vertices(), 0);
    for (const auto& f : mesh.faces)
      for (int v : f) used[v] = 1;
    for (int v = 0; v < mesh.num_vertices(); ++v)
      if (used[v]) out.push_back(mesh.points.row(v).transpose());
  }
  return out;
}

OneSidedDistance one_sided_distance(const Mesh& from, const Mesh& to, const SamplingParams& params) {
  const std::vector<Tri> target = triangles(to);
  std::vector<std::array<Eigen::Vector3d, 3>> corners;
  corners.reserve(target.size());
  for (const Tri& t : target) corners.push_back({t.a, t.b, t.c});
  const TriangleDistanceTree tree(corners);

  const auto points = sample_surface(from, params.samples, params.seed, params.include_vertices);
  if (points.empty()) throw InputError("quality", "no samples: give samples > 0 or include vertices");
  OneSidedDistance d;
  double sum = 0, sum_sq = 0;
  // Consecutive samples lie on the same or neighbouring triangles: each query starts from the
  // previous answer.
  int hint = -1;
  for (const auto& p : points) {
    const double sq = tree.squared_distance(p, hint);
    const double dist = std::sqrt(sq);
    d.max = std::max(d.max, dist);
    sum += dist;
    sum_sq += sq;
  }
  d.samples = points.size();
  d.mean = sum / static_cast<double>(points.size());
  d.rms = std::sqrt(sum_sq / static_cast<double>(points.size()));
  return d;
}

SurfaceDistance decoded_distance(const Mesh& part, const Mesh& control, int levels, const SamplingParams& params) {
  return surface_distance(part, decompress_to_level(control, levels), params);
}

SurfaceDistance surface_distance(const Mesh& a, const Mesh& b, const SamplingParams& params) {
  SurfaceDistance s;
  s.a_to_b = one_sided_distance(a, b, params);
  // A different seed for the other direction keeps the two sample sets independent.
  SamplingParams back = params;
  back.seed = params.seed ^ 0x9E3779B97F4A7C15ull;
  s.b_to_a = one_sided_distance(b, a, back);
  s.hausdorff = std::max(s.a_to_b.max, s.b_to_a.max);
  s.rms = std::max(s.a_to_b.rms, s.b_to_a.rms);
  s.mean = std::max(s.a_to_b.mean, s.b_to_a.mean);
  s.diagonal = diagonal_of(a);
  return s;
}

}  // namespace mm

#include "quality/coordinate_slack.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "quality/triangle_distance_tree.h"
#include "subdivision/subdivide.h"

namespace mm {
namespace {

using K = CGAL::Simple_cartesian<double>;
using Triangle = K::Triangle_3;
using Point = K::Point_3;
using TriangleIt = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<K, TriangleIt>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

Point point(const Points& p, int v) { return Point(p(v, 0), p(v, 1), p(v, 2)); }

// Fan triangles of positive area with their corner indices.
void fan(const Mesh& m, std::vector<Triangle>& tris, std::vector<std::array<int, 3>>* corners) {
  for (const auto& f : m.faces)
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {
      Triangle t(point(m.points, f[0]), point(m.points, f[k]), point(m.points, f[k + 1]));
      if (t.is_degenerate()) continue;
      tris.push_back(t);
      if (corners) corners->push_back({f[0], f[k], f[k + 1]});
    }
}

constexpr double kUnlimited = 1e30, kTangent = 1e-3;

}  // namespace

std::vector<double> coordinate_slack(const Mesh& part, const Mesh& control, int levels, double tolerance,
                                     const SamplingParams& params) {
  const SubdivisionOperator op = build_subdivision(control, levels);
  Mesh refined = op.refined;
  refined.points = apply_subdivision(op, control.points);
  const int nr = refined.num_vertices();

  std::vector<Triangle> part_tris;
  fan(part, part_tris, nullptr);
  if (part_tris.empty()) throw InputError("quality", "part has no face of positive area");
  // The quality code's own tree (CGAL's numbers bit for bit); refined vertices come in mesh
  // order, so each query starts from the previous answer.
  std::vector<std::array<Eigen::Vector3d, 3>> part_corners;
  part_corners.reserve(part_tris.size());
  for (const Triangle& t : part_tris) {
    std::array<Eigen::Vector3d, 3> c;
    for (int j = 0; j < 3; ++j) c[static_cast<std::size_t>(j)] = {t[j].x(), t[j].y(), t[j].z()};
    part_corners.push_back(c);
  }
  const TriangleDistanceTree part_tree(part_corners);
  std::vector<double> e(static_cast<std::size_t>(nr));
  int hint = -1;
  for (int r = 0; r < nr; ++r) e[r] = std::sqrt(part_tree.squared_distance(refined.points.row(r).transpose(), hint));

  std::vector<Triangle> tris;
  std::vector<std::array<int, 3>> corners;
  fan(refined, tris, &corners);
  if (tris.empty()) throw InputError("quality", "subdivided control mesh has no face of positive area");
  std::vector<std::array<double, 3>> m(static_cast<std::size_t>(nr), {0, 0, 0});
  for (std::size_t t = 0; t < tris.size(); ++t) {
    const auto n = CGAL::normal(tris[t][0], tris[t][1], tris[t][2]);
    const double len = std::sqrt(n.squared_length());
    for (int r : corners[t])
      for (int a = 0; a < 3; ++a) m[r][a] = std::max(m[r][a], std::abs(n[a]) / len);
  }
  Tree tree(tris.begin(), tris.end());
  tree.accelerate_distance_queries();
  for (const auto& p : sample_surface(part, params.samples, params.seed, params.include_vertices)) {
    const Point q(p.x(), p.y(), p.z());
    const auto [closest, it] = tree.closest_point_and_primitive(q);
    const double d = std::sqrt(CGAL::squared_distance(q, closest));
    for (int r : corners[static_cast<std::size_t>(it - tris.begin())]) e[r] = std::max(e[r], d);
  }

  std::vector<double> out(3 * static_cast<std::size_t>(control.num_vertices()), kUnlimited);
  for (int r = 0; r < op.S.outerSize(); ++r) {
    const double sum = m[r][0] + m[r][1] + m[r][2];
    const double slack = sum > 0 ? std::max(0.0, tolerance - e[r]) / sum : kUnlimited;
    for (SparseOperator::InnerIterator it(op.S, r); it; ++it)
      if (it.value() != 0)
        for (int a = 0; a < 3; ++a)
          if (m[r][a] > kTangent) out[3 * it.col() + a] = std::min(out[3 * it.col() + a], slack);
  }
  return out;
}

}  // namespace mm

#include "compression/coordinate_slack.h"

#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "geometry/triangle_distance_tree.h"
#include "subdivision/subdivide.h"

namespace mm {
namespace {

using K = CGAL::Simple_cartesian<double>;
using Triangle = K::Triangle_3;
using Point = K::Point_3;

Point point(const Points& p, int v) { return Point(p(v, 0), p(v, 1), p(v, 2)); }

// Fan triangles of positive area with their corner indices.
void fan(const Mesh& m, std::vector<Triangle>& tris, std::vector<std::array<int, 3>>& corners) {
  for (const auto& f : m.faces)
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {
      Triangle t(point(m.points, f[0]), point(m.points, f[k]), point(m.points, f[k + 1]));
      if (t.is_degenerate()) continue;
      tris.push_back(t);
      corners.push_back({f[0], f[k], f[k + 1]});
    }
}

constexpr double kUnlimited = 1e30, kTangent = 1e-3;

}  // namespace

std::vector<double> coordinate_slack(const Mesh& part, const Mesh& control, int levels, double tolerance,
                                     const SamplingParams& params) {
  return coordinate_slack(MeasuredSurface(part, params), control, levels, tolerance, params);
}

std::vector<double> coordinate_slack(const MeasuredSurface& part, const Mesh& control, int levels, double tolerance,
                                     const SamplingParams& params, double exact_up_to) {
  const SubdivisionOperator op = build_subdivision(control, levels);
  Mesh refined = op.refined;
  refined.points = apply_subdivision(op, control.points);
  const int nr = refined.num_vertices();

  // A slack of at most exact_up_to needs an error of at least `relevant` (the normals' weights sum
  // to at most 3), so nearer distances are left at 0 once a triangle is certainly within it.
  const double relevant = std::isfinite(exact_up_to) ? tolerance - 3 * exact_up_to : 0;
  const auto distance = [relevant](const TriangleDistanceTree& tree, const Eigen::Vector3d& p, int& hint) {
    if (relevant > 0 && tree.within(p, relevant, hint)) return -1.0;
    return std::sqrt(tree.squared_distance(p, hint));
  };
  // Refined vertices come in mesh order, so each query starts from the previous answer.
  const TriangleDistanceTree& part_tree = part.tree();
  std::vector<double> e(static_cast<std::size_t>(nr));
  int hint = -1;
  for (int r = 0; r < nr; ++r) e[r] = std::max(0.0, distance(part_tree, refined.points.row(r).transpose(), hint));

  std::vector<Triangle> tris;
  std::vector<std::array<int, 3>> corners;
  fan(refined, tris, corners);
  if (tris.empty()) throw InputError("quality", "subdivided control mesh has no face of positive area");
  std::vector<std::array<double, 3>> m(static_cast<std::size_t>(nr), {0, 0, 0});
  for (std::size_t t = 0; t < tris.size(); ++t) {
    const auto n = CGAL::normal(tris[t][0], tris[t][1], tris[t][2]);
    const double len = std::sqrt(n.squared_length());
    for (int r : corners[t])
      for (int a = 0; a < 3; ++a) m[r][a] = std::max(m[r][a], std::abs(n[a]) / len);
  }
  // The quality code's tree again (CGAL's distances). Of equally close triangles it names the
  // first in fan order, whatever order the samples are queried in and whichever were skipped.
  std::vector<std::array<Eigen::Vector3d, 3>> refined_corners;
  refined_corners.reserve(corners.size());
  for (const auto& c : corners)
    refined_corners.push_back({refined.points.row(c[0]).transpose(), refined.points.row(c[1]).transpose(),
                               refined.points.row(c[2]).transpose()});
  const TriangleDistanceTree tree(refined_corners);
  int at = -1;  // each query starts from the previous answer
  const auto& own = part.params();
  const bool same = own.samples == params.samples && own.seed == params.seed &&
                    own.include_vertices == params.include_vertices;
  const std::vector<Eigen::Vector3d> other =
      same ? std::vector<Eigen::Vector3d>{}
           : sample_surface(part.mesh(), params.samples, params.seed, params.include_vertices);
  const auto charge = [&](const Eigen::Vector3d& p) {
    const double d = distance(tree, p, at);
    if (d >= 0)
      for (int r : corners[static_cast<std::size_t>(tree.triangle_of(at))]) e[r] = std::max(e[r], d);
  };
  // The samples along a curve through space (MeasuredSurface::sample_order for the part's own).
  const std::vector<Eigen::Vector3d>& points = same ? part.samples() : other;
  for (int i : same ? part.sample_order() : spatial_order(other)) charge(points[static_cast<std::size_t>(i)]);

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

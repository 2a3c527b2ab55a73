#include "fitting/rail_quads.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <tuple>

namespace mm {
namespace {

using Edge = std::pair<int, int>;
Edge key(int a, int b) { return {std::min(a, b), std::max(a, b)}; }

Eigen::Vector3d triangle_normal(const Points& p, int a, int b, int c) {
  const Eigen::Vector3d pa = p.row(a), pb = p.row(b), pc = p.row(c);
  return (pb - pa).cross(pc - pa);
}

struct Candidate {
  double fold;       // angle between the two triangles' normals, radians
  int quad[4];       // u, d, v, a: counter-clockwise when both triangles are
  int t1, t2;
};

// A strip cell: convex, every corner angle between 30 and 150 degrees, and the two rails run
// side by side (within 45 degrees of parallel). A concave or kite-shaped quad makes
// Catmull-Clark's face point fall outside it: its surface bulges where the triangles' did not.
bool strip_shaped(const Points& p, const int (&q)[4], bool rails_01_23) {
  Eigen::Vector3d c[4];
  for (int k = 0; k < 4; ++k) c[k] = p.row(q[k]);
  const Eigen::Vector3d n = (c[2] - c[0]).cross(c[3] - c[1]);
  if (!(n.norm() > 0)) return false;
  const double cos_lo = std::cos(150.0 * M_PI / 180.0), cos_hi = std::cos(30.0 * M_PI / 180.0);
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d in = c[k] - c[(k + 3) % 4], out = c[(k + 1) % 4] - c[k];
    if (!(in.cross(out).dot(n) > 0)) return false;  // reflex or degenerate corner
    const Eigen::Vector3d e1 = c[(k + 3) % 4] - c[k], e2 = out;
    const double cosine = e1.dot(e2) / (e1.norm() * e2.norm());
    if (!(cosine > cos_lo && cosine < cos_hi)) return false;
  }
  const int r = rails_01_23 ? 0 : 1;
  const Eigen::Vector3d rail1 = c[r + 1] - c[r], rail2 = c[r + 2] - c[(r + 3) % 4];
  return rail1.dot(rail2) > std::cos(45.0 * M_PI / 180.0) * rail1.norm() * rail2.norm();
}

}  // namespace

Mesh pair_rail_quads(const Mesh& control, double max_fold_degrees) {
  const std::set<Edge> creases(control.creases.begin(), control.creases.end());
  // Directed edge -> (triangle, opposite vertex).
  std::map<Edge, std::pair<int, int>> directed;
  for (int f = 0; f < control.num_faces(); ++f) {
    const auto& t = control.faces[f];
    if (t.size() != 3) continue;
    for (int k = 0; k < 3; ++k) directed[{t[k], t[(k + 1) % 3]}] = {f, t[(k + 2) % 3]};
  }
  const double max_fold = max_fold_degrees * M_PI / 180.0;
  std::vector<Candidate> candidates;
  for (const auto& [uv, first] : directed) {
    const auto [u, v] = uv;
    if (u > v || creases.count(key(u, v))) continue;
    const auto other = directed.find({v, u});
    if (other == directed.end()) continue;
    const auto [t1, a] = first;
    const auto [t2, d] = other->second;
    if (a == d) continue;
    // Quad u -> d -> v -> a: t2 gives u->d, d->v; t1 gives v->a, a->u.
    const bool rails_ud_va = creases.count(key(u, d)) && creases.count(key(v, a));
    const bool rails_dv_au = creases.count(key(d, v)) && creases.count(key(a, u));
    if (!rails_ud_va && !rails_dv_au) continue;
    const Eigen::Vector3d n1 = triangle_normal(control.points, u, v, a);
    const Eigen::Vector3d n2 = triangle_normal(control.points, v, u, d);
    const double len = n1.norm() * n2.norm();
    if (!(len > 0)) continue;
    const double fold = std::acos(std::clamp(n1.dot(n2) / len, -1.0, 1.0));
    if (fold > max_fold) continue;
    if (!strip_shaped(control.points, {u, d, v, a}, rails_ud_va)) continue;
    candidates.push_back({fold, {u, d, v, a}, t1, t2});
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    return std::tie(x.fold, x.quad[0], x.quad[2]) < std::tie(y.fold, y.quad[0], y.quad[2]);
  });
  std::vector<char> used(control.faces.size(), 0);
  std::vector<std::vector<int>> quads;
  for (const Candidate& c : candidates) {
    if (used[c.t1] || used[c.t2]) continue;
    used[c.t1] = used[c.t2] = 1;
    quads.push_back({c.quad[0], c.quad[1], c.quad[2], c.quad[3]});
  }
  Mesh out;
  out.points = control.points;
  out.creases = control.creases;
  out.corners = control.corners;
  for (size_t f = 0; f < control.faces.size(); ++f)
    if (!used[f]) out.faces.push_back(control.faces[f]);
  for (auto& q : quads) out.faces.push_back(std::move(q));
  return out;
}

}  // namespace mm

#include "fitting/collapse_control.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <map>
#include <set>

namespace mm {

std::optional<Mesh> collapse_control_vertex(const Mesh& control, int v, int t) {
  const int n = control.num_vertices();
  if (v == t || v < 0 || t < 0 || v >= n || t >= n || n <= 5) return std::nullopt;
  if (std::binary_search(control.corners.begin(), control.corners.end(), v)) return std::nullopt;

  // v's one-ring: its faces, and how many faces each of its edges has (1 = open boundary).
  // A face on edge (v, t) goes if it is a triangle and loses v if it is a quad; a quad with v
  // and t opposite would fold.
  std::map<int, int> edge_faces;  // neighbour -> faces on edge (v, neighbour)
  std::vector<int> around_v, on_edge;
  std::set<int> opposite;  // third vertices of the triangles on edge (v, t)
  for (int f = 0; f < control.num_faces(); ++f) {
    const auto& face = control.faces[f];
    const int k = static_cast<int>(face.size());
    const int at = static_cast<int>(std::find(face.begin(), face.end(), v) - face.begin());
    if (at == k) continue;
    if (k != 3 && k != 4) return std::nullopt;
    around_v.push_back(f);
    const int next = face[(at + 1) % k], prev = face[(at + k - 1) % k];
    ++edge_faces[next];
    ++edge_faces[prev];
    if (std::find(face.begin(), face.end(), t) == face.end()) continue;
    if (next != t && prev != t) return std::nullopt;
    on_edge.push_back(f);
    if (k == 3)
      for (int w : face)
        if (w != v && w != t) opposite.insert(w);
  }
  if (!edge_faces.count(t) || on_edge.size() != 2) return std::nullopt;
  for (const auto& [w, faces] : edge_faces)
    if (faces != 2) return std::nullopt;  // open boundary (or non-manifold) around v

  // Crease rules: a smooth vertex may go anywhere; a crease vertex only along its crease.
  std::vector<int> crease_neighbours;
  for (const auto& [a, b] : control.creases) {
    if (a == v) crease_neighbours.push_back(b);
    if (b == v) crease_neighbours.push_back(a);
  }
  if (!crease_neighbours.empty() &&
      (crease_neighbours.size() != 2 ||
       std::find(crease_neighbours.begin(), crease_neighbours.end(), t) == crease_neighbours.end()))
    return std::nullopt;

  // Link condition: the common neighbours of v and t are exactly the two opposite vertices.
  std::set<int> neighbours_t;
  for (const auto& face : control.faces) {
    const int k = static_cast<int>(face.size());
    const int at = static_cast<int>(std::find(face.begin(), face.end(), t) - face.begin());
    if (at == k) continue;
    neighbours_t.insert(face[(at + 1) % k]);
    neighbours_t.insert(face[(at + k - 1) % k]);
  }
  for (const auto& [w, faces] : edge_faces)
    if (w != t && neighbours_t.count(w) && !opposite.count(w)) return std::nullopt;
  std::set<int> after_t = neighbours_t;  // t's neighbours after the collapse: at least three
  for (const auto& [w, faces] : edge_faces) after_t.insert(w);
  after_t.erase(v);
  after_t.erase(t);
  if (after_t.size() < 3) return std::nullopt;

  // No face of v may fold over when v moves onto t.
  const Points& p = control.points;
  const auto normal = [&p, v, t](const std::vector<int>& face, bool moved) {
    std::vector<Eigen::Vector3d> c;
    for (int w : face)
      if (!(moved && w == v && std::find(face.begin(), face.end(), t) != face.end()))
        c.push_back(p.row(moved && w == v ? t : w));
    return c.size() == 3 ? Eigen::Vector3d((c[1] - c[0]).cross(c[2] - c[0]))
                         : Eigen::Vector3d((c[2] - c[0]).cross(c[3] - c[1]));
  };
  for (int f : around_v) {
    const auto& face = control.faces[f];
    if (face.size() == 3 && std::find(face.begin(), face.end(), t) != face.end()) continue;
    if (!(normal(face, false).dot(normal(face, true)) > 0)) return std::nullopt;
  }

  const auto renumber = [v, t](int w) {
    if (w == v) w = t;
    return w > v ? w - 1 : w;
  };
  Mesh out;
  out.points.resize(n - 1, 3);
  for (int w = 0, row = 0; w < n; ++w)
    if (w != v) out.points.row(row++) = p.row(w);
  for (int f = 0; f < control.num_faces(); ++f) {
    const bool on = std::find(on_edge.begin(), on_edge.end(), f) != on_edge.end();
    if (on && control.faces[f].size() == 3) continue;
    std::vector<int> face;
    for (int w : control.faces[f])
      if (!(on && w == v)) face.push_back(renumber(w));
    out.faces.push_back(std::move(face));
  }
  for (const auto& [a, b] : control.creases) {
    if ((a == v && b == t) || (a == t && b == v)) continue;
    const int x = renumber(a), y = renumber(b);
    out.creases.push_back({std::min(x, y), std::max(x, y)});
  }
  std::sort(out.creases.begin(), out.creases.end());
  out.creases.erase(std::unique(out.creases.begin(), out.creases.end()), out.creases.end());
  for (int c : control.corners) out.corners.push_back(renumber(c));
  std::sort(out.corners.begin(), out.corners.end());
  return out;
}

}  // namespace mm

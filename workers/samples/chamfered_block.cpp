#include "samples/chamfered_block.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <stdexcept>

#include "samples/shape_building.h"

namespace mm::samples {

Mesh chamfered_block(const ChamferedBlock& p) {
  const double size[3] = {p.size_x, p.size_y, p.size_z};
  if (!(p.chamfer > 0) || !(p.edge_length > 0) || 2 * p.chamfer >= std::min({size[0], size[1], size[2]}))
    throw std::invalid_argument("chamfered_block: need 0 < 2 chamfer < every side and edge_length > 0");
  // Corner (sx, sy, sz) contributes one point on each of its three faces: on the face normal
  // to axis a it sits on the face, inset by the chamfer along the other two axes.
  Mesh coarse;
  coarse.points.resize(24, 3);
  auto id = [](int corner, int axis) { return corner * 3 + axis; };
  for (int corner = 0; corner < 8; ++corner)
    for (int a = 0; a < 3; ++a) {
      Eigen::Vector3d q;
      for (int k = 0; k < 3; ++k) {
        bool high = corner >> k & 1;
        q[k] = k == a ? (high ? size[k] : 0.0) : (high ? size[k] - p.chamfer : p.chamfer);
      }
      coarse.points.row(id(corner, a)) = q.transpose();
    }
  std::vector<std::vector<int>> faces;
  for (int a = 0; a < 3; ++a)
    for (int side = 0; side < 2; ++side) {  // flat face normal to axis a
      std::vector<int> f;
      for (int corner = 0; corner < 8; ++corner)
        if ((corner >> a & 1) == side) f.push_back(id(corner, a));
      faces.push_back(f);
    }
  for (int a = 0; a < 3; ++a) {  // chamfer strip along axis a, between faces b and c
    int b = (a + 1) % 3, c = (a + 2) % 3;
    for (int hb = 0; hb < 2; ++hb)
      for (int hc = 0; hc < 2; ++hc) {
        std::vector<int> f;
        for (int ha = 0; ha < 2; ++ha) {
          int corner = ha << a | hb << b | hc << c;
          f.push_back(id(corner, b));
          f.push_back(id(corner, c));
        }
        faces.push_back(f);
      }
  }
  for (int corner = 0; corner < 8; ++corner) faces.push_back({id(corner, 0), id(corner, 1), id(corner, 2)});
  // Order each (convex) face counter-clockwise seen from outside the (convex) solid.
  const Eigen::Vector3d center(size[0] / 2, size[1] / 2, size[2] / 2);
  for (auto& f : faces) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int v : f) c += coarse.points.row(v).transpose();
    c /= static_cast<double>(f.size());
    Eigen::Vector3d n = (c - center).normalized();
    Eigen::Vector3d u = n.unitOrthogonal(), w = n.cross(u);
    auto angle = [&](int v) {
      Eigen::Vector3d d = coarse.points.row(v).transpose() - c;
      return std::atan2(d.dot(w), d.dot(u));
    };
    std::sort(f.begin(), f.end(), [&](int x, int y) { return angle(x) < angle(y); });
  }
  coarse.faces = faces;
  auto segments = [&](int u, int v) {
    double len = (coarse.points.row(u) - coarse.points.row(v)).norm();
    len = std::round(len * 1e9) / 1e9;  // equal edges must get equal counts
    return std::max(1, static_cast<int>(std::ceil(len / p.edge_length - 1e-9)));
  };
  return refine(coarse, segments);
}

}  // namespace mm::samples

// Small control meshes for the subdivision tests, built in code.
#pragma once
#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <random>

#include "meshio/mesh.h"

namespace mm::test {

inline Mesh make_mesh(std::vector<std::array<double, 3>> pts, std::vector<std::vector<int>> faces) {
  Mesh m;
  m.points.resize(static_cast<int>(pts.size()), 3);
  for (size_t i = 0; i < pts.size(); ++i)
    for (int c = 0; c < 3; ++c) m.points(static_cast<int>(i), c) = pts[i][c];
  m.faces = std::move(faces);
  return m;
}

inline Mesh tetrahedron() {
  return make_mesh({{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}},
                   {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}});
}

inline Mesh octahedron() {
  return make_mesh({{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}},
                   {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}});
}

inline Mesh cube() {
  return make_mesh({{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                    {-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}},
                   {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}});
}

// An open nx x ny grid of unit quads in the plane z = 0 (boundary all around).
inline Mesh grid(int nx, int ny) {
  Mesh m;
  m.points.resize((nx + 1) * (ny + 1), 3);
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) m.points.row(j * (nx + 1) + i) << i, j, 0.0;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int a = j * (nx + 1) + i;
      m.faces.push_back({a, a + 1, a + nx + 2, a + nx + 1});
    }
  return m;
}

// Splits every quad into two triangles along its 0-2 diagonal.
inline Mesh triangulated(const Mesh& m) {
  Mesh t = m;
  t.faces.clear();
  for (const auto& f : m.faces) {
    if (f.size() == 4) {
      t.faces.push_back({f[0], f[1], f[2]});
      t.faces.push_back({f[0], f[2], f[3]});
    } else {
      t.faces.push_back(f);
    }
  }
  return t;
}

// Linear (midpoint/centroid) split of every face into quads: an all-quad mesh of the same shape.
// Creases are carried to both halves.
inline Mesh quadrangulated(const Mesh& m) {
  Mesh q;
  std::map<std::pair<int, int>, int> mid;
  std::vector<Eigen::RowVector3d> pts;
  for (int i = 0; i < m.num_vertices(); ++i) pts.push_back(m.points.row(i));
  auto midpoint = [&](int a, int b) {
    auto key = std::make_pair(std::min(a, b), std::max(a, b));
    auto it = mid.find(key);
    if (it != mid.end()) return it->second;
    pts.push_back(0.5 * (m.points.row(a) + m.points.row(b)));
    return mid[key] = static_cast<int>(pts.size()) - 1;
  };
  for (const auto& f : m.faces) {
    Eigen::RowVector3d c = Eigen::RowVector3d::Zero();
    for (int v : f) c += m.points.row(v);
    pts.push_back(c / static_cast<double>(f.size()));
    const int fc = static_cast<int>(pts.size()) - 1;
    const int n = static_cast<int>(f.size());
    for (int k = 0; k < n; ++k)
      q.faces.push_back({f[k], midpoint(f[k], f[(k + 1) % n]), fc, midpoint(f[(k + n - 1) % n], f[k])});
  }
  for (const auto& [a, b] : m.creases) {
    const int mm_ = midpoint(a, b);
    q.creases.emplace_back(std::min(a, mm_), std::max(a, mm_));
    q.creases.emplace_back(std::min(b, mm_), std::max(b, mm_));
  }
  q.corners = m.corners;
  q.points.resize(static_cast<int>(pts.size()), 3);
  for (size_t i = 0; i < pts.size(); ++i) q.points.row(static_cast<int>(i)) = pts[i];
  return q;
}

// Moves every vertex by up to `amount` (seeded), so symmetric configurations cannot hide errors.
inline Mesh jittered(Mesh m, double amount, unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  for (int i = 0; i < m.num_vertices(); ++i)
    for (int c = 0; c < 3; ++c) m.points(i, c) += u(rng);
  return m;
}

// Edges whose adjacent face normals differ by more than `degrees`: the sharp features.
inline std::vector<std::pair<int, int>> sharp_edges(const Mesh& m, double degrees) {
  std::map<std::pair<int, int>, std::vector<Eigen::Vector3d>> normals;
  for (const auto& f : m.faces) {
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    const int s = static_cast<int>(f.size());
    for (int k = 0; k < s; ++k) {
      Eigen::Vector3d a = m.points.row(f[k]).transpose(), b = m.points.row(f[(k + 1) % s]).transpose();
      n += a.cross(b);
    }
    n.normalize();
    for (int k = 0; k < s; ++k) {
      const int a = f[k], b = f[(k + 1) % s];
      normals[{std::min(a, b), std::max(a, b)}].push_back(n);
    }
  }
  std::vector<std::pair<int, int>> out;
  const double c = std::cos(degrees * 3.14159265358979323846 / 180.0);
  for (const auto& [e, ns] : normals)
    if (ns.size() == 2 && ns[0].dot(ns[1]) < c) out.push_back(e);
  return out;
}

}  // namespace mm::test

// Small synthetic control polyhedra for the codec tests.
#pragma once
#include <algorithm>
#include <numeric>
#include <random>

#include "meshio/mesh.h"

namespace mm::test {

// Unit cube scaled and shifted off the origin: 6 quads, 12 crease edges, 8 corners.
inline Mesh crease_cube() {
  Mesh m;
  m.points.resize(8, 3);
  for (int i = 0; i < 8; ++i)
    m.points.row(i) << 3.0 + 2.5 * (i & 1), -7.0 + 2.5 * ((i >> 1) & 1), 0.25 + 2.5 * ((i >> 2) & 1);
  m.faces = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  m.creases = unique_edges(m);
  m.corners = {0, 1, 2, 3, 4, 5, 6, 7};
  return m;
}

// A wavy nx x ny grid: quads, with every third quad split into two triangles; a few creases
// along one row and corners at the grid corners. Vertices are shuffled with the seed so the
// stored order is not a nice scan order.
inline Mesh wavy_grid(int nx, int ny, unsigned seed) {
  Mesh m;
  const int n = nx * ny;
  std::vector<int> perm(n);
  std::iota(perm.begin(), perm.end(), 0);
  std::mt19937 rng(seed);
  std::shuffle(perm.begin(), perm.end(), rng);
  m.points.resize(n, 3);
  auto id = [&](int i, int j) { return perm[j * nx + i]; };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      m.points.row(id(i, j)) << 0.1 * i, 0.13 * j, 0.2 * std::sin(0.7 * i) * std::cos(0.4 * j);
  int q = 0;
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i, ++q) {
      const int a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      if (q % 3 == 0) {
        m.faces.push_back({a, b, c});
        m.faces.push_back({a, c, d});
      } else {
        m.faces.push_back({a, b, c, d});
      }
    }
  for (int i = 0; i + 1 < nx; ++i)
    m.creases.emplace_back(std::min(id(i, ny / 2), id(i + 1, ny / 2)),
                           std::max(id(i, ny / 2), id(i + 1, ny / 2)));
  m.corners = {id(0, 0), id(nx - 1, 0), id(0, ny - 1), id(nx - 1, ny - 1)};
  return m;
}

}  // namespace mm::test

// Small control polyhedra built in code, shared by the fitting tests.
#pragma once
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "meshio/mesh.h"

namespace mm::test {

// A closed cylinder: `rows` rows of `n` triangle pairs, fan caps around a centre vertex, the two
// rim rings as creases when `crease_rims`.
inline mm::Mesh cylinder(int n, int rows, double radius, double height, bool crease_rims, double twist = 0) {
  mm::Mesh m;
  m.points.resize((rows + 1) * n + 2, 3);
  for (int r = 0; r <= rows; ++r)
    for (int i = 0; i < n; ++i)
      m.points.row(r * n + i) << radius * std::cos(2 * M_PI * (i + twist * r) / n),
          radius * std::sin(2 * M_PI * (i + twist * r) / n), height * r / rows;
  const int bottom = (rows + 1) * n, top = bottom + 1;
  m.points.row(bottom) << 0, 0, 0;
  m.points.row(top) << 0, 0, height;
  for (int r = 0; r < rows; ++r)
    for (int i = 0; i < n; ++i) {
      const int a = r * n + i, b = r * n + (i + 1) % n, c = a + n, d = b + n;
      m.faces.push_back({a, b, d});
      m.faces.push_back({a, d, c});
    }
  for (int i = 0; i < n; ++i) {
    m.faces.push_back({bottom, (i + 1) % n, i});
    m.faces.push_back({top, rows * n + i, rows * n + (i + 1) % n});
  }
  if (crease_rims)
    for (int i = 0; i < n; ++i)
      for (int base : {0, rows * n}) {
        const int a = base + i, b = base + (i + 1) % n;
        m.creases.emplace_back(std::min(a, b), std::max(a, b));
      }
  return m;
}

inline int count_quads(const mm::Mesh& m) {
  int q = 0;
  for (const auto& f : m.faces) q += f.size() == 4;
  return q;
}

// Every directed edge once (consistently oriented) and, if `closed`, its reverse too.
inline void expect_oriented(const mm::Mesh& m, bool closed) {
  std::map<std::pair<int, int>, int> directed;
  for (const auto& f : m.faces)
    for (size_t k = 0; k < f.size(); ++k) ++directed[{f[k], f[(k + 1) % f.size()]}];
  for (const auto& [e, count] : directed) {
    EXPECT_EQ(count, 1) << e.first << "->" << e.second;
    if (closed) {
      EXPECT_EQ(directed.count({e.second, e.first}), 1u) << e.first << "->" << e.second;
    }
  }
}

}  // namespace mm::test

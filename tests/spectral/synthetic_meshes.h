// Small meshes made in code for the spectral and watermark tests and benchmarks: seeded, so every
// run sees the same geometry bit for bit.
#pragma once
#include <cmath>
#include <cstdint>
#include <random>

#include "meshio/mesh.h"

namespace mm::test {

// Uniform in [-1, 1) from a 64-bit Mersenne twister, the same on every standard library
// (std::uniform_real_distribution is not).
inline double uniform_pm1(std::mt19937_64& rng) {
  return double(rng() >> 11) * 0x1.0p-53 * 2.0 - 1.0;
}

// A closed quad torus with a x b vertices (a, b >= 3), vertices jittered by `jitter`.
inline Mesh quad_torus(int a, int b, std::uint64_t seed = 1, double jitter = 0.02) {
  Mesh m;
  m.points.resize(a * b, 3);
  std::mt19937_64 rng(seed);
  const double pi = std::acos(-1.0);
  for (int i = 0; i < a; ++i)
    for (int j = 0; j < b; ++j) {
      const double u = 2 * pi * i / a, v = 2 * pi * j / b;
      const double r = 1.0 + 0.35 * std::cos(v);
      m.points.row(i * b + j) << r * std::cos(u) + jitter * uniform_pm1(rng),
          r * std::sin(u) + jitter * uniform_pm1(rng), 0.35 * std::sin(v) + jitter * uniform_pm1(rng);
    }
  for (int i = 0; i < a; ++i)
    for (int j = 0; j < b; ++j) {
      const int i1 = (i + 1) % a, j1 = (j + 1) % b;
      m.faces.push_back({i * b + j, i1 * b + j, i1 * b + j1, i * b + j1});
    }
  return m;
}

// An open (a+1) x (b+1) grid of quads in the unit square with a seeded height field.
inline Mesh quad_grid(int a, int b, std::uint64_t seed = 1) {
  Mesh m;
  m.points.resize((a + 1) * (b + 1), 3);
  std::mt19937_64 rng(seed);
  for (int i = 0; i <= a; ++i)
    for (int j = 0; j <= b; ++j)
      m.points.row(i * (b + 1) + j) << double(i) / a, double(j) / b, 0.05 * uniform_pm1(rng);
  for (int i = 0; i < a; ++i)
    for (int j = 0; j < b; ++j)
      m.faces.push_back({i * (b + 1) + j, (i + 1) * (b + 1) + j, (i + 1) * (b + 1) + j + 1,
                         i * (b + 1) + j + 1});
  return m;
}

// The unit cube as 6 quads (graph Laplacian eigenvalues 0, 2, 2, 2, 4, 4, 4, 6).
inline Mesh cube() {
  Mesh m;
  m.points.resize(8, 3);
  for (int v = 0; v < 8; ++v) m.points.row(v) << (v & 1), (v >> 1) & 1, (v >> 2) & 1;
  m.faces = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  return m;
}

// One n-gon face: the cycle graph, eigenvalues 2 - 2 cos(2 pi k / n).
inline Mesh polygon(int n) {
  Mesh m;
  m.points.resize(n, 3);
  m.faces.emplace_back();
  const double pi = std::acos(-1.0);
  for (int v = 0; v < n; ++v) {
    m.points.row(v) << std::cos(2 * pi * v / n), std::sin(2 * pi * v / n), 0.1 * (v % 3);
    m.faces[0].push_back(v);
  }
  return m;
}

// Two disjoint pieces (a torus then a grid, vertex indices offset) plus one isolated vertex.
inline Mesh two_pieces_and_a_point() {
  Mesh a = quad_torus(6, 5, 3), b = quad_grid(4, 3, 4);
  Mesh m;
  const int na = a.num_vertices(), nb = b.num_vertices();
  m.points.resize(na + nb + 1, 3);
  m.points.topRows(na) = a.points;
  m.points.middleRows(na, nb) = b.points;
  m.points.middleRows(na, nb).col(0).array() += 3.0;
  m.points.row(na + nb) << -2.0, 0.5, 0.25;
  m.faces = a.faces;
  for (auto f : b.faces) {
    for (int& v : f) v += na;
    m.faces.push_back(f);
  }
  return m;
}

}  // namespace mm::test

// A mesh as an STL round trip or a hostile exporter leaves it: vertices renumbered by a seeded
// permutation, each face's vertex list rotated, faces listed in shuffled order. Same surface, no index correspondence left.
#pragma once
#include <algorithm>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include "meshio/mesh.h"

namespace mm::test {

inline Mesh shuffled(const Mesh& m, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<int> perm(m.num_vertices());
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), rng);
  Mesh out;
  out.points.resize(m.num_vertices(), 3);
  for (int v = 0; v < m.num_vertices(); ++v) out.points.row(perm[v]) = m.points.row(v);
  for (const auto& f : m.faces) {
    std::vector<int> g;
    for (int v : f) g.push_back(perm[v]);
    std::rotate(g.begin(), g.begin() + static_cast<long>(rng() % g.size()), g.end());
    out.faces.push_back(g);
  }
  std::shuffle(out.faces.begin(), out.faces.end(), rng);
  return out;
}

}  // namespace mm::test

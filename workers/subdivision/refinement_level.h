// Internal to workers/subdivision: one refinement level in flat arrays and its incidence, as
// the refinement rules (subdivide.cpp) read them. Not part of the library's interface.
#pragma once
#include <array>
#include <vector>

#include "meshio/mesh.h"

namespace mm::subdivision_detail {

// One refinement level in flat arrays. Face sides k go from fverts[k] to fverts[k+1]; fedges[k]
// is the edge of that side. Edge orientation matters: it orders the edge's two children.
struct Level {
  int nv = 0;
  std::vector<int> foff{0};  // size nf + 1
  std::vector<int> fverts;
  std::vector<int> fedges;
  std::vector<std::array<int, 2>> everts;
  std::vector<char> ecrease;  // tagged crease (boundary edges are sharp without a tag)
  std::vector<char> vcorner;  // tagged corner or non-manifold vertex: never moves
  int nf() const { return static_cast<int>(foff.size()) - 1; }
  int ne() const { return static_cast<int>(everts.size()); }
  int fsize(int f) const { return foff[f + 1] - foff[f]; }
};

// Compressed lists (offsets + items), for vertex-edge and vertex-face incidence.
struct Csr {
  std::vector<int> off, items;
  int size(int i) const { return off[i + 1] - off[i]; }
  const int* begin(int i) const { return items.data() + off[i]; }
  const int* end(int i) const { return items.data() + off[i + 1]; }
};

template <class ForEach>
Csr build_csr(int n, ForEach for_each_pair) {
  Csr c;
  c.off.assign(n + 1, 0);
  for_each_pair([&](int key, int) { ++c.off[key + 1]; });
  for (int i = 0; i < n; ++i) c.off[i + 1] += c.off[i];
  c.items.resize(c.off[n]);
  std::vector<int> fill(c.off.begin(), c.off.end() - 1);
  for_each_pair([&](int key, int item) { c.items[fill[key]++] = item; });
  return c;
}

// Level 0 from the mesh: validates (InputError naming the control mesh), numbers edges as
// OpenSubdiv does (faces in order, each face's sides in order, a new edge takes the orientation
// of the side that first meets it).
Level make_base_level(const Mesh& m);

// Per-level incidence the rules need.
struct Adjacency {
  std::vector<std::array<int, 2>> efaces;  // -1 when absent
  Csr vedges, vfaces;
};
Adjacency adjacency(const Level& L);

// Vertices whose faces form more than one fan (touching cones, bow-ties): kept fixed.
void mark_nonmanifold_vertices(Level& L, const Adjacency& a);

}  // namespace mm::subdivision_detail

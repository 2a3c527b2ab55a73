#include "subdivision/refinement_level.h"

#include <string>
#include <unordered_map>
#include <utility>

namespace mm::subdivision_detail {
namespace {

const char* kSource = "subdivision control mesh";

std::string edge_name(int a, int b) {
  return "edge (" + std::to_string(a) + ", " + std::to_string(b) + ")";
}

}  // namespace

Level make_base_level(const Mesh& m) {
  Level L;
  const int n = m.num_vertices();
  L.nv = n;
  if (m.faces.empty()) throw InputError(kSource, "no faces");
  long long total = 0;
  for (const auto& f : m.faces) total += static_cast<long long>(f.size());
  if (total > 100'000'000) throw InputError(kSource, "more than 100 million face corners");
  L.foff.reserve(m.faces.size() + 1);
  L.fverts.reserve(total);
  std::vector<int> seen_in_face(n, -1);  // linear repeat check, also for huge polygons
  for (size_t fi = 0; fi < m.faces.size(); ++fi) {
    const auto& f = m.faces[fi];
    auto where = [fi] { return "face " + std::to_string(fi); };
    if (f.size() < 3) throw InputError(kSource, where() + " has fewer than 3 vertices");
    for (size_t k = 0; k < f.size(); ++k) {
      if (f[k] < 0 || f[k] >= n)
        throw InputError(kSource, where() + " has vertex index " + std::to_string(f[k]) +
                                      " out of range [0, " + std::to_string(n) + ")");
      if (seen_in_face[f[k]] == static_cast<int>(fi))
        throw InputError(kSource, where() + " repeats vertex " + std::to_string(f[k]));
      seen_in_face[f[k]] = static_cast<int>(fi);
      L.fverts.push_back(f[k]);
    }
    L.foff.push_back(static_cast<int>(L.fverts.size()));
  }
  // The first step gives every edge and vertex of an n-gon (n > 4) a row with all n corners of
  // its face point: about 2 n^2 entries per n-gon. Bound it before allocating.
  long long dense = 0;
  for (const auto& f : m.faces)
    if (f.size() > 4) dense += static_cast<long long>(f.size()) * static_cast<long long>(f.size());
  if (dense > 20'000'000)
    throw InputError(kSource, "polygons too large for subdivision (sum of squared sizes of faces with "
                              "more than 4 sides is " + std::to_string(dense) + ", limit 20000000)");
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c)
      if (!std::isfinite(m.points(i, c)))
        throw InputError(kSource, "vertex " + std::to_string(i) + " has a non-finite coordinate");

  // Edges by hashed endpoint pair (a list per vertex would be quadratic on a hostile fan).
  std::unordered_map<long long, int> edge_of;
  edge_of.reserve(static_cast<size_t>(total));
  auto key = [n](int a, int b) { return static_cast<long long>(std::min(a, b)) * n + std::max(a, b); };
  std::vector<int> uses;      // faces per edge
  std::vector<int> forward;   // sides traversing the edge as everts[0] -> everts[1]
  L.fedges.resize(L.fverts.size());
  for (int f = 0; f < L.nf(); ++f) {
    const int b = L.foff[f], s = L.fsize(f);
    for (int k = 0; k < s; ++k) {
      const int v0 = L.fverts[b + k], v1 = L.fverts[b + (k + 1) % s];
      const auto [it, inserted] = edge_of.try_emplace(key(v0, v1), L.ne());
      const int e = it->second;
      if (inserted) {
        L.everts.push_back({v0, v1});
        uses.push_back(0);
        forward.push_back(0);
      }
      L.fedges[b + k] = e;
      if (++uses[e] > 2)
        throw InputError(kSource, "non-manifold " + edge_name(v0, v1) +
                                      " is shared by more than two faces");
      if (L.everts[e][0] == v0 && ++forward[e] > 1)
        throw InputError(kSource, edge_name(v0, v1) +
                                      " is traversed twice in the same direction "
                                      "(inconsistent orientation or duplicate face)");
      if (L.everts[e][0] != v0 && uses[e] - forward[e] > 1)
        throw InputError(kSource, edge_name(v0, v1) +
                                      " is traversed twice in the same direction "
                                      "(inconsistent orientation or duplicate face)");
    }
  }
  L.ecrease.assign(L.ne(), 0);
  for (const auto& [a, b] : m.creases) {
    if (a < 0 || b < 0 || a >= n || b >= n || a == b)
      throw InputError(kSource, "crease " + edge_name(a, b) + " has invalid vertex indices");
    const auto it = edge_of.find(key(a, b));
    if (it == edge_of.end()) throw InputError(kSource, "crease " + edge_name(a, b) + " is not an edge of the mesh");
    L.ecrease[it->second] = 1;
  }
  L.vcorner.assign(n, 0);
  for (int c : m.corners) {
    if (c < 0 || c >= n)
      throw InputError(kSource, "corner vertex " + std::to_string(c) + " out of range");
    L.vcorner[c] = 1;
  }
  return L;
}

Adjacency adjacency(const Level& L) {
  Adjacency a;
  a.efaces.assign(L.ne(), {-1, -1});
  for (int f = 0; f < L.nf(); ++f)
    for (int k = L.foff[f]; k < L.foff[f + 1]; ++k) {
      auto& ef = a.efaces[L.fedges[k]];
      (ef[0] < 0 ? ef[0] : ef[1]) = f;
    }
  a.vedges = build_csr(L.nv, [&](auto emit) {
    for (int e = 0; e < L.ne(); ++e) {
      emit(L.everts[e][0], e);
      emit(L.everts[e][1], e);
    }
  });
  a.vfaces = build_csr(L.nv, [&](auto emit) {
    for (int f = 0; f < L.nf(); ++f)
      for (int k = L.foff[f]; k < L.foff[f + 1]; ++k) emit(L.fverts[k], f);
  });
  return a;
}

void mark_nonmanifold_vertices(Level& L, const Adjacency& a) {
  std::vector<int> parent;
  std::vector<int> slot(L.nf(), -1);  // face -> its index among the current vertex's faces
  for (int v = 0; v < L.nv; ++v) {
    const int nfaces = a.vfaces.size(v);
    if (nfaces <= 1) continue;
    const int* fb = a.vfaces.begin(v);
    parent.resize(nfaces);
    for (int i = 0; i < nfaces; ++i) {
      parent[i] = i;
      slot[fb[i]] = i;
    }
    auto local = [&](int f) { return slot[f]; };
    auto find = [&](int i) {
      while (parent[i] != i) i = parent[i] = parent[parent[i]];
      return i;
    };
    int components = nfaces;
    for (const int* e = a.vedges.begin(v); e != a.vedges.end(v); ++e) {
      const auto& ef = a.efaces[*e];
      if (ef[1] < 0) continue;
      const int r0 = find(local(ef[0])), r1 = find(local(ef[1]));
      if (r0 != r1) {
        parent[r0] = r1;
        --components;
      }
    }
    if (components > 1) L.vcorner[v] = 1;
  }
}

}  // namespace mm::subdivision_detail

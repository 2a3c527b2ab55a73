#include "meshio/repair_manifold.h"

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

namespace mm {
namespace {

struct Analysis {
  std::vector<int> corner_offset;      // first corner id of each face
  std::vector<int> partner;            // per halfedge (= corner id of its start): paired halfedge or -1
  std::vector<std::vector<int>> bad_edges;  // halfedge groups of complex edges
  std::vector<int> fan_root;           // per corner: representative of its fan at that vertex
};

int find(std::vector<int>& parent, int x) {
  while (parent[static_cast<size_t>(x)] != x) {
    parent[static_cast<size_t>(x)] = parent[static_cast<size_t>(parent[static_cast<size_t>(x)])];
    x = parent[static_cast<size_t>(x)];
  }
  return x;
}

Analysis analyse(const Mesh& mesh) {
  Analysis a;
  const auto& faces = mesh.faces;
  a.corner_offset.resize(faces.size() + 1, 0);
  for (size_t f = 0; f < faces.size(); ++f)
    a.corner_offset[f + 1] = a.corner_offset[f] + static_cast<int>(faces[f].size());
  const int nc = a.corner_offset.back();
  std::vector<int> from(static_cast<size_t>(nc)), to(static_cast<size_t>(nc)), face_of(static_cast<size_t>(nc));
  for (size_t f = 0; f < faces.size(); ++f)
    for (size_t k = 0; k < faces[f].size(); ++k) {
      int h = a.corner_offset[f] + static_cast<int>(k);
      from[static_cast<size_t>(h)] = faces[f][k];
      to[static_cast<size_t>(h)] = faces[f][(k + 1) % faces[f].size()];
      face_of[static_cast<size_t>(h)] = static_cast<int>(f);
    }
  auto key = [&](int h) {
    uint64_t lo = static_cast<uint32_t>(std::min(from[static_cast<size_t>(h)], to[static_cast<size_t>(h)]));
    uint64_t hi = static_cast<uint32_t>(std::max(from[static_cast<size_t>(h)], to[static_cast<size_t>(h)]));
    return lo << 32 | hi;
  };
  std::vector<int> order(static_cast<size_t>(nc));
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int x, int y) { return key(x) < key(y); });
  a.partner.assign(static_cast<size_t>(nc), -1);
  for (size_t i = 0; i < order.size();) {
    size_t j = i;
    while (j < order.size() && key(order[j]) == key(order[i])) ++j;
    if (j - i == 2) {
      int h = order[i], g = order[i + 1];
      if (from[static_cast<size_t>(h)] != from[static_cast<size_t>(g)]) {
        a.partner[static_cast<size_t>(h)] = g;
        a.partner[static_cast<size_t>(g)] = h;
      } else {
        a.bad_edges.emplace_back(order.begin() + static_cast<long>(i), order.begin() + static_cast<long>(j));
      }
    } else if (j - i > 2) {
      a.bad_edges.emplace_back(order.begin() + static_cast<long>(i), order.begin() + static_cast<long>(j));
    }
    i = j;
  }
  // Corner h (at vertex from[h]) is glued to the corner of the partner face at the same vertex:
  // the partner runs to[h] -> from[h], so that corner is the partner's successor in its face.
  a.fan_root.resize(static_cast<size_t>(nc));
  std::iota(a.fan_root.begin(), a.fan_root.end(), 0);
  for (int h = 0; h < nc; ++h) {
    int p = a.partner[static_cast<size_t>(h)];
    if (p < 0) continue;
    int g = face_of[static_cast<size_t>(p)];
    int k = p - a.corner_offset[static_cast<size_t>(g)];
    int next = a.corner_offset[static_cast<size_t>(g)] + (k + 1) % static_cast<int>(faces[static_cast<size_t>(g)].size());
    int r1 = find(a.fan_root, h), r2 = find(a.fan_root, next);
    if (r1 != r2) a.fan_root[static_cast<size_t>(std::max(r1, r2))] = std::min(r1, r2);
  }
  for (int h = 0; h < nc; ++h) a.fan_root[static_cast<size_t>(h)] = find(a.fan_root, h);
  return a;
}

void check_faces(const Mesh& mesh) {
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& face = mesh.faces[f];
    std::vector<int> s = face;
    std::sort(s.begin(), s.end());
    if (face.size() < 3 || std::adjacent_find(s.begin(), s.end()) != s.end() || s.front() < 0 ||
        s.back() >= mesh.num_vertices())
      throw std::invalid_argument("repair_manifold: face " + std::to_string(f) +
                                  " needs >= 3 distinct in-range vertices");
  }
}

int append_copy(Mesh& mesh, std::vector<int>& original, int v) {
  int n = mesh.num_vertices();
  mesh.points.conservativeResize(n + 1, 3);
  mesh.points.row(n) = mesh.points.row(v);
  original.push_back(original[static_cast<size_t>(v)]);
  return n;
}

// Per vertex, the fans (roots) in order of first corner; vertex -> number of fans.
int count_split_vertices(const Mesh& mesh, const Analysis& a) {
  std::unordered_map<int, int> first_root;
  std::unordered_set<int> complex;
  int c = 0;
  for (const auto& f : mesh.faces)
    for (int v : f) {
      int r = a.fan_root[static_cast<size_t>(c++)];
      auto [it, inserted] = first_root.try_emplace(v, r);
      if (!inserted && it->second != r) complex.insert(v);
    }
  return static_cast<int>(complex.size());
}

}  // namespace

ManifoldRepair check_manifold(const Mesh& mesh) {
  check_faces(mesh);
  Analysis a = analyse(mesh);
  ManifoldRepair r;
  r.complex_edges = static_cast<int>(a.bad_edges.size());
  r.complex_vertices = count_split_vertices(mesh, a);
  r.original_vertex.resize(static_cast<size_t>(mesh.num_vertices()));
  std::iota(r.original_vertex.begin(), r.original_vertex.end(), 0);
  return r;
}

ManifoldRepair repair_manifold(Mesh& mesh) {
  ManifoldRepair r = check_manifold(mesh);
  const int n0 = mesh.num_vertices();
  // Each pass either splits a vertex or detaches a face corner, and a mesh where every face has
  // private vertices is manifold, so the loop ends; the bound only guards against a logic error.
  size_t corners = 0;
  for (const auto& f : mesh.faces) corners += f.size();
  for (size_t pass = 0; pass <= corners + 1; ++pass) {
    Analysis a = analyse(mesh);
    // 1. One vertex per fan: the fan met first keeps the index, later fans get copies.
    std::unordered_map<int, int> first_root;   // vertex -> root that keeps it
    std::unordered_map<int, int> root_vertex;  // root -> copy
    bool split = false;
    int c = 0;
    for (auto& f : mesh.faces)
      for (int& v : f) {
        int root = a.fan_root[static_cast<size_t>(c++)];
        auto [it, inserted] = first_root.try_emplace(v, root);
        if (inserted || it->second == root) continue;
        auto rv = root_vertex.find(root);
        if (rv == root_vertex.end()) rv = root_vertex.emplace(root, append_copy(mesh, r.original_vertex, v)).first;
        v = rv->second;
        split = true;
      }
    if (split) continue;
    if (a.bad_edges.empty()) break;
    // 2. Cut edges whose faces still share both endpoints: the first face keeps them, the
    // others get private copies (the next pass regroups the remaining fans).
    std::unordered_set<int> detached;
    for (const auto& group : a.bad_edges)
      for (size_t i = 1; i < group.size(); ++i) {
        int h = group[i];
        size_t f = static_cast<size_t>(std::upper_bound(a.corner_offset.begin(), a.corner_offset.end(), h) -
                                       a.corner_offset.begin() - 1);
        int k = h - a.corner_offset[f];
        int k2 = (k + 1) % static_cast<int>(mesh.faces[f].size());
        for (int kk : {k, k2}) {
          int corner = a.corner_offset[f] + kk;
          if (!detached.insert(corner).second) continue;
          int& v = mesh.faces[f][static_cast<size_t>(kk)];
          v = append_copy(mesh, r.original_vertex, v);
        }
      }
  }
  r.vertices_duplicated = mesh.num_vertices() - n0;
  return r;
}

Mesh read_mesh_manifold(const std::string& path, ReadReport* report, ManifoldRepair* repair) {
  Mesh m = read_mesh(path, report);
  ManifoldRepair r = repair_manifold(m);
  if (repair) *repair = std::move(r);
  return m;
}

}  // namespace mm

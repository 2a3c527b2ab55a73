#include "fitting/sharp_features.h"

#include <algorithm>
#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <set>

namespace mm {
namespace {

// Newell's normal: robust for non-planar polygons; zero for degenerate faces.
Eigen::Vector3d face_normal(const Mesh& m, const std::vector<int>& f) {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < f.size(); ++k) {
    Eigen::Vector3d a = m.points.row(f[k]), b = m.points.row(f[(k + 1) % f.size()]);
    n += a.cross(b);
  }
  return n;
}

// Drops short crease chains that start at a dangling end (valence 1): walking from the end
// through valence-2 vertices, if another end or a branching is reached within `min_edges` edges,
// the chain is removed. Boundary edges (one face) are never removed.
void prune_fragments(Features& f, int n, int min_edges) {
  std::vector<std::vector<int>> nbrs(n);
  for (auto [a, b] : f.sharp_edges) {
    nbrs[a].push_back(b);
    nbrs[b].push_back(a);
  }
  std::set<std::pair<int, int>> removed;
  auto key = [](int a, int b) { return std::make_pair(std::min(a, b), std::max(a, b)); };
  for (int v = 0; v < n; ++v) {
    if (nbrs[v].size() != 1) continue;
    std::vector<std::pair<int, int>> chain;
    int prev = v, cur = nbrs[v][0];
    chain.push_back(key(prev, cur));
    while (nbrs[cur].size() == 2 && static_cast<int>(chain.size()) < min_edges) {
      int next = nbrs[cur][0] == prev ? nbrs[cur][1] : nbrs[cur][0];
      prev = cur;
      cur = next;
      chain.push_back(key(prev, cur));
    }
    if (static_cast<int>(chain.size()) < min_edges && nbrs[cur].size() != 2)
      removed.insert(chain.begin(), chain.end());
  }
  if (removed.empty()) return;
  std::vector<std::pair<int, int>> kept;
  for (const auto& e : f.sharp_edges)
    if (!removed.count(e) || f.boundary_set.count(e)) kept.push_back(e);
  f.sharp_edges = std::move(kept);
  std::fill(f.sharp_valence.begin(), f.sharp_valence.end(), 0);
  for (auto [a, b] : f.sharp_edges) ++f.sharp_valence[a], ++f.sharp_valence[b];
}

}  // namespace

Features detect_features(const Mesh& mesh, const FeatureOptions& options) {
  const int n = mesh.num_vertices();
  std::vector<Eigen::Vector3d> normals(mesh.faces.size());
  double max_len = 0;
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    normals[f] = face_normal(mesh, mesh.faces[f]);
    max_len = std::max(max_len, normals[f].norm());
  }
  // Slivers (area ~ 0 relative to the largest face) carry no reliable orientation.
  const double degenerate = max_len * 1e-12;
  for (auto& nf : normals) nf = nf.norm() > degenerate ? nf.normalized() : Eigen::Vector3d::Zero();

  std::map<std::pair<int, int>, std::vector<int>> edge_faces;
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& face = mesh.faces[f];
    for (size_t k = 0; k < face.size(); ++k) {
      int a = face[k], b = face[(k + 1) % face.size()];
      if (a != b) edge_faces[{std::min(a, b), std::max(a, b)}].push_back(static_cast<int>(f));
    }
  }

  Features out;
  out.sharp_valence.assign(n, 0);
  const double cos_threshold = std::cos(options.angle_degrees * M_PI / 180.0);
  for (const auto& [e, faces] : edge_faces) {
    bool sharp = false;
    if (faces.size() == 1) {
      sharp = true;
      ++out.boundary_edges;
      out.boundary_set.insert(e);
    } else if (faces.size() > 2) {
      sharp = true;
      ++out.nonmanifold_edges;
    } else {
      const auto &n0 = normals[faces[0]], &n1 = normals[faces[1]];
      if (!n0.isZero() && !n1.isZero()) sharp = n0.dot(n1) < cos_threshold;
    }
    if (sharp) {
      out.sharp_edges.push_back(e);
      ++out.sharp_valence[e.first];
      ++out.sharp_valence[e.second];
    }
  }

  if (options.min_crease_edges > 0) prune_fragments(out, n, options.min_crease_edges);

  // Corners: crease ends (valence 1), branchings (valence >= 3) and sharp turns (valence 2).
  std::vector<std::vector<int>> crease_nbrs(n);
  for (auto [a, b] : out.sharp_edges) {
    crease_nbrs[a].push_back(b);
    crease_nbrs[b].push_back(a);
  }
  const double cos_turn = std::cos(options.corner_turn_degrees * M_PI / 180.0);
  for (int v = 0; v < n; ++v) {
    int val = out.sharp_valence[v];
    if (val == 0) continue;
    bool corner = val != 2;
    if (!corner) {
      Eigen::Vector3d p = mesh.points.row(v);
      Eigen::Vector3d d0 = p - Eigen::Vector3d(mesh.points.row(crease_nbrs[v][0]));
      Eigen::Vector3d d1 = Eigen::Vector3d(mesh.points.row(crease_nbrs[v][1])) - p;
      double l = d0.norm() * d1.norm();
      corner = l > 0 && d0.dot(d1) / l < cos_turn;
    }
    if (corner) out.corners.push_back(v);
  }
  return out;
}

bool same_crease_network(const Features& a, const Features& b) {
  return a.sharp_edges == b.sharp_edges && a.corners == b.corners;
}

}  // namespace mm

#include "meshio/mesh.h"
#include "samples/shape_building.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <stdexcept>

namespace mm::samples {
namespace {

struct Builder {
  std::vector<Eigen::Vector3d> pts;
  std::vector<std::vector<int>> faces;
  int add(const Eigen::Vector3d& p) {
    pts.push_back(p);
    return static_cast<int>(pts.size()) - 1;
  }
  Mesh finish() {
    Mesh m;
    m.points.resize(static_cast<Eigen::Index>(pts.size()), 3);
    for (size_t i = 0; i < pts.size(); ++i) m.points.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();
    m.faces = std::move(faces);
    return m;
  }
};

}  // namespace

Mesh refine(const Mesh& coarse, const std::function<int(int, int)>& segments) {
  Builder b;
  for (int i = 0; i < coarse.num_vertices(); ++i) b.add(coarse.points.row(i).transpose());
  auto P = [&](int v) -> Eigen::Vector3d { return coarse.points.row(v).transpose(); };
  // Interior points of each coarse edge, stored from the lower to the higher index.
  std::map<std::pair<int, int>, std::vector<int>> edge_points;
  auto edge = [&](int u, int v, int n) {
    std::pair<int, int> key(std::min(u, v), std::max(u, v));
    auto it = edge_points.find(key);
    if (it == edge_points.end()) {
      std::vector<int> ids{key.first};
      for (int s = 1; s < n; ++s) ids.push_back(b.add(P(key.first) + (P(key.second) - P(key.first)) * (double(s) / n)));
      ids.push_back(key.second);
      it = edge_points.emplace(key, std::move(ids)).first;
    }
    if (static_cast<int>(it->second.size()) != n + 1) throw std::logic_error("refine: inconsistent edge segments");
    std::vector<int> ids = it->second;
    if (u > v) std::reverse(ids.begin(), ids.end());
    return ids;  // from u to v
  };
  for (const auto& f : coarse.faces) {
    if (f.size() == 4) {
      int n = segments(f[0], f[1]), m = segments(f[1], f[2]);
      if (segments(f[3], f[2]) != n || segments(f[0], f[3]) != m)
        throw std::logic_error("refine: quad with unequal opposite edge counts");
      auto e01 = edge(f[0], f[1], n), e32 = edge(f[3], f[2], n);
      auto e03 = edge(f[0], f[3], m), e12 = edge(f[1], f[2], m);
      std::vector<std::vector<int>> g(static_cast<size_t>(n + 1), std::vector<int>(static_cast<size_t>(m + 1)));
      for (int i = 0; i <= n; ++i)
        for (int j = 0; j <= m; ++j) {
          int& id = g[static_cast<size_t>(i)][static_cast<size_t>(j)];
          if (j == 0) id = e01[static_cast<size_t>(i)];
          else if (j == m) id = e32[static_cast<size_t>(i)];
          else if (i == 0) id = e03[static_cast<size_t>(j)];
          else if (i == n) id = e12[static_cast<size_t>(j)];
          else {
            // Between the matching points of the two opposite edges: a coordinate shared by the
            // whole face stays bit-exact (flat CAD faces stay exactly flat).
            const Eigen::Vector3d& lo = b.pts[static_cast<size_t>(e01[static_cast<size_t>(i)])];
            const Eigen::Vector3d& hi = b.pts[static_cast<size_t>(e32[static_cast<size_t>(i)])];
            id = b.add(lo + (hi - lo) * (double(j) / m));
          }
        }
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < m; ++j) {
          auto at = [&](int a, int c) { return g[static_cast<size_t>(a)][static_cast<size_t>(c)]; };
          b.faces.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
        }
    } else if (f.size() == 3) {
      int k = segments(f[0], f[1]);
      if (segments(f[1], f[2]) != k || segments(f[0], f[2]) != k)
        throw std::logic_error("refine: triangle with unequal edge counts");
      auto e01 = edge(f[0], f[1], k), e02 = edge(f[0], f[2], k), e12 = edge(f[1], f[2], k);
      // Point (i, j) = f0 + i/k (f1 - f0) + j/k (f2 - f0), i + j <= k.
      std::map<std::pair<int, int>, int> g;
      for (int i = 0; i <= k; ++i)
        for (int j = 0; i + j <= k; ++j) {
          int id;
          if (j == 0) id = e01[static_cast<size_t>(i)];
          else if (i == 0) id = e02[static_cast<size_t>(j)];
          else if (i + j == k) id = e12[static_cast<size_t>(j)];
          else id = b.add(P(f[0]) + (P(f[1]) - P(f[0])) * (double(i) / k) + (P(f[2]) - P(f[0])) * (double(j) / k));
          g[{i, j}] = id;
        }
      for (int i = 0; i < k; ++i)
        for (int j = 0; i + j < k; ++j) {
          b.faces.push_back({g[{i, j}], g[{i + 1, j}], g[{i, j + 1}]});
          if (i + j + 1 < k) b.faces.push_back({g[{i + 1, j}], g[{i + 1, j + 1}], g[{i, j + 1}]});
        }
    } else {
      throw std::logic_error("refine: only triangles and quads");
    }
  }
  return b.finish();
}

Mesh extrude(const Region& region, double height, int layers) {
  const int n = static_cast<int>(region.points.size());
  Builder b;
  for (int layer = 0; layer <= layers; ++layer) {
    double z = height * layer / layers;
    for (const auto& p : region.points) b.add({p.x(), p.y(), z});
  }
  // Only boundary points need the intermediate layers, but keeping the full grid of layer
  // copies would leave interior points unused; so intermediate layers are remapped below.
  std::set<std::pair<int, int>> directed;
  for (const auto& f : region.faces)
    for (size_t k = 0; k < f.size(); ++k) directed.insert({f[k], f[(k + 1) % f.size()]});
  std::vector<std::pair<int, int>> boundary;
  for (const auto& f : region.faces)
    for (size_t k = 0; k < f.size(); ++k) {
      int a = f[k], c = f[(k + 1) % f.size()];
      if (!directed.count({c, a})) boundary.push_back({a, c});
    }
  std::vector<char> on_boundary(static_cast<size_t>(n), 0);
  for (auto [a, c] : boundary) on_boundary[static_cast<size_t>(a)] = on_boundary[static_cast<size_t>(c)] = 1;
  // Compact: bottom (all), top (all), intermediate layers (boundary points only).
  std::vector<int> remap(static_cast<size_t>(n * (layers + 1)), -1);
  Builder out;
  auto keep = [&](int layer, int v) {
    int old = layer * n + v;
    if (remap[static_cast<size_t>(old)] < 0) remap[static_cast<size_t>(old)] = out.add(b.pts[static_cast<size_t>(old)]);
    return remap[static_cast<size_t>(old)];
  };
  for (int v = 0; v < n; ++v) keep(0, v);
  for (int v = 0; v < n; ++v) keep(layers, v);
  for (int layer = 1; layer < layers; ++layer)
    for (int v = 0; v < n; ++v)
      if (on_boundary[static_cast<size_t>(v)]) keep(layer, v);
  for (const auto& f : region.faces) {
    std::vector<int> top, bottom;
    for (int v : f) top.push_back(keep(layers, v));
    for (auto it = f.rbegin(); it != f.rend(); ++it) bottom.push_back(keep(0, *it));
    out.faces.push_back(top);
    out.faces.push_back(bottom);
  }
  for (auto [a, c] : boundary)
    for (int layer = 0; layer < layers; ++layer)
      out.faces.push_back({keep(layer, a), keep(layer, c), keep(layer + 1, c), keep(layer + 1, a)});
  return out.finish();
}

Mesh revolve(const std::vector<Eigen::Vector2d>& profile, int sectors) {
  const int n = static_cast<int>(profile.size());
  Builder b;
  for (int s = 0; s < sectors; ++s) {
    double phi = 2 * M_PI * s / sectors;
    for (const auto& p : profile) {
      if (!(p.x() > 0)) throw std::invalid_argument("revolve: profile must stay off the axis (r > 0)");
      b.add({p.x() * std::cos(phi), p.x() * std::sin(phi), p.y()});
    }
  }
  auto at = [&](int s, int i) { return (s % sectors) * n + (i % n); };
  for (int s = 0; s < sectors; ++s)
    for (int i = 0; i < n; ++i) b.faces.push_back({at(s, i), at(s + 1, i), at(s + 1, i + 1), at(s, i + 1)});
  return b.finish();
}

std::vector<Eigen::Vector2d> subdivide_polygon(const std::vector<Eigen::Vector2d>& polygon, double edge_length) {
  std::vector<Eigen::Vector2d> out;
  for (size_t i = 0; i < polygon.size(); ++i) {
    const auto& a = polygon[i];
    const auto& c = polygon[(i + 1) % polygon.size()];
    int pieces = std::max(1, static_cast<int>(std::ceil((c - a).norm() / edge_length - 1e-9)));
    for (int k = 0; k < pieces; ++k) out.push_back(a + (c - a) * (double(k) / pieces));
  }
  return out;
}

}  // namespace mm::samples

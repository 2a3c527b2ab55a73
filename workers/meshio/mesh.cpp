#include "meshio/mesh.h"

#include <algorithm>

namespace mm {

std::vector<std::pair<int, int>> unique_edges(const Mesh& mesh) {
  std::vector<std::pair<int, int>> edges;
  for (const auto& f : mesh.faces)
    for (size_t k = 0; k < f.size(); ++k) {
      int a = f[k], b = f[(k + 1) % f.size()];
      if (a != b) edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

void check_mesh(const Mesh& mesh, const std::string& source) {
  if (mesh.faces.empty()) throw InputError(source, "no faces");
  if (mesh.num_vertices() == 0) throw InputError(source, "no vertices");
  for (Eigen::Index i = 0; i < mesh.points.rows(); ++i)
    if (!mesh.points.row(i).allFinite())
      throw InputError(source, "non-finite coordinate in vertex " + std::to_string(i));
  for (std::size_t i = 0; i < mesh.faces.size(); ++i) {
    if (mesh.faces[i].size() < 3) throw InputError(source, "face " + std::to_string(i) + " has fewer than 3 vertices");
    for (int v : mesh.faces[i])
      if (v < 0 || v >= mesh.num_vertices())
        throw InputError(source, "face " + std::to_string(i) + " index " + std::to_string(v) + " out of range");
  }
}

}  // namespace mm

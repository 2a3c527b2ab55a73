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

}  // namespace mm

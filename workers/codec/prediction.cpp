#include "codec/prediction.h"

#include <algorithm>
#include <unordered_map>

namespace mm::codec_detail {

LowerNeighbours lower_neighbours(const std::vector<std::pair<int, int>>& edges, int num_vertices) {
  LowerNeighbours nb;
  nb.start.assign(static_cast<std::size_t>(num_vertices) + 1, 0);
  for (const auto& [a, b] : edges) ++nb.start[static_cast<std::size_t>(std::max(a, b)) + 1];
  for (std::size_t i = 1; i < nb.start.size(); ++i) nb.start[i] += nb.start[i - 1];
  nb.list.resize(edges.size());
  std::vector<std::uint32_t> fill(nb.start.begin(), nb.start.end() - 1);
  for (const auto& [a, b] : edges) nb.list[fill[std::max(a, b)]++] = static_cast<std::uint32_t>(std::min(a, b));
  return nb;
}

}  // namespace mm::codec_detail

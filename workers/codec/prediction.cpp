#include "codec/prediction.h"

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

std::int64_t predict(const GridPoints& grid, int i, int axis, Prediction mode, const LowerNeighbours& nb) {
  if (mode == Prediction::plain) return 0;
  if (mode == Prediction::neighbours) {
    const std::uint32_t lo = nb.start[i], hi = nb.start[i + 1];
    if (hi > lo) {
      std::int64_t sum = 0;
      for (std::uint32_t k = lo; k < hi; ++k) sum += grid(nb.list[k], axis);
      const std::int64_t count = hi - lo;
      return (sum + count / 2) / count;  // grid values are >= 0: rounds half up
    }
  }
  return i > 0 ? grid(i - 1, axis) : 0;
}

}  // namespace mm::codec_detail

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

Parallelograms parallelograms(const std::vector<std::vector<int>>& faces, int num_vertices) {
  Parallelograms out(static_cast<std::size_t>(num_vertices), {-1, -1, -1});
  std::vector<char> seen(static_cast<std::size_t>(num_vertices), 0);
  auto key = [](int u, int v) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(u)) << 32) | static_cast<std::uint32_t>(v);
  };
  // Directed edge -> third vertex of the first triangle holding it.
  std::unordered_map<std::uint64_t, int> opposite;
  opposite.reserve(faces.size() * 3);
  for (const auto& f : faces) {
    if (f.size() == 3) {
      for (int k = 0; k < 3; ++k) {
        const int w = f[k], u = f[(k + 1) % 3], v = f[(k + 2) % 3];
        if (seen[w] || !seen[u] || !seen[v]) continue;
        const auto it = opposite.find(key(v, u));
        if (it == opposite.end()) continue;
        const int c = it->second;
        if (u < w && v < w && c < w) out[w] = {u, v, c};
      }
      for (int k = 0; k < 3; ++k) opposite.emplace(key(f[k], f[(k + 1) % 3]), f[(k + 2) % 3]);
    }
    for (int x : f) seen[x] = 1;
  }
  return out;
}

std::int64_t predict(const GridPoints& grid, int i, int axis, Prediction mode, const PredictionContext& ctx) {
  if (mode == Prediction::plain) return 0;
  if (mode == Prediction::parallelogram && ctx.parallelogram[i][0] >= 0) {
    const auto& p = ctx.parallelogram[i];
    const std::int64_t guess = static_cast<std::int64_t>(grid(p[0], axis)) + grid(p[1], axis) - grid(p[2], axis);
    return std::clamp<std::int64_t>(guess, 0, ctx.max_value);
  }
  if (mode == Prediction::neighbours || mode == Prediction::parallelogram) {
    const LowerNeighbours& nb = ctx.lower;
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

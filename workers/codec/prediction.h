// Neighbourhoods for coordinate prediction (codec/stream_v3.cpp): each quantised coordinate is
// coded against a prediction from vertices stored before it, in the given vertex order (which is
// never changed).
#pragma once
#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "codec/quantize.h"

namespace mm::codec_detail {

// For each vertex, its neighbours with a smaller index (compressed rows).
struct LowerNeighbours {
  std::vector<std::uint32_t> start;  // n + 1 offsets into list
  std::vector<std::uint32_t> list;
};
LowerNeighbours lower_neighbours(const std::vector<std::pair<int, int>>& edges, int num_vertices);

}  // namespace mm::codec_detail

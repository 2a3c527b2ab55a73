// Coordinate prediction for the stream, in the given vertex order (which is never changed):
// each quantised coordinate is coded as its difference from a prediction made from vertices
// stored before it. Predicting from already-decoded mesh neighbours beats the previous vertex
// whenever the order is not a scan order, which is the usual case for control polyhedra.
#pragma once
#include <cstdint>
#include <utility>
#include <vector>

#include "codec/quantize.h"

namespace mm::codec_detail {

enum class Prediction : std::uint8_t {
  plain = 0,       // no prediction: the value itself
  previous = 1,    // the previous vertex's value (0 for the first)
  neighbours = 2,  // rounded mean of the neighbours with smaller index; else as `previous`
};

// For each vertex, its neighbours with a smaller index (compressed rows).
struct LowerNeighbours {
  std::vector<std::uint32_t> start;  // n + 1 offsets into list
  std::vector<std::uint32_t> list;
};
LowerNeighbours lower_neighbours(const std::vector<std::pair<int, int>>& edges, int num_vertices);

// Prediction of grid(i, axis) from rows 0..i-1 of the same axis.
std::int64_t predict(const GridPoints& grid, int i, int axis, Prediction mode, const LowerNeighbours& nb);

}  // namespace mm::codec_detail

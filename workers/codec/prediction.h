// Coordinate prediction for the stream, in the given vertex order (which is never changed):
// each quantised coordinate is coded as its difference from a prediction made from vertices
// stored before it. Predicting from already-decoded mesh neighbours beats the previous vertex
// whenever the order is not a scan order, which is the usual case for control polyhedra.
#pragma once
#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "codec/quantize.h"

namespace mm::codec_detail {

enum class Prediction : std::uint8_t {
  plain = 0,       // no prediction: the value itself
  previous = 1,    // the previous vertex's value (0 for the first)
  neighbours = 2,  // rounded mean of the neighbours with smaller index; else as `previous`
  // Format version 2 and later: u + v - c (clamped to the grid) when the vertex first appears
  // in a triangle (w, u, v) of the face traversal whose edge (u, v) is shared with an earlier
  // triangle (v, u, c), all of u, v, c stored before it; else as `neighbours`.
  parallelogram = 3,
};

// For each vertex, its neighbours with a smaller index (compressed rows).
struct LowerNeighbours {
  std::vector<std::uint32_t> start;  // n + 1 offsets into list
  std::vector<std::uint32_t> list;
};
LowerNeighbours lower_neighbours(const std::vector<std::pair<int, int>>& edges, int num_vertices);

// Per vertex: the parallelogram (u, v, c) predicting it, or {-1, -1, -1}. `faces` in the
// connectivity coder's traversal order (what the decoder produces), so both sides agree.
using Parallelograms = std::vector<std::array<int, 3>>;
Parallelograms parallelograms(const std::vector<std::vector<int>>& faces, int num_vertices);

struct PredictionContext {
  LowerNeighbours lower;
  Parallelograms parallelogram;  // only needed by Prediction::parallelogram
  std::int64_t max_value = 0;    // grid maximum; parallelogram predictions are clamped to it
};

// Prediction of grid(i, axis) from rows 0..i-1 of the same axis.
std::int64_t predict(const GridPoints& grid, int i, int axis, Prediction mode, const PredictionContext& ctx);

}  // namespace mm::codec_detail

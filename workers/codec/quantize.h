// Uniform quantisation of positions onto an integer grid: p = offset + q * step, q in
// [0, 2^bits - 1] per axis. The grid covers the bounding box, its step set by the longest side.
//
// The grid has power-of-two cells: step = 2^e and
// offset = (o + 1/2) 2^e with integer o per axis, so a point is coded by the cell
// floor(p / 2^e) - o it falls in and decodes to that cell's centre (exactly: (2 (o + q) + 1)
// 2^(e-1) is a double). Such a grid takes a few bytes to store (e and three integers instead
// of four binary64 values), and it is exactly reproducible: e is the smallest exponent whose
// cells hold every coordinate in 2^bits cells per axis with cell numbers in [-2^50, 2^50];
// the cells of decoded centres are the same cells, and one exponent lower they are twice as
// many (2 (o + q) + 1, odd), so no smaller exponent fits them either (docs/stream-format.md
// has the argument).
#pragma once
#include <Eigen/Core>
#include <cstdint>

#include "meshio/mesh.h"

namespace mm {

using GridPoints = Eigen::Matrix<std::int32_t, Eigen::Dynamic, 3, Eigen::RowMajor>;

struct Quantization {
  int bits = 12;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // grid origin (bounding box minimum)
  double step = 1.0;                                 // grid spacing, same on every axis
  std::int32_t max_value() const { return static_cast<std::int32_t>((1u << bits) - 1u); }
};

// Bits per coordinate: 6..24 in all. Version 3 stores 8..24; version 4 (version 3 with a
// wider bits field) holds 6 and 7, for polyhedra whose surface meets the tolerance on such a
// coarse grid (abc9: 42 vertices at 7 bits, 116 bytes, against 132 at 8).
constexpr int kMinQuantBits = 6, kMaxQuantBits = 24;
constexpr int kMinQuantBitsV3 = 8;  // the fewest version 3 stores

// The grid for these points. The cells of decoded centres are the same cells, so re-quantising
// dequantised points gives the same grid bit for bit; this is what makes
// encode(decode(encode(m))) byte-identical. Throws InputError("quantize", ...) for
// bits outside [kMinQuantBits, kMaxQuantBits] or non-finite coordinates.
Quantization quantization_for(const Points& points, int bits);

// Power-of-two cell grids: exponent limits (cell size 2^e) and the cell number bound.
constexpr int kMinCellExponent = -1000, kMaxCellExponent = 1000;
constexpr std::int64_t kMaxCellNumber = std::int64_t{1} << 50;

// Grid coordinates of points on the given grid (rounded to nearest, clamped to the grid).
GridPoints quantize(const Points& points, const Quantization& q);
Points dequantize(const GridPoints& grid, const Quantization& q);

// The positions a decoder will see: dequantize(quantize(p)) on quantization_for(p, bits).
Points quantized_positions(const Points& points, int bits);

}  // namespace mm

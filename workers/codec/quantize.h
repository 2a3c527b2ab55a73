// Uniform quantisation of positions onto an integer grid: p = offset + q * step, q in
// [0, 2^bits - 1] per axis. The grid covers the bounding box, its step set by the longest side.
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

constexpr int kMinQuantBits = 8, kMaxQuantBits = 24;

// The grid for these points. The step is a fixed point of "quantise, dequantise, measure
// again", so re-quantising dequantised points gives the same grid bit for bit; this is what
// makes encode(decode(encode(m))) byte-identical. Throws InputError("quantize", ...) for
// bits outside [kMinQuantBits, kMaxQuantBits] or non-finite coordinates.
Quantization quantization_for(const Points& points, int bits);

// Grid coordinates of points on the given grid (rounded to nearest, clamped to the grid).
GridPoints quantize(const Points& points, const Quantization& q);
Points dequantize(const GridPoints& grid, const Quantization& q);

// The positions a decoder will see: dequantize(quantize(p)) on quantization_for(p, bits).
Points quantized_positions(const Points& points, int bits);

}  // namespace mm

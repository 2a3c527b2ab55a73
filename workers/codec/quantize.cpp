#include "codec/quantize.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace mm {
namespace {

struct Box {
  Eigen::Vector3d lo, hi;
};

Box bounds(const Points& points) {
  Box b{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  if (points.rows() == 0) return b;
  b.lo = points.colwise().minCoeff().transpose();
  b.hi = points.colwise().maxCoeff().transpose();
  return b;
}

}  // namespace

namespace {

void check_quantisable(const Points& points, int bits) {
  if (bits < kMinQuantBits || bits > kMaxQuantBits)
    throw InputError("quantize", "quantisation bits " + std::to_string(bits) + " outside [" +
                                     std::to_string(kMinQuantBits) + ", " +
                                     std::to_string(kMaxQuantBits) + "]");
  if (!points.allFinite()) throw InputError("quantize", "non-finite coordinates");
  const Box box = bounds(points);
  if (!((box.hi - box.lo).array() < 1e300).all() || !(box.lo.array().abs() < 1e300).all())
    throw InputError("quantize", "coordinates too large to quantise");
}

// Whether cells of size 2^e hold the box: every cell number floor(x / 2^e) in
// [-kMaxCellNumber, kMaxCellNumber] and at most 2^bits cells per axis. Monotone in e.
bool cells_fit(const Box& box, int bits, int e) {
  for (int a = 0; a < 3; ++a) {
    const double lo = std::floor(std::ldexp(box.lo[a], -e)), hi = std::floor(std::ldexp(box.hi[a], -e));
    if (lo < -static_cast<double>(kMaxCellNumber) || hi > static_cast<double>(kMaxCellNumber)) return false;
    if (hi - lo > static_cast<double>((1u << bits) - 1u)) return false;
  }
  return true;
}

}  // namespace

Quantization quantization_for(const Points& points, int bits) {
  check_quantisable(points, bits);
  const Box box = bounds(points);
  // Start below the answer: at e0 the longest side spans more than 2^(bits+1) cells, or the
  // largest coordinate's cell number exceeds 2^51; the predicate is monotone, so the first
  // exponent that fits from there is the smallest of all.
  int e = kMinCellExponent;
  const double extent = (box.hi - box.lo).maxCoeff();
  const double magnitude = std::max(box.lo.cwiseAbs().maxCoeff(), box.hi.cwiseAbs().maxCoeff());
  if (extent > 0) e = std::max(e, std::ilogb(extent) - bits - 2);
  if (magnitude > 0) e = std::max(e, std::ilogb(magnitude) - 52);
  while (!cells_fit(box, bits, e)) {
    if (++e > kMaxCellExponent) throw InputError("quantize", "coordinates too large to quantise");
  }
  Quantization q;
  q.bits = bits;
  q.step = std::ldexp(1.0, e);
  for (int a = 0; a < 3; ++a) q.offset[a] = std::ldexp(2.0 * std::floor(std::ldexp(box.lo[a], -e)) + 1.0, e - 1);
  return q;
}

GridPoints quantize(const Points& points, const Quantization& q) {
  GridPoints grid(points.rows(), 3);
  const double top = q.max_value();
  const int e = std::ilogb(q.step);
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    for (int a = 0; a < 3; ++a) {
      const double origin = std::floor(std::ldexp(q.offset[a], -e));
      const double v = std::floor(std::ldexp(points(i, a), -e)) - origin;
      grid(i, a) = static_cast<std::int32_t>(std::clamp(std::isfinite(v) ? v : 0.0, 0.0, top));
    }
  return grid;
}

Points dequantize(const GridPoints& grid, const Quantization& q) {
  Points p(grid.rows(), 3);
  for (Eigen::Index i = 0; i < grid.rows(); ++i)
    for (int a = 0; a < 3; ++a) p(i, a) = q.offset[a] + grid(i, a) * q.step;
  return p;
}

Points quantized_positions(const Points& points, int bits) {
  const Quantization q = quantization_for(points, bits);
  return dequantize(quantize(points, q), q);
}

}  // namespace mm

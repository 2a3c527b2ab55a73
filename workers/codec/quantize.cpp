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

// Step for a box: longest side over the number of grid intervals.
double step_for(const Box& b, int bits) {
  const double extent = (b.hi - b.lo).maxCoeff();
  const double intervals = static_cast<double>((1u << bits) - 1u);
  const double step = extent / intervals;
  return step > 0 && std::isfinite(step) ? step : 1.0;  // a single point or a flat nothing
}

}  // namespace

Quantization quantization_for(const Points& points, int bits) {
  if (bits < kMinQuantBits || bits > kMaxQuantBits)
    throw InputError("quantize", "quantisation bits " + std::to_string(bits) + " outside [" +
                                     std::to_string(kMinQuantBits) + ", " +
                                     std::to_string(kMaxQuantBits) + "]");
  if (!points.allFinite()) throw InputError("quantize", "non-finite coordinates");
  const Box box = bounds(points);
  if (!((box.hi - box.lo).array() < 1e300).all() || !(box.lo.array().abs() < 1e300).all())
    throw InputError("quantize", "coordinates too large to quantise");
  Quantization q;
  q.bits = bits;
  q.offset = box.lo;
  q.step = step_for(box, bits);
  // Iterate to a fixed point: the box of the dequantised points must give back the same step
  // (the offset is reproduced exactly, as some point of each axis sits at grid value 0). It
  // converges in one or two rounds; the step moves by a few ulps at most.
  for (int round = 0; round < 16; ++round) {
    const Points back = dequantize(quantize(points, q), q);
    const double again = step_for(bounds(back), bits);
    if (again == q.step) break;
    q.step = again;
  }
  return q;
}

GridPoints quantize(const Points& points, const Quantization& q) {
  GridPoints grid(points.rows(), 3);
  const double top = q.max_value();
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    for (int a = 0; a < 3; ++a) {
      const double v = std::round((points(i, a) - q.offset[a]) / q.step);
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

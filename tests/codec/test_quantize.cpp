#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "codec/quantize.h"

namespace {

mm::Points random_points(int n, unsigned seed, double scale, double shift) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  mm::Points p(n, 3);
  for (int i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) p(i, a) = shift + scale * u(rng) * (a + 1);
  return p;
}

}  // namespace

TEST(Quantize, GridCoversTheBoxAndErrorIsHalfAStep) {
  for (int bits : {8, 10, 12, 16, 20, 24}) {
    const mm::Points p = random_points(500, 7u + bits, 3.0, 100.0);
    const mm::Quantization q = mm::quantization_for(p, bits);
    const mm::GridPoints g = mm::quantize(p, q);
    EXPECT_EQ(g.minCoeff(), 0);
    EXPECT_EQ(g.maxCoeff(), q.max_value()) << bits;  // the longest axis spans the whole grid
    const mm::Points back = mm::dequantize(g, q);
    EXPECT_LE((back - p).cwiseAbs().maxCoeff(), 0.5 * q.step * (1 + 1e-6)) << bits;
    // Longest side is 2 * 3 * 3 = 18 units (z axis).
    EXPECT_NEAR(q.step * q.max_value(), (p.col(2).maxCoeff() - p.col(2).minCoeff()), 1e-9);
  }
}

TEST(Quantize, RequantisingDequantisedPointsIsExact) {
  for (unsigned seed = 0; seed < 40; ++seed)
    for (int bits : {10, 12, 16, 24}) {
      const mm::Points p = random_points(50 + seed, seed, std::pow(10.0, int(seed % 9) - 4),
                                         (seed % 5) * 123.456);
      const mm::Quantization q = mm::quantization_for(p, bits);
      const mm::GridPoints g = mm::quantize(p, q);
      const mm::Points back = mm::dequantize(g, q);
      const mm::Quantization q2 = mm::quantization_for(back, bits);
      ASSERT_EQ(q2.step, q.step) << seed << " " << bits;
      ASSERT_EQ(q2.offset, q.offset);
      ASSERT_EQ(mm::quantize(back, q2), g);
    }
}

TEST(Quantize, DegenerateInputs) {
  mm::Points one(1, 3);
  one << 1.5, -2, 3;
  const mm::Quantization q = mm::quantization_for(one, 12);
  EXPECT_GT(q.step, 0);
  EXPECT_EQ(mm::quantized_positions(one, 12), one);
  EXPECT_EQ(mm::quantized_positions(mm::Points(0, 3), 12).rows(), 0);
  mm::Points bad = one;
  bad(0, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(mm::quantization_for(bad, 12), mm::InputError);
  EXPECT_THROW(mm::quantization_for(one, 7), mm::InputError);
  EXPECT_THROW(mm::quantization_for(one, 25), mm::InputError);
}

#include <gtest/gtest.h>

#include <cmath>
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

TEST(Quantize, CellGridCoversTheBoxAndErrorIsHalfAStep) {
  for (int bits : {8, 10, 12, 16, 20, 24}) {
    const mm::Points p = random_points(500, 7u + bits, 3.0, 100.0);
    const mm::Quantization q = mm::quantization_for(p, bits);
    int e = 0;
    EXPECT_EQ(std::frexp(q.step, &e), 0.5);  // a power of two
    const mm::GridPoints g = mm::quantize(p, q);
    EXPECT_EQ(g.minCoeff(), 0);
    // The smallest power of two that fits: the longest axis uses more than half the cells.
    EXPECT_LE(g.maxCoeff(), q.max_value());
    EXPECT_GT(g.maxCoeff(), q.max_value() / 2) << bits;
    const mm::Points back = mm::dequantize(g, q);
    EXPECT_LE((back - p).cwiseAbs().maxCoeff(), 0.5 * q.step) << bits;  // exact: cell centres
    EXPECT_LE(q.step * q.max_value(), 2 * (p.col(2).maxCoeff() - p.col(2).minCoeff()) * (1 + 1e-12));
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

TEST(Quantize, CellGridIsAFixedPointOnAwkwardBoxes) {
  // Boxes whose longest side sits at the edges the choice of exponent turns on (just below and
  // above powers of two times the cell count), tiny point sets, offsets of either sign and
  // points far from the origin: quantising the decoded points again gives the same grid.
  std::mt19937 rng(20261201);
  std::uniform_int_distribution<int> pick(0, 1 << 20);
  int cases = 0;
  for (int bits : {8, 9, 12, 24})
    for (int k = 0; k < 400; ++k) {
      const int n = 2 + k % 4;
      mm::Points p(n, 3);
      const double unit = std::ldexp(1.0, k % 40 - 20);
      const double side = unit * ((1 << bits) - 2 + k % 5) * (1 + (pick(rng) - (1 << 19)) * 1e-12);
      const double shift = (k % 3 - 1) * unit * pick(rng) * (k % 7 == 0 ? 1e9 : 1.0);
      for (int i = 0; i < n; ++i)
        for (int a = 0; a < 3; ++a) p(i, a) = shift + (i == 0 ? 0.0 : side * pick(rng) / (1 << 20)) * (a == 0 && i == 1 ? 0 : 1);
      p(1, 0) = shift + side;
      const mm::Quantization q = mm::quantization_for(p, bits);
      const mm::GridPoints g = mm::quantize(p, q);
      const mm::Points back = mm::dequantize(g, q);
      ASSERT_LE((back - p).cwiseAbs().maxCoeff(), 0.5 * q.step);
      const mm::Quantization q2 = mm::quantization_for(back, bits);
      ASSERT_EQ(q2.step, q.step) << bits << " " << k;
      ASSERT_EQ(q2.offset, q.offset) << bits << " " << k;
      ASSERT_EQ(mm::quantize(back, q2), g);
      ++cases;
    }
  EXPECT_EQ(cases, 1600);
}

TEST(Quantize, DegenerateInputs) {
  mm::Points one(1, 3);
  one << 1.5, -2, 3;
  const mm::Quantization q = mm::quantization_for(one, 12);
  EXPECT_GT(q.step, 0);
  // A single point moves to the centre of a cell of 2^-48 (the smallest whose cell numbers, up
  // to 3 / 2^-48, stay within 2^50).
  EXPECT_EQ(q.step, std::ldexp(1.0, -48));
  EXPECT_LE((mm::quantized_positions(one, 12) - one).cwiseAbs().maxCoeff(), 0.5 * q.step);
  EXPECT_EQ(mm::quantized_positions(mm::Points(0, 3), 12).rows(), 0);
  mm::Points bad = one;
  bad(0, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(mm::quantization_for(bad, 12), mm::InputError);
  EXPECT_THROW(mm::quantization_for(one, 5), mm::InputError);
  EXPECT_THROW(mm::quantization_for(one, 25), mm::InputError);
}

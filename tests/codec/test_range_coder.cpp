// The range coder's ideal costs: the snapping's cost model compares them to choose values, so
// the table they come from must give exactly -log2(p / 65536) * 256, rounded, for every
// probability a model can hold, and the encoder's running cost must be their sum. Neither
// leaving the costs out nor the adaptation's division by a multiply may change a coded byte.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "codec/range_coder.h"

namespace {

using mm::codec_detail::BitModel;

std::uint32_t computed(std::uint32_t p16) {
  return static_cast<std::uint32_t>(std::lround(-std::log2(p16 / 65536.0) * 256.0));
}

TEST(RangeCoder, BitCostsAreTheRoundedLog2OfEveryProbability) {
  for (std::uint32_t p = 48; p <= 65536 - 48; ++p) {
    BitModel m;
    m.p = static_cast<std::uint16_t>(p);
    ASSERT_EQ(mm::codec_detail::bit_cost_256(m, 0), computed(p)) << p;
    ASSERT_EQ(mm::codec_detail::bit_cost_256(m, 1), computed(65536 - p)) << p;
  }
}

TEST(RangeCoder, EncoderCostIsTheSumOfItsBitsCosts) {
  std::mt19937 rng(5);
  mm::codec_detail::RangeEncoder rc;
  BitModel coded, mirror;
  std::uint64_t sum = 0;
  for (int i = 0; i < 5000; ++i) {
    const int b = (rng() % 10) < 2;  // skewed, so the model moves away from one half
    sum += mm::codec_detail::bit_cost_256(mirror, b);
    mm::codec_detail::adapt(mirror, b);
    rc.bit(coded, b);
  }
  rc.bits(0x2A5u, 10);
  EXPECT_EQ(rc.cost_256(), sum + 10 * 256);
  EXPECT_LT(rc.cost_256(), 5010ull * 256);  // skewed bits cost less than one bit each
}

TEST(RangeCoder, EncoderWithoutCostCodesTheSameBytes) {
  std::mt19937 rng(6);
  mm::codec_detail::RangeEncoder counting, plain(false);
  BitModel a, b;
  for (int i = 0; i < 5000; ++i) {
    const int bit = (rng() % 10) < 3;
    counting.bit(a, bit);
    plain.bit(b, bit);
  }
  EXPECT_EQ(plain.cost_256(), 0u);
  EXPECT_GT(counting.cost_256(), 0u);
  EXPECT_EQ(plain.finish(), counting.finish());
}

// The models' adaptation divides by its rate with a multiply: exactly the integer quotient for
// every value a probability or its complement can take.
TEST(RangeCoder, RateDivisionIsExact) {
  for (int rate = 1; rate <= mm::codec_detail::kMaxRate; ++rate)
    for (std::uint32_t x = 0; x <= 65536; ++x)
      ASSERT_EQ(mm::codec_detail::divide_by_rate(x, rate), x / static_cast<std::uint32_t>(rate)) << x << " / " << rate;
}

}  // namespace

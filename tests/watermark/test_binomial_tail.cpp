#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>

#include "watermark/binomial_tail.h"

namespace mm {
namespace {

// Exact for m <= 62: integer binomial coefficients, the sum fits in 64 bits.
long double brute_force_tail(int m, int k) {
  std::uint64_t sum = 0, c = 1;  // c = C(m, i)
  for (int i = 0; i <= m; ++i) {
    if (i >= k) sum += c;
    c = c * (m - i) / (i + 1);
  }
  return static_cast<long double>(sum) / std::ldexp(1.0L, m);
}

TEST(BinomialTail, MatchesBruteForceForSmallM) {
  for (int m = 0; m <= 62; ++m)
    for (int k = 0; k <= m + 1; ++k) {
      const BinomialTail t = binomial_upper_tail(m, k);
      const long double exact = k > m ? 0.0L : brute_force_tail(m, k);
      if (exact == 0) {
        EXPECT_EQ(t.p, 0.0);
        continue;
      }
      EXPECT_NEAR(t.p / double(exact), 1.0, 1e-12) << "m=" << m << " k=" << k;
      EXPECT_NEAR(t.neg_log10_p, -std::log10(double(exact)), 1e-11);
    }
}

TEST(BinomialTail, MatchesLongDoubleSumsForLargeM) {
  // Terms by the multiplicative recurrence in long double (range to 1e-4932).
  for (int m : {500, 2000, 4000})
    for (int k : {m / 2, m / 2 + 40, (3 * m) / 4, m - 3}) {
      long double term = std::pow(0.5L, m), sum = 0;  // C(m,0)/2^m
      for (int i = 0; i <= m; ++i) {
        if (i >= k) sum += term;
        term = term * (m - i) / (i + 1);
      }
      const BinomialTail t = binomial_upper_tail(m, k);
      EXPECT_NEAR(t.log_p, double(std::log(sum)), 1e-9 * std::max(1.0, std::abs(t.log_p)))
          << "m=" << m << " k=" << k;
    }
}

TEST(BinomialTail, KnownValues) {
  EXPECT_EQ(binomial_upper_tail(10, 0).p, 1.0);
  EXPECT_EQ(binomial_upper_tail(0, 0).p, 1.0);
  EXPECT_NEAR(binomial_upper_tail(1, 1).p, 0.5, 1e-15);
  EXPECT_NEAR(binomial_upper_tail(10, 8).p, 56.0 / 1024, 1e-15);
  EXPECT_NEAR(binomial_upper_tail(1000, 1000).p / std::ldexp(1.0, -1000), 1.0, 1e-12);
  EXPECT_EQ(binomial_upper_tail(5, 6).p, 0.0);
  EXPECT_TRUE(std::isinf(binomial_upper_tail(5, 6).neg_log10_p));
  // m = 10^5: P[X >= m/2] = 1/2 + P[X = m/2]/2, P[X = m/2] ~ sqrt(2/(pi m)) (1 - 1/(4m)).
  const double m = 1e5, half = 0.5 + 0.5 * std::sqrt(2 / (std::acos(-1.0) * m)) * (1 - 0.25 / m);
  EXPECT_NEAR(binomial_upper_tail(100000, 50000).p, half, 1e-9);
}

TEST(BinomialTail, TinyTailsKeepTheirExponent) {
  // 2^-100000: far below the smallest double; p clamps, -log10 p stays exact.
  const BinomialTail t = binomial_upper_tail(100000, 100000);
  EXPECT_EQ(t.p, std::numeric_limits<double>::denorm_min());
  EXPECT_NEAR(t.neg_log10_p, 100000 * std::log10(2.0), 1e-6);
  // P[X >= m - 1] = (m + 1) 2^-m.
  const BinomialTail u = binomial_upper_tail(100000, 99999);
  EXPECT_NEAR(u.neg_log10_p, 100000 * std::log10(2.0) - std::log10(100001.0), 1e-6);
  // Around 1e-300, still a normal double.
  const BinomialTail v = binomial_upper_tail(997, 997);
  EXPECT_NEAR(v.p / std::ldexp(1.0, -997), 1.0, 1e-12);
}

TEST(BinomialTail, MonotoneInK) {
  double last = 2;
  for (int k = 0; k <= 3001; ++k) {
    const double p = binomial_upper_tail(3000, k).log_p;
    EXPECT_LE(p, last);
    last = p;
  }
}

TEST(MajorityVoteTail, MatchesEnumeration) {
  const std::vector<int> copies = {3, 3, 2, 1, 4};
  int total = 0;
  for (int r : copies) total += r;
  std::vector<double> count(total + 1, 0.0);
  for (std::uint32_t mask = 0; mask < (1u << total); ++mask) {
    int s = 0, bit = 0;
    for (int r : copies) {
      int ones = 0;
      for (int c = 0; c < r; ++c) ones += (mask >> bit++) & 1;
      s += std::max(ones, r - ones);
    }
    count[s] += 1;
  }
  for (int k = 0; k <= total + 1; ++k) {
    double tail = 0;
    for (int s = k; s <= total; ++s) tail += count[s];
    tail /= double(1u << total);
    const BinomialTail t = majority_vote_tail(copies, k);
    if (tail == 0)
      EXPECT_EQ(t.p, 0.0) << k;
    else
      EXPECT_NEAR(t.p, tail, 1e-15) << k;
  }
}

TEST(MajorityVoteTail, SingleCopiesAreCertain) {
  // With one copy per bit, the decoded message always agrees with every copy.
  EXPECT_EQ(majority_vote_tail(std::vector<int>(50, 1), 50).p, 1.0);
  // One bit with r copies: P[max(A, r-A) = r] = 2^(1-r).
  EXPECT_NEAR(majority_vote_tail({20}, 20).p, std::ldexp(1.0, -19), 1e-20);
}

}  // namespace
}  // namespace mm

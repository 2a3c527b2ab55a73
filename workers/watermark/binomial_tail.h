// The exact one-sided binomial tail used as the watermark's p-value: the probability that a mesh
// carrying no mark (or checked with the wrong key) agrees with the sequence at least this well.
#pragma once
#include <vector>

namespace mm {

struct BinomialTail {
  double log_p = 0;        // natural log of P[X >= k], exact up to rounding, never -inf
  double p = 1;            // exp(log_p), clamped to the smallest positive (subnormal) double
  double neg_log10_p = 0;  // -log10 P[X >= k]: keeps its meaning where p has underflowed
};

// X ~ Binomial(m, 1/2). Summed in log space (lgamma + log-sum-exp), so it is accurate for m up to
// 10^6 and for tails far below 1e-308. k <= 0 gives p = 1; k > m gives p = 0 (log_p = -inf,
// neg_log10_p = +inf). Throws std::invalid_argument for m < 0.
BinomialTail binomial_upper_tail(long m, long k);

// The tail of the majority-vote agreement count, for extraction without the expected message:
// bit i has copies[i] fair +-1 votes, A_i of them +1, and decoding picks the majority, so the
// copies agreeing with the decoded message number M_i = max(A_i, copies[i] - A_i). Returns
// P[sum M_i >= k] by exact convolution in long double (accurate down to ~1e-4900; below that the
// tail is reported as underflowed: p = smallest double, neg_log10_p = 4900).
BinomialTail majority_vote_tail(const std::vector<int>& copies, long k);

}  // namespace mm

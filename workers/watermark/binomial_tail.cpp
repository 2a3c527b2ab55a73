#include "watermark/binomial_tail.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace mm {
namespace {

// glibc's lgamma writes the global signgam; lgamma_r does not, so it is safe from the daemon's
// worker threads. All arguments here are >= 1, where the sign is always positive.
double log_gamma(double x) {
#if defined(__GLIBC__)
  int sign = 0;
  return ::lgamma_r(x, &sign);
#else
  return std::lgamma(x);
#endif
}

double log_choose(long m, long i) {
  return log_gamma(double(m) + 1) - log_gamma(double(i) + 1) - log_gamma(double(m - i) + 1);
}

}  // namespace

BinomialTail binomial_upper_tail(long m, long k) {
  if (m < 0) throw std::invalid_argument("binomial_upper_tail: negative trial count");
  BinomialTail t;
  if (k <= 0) return t;
  if (k > m) {
    t.log_p = -std::numeric_limits<double>::infinity();
    t.p = 0;
    t.neg_log10_p = std::numeric_limits<double>::infinity();
    return t;
  }
  // Terms C(m,i) 2^-m for i = k..m; the largest is at i = max(k, m/2).
  const long peak = std::max(k, m / 2);
  const double log_peak = log_choose(m, peak);
  double sum = 0;  // sum of exp(log C(m,i) - log_peak), >= 1 since the peak term is 1
  for (long i = k; i <= m; ++i) {
    const double rel = log_choose(m, i) - log_peak;
    if (rel < -745 && i > peak) break;  // every later term is smaller still and underflows
    sum += std::exp(rel);
  }
  t.log_p = std::min(0.0, log_peak + std::log(sum) - double(m) * std::log(2.0));
  t.p = std::max(std::exp(t.log_p), std::numeric_limits<double>::denorm_min());
  t.neg_log10_p = -t.log_p / std::log(10.0);
  return t;
}

}  // namespace mm

namespace mm {

BinomialTail majority_vote_tail(const std::vector<int>& copies, long k) {
  // dist[s] = P[sum of M_i so far == s]; starts as the point mass at 0.
  std::vector<long double> dist{1.0L};
  for (int r : copies) {
    if (r < 0) throw std::invalid_argument("majority_vote_tail: negative copy count");
    if (r == 0) continue;
    // P[M = v] for v = ceil(r/2)..r: C(r,v) 2^-r from each side, once when v == r - v.
    std::vector<long double> pm(r + 1, 0.0L);
    for (int v = 0; v <= r; ++v)
      pm[std::max(v, r - v)] +=
          std::exp(static_cast<long double>(log_choose(r, v)) - r * std::log(2.0L));
    std::vector<long double> next(dist.size() + r, 0.0L);
    for (std::size_t s = 0; s < dist.size(); ++s)
      if (dist[s] != 0)
        for (int v = (r + 1) / 2; v <= r; ++v) next[s + v] += dist[s] * pm[v];
    dist.swap(next);
  }
  BinomialTail t;
  if (k <= 0) return t;
  if (static_cast<long>(dist.size()) <= k) {
    t.log_p = -std::numeric_limits<double>::infinity();
    t.p = 0;
    t.neg_log10_p = std::numeric_limits<double>::infinity();
    return t;
  }
  long double tail = 0;
  for (std::size_t s = dist.size(); s-- > 0 && static_cast<long>(s) >= k;) tail += dist[s];
  if (tail <= 0) {
    t.log_p = -4900 * std::log(10.0);
  } else {
    t.log_p = std::min(0.0, static_cast<double>(std::log(tail)));
  }
  t.p = std::max(std::exp(t.log_p), std::numeric_limits<double>::denorm_min());
  t.neg_log10_p = -t.log_p / std::log(10.0);
  return t;
}

}  // namespace mm

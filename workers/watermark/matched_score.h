// A magnitude-aware detection statistic beside extract()'s sign count, distribution-free.
//
// extract() keeps one sign per coefficient, so a coefficient the attack pushed far and one it
// barely moved weigh the same, and an attack's systematic part (smoothing's shrink) turns every
// sign one way. Here each coefficient's displacement d_j = (W^T (suspect - original))_j is kept
// as a number, in the direction its mark would move it (sign of C_j for a multiplicative move),
// with its attack bias taken out and weighted by how much it can say:
//
//   u_j = (d_j - beta_b C_j) s_j g_j / (g_j^2 + sigma_b^2)
//
// g_j is the mark's move |a C_j| or T a, s_j its direction, beta_b the band's systematic gain
// (a least-squares fit of d on C over a band of neighbouring frequencies, removed only when it is
// larger than the mark could cause), sigma_b^2 the band's spread of d. None of it depends on a
// key. A copy's sequence B (+-1 per coefficient) is scored by T = sum_j u_j B_j / |u|: for a
// suspect made without that copy's key stream, the B_j are independent fair signs whatever u is,
// so by Hoeffding's inequality P[T >= t] <= exp(-t^2 / 2), exactly, with no model of the noise.
// Each message bit is decoded from the weighted votes of its coefficients.
#pragma once
#include <vector>

#include "watermark/watermark.h"

namespace mm {

// What a suspect shows, for every copy of one polyhedron: key-independent.
struct CoefficientEvidence {
  int message_bits = 0;
  int repeat = 0;
  std::vector<double> u;  // per sequence entry j < repeat * message_bits
  int bias_bands = 0;     // bands whose systematic gain was removed
};

// Throws like extract() for a suspect of the wrong vertex count or non-finite coordinates.
CoefficientEvidence coefficient_evidence(const SpectralBasis& basis, const Points& original, const Points& suspect,
                                         int message_bits, const EmbedParams& params);

struct MatchedScore {
  double statistic = 0;    // T
  double p = 1;            // Hoeffding's bound exp(-T^2 / 2) for T > 0, else 1
  double neg_log10_p = 0;  // T^2 / (2 ln 10), meaningful where p underflows
  std::vector<bool> message;  // decoded from the weighted votes
};

// The copy's sequence is make_sequence(expected, ...). Throws std::invalid_argument for an
// expected message of another length than the evidence's.
MatchedScore matched_score(const CoefficientEvidence& evidence, const Key& key, const Nonce& nonce,
                           const std::vector<bool>& expected, int num_coefficients);

}  // namespace mm

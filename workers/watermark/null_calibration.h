// An empirical null for the extraction statistic: the same correlation, computed from the same
// recovered signs B'', against sequences that belong to no issued copy. Their spread is the
// chance level of *this* suspect, so a calibrated p-value does not rest on the binomial model
// alone. The null sequences are public and fixed (XChaCha20 under a key and nonces derived by
// BLAKE2b from a domain string and the sequence index): the same suspect gives the same numbers.
#pragma once
#include <cstdint>
#include <vector>

namespace mm {

constexpr int kNullSequences = 256;

struct NullCalibration {
  int sequences = 0;       // null sequences used
  double mean = 0;         // of the null correlations
  double sd = 0;           // sample standard deviation of the null correlations
  double z = 0;            // (correlation - mean) / sd; 0 when sd is 0
  double p = 1;            // upper normal tail of z; 1 when nothing was compared or sd is 0
  double neg_log10_p = 0;  // -log10 of that, from the asymptotic tail where p underflows
};

// `signs`: B''_j per coefficient j (+1 / -1, 0 where the coefficient was not compared), as
// Extraction::signs. Each null sequence z stands in for a copy's key stream: copy j votes
// -B''_j z_j for message bit j mod message_bits. With `expected`, the null correlation is that of
// the votes with the expected message (extract with the message known); without it, that of the
// majority-decoded message (extract without it). `correlation`: the suspect's, as extracted.
// Throws std::invalid_argument for message_bits <= 0, sequences < 2 or a wrong-length `expected`.
NullCalibration calibrate_null(const std::vector<std::int8_t>& signs, int message_bits, double correlation,
                               const std::vector<bool>* expected = nullptr, int sequences = kNullSequences);

// The null sequences themselves, for statistics over `length` coefficients: generating them is
// most of a calibration's cost and they are the same for every copy of a polyhedron, so a caller
// scoring many copies makes them once. Bits packed 64 to a word, entry j in word j / 64.
struct NullSequences {
  std::size_t length = 0;
  std::vector<std::vector<std::uint64_t>> bits;  // one per sequence
};
NullSequences make_null_sequences(std::size_t length, int sequences = kNullSequences);
// As above, over prepared sequences (signs.size() must equal nulls.length, else
// std::invalid_argument); the same numbers, bit for bit.
NullCalibration calibrate_null(const std::vector<std::int8_t>& signs, int message_bits, double correlation,
                               const std::vector<bool>* expected, const NullSequences& nulls);

// P[N(0,1) > z] with -log10 of it; accurate far beyond where the double p underflows.
void normal_upper_tail(double z, double* p, double* neg_log10_p);

}  // namespace mm

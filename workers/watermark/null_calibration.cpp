#include "watermark/null_calibration.h"

#include <sodium.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "watermark/key_stream.h"

namespace mm {
namespace {

// Public constants: changing them changes every calibrated p-value on record.
constexpr char kNullDomain[] = "meshmark empirical null v1";

Key null_key() {
  Key k{};
  const std::string tag = std::string(kNullDomain) + " key";
  crypto_generichash(k.data(), k.size(), reinterpret_cast<const unsigned char*>(tag.data()), tag.size(),
                     nullptr, 0);
  return k;
}

Nonce null_nonce(int index) {
  std::string tag = std::string(kNullDomain) + " nonce ";
  for (int b = 0; b < 8; ++b) tag.push_back(static_cast<char>((static_cast<std::uint64_t>(index) >> (8 * b)) & 0xff));
  Nonce n{};
  crypto_generichash(n.data(), n.size(), reinterpret_cast<const unsigned char*>(tag.data()), tag.size(), nullptr,
                     0);
  return n;
}

}  // namespace

void normal_upper_tail(double z, double* p, double* neg_log10_p) {
  const double q = 0.5 * std::erfc(z / std::sqrt(2.0));
  if (q > 1e-300 || z < 10) {
    *p = q;
    *neg_log10_p = q > 0 ? -std::log10(q) : 0;
    return;
  }
  // Mills ratio: log Q(z) = -z^2/2 - log(z sqrt(2 pi)) + log(1 - 1/z^2 + 3/z^4 - ...).
  const double z2 = z * z;
  const double log_q = -0.5 * z2 - std::log(z * std::sqrt(2 * M_PI)) + std::log1p(-1 / z2 + 3 / (z2 * z2));
  *p = std::max(q, 4.9406564584124654e-324);
  *neg_log10_p = -log_q / std::log(10.0);
}

NullSequences make_null_sequences(std::size_t length, int sequences) {
  if (sequences < 2) throw std::invalid_argument("calibrate_null: at least 2 null sequences");
  NullSequences out;
  out.length = length;
  const Key key = null_key();
  for (int k = 0; k < sequences; ++k) {
    const std::vector<std::uint8_t> z = key_stream_bits(key, null_nonce(k), length);
    std::vector<std::uint64_t> words((length + 63) / 64, 0);
    for (std::size_t j = 0; j < length; ++j)
      if (z[j]) words[j / 64] |= std::uint64_t{1} << (j % 64);
    out.bits.push_back(std::move(words));
  }
  return out;
}

NullCalibration calibrate_null(const std::vector<std::int8_t>& signs, int message_bits, double correlation,
                               const std::vector<bool>* expected, int sequences) {
  return calibrate_null(signs, message_bits, correlation, expected, make_null_sequences(signs.size(), sequences));
}

NullCalibration calibrate_null(const std::vector<std::int8_t>& signs, int message_bits, double correlation,
                               const std::vector<bool>* expected, const NullSequences& nulls) {
  if (message_bits <= 0) throw std::invalid_argument("calibrate_null: message_bits must be positive");
  const int sequences = static_cast<int>(nulls.bits.size());
  if (sequences < 2) throw std::invalid_argument("calibrate_null: at least 2 null sequences");
  if (nulls.length != signs.size()) throw std::invalid_argument("calibrate_null: null sequences of another length");
  if (expected && static_cast<int>(expected->size()) != message_bits)
    throw std::invalid_argument("calibrate_null: expected message length differs from message_bits");
  NullCalibration out;
  out.sequences = sequences;
  long compared = 0;
  for (auto s : signs) compared += s != 0;
  if (compared == 0) return out;

  const std::size_t words = (signs.size() + 63) / 64;
  // With the message known, entry j agrees when its null bit equals (B''_j > 0) xor the expected
  // bit (its vote -B''_j z_j is positive exactly for a 1 bit): a popcount per word.
  std::vector<std::uint64_t> used(words, 0), target(words, 0);
  if (expected)
    for (std::size_t j = 0; j < signs.size(); ++j) {
      if (signs[j] == 0) continue;
      const std::uint64_t bit = std::uint64_t{1} << (j % 64);
      used[j / 64] |= bit;
      if ((signs[j] > 0) != bool((*expected)[j % static_cast<std::size_t>(message_bits)])) target[j / 64] |= bit;
    }
  std::vector<int> votes(static_cast<std::size_t>(message_bits));
  std::vector<int> copies(static_cast<std::size_t>(message_bits));
  double sum = 0, sum2 = 0;
  for (int k = 0; k < sequences; ++k) {
    const std::vector<std::uint64_t>& z = nulls.bits[static_cast<std::size_t>(k)];
    long agreements = 0;
    if (expected) {
      for (std::size_t w = 0; w < words; ++w) agreements += __builtin_popcountll(used[w] & ~(z[w] ^ target[w]));
    } else {
      std::fill(votes.begin(), votes.end(), 0);
      std::fill(copies.begin(), copies.end(), 0);
      for (std::size_t j = 0; j < signs.size(); ++j) {
        if (signs[j] == 0) continue;
        const bool one = (z[j / 64] >> (j % 64)) & 1;
        const std::size_t bit = j % static_cast<std::size_t>(message_bits);
        votes[bit] += -signs[j] * (one ? 1 : -1);
        ++copies[bit];
      }
      for (int i = 0; i < message_bits; ++i) agreements += (copies[i] + std::abs(votes[i])) / 2;
    }
    const double c = double(2 * agreements - compared) / double(compared);
    sum += c;
    sum2 += c * c;
  }
  out.mean = sum / sequences;
  out.sd = std::sqrt(std::max(0.0, (sum2 - sum * out.mean) / (sequences - 1)));
  if (!(out.sd > 0)) return out;
  out.z = (correlation - out.mean) / out.sd;
  normal_upper_tail(out.z, &out.p, &out.neg_log10_p);
  return out;
}

}  // namespace mm

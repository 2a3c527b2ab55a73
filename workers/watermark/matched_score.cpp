#include "watermark/matched_score.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mm {
namespace {

// Coefficients per band for the systematic gain and the spread: wide enough for a stable fit,
// narrow enough that an attack's gain (a function of frequency) is about constant across it.
constexpr int kBandSize = 24;
// A band's gain is removed when it exceeds this many times the mark's strength a: the mark alone
// projects onto C by at most a, an attack that shrinks or swells the part by far more.
constexpr double kBiasFactor = 3;
// The noise estimate's floor, as a share of the band's mean squared move.
constexpr double kNoiseFloor = 1e-4;

}  // namespace

CoefficientEvidence coefficient_evidence(const SpectralBasis& basis, const Points& original, const Points& suspect,
                                         int message_bits, const EmbedParams& params) {
  const int n = basis.num_vertices();
  if (original.rows() != n) throw std::invalid_argument("coefficient_evidence: original of another vertex count");
  if (suspect.rows() != n)
    throw InputError("suspect mesh", "has " + std::to_string(suspect.rows()) + " vertices, the original has " +
                                         std::to_string(n) + " (resynchronise it first)");
  if (!suspect.allFinite()) throw InputError("suspect mesh", "has NaN or infinite coordinates");
  if (message_bits <= 0) throw std::invalid_argument("coefficient_evidence: message_bits must be positive");
  const int usable = usable_coefficients(basis);
  CoefficientEvidence ev;
  ev.message_bits = message_bits;
  ev.repeat = usable / message_bits;
  const int len = ev.repeat * message_bits;
  const Points cs = to_spectral(basis, original);
  const Points d = to_spectral(basis, suspect - original);
  auto at = [&](const Points& m, int j) { return m(basis.num_components + j / 3, j % 3); };

  ev.u.assign(static_cast<std::size_t>(len), 0.0);
  for (int start = 0; start < usable; start += kBandSize) {
    // The last band takes the remainder, so no band is short.
    int end = std::min(usable, start + kBandSize);
    if (usable - end < kBandSize / 2) end = usable;
    double dc = 0, cc = 0;
    for (int j = start; j < end; ++j) {
      dc += at(d, j) * at(cs, j);
      cc += at(cs, j) * at(cs, j);
    }
    const double gain = cc > 0 ? dc / cc : 0;
    const bool biased = std::abs(gain) > kBiasFactor * params.strength;
    ev.bias_bands += biased;
    std::vector<double> residual, move;
    double rr = 0, gg = 0, g4 = 0, r2g2 = 0;
    for (int j = start; j < end; ++j) {
      const double r = at(d, j) - (biased ? gain * at(cs, j) : 0.0);
      const double g = j < len ? coefficient_move(params, at(cs, j)).size : 0.0;
      residual.push_back(r);
      move.push_back(g);
      rr += r * r;
      gg += g * g;
      g4 += g * g * g * g;
      r2g2 += r * r * g * g;
    }
    // The noise: what the band's spread has beyond a whole mark. Its floor keeps a coefficient
    // whose move is far below the band's from weighing in by rounding alone.
    // The band's mark gain h and noise: r_j^2 = h^2 g_j^2 + noise on average, fitted by least
    // squares over the band where the moves differ enough to tell the two apart; else the whole
    // spread counts as noise (h = 1), which only makes the weights more even.
    const double count = static_cast<double>(end - start);
    const double mg = gg / count, mr = rr / count;
    const double var_g2 = g4 / count - mg * mg, cov = r2g2 / count - mg * mr;
    double h2 = 1, noise = mr;
    if (var_g2 > 0.05 * mg * mg) {
      h2 = std::clamp(cov / var_g2, 0.0, 4.0);
      noise = mr - h2 * mg;
    }
    noise = std::max(noise, kNoiseFloor * mg);
    const double h = std::sqrt(h2);
    for (int j = start; j < std::min(end, len); ++j) {
      const double g = move[static_cast<std::size_t>(j - start)];
      const double direction = coefficient_move(params, at(cs, j)).direction;
      // The weight that maximises T's expectation under the mark: h g / (h^2 g^2 + noise).
      const double denominator = h2 * g * g + noise;
      ev.u[static_cast<std::size_t>(j)] =
          denominator > 0 ? residual[static_cast<std::size_t>(j - start)] * direction * h * g / denominator : 0;
    }
    if (end == usable) break;
  }
  return ev;
}

MatchedScore matched_score(const CoefficientEvidence& ev, const Key& key, const Nonce& nonce,
                           const std::vector<bool>& expected, int num_coefficients) {
  if (static_cast<int>(expected.size()) != ev.message_bits)
    throw std::invalid_argument("matched_score: expected message length differs from the evidence's");
  // B for the all-zero message is the key stream in +-1 form; a 1 bit inverts its entries.
  const MarkSequence stream =
      make_sequence(std::vector<bool>(expected.size(), false), num_coefficients, key, nonce);
  MatchedScore out;
  double dot = 0, norm2 = 0;
  std::vector<double> vote(expected.size(), 0.0);
  for (std::size_t j = 0; j < ev.u.size() && j < stream.b.size(); ++j) {
    const int b = expected[j % expected.size()] ? -stream.b[j] : stream.b[j];
    dot += ev.u[j] * b;
    norm2 += ev.u[j] * ev.u[j];
    // -u_j stream_j votes for a 1 bit.
    vote[j % expected.size()] -= ev.u[j] * stream.b[j];
  }
  out.message.resize(expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) out.message[i] = vote[i] > 0;
  if (norm2 > 0 && dot > 0) {
    out.statistic = dot / std::sqrt(norm2);
    out.neg_log10_p = out.statistic * out.statistic / (2 * std::log(10.0));
    out.p = std::exp(-out.statistic * out.statistic / 2);
  } else if (norm2 > 0) {
    out.statistic = dot / std::sqrt(norm2);
  }
  return out;
}

}  // namespace mm

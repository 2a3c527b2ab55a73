#include "watermark/watermark.h"

#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>

namespace mm {
namespace {

// Below this fraction of the largest coefficient, an embedding move is lost in the rounding of
// the transforms (~sqrt(n) x 1e-16 relative), so it cannot carry a sign.
constexpr double kRoundingFloor = 1e-11;

void check_params(const EmbedParams& p) {
  if (p.method != Method::Multiplicative && p.method != Method::Additive && p.method != Method::Uniform)
    throw std::invalid_argument("watermark: unknown method");
  if (!(std::isfinite(p.strength) && p.strength > 0 && p.strength < 1))
    throw std::invalid_argument("watermark: strength a must be in (0, 1)");
  if (!(std::isfinite(p.threshold) && p.threshold >= 0))
    throw std::invalid_argument("watermark: threshold T must be finite and >= 0");
}

bool additive(const EmbedParams& p, double cs) {
  return p.method == Method::Uniform || (p.method == Method::Additive && std::abs(cs) < p.threshold);
}

// Coefficient j of the documented order: eigenvector num_components + j / 3, axis j % 3.
double& coefficient(const SpectralBasis& basis, Points& cs, int j) {
  return cs(basis.num_components + j / 3, j % 3);
}
double coefficient(const SpectralBasis& basis, const Points& cs, int j) {
  return cs(basis.num_components + j / 3, j % 3);
}

}  // namespace

const char* method_name(Method method) {
  switch (method) {
    case Method::Multiplicative: return "multiplicative";
    case Method::Additive: return "additive";
    case Method::Uniform: return "uniform";
  }
  return "unknown";
}

Method method_from_name(const std::string& name) {
  for (Method m : kMethods)
    if (name == method_name(m)) return m;
  throw std::invalid_argument("watermark: unknown method \"" + name + "\"");
}

CoefficientMove coefficient_move(const EmbedParams& params, double c) {
  const bool add = additive(params, c);
  return {add ? params.threshold * params.strength : std::abs(c) * params.strength, add || c > 0 ? 1.0 : -1.0};
}

int usable_coefficients(const SpectralBasis& basis) {
  return 3 * (basis.num_vertices() - basis.num_components);
}

MarkSequence make_sequence(const std::vector<bool>& message, int num_coefficients, const Key& key,
                           const Nonce& nonce) {
  const int l = static_cast<int>(message.size());
  if (l == 0) throw std::invalid_argument("watermark: the message is empty");
  if (l > num_coefficients)
    throw std::invalid_argument("watermark: a " + std::to_string(l) + "-bit message does not fit in " +
                                std::to_string(num_coefficients) + " spectral coefficients");
  MarkSequence seq;
  seq.message_bits = l;
  seq.repeat = num_coefficients / l;  // eq. (7): r = floor(3n' / l)
  const std::size_t len = std::size_t(seq.repeat) * l;
  const std::vector<std::uint8_t> stream = key_stream_bits(key, nonce, len);
  seq.b.resize(len);
  for (std::size_t i = 0; i < len; ++i)
    seq.b[i] = ((message[i % l] ? 1 : 0) ^ stream[i]) ? 1 : -1;
  return seq;
}

Points embed(const SpectralBasis& basis, const Points& original, const std::vector<bool>& message,
             const Key& key, const Nonce& nonce, const EmbedParams& params) {
  check_params(params);
  if (original.rows() != basis.num_vertices())
    throw std::invalid_argument("embed: " + std::to_string(original.rows()) +
                                " vertices for a basis of " + std::to_string(basis.num_vertices()));
  if (!original.allFinite()) throw std::invalid_argument("embed: non-finite original coordinates");
  const MarkSequence seq = make_sequence(message, usable_coefficients(basis), key, nonce);
  const Points cs = to_spectral(basis, original);
  Points delta = Points::Zero(cs.rows(), 3);
  for (int j = 0; j < static_cast<int>(seq.b.size()); ++j) {
    const CoefficientMove move = coefficient_move(params, coefficient(basis, cs, j));
    coefficient(basis, delta, j) = move.size * move.direction * seq.b[j];
  }
  return original + from_spectral(basis, delta);
}

SpectralDisplacement spectral_displacement(const SpectralBasis& basis, const Points& original, const Points& suspect) {
  const int n = basis.num_vertices();
  if (original.rows() != n)
    throw std::invalid_argument("extract: " + std::to_string(original.rows()) +
                                " original vertices for a basis of " + std::to_string(n));
  if (suspect.rows() != n)
    throw InputError("suspect mesh", "has " + std::to_string(suspect.rows()) +
                                         " vertices, the original has " + std::to_string(n) +
                                         " (resynchronise it first)");
  if (!suspect.allFinite()) throw InputError("suspect mesh", "has NaN or infinite coordinates");
  if (!original.allFinite()) throw std::invalid_argument("extract: non-finite original coordinates");
  SpectralDisplacement out;
  out.original = to_spectral(basis, original);
  out.displacement = to_spectral(basis, suspect - original);  // without cancellation
  return out;
}

Extraction extract(const SpectralBasis& basis, const Points& original, const Points& suspect,
                   int message_bits, const Key& key, const Nonce& nonce, const EmbedParams& params,
                   const std::vector<bool>* expected) {
  check_params(params);
  return extract(basis, spectral_displacement(basis, original, suspect), message_bits, key, nonce, params, expected);
}

Extraction extract(const SpectralBasis& basis, const SpectralDisplacement& spectral, int message_bits, const Key& key,
                   const Nonce& nonce, const EmbedParams& params, const std::vector<bool>* expected) {
  check_params(params);
  if (spectral.original.rows() != basis.num_vertices() || spectral.displacement.rows() != basis.num_vertices())
    throw std::invalid_argument("extract: spectral coordinates of another vertex count");
  if (message_bits <= 0) throw std::invalid_argument("extract: message_bits must be positive");
  if (expected && static_cast<int>(expected->size()) != message_bits)
    throw std::invalid_argument("extract: expected message length differs from message_bits");

  // Sequence with the message all zeros: its entries are the key stream mapped to +-1.
  const MarkSequence stream =
      make_sequence(std::vector<bool>(message_bits, false), usable_coefficients(basis), key, nonce);
  const Points& cs = spectral.original;
  const Points& d = spectral.displacement;
  const double floor = kRoundingFloor * cs.cwiseAbs().maxCoeff();

  Extraction out;
  out.repeat = stream.repeat;
  out.signs.assign(stream.b.size(), 0);
  std::vector<int> votes(message_bits, 0), copies(message_bits, 0);
  // Per bit, the copies' displacements in units of their embedding move, signed as votes: what
  // decides a tied vote. With 4 copies a bit (a 32-bit payload on 48 control vertices), two
  // flipped signs of one bit tie it, and a noisy STL leak of abc9 matched its copy at p 1e-24
  // yet decoded one bit wrong when ties read as 0 (docs/watermark.md, "Extraction (paper IV.D)").
  std::vector<double> soft(message_bits, 0.0);
  for (int j = 0; j < static_cast<int>(stream.b.size()); ++j) {
    const CoefficientMove mv = coefficient_move(params, coefficient(basis, cs, j));
    const double move = mv.size;
    const double dj = coefficient(basis, d, j);
    if (!(move > floor) || dj == 0) continue;
    const int sign_b = (dj > 0 ? 1 : -1) * static_cast<int>(mv.direction);  // B''_j
    // `stream` is B for the all-zero message; a 1 bit inverts its copies (XOR in +-1 form), so
    // -B''_j stream_j is this copy's vote for message bit j mod l: +1 for 1, -1 for 0.
    out.signs[static_cast<std::size_t>(j)] = static_cast<std::int8_t>(sign_b);
    const int vote = -sign_b * stream.b[j];
    const int bit = j % message_bits;
    votes[bit] += vote;
    soft[bit] -= dj * mv.direction / move * stream.b[j];
    ++copies[bit];
    ++out.compared;
    if (expected) out.agreements += (vote > 0) == bool((*expected)[bit]);
  }
  out.message.resize(message_bits);
  for (int i = 0; i < message_bits; ++i) {
    out.message[i] = votes[i] != 0 ? votes[i] > 0 : soft[i] > 0;
    out.tied_bits += votes[i] == 0;
  }
  BinomialTail tail;
  if (expected) {
    int errors = 0;
    for (int i = 0; i < message_bits; ++i) errors += out.message[i] != (*expected)[i];
    out.bit_error_rate = double(errors) / message_bits;
    tail = binomial_upper_tail(out.compared, out.agreements);
  } else {
    // B rebuilt from the decoded message agrees with at least half of each bit's copies by
    // construction, so the fair-coin binomial would overstate the evidence: use the exact
    // distribution of the majority-vote agreement count instead.
    for (int i = 0; i < message_bits; ++i) out.agreements += (copies[i] + std::abs(votes[i])) / 2;
    out.bit_error_rate = std::numeric_limits<double>::quiet_NaN();
    tail = majority_vote_tail(copies, out.agreements);
  }
  out.message_known = expected != nullptr;
  if (out.compared > 0) out.correlation = double(2 * out.agreements - out.compared) / out.compared;
  out.p_value = out.compared > 0 ? tail.p : 1.0;
  out.neg_log10_p = out.compared > 0 ? tail.neg_log10_p : 0.0;
  return out;
}

}  // namespace mm

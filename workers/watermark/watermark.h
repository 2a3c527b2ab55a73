// The spectral watermark of the paper, section IV: embed a message into the Kirchhoff spectrum
// of a (control) mesh with a secret key, and extract it non-blind against the original.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "meshio/mesh.h"
#include "spectral/spectral_basis.h"

namespace mm {

using Key = std::array<std::uint8_t, 32>;    // 256-bit customer key
using Nonce = std::array<std::uint8_t, 24>;  // per-copy nonce for the XChaCha20 key stream

enum class Method { Multiplicative = 1, Additive = 2 };  // eq. (8) and eq. (9)

struct EmbedParams {
  Method method = Method::Additive;
  double strength = 0.01;   // a
  double threshold = 0.05;  // T (Method 2)
};

// The per-coefficient sequence B in {-1,+1}, message spread r times and XORed with the key stream.
struct MarkSequence {
  int message_bits = 0;  // l
  int repeat = 0;        // r = floor(3 n_usable / l)
  std::vector<std::int8_t> b;  // r*l entries, +1 / -1
};

MarkSequence make_sequence(const std::vector<bool>& message, int num_coefficients, const Key& key,
                           const Nonce& nonce);

// Returns the watermarked positions (same connectivity, same vertex order as `original`).
Points embed(const SpectralBasis& basis, const Points& original, const std::vector<bool>& message,
             const Key& key, const Nonce& nonce, const EmbedParams& params);

struct Extraction {
  double correlation = 0;        // paper: correlation between B'' and B
  std::vector<bool> message;     // majority vote per bit
  double bit_error_rate = 0;     // against `expected` when given, else NaN
  int agreements = 0, compared = 0;  // coefficient signs that agree with B / that carried a sign
  double p_value = 1;            // P[X >= agreements], X ~ Binomial(compared, 1/2)
};

// Non-blind extraction: `suspect` must already be resynchronised to the original's vertex order.
Extraction extract(const SpectralBasis& basis, const Points& original, const Points& suspect,
                   int message_bits, const Key& key, const Nonce& nonce, const EmbedParams& params,
                   const std::vector<bool>* expected = nullptr);

}  // namespace mm

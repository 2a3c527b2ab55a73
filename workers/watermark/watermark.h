// The spectral watermark of the paper, section IV: embed a message into the Kirchhoff spectrum
// of a (control) mesh with a secret key, and extract it non-blind against the original.
//
// Coefficient order (docs/watermark.md): the usable coefficients are those of the non-zero
// eigenvalues, k = num_components .. n-1; coefficient j is (k, axis) with
// k = num_components + j / 3 and axis = j % 3 (X, Y, Z interleaved, lowest frequency first).
// The zero-eigenvalue coefficients (one per connected component: its centroid) are never touched,
// so marking does not translate any part. Sequence entry i goes to coefficient i; the
// 3n' - r*l highest-frequency coefficients stay unmarked.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "meshio/mesh.h"
#include "spectral/spectral_basis.h"
#include "watermark/binomial_tail.h"
#include "watermark/key_stream.h"

namespace mm {

// eq. (8), eq. (9), and Uniform: every marked coefficient moves by T a (eq. (9)'s additive branch
// for all of them). The multiplicative moves |a C| put most of a mark's energy into the few
// low-frequency coefficients of the part's shape, whose signs a random key matches with
// probability 2^-k however strong they are; spread evenly, the same displacement budget gives
// every coefficient a sign the noise can flip only rarely (docs/watermark.md, "Uniform moves").
enum class Method { Multiplicative = 1, Additive = 2, Uniform = 3 };
constexpr Method kMethods[] = {Method::Multiplicative, Method::Additive, Method::Uniform};

// "multiplicative", "additive", "uniform": the names copy records and the config use.
const char* method_name(Method method);
// Throws std::invalid_argument for another name.
Method method_from_name(const std::string& name);

struct EmbedParams {
  Method method = Method::Additive;
  double strength = 0.01;   // a, in (0, 1)
  double threshold = 0.05;  // T: coefficients with |Cs| < T (Method 2), or all (Uniform), move by T a b
};

// How embedding moves a coefficient of value c (eq. 8, 9) for a +1 sequence entry: by `size`, in
// `direction` (+1 or -1); a -1 entry moves it the other way. The same for every copy of a
// polyhedron: only the entry's sign is the key's.
struct CoefficientMove {
  double size = 0;
  double direction = 1;
};
CoefficientMove coefficient_move(const EmbedParams& params, double c);

// 3 (n - num_components): the coefficient values that can carry the mark (3n' in the docs).
int usable_coefficients(const SpectralBasis& basis);

// The per-coefficient sequence B in {-1,+1}: the message spread r times (interleaved: entry i
// carries message bit i mod l), XORed with the key stream, 1 -> +1, 0 -> -1.
struct MarkSequence {
  int message_bits = 0;  // l
  int repeat = 0;        // r = floor(num_coefficients / l)
  std::vector<std::int8_t> b;  // r*l entries, +1 / -1
};

// Throws std::invalid_argument when the message is empty or longer than num_coefficients.
MarkSequence make_sequence(const std::vector<bool>& message, int num_coefficients, const Key& key,
                           const Nonce& nonce);

// Returns the watermarked positions (same connectivity, same vertex order as `original`):
// original + W (Cs' - Cs), so unmarked coefficients are reproduced up to one rounding.
// Throws std::invalid_argument for bad parameters or a message that does not fit.
Points embed(const SpectralBasis& basis, const Points& original, const std::vector<bool>& message,
             const Key& key, const Nonce& nonce, const EmbedParams& params);

// With the expected message, B is the inserted sequence and the p-value is the fair-coin binomial
// tail. Without it, B is rebuilt from the decoded message, which agrees with at least half of each
// bit's copies by construction, so the p-value is the exact tail of that majority-vote count
// (majority_vote_tail) rather than the binomial.
struct Extraction {
  double correlation = 0;        // (1/m) sum B'' B = (2 agreements - m) / m over the m compared
  // Majority vote per bit; a tie goes to the sign of the bit's summed displacements, each in units
  // of its embedding move (the copies that moved far outweigh those that barely crossed zero);
  // no compared copy gives false.
  std::vector<bool> message;
  int tied_bits = 0;             // bits whose vote was tied (however broken) or had no compared copy
  double bit_error_rate = 0;     // against `expected` when given, else NaN
  int agreements = 0, compared = 0;  // coefficient signs that agree with B / that carried a sign
  int repeat = 0;                // r used
  bool message_known = false;    // whether B came from `expected` (else from the decoded message)
  double p_value = 1;            // P[chance agreement >= agreements] (see above); 1 if m = 0
  double neg_log10_p = 0;        // -log10 of that, still meaningful where p_value underflows
  std::vector<std::int8_t> signs;  // B''_j per coefficient j < r*l: +1 / -1, 0 if not compared
};

// Non-blind extraction: `suspect` must already be resynchronised to the original's vertex order.
// A coefficient is compared when its embedding move (|a Cs| or T a) is above the transform's
// rounding floor (1e-11 x the largest |Cs|) and the suspect's displacement is non-zero.
// Throws InputError("suspect mesh", ...) for a vertex count mismatch or non-finite coordinates.
Extraction extract(const SpectralBasis& basis, const Points& original, const Points& suspect,
                   int message_bits, const Key& key, const Nonce& nonce, const EmbedParams& params,
                   const std::vector<bool>* expected = nullptr);

// What extract() compares, which depends on the suspect and not on the key: the original's
// spectral coefficients and the suspect's displacement from them (two dense n x n products,
// most of an extraction's cost). Made once, it serves every copy of the polyhedron. Throws
// like extract() for a suspect of the wrong vertex count or non-finite coordinates.
struct SpectralDisplacement {
  Points original;      // Cs, n x 3
  Points displacement;  // Cs'' - Cs = W^T (suspect - original), n x 3
};
SpectralDisplacement spectral_displacement(const SpectralBasis& basis, const Points& original, const Points& suspect);
Extraction extract(const SpectralBasis& basis, const SpectralDisplacement& spectral, int message_bits, const Key& key,
                   const Nonce& nonce, const EmbedParams& params, const std::vector<bool>* expected = nullptr);

}  // namespace mm

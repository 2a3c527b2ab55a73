#include <gtest/gtest.h>
#include <sodium.h>

#include <cmath>
#include <cstring>
#include <random>

#include "common/seeded_keys.h"
#include "common/shared_meshes.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"
#include "spectral/synthetic_meshes.h"
#include "watermark/watermark.h"

namespace mm {
namespace {

using test::seeded_key;
using test::seeded_message;
using test::seeded_nonce;

Mesh fandisk() {
  Mesh m = read_mesh(test::shared_mesh("fandisk_quads.off"));
  apply(unit_box_normalization(m.points), m.points);
  return m;
}

Mesh torus() {
  Mesh m = test::quad_torus(16, 12, 5);
  apply(unit_box_normalization(m.points), m.points);
  return m;
}

const EmbedParams kMethod1{Method::Multiplicative, 0.01, 0.05};
const EmbedParams kMethod2{Method::Additive, 0.01, 0.05};
const EmbedParams kUniform{Method::Uniform, 0.01, 0.05};

bool same_bytes(const Points& a, const Points& b) {
  return a.rows() == b.rows() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * std::size_t(a.size())) == 0;
}

// --- key stream and sequence ---

TEST(KeyStream, IsXChaCha20LeastSignificantBitFirst) {
  const Key key = seeded_key(1);
  const Nonce nonce = seeded_nonce(1);
  ASSERT_GE(sodium_init(), 0);
  std::vector<std::uint8_t> bytes(40);
  crypto_stream_xchacha20(bytes.data(), bytes.size(), nonce.data(), key.data());
  const auto bits = key_stream_bits(key, nonce, 317);
  ASSERT_EQ(bits.size(), 317u);
  for (std::size_t i = 0; i < bits.size(); ++i) EXPECT_EQ(bits[i], (bytes[i / 8] >> (i % 8)) & 1);
  EXPECT_EQ(key_stream_bits(key, nonce, 317), bits);
  EXPECT_NE(key_stream_bits(key, seeded_nonce(2), 317), bits);
  EXPECT_NE(key_stream_bits(seeded_key(2), nonce, 317), bits);
}

TEST(KeyStream, GeneratedKeysDiffer) {
  EXPECT_NE(generate_key(), generate_key());
  EXPECT_NE(generate_nonce(), generate_nonce());
}

TEST(Sequence, SpreadsInterleavedAndXorsTheKeyStream) {
  const auto msg = seeded_message(13, 3);
  const Key key = seeded_key(3);
  const Nonce nonce = seeded_nonce(3);
  const MarkSequence s = make_sequence(msg, 100, key, nonce);
  EXPECT_EQ(s.message_bits, 13);
  EXPECT_EQ(s.repeat, 7);  // floor(100 / 13)
  ASSERT_EQ(s.b.size(), 91u);
  const auto stream = key_stream_bits(key, nonce, 91);
  for (int i = 0; i < 91; ++i) EXPECT_EQ(s.b[i], (msg[i % 13] ^ (stream[i] != 0)) ? 1 : -1) << i;
  EXPECT_THROW(make_sequence({}, 100, key, nonce), std::invalid_argument);
  EXPECT_THROW(make_sequence(seeded_message(101, 1), 100, key, nonce), std::invalid_argument);
}

// --- embedding and extraction ---

void expect_perfect(const Mesh& mesh, const EmbedParams& params) {
  const SpectralBasis basis = compute_basis(mesh);
  const auto msg = seeded_message(64, 11);
  const Key key = seeded_key(11);
  const Nonce nonce = seeded_nonce(11);
  const Points marked = embed(basis, mesh.points, msg, key, nonce, params);
  const Extraction e = extract(basis, mesh.points, marked, 64, key, nonce, params, &msg);
  const int len = e.repeat * 64;
  EXPECT_EQ(e.repeat, usable_coefficients(basis) / 64);
  EXPECT_EQ(e.correlation, 1.0);
  EXPECT_EQ(e.message, msg);
  EXPECT_EQ(e.bit_error_rate, 0.0);
  EXPECT_EQ(e.tied_bits, 0);
  EXPECT_EQ(e.agreements, e.compared);
  EXPECT_GE(e.compared, len * 99 / 100);  // only coefficients at rounding level are skipped
  EXPECT_LE(e.compared, len);
  EXPECT_GT(e.neg_log10_p, 0.99 * len * std::log10(2.0));
  EXPECT_TRUE(e.message_known);
  // Without the expected message: same message, same correlation, honest (smaller) evidence.
  const Extraction blind = extract(basis, mesh.points, marked, 64, key, nonce, params);
  EXPECT_EQ(blind.message, msg);
  EXPECT_EQ(blind.correlation, 1.0);
  EXPECT_TRUE(std::isnan(blind.bit_error_rate));
  EXPECT_LT(blind.p_value, 1e-100);
  EXPECT_FALSE(blind.message_known);
}

TEST(Watermark, UnattackedIsPerfectOnSyntheticMeshEveryMethod) {
  expect_perfect(torus(), kMethod1);
  expect_perfect(torus(), kMethod2);
  expect_perfect(torus(), kUniform);
  expect_perfect(torus(), {Method::Multiplicative, 0.1, 0.05});
  expect_perfect(torus(), {Method::Additive, 0.1, 0.05});
}

TEST(Watermark, UnattackedIsPerfectOnFandiskEveryMethod) {
  MM_REQUIRE_SHARED_MESHES();
  expect_perfect(fandisk(), kMethod1);
  expect_perfect(fandisk(), kMethod2);
  expect_perfect(fandisk(), kUniform);
}

// A polyhedron past the dense basis's limit is marked and read through the patched basis alike,
// and another key reads nothing from it.
TEST(Watermark, PatchedBasisMarksAndReadsLikeTheDenseOne) {
  const Mesh m = test::quad_torus(90, 70, 8);  // 6,300 vertices
  ASSERT_GT(m.num_vertices(), kDenseBasisVertices);
  expect_perfect(m, kMethod1);
  expect_perfect(m, kMethod2);
  const SpectralBasis basis = compute_basis(m);
  const auto msg = seeded_message(64, 9);
  const Points marked = embed(basis, m.points, msg, seeded_key(9), seeded_nonce(9), kMethod2);
  for (std::uint64_t s = 200; s < 205; ++s) {
    const Extraction e = extract(basis, m.points, marked, 64, seeded_key(s), seeded_nonce(9), kMethod2, &msg);
    EXPECT_LT(std::abs(e.correlation), 0.05) << s;
    EXPECT_GT(e.p_value, 0.01) << s;
  }
}

TEST(Watermark, SpectralChangeFollowsEquations8And9AndUniform) {
  const Mesh m = torus();
  const SpectralBasis basis = compute_basis(m);
  const auto msg = seeded_message(20, 4);
  const Key key = seeded_key(4);
  const Nonce nonce = seeded_nonce(4);
  const MarkSequence seq = make_sequence(msg, usable_coefficients(basis), key, nonce);
  const Points cs = to_spectral(basis, m.points);
  for (const EmbedParams& p : {kMethod1, EmbedParams{Method::Additive, 0.02, 0.3}, kUniform}) {
    const Points cs2 = to_spectral(basis, embed(basis, m.points, msg, key, nonce, p));
    int additive = 0;
    for (int j = 0; j < usable_coefficients(basis); ++j) {
      const int k = basis.num_components + j / 3, axis = j % 3;
      double expected = cs(k, axis);
      if (j < static_cast<int>(seq.b.size())) {
        const double ab = p.strength * seq.b[j];
        if (p.method == Method::Uniform || (p.method == Method::Additive && std::abs(cs(k, axis)) < p.threshold)) {
          expected += p.threshold * ab;
          ++additive;
        } else {
          expected *= 1 + ab;
        }
      }
      EXPECT_NEAR(cs2(k, axis), expected, 1e-13) << j;
    }
    if (p.method == Method::Additive) {
      EXPECT_GT(additive, 50);  // both branches exercised
    }
    if (p.method == Method::Uniform) {
      EXPECT_EQ(additive, static_cast<int>(seq.b.size()));  // every marked coefficient by T a
    }
    // The zero-frequency (centroid) coefficient is untouched.
    EXPECT_NEAR(cs2(0, 0), cs(0, 0), 1e-13);
  }
}

TEST(Watermark, CentroidsAreUntouched) {
  const Mesh m = test::two_pieces_and_a_point();
  const SpectralBasis basis = compute_basis(m);
  const auto msg = seeded_message(16, 5);
  for (const EmbedParams& p : {EmbedParams{Method::Multiplicative, 0.1, 0.05},
                               EmbedParams{Method::Additive, 0.1, 0.5}}) {
    const Points marked = embed(basis, m.points, msg, seeded_key(5), seeded_nonce(5), p);
    EXPECT_GT((marked - m.points).cwiseAbs().maxCoeff(), 1e-3);  // it did move
    // torus 0..29, grid 30..49, lone point 50
    EXPECT_LT((marked.topRows(30).colwise().mean() - m.points.topRows(30).colwise().mean())
                  .cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((marked.middleRows(30, 20).colwise().mean() -
               m.points.middleRows(30, 20).colwise().mean()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((marked.row(50) - m.points.row(50)).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(Watermark, FandiskCentroidIsUntouched) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh m = fandisk();
  const SpectralBasis basis = compute_basis(m);
  for (const EmbedParams& p : {kMethod1, kMethod2}) {
    const Points marked =
        embed(basis, m.points, seeded_message(64, 6), seeded_key(6), seeded_nonce(6), p);
    EXPECT_LT((marked.colwise().mean() - m.points.colwise().mean()).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(Watermark, WrongKeyOrNonceFindsNothing) {
  const Mesh m = torus();
  const SpectralBasis basis = compute_basis(m);
  const auto msg = seeded_message(32, 7);
  for (const EmbedParams& p : {kMethod1, kMethod2}) {
    const Points marked = embed(basis, m.points, msg, seeded_key(7), seeded_nonce(7), p);
    for (std::uint64_t s = 100; s < 110; ++s) {
      const Extraction e = extract(basis, m.points, marked, 32, seeded_key(s), seeded_nonce(7), p, &msg);
      EXPECT_LT(std::abs(e.correlation), 0.15) << s;
      EXPECT_GT(e.p_value, 0.01) << s;
      EXPECT_GT(e.bit_error_rate, 0.2) << s;
      const Extraction nonce = extract(basis, m.points, marked, 32, seeded_key(7), seeded_nonce(s), p, &msg);
      EXPECT_LT(std::abs(nonce.correlation), 0.15) << s;
      EXPECT_GT(nonce.p_value, 0.01) << s;
    }
  }
}

// Under a wrong key the p-value must be calibrated: P[p < x] <= x (about equal, the count being
// discrete), with and without the expected message.
TEST(Watermark, WrongKeyPValuesAreCalibrated) {
  const Mesh m = torus();
  const SpectralBasis basis = compute_basis(m);
  const auto msg = seeded_message(32, 13);
  const Points marked = embed(basis, m.points, msg, seeded_key(13), seeded_nonce(13), kMethod2);
  const int trials = 400;
  int known_below_1pc = 0, known_below_half = 0, blind_below_1pc = 0, blind_below_half = 0;
  for (int s = 0; s < trials; ++s) {
    const Key wrong = seeded_key(1000 + s);
    const Extraction known = extract(basis, m.points, marked, 32, wrong, seeded_nonce(13), kMethod2, &msg);
    const Extraction blind = extract(basis, m.points, marked, 32, wrong, seeded_nonce(13), kMethod2);
    known_below_1pc += known.p_value < 0.01;
    known_below_half += known.p_value < 0.5;
    blind_below_1pc += blind.p_value < 0.01;
    blind_below_half += blind.p_value < 0.5;
  }
  // Binomial(400, 0.01) exceeds 12 with probability < 0.001; Binomial(400, 0.5) stays in
  // [160, 240] except with probability < 1e-4.
  EXPECT_LE(known_below_1pc, 12);
  EXPECT_LE(blind_below_1pc, 12);
  EXPECT_GE(known_below_half, 160);
  EXPECT_LE(known_below_half, 240);
  EXPECT_GE(blind_below_half, 160);
  EXPECT_LE(blind_below_half, 240);
}

TEST(Watermark, UnmarkedCopiesFindNothing) {
  const Mesh m = torus();
  const SpectralBasis basis = compute_basis(m);
  const auto msg = seeded_message(32, 8);
  // The original itself: no displacement, nothing to compare.
  const Extraction same = extract(basis, m.points, m.points, 32, seeded_key(8), seeded_nonce(8), kMethod2, &msg);
  EXPECT_EQ(same.compared, 0);
  EXPECT_EQ(same.correlation, 0.0);
  EXPECT_EQ(same.p_value, 1.0);
  // A noisy unmarked copy: random signs.
  std::mt19937_64 rng(8);
  for (int trial = 0; trial < 5; ++trial) {
    Points noisy = m.points;
    for (int i = 0; i < noisy.size(); ++i) noisy.data()[i] += 0.001 * test::uniform_pm1(rng);
    const Extraction e = extract(basis, m.points, noisy, 32, seeded_key(8), seeded_nonce(8), kMethod2, &msg);
    EXPECT_LT(std::abs(e.correlation), 0.15);
    EXPECT_GT(e.p_value, 0.01);
  }
}

TEST(Watermark, MajorityVoteCorrectsMinorityFlips) {
  const Mesh m = torus();
  const SpectralBasis basis = compute_basis(m);
  const int l = 24;
  const auto msg = seeded_message(l, 9);
  const Key key = seeded_key(9);
  const Nonce nonce = seeded_nonce(9);
  const Points marked = embed(basis, m.points, msg, key, nonce, kMethod2);
  const int r = usable_coefficients(basis) / l;
  ASSERT_GE(r, 5);
  // Reverse the displacement of chosen coefficients: each flips one copy's sign.
  auto flip = [&](const std::vector<int>& coefficients) {
    Points d = to_spectral(basis, marked) - to_spectral(basis, m.points);
    for (int j : coefficients) d(basis.num_components + j / 3, j % 3) *= -1;
    return Points(m.points + from_spectral(basis, d));
  };
  // Bit 3 loses (r-1)/2 copies, bit 5 one copy: still decoded.
  std::vector<int> flips;
  for (int c = 0; c < (r - 1) / 2; ++c) flips.push_back(c * l + 3);
  flips.push_back(2 * l + 5);
  const Extraction e = extract(basis, m.points, flip(flips), l, key, nonce, kMethod2, &msg);
  EXPECT_EQ(e.message, msg);
  EXPECT_EQ(e.compared - e.agreements, static_cast<int>(flips.size()));
  EXPECT_NEAR(e.correlation, 1.0 - 2.0 * flips.size() / e.compared, 1e-15);
  // Bit 7 loses a majority of its copies: exactly that bit is wrong.
  std::vector<int> majority;
  for (int c = 0; c < r / 2 + 1; ++c) majority.push_back(c * l + 7);
  const Extraction f = extract(basis, m.points, flip(majority), l, key, nonce, kMethod2, &msg);
  auto wrong = msg;
  wrong[7] = !wrong[7];
  EXPECT_EQ(f.message, wrong);
  EXPECT_NEAR(f.bit_error_rate, 1.0 / l, 1e-15);
}

// A tied vote goes to the copies that moved furthest in units of their embedding move: half of a
// bit's copies barely pushed past zero lose to the half that kept the mark's full move, and win
// when they moved further. (Before, every tie decoded as 0.)
TEST(Watermark, TiedVoteGoesToTheLargerDisplacements) {
  const Mesh m = torus();
  const SpectralBasis basis = compute_basis(m);
  const int l = 64;
  const int r = usable_coefficients(basis) / l;
  ASSERT_EQ(r % 2, 0) << r;
  for (int bit : {3, 4}) {
    for (std::uint64_t seed : {11u, 12u}) {
      const auto msg = seeded_message(l, seed);
      const Key key = seeded_key(seed);
      const Nonce nonce = seeded_nonce(seed);
      const Points marked = embed(basis, m.points, msg, key, nonce, kMethod2);
      // Half of the bit's copies displaced by `factor` times their mark.
      auto tie = [&](double factor) {
        Points d = to_spectral(basis, marked) - to_spectral(basis, m.points);
        for (int c = 0; c < r / 2; ++c) {
          const int j = c * l + bit;
          d(basis.num_components + j / 3, j % 3) *= factor;
        }
        return Points(m.points + from_spectral(basis, d));
      };
      const Extraction slight = extract(basis, m.points, tie(-0.2), l, key, nonce, kMethod2, &msg);
      EXPECT_EQ(slight.tied_bits, 1);
      EXPECT_EQ(slight.message, msg) << "bit " << bit << " seed " << seed;
      EXPECT_EQ(slight.compared - slight.agreements, r / 2);
      const Extraction far = extract(basis, m.points, tie(-3.0), l, key, nonce, kMethod2, &msg);
      EXPECT_EQ(far.tied_bits, 1);
      auto wrong = msg;
      wrong[static_cast<std::size_t>(bit)] = !wrong[static_cast<std::size_t>(bit)];
      EXPECT_EQ(far.message, wrong) << "bit " << bit << " seed " << seed;
      // Without the expected message the decoded one is the same, and so is the agreement count.
      const Extraction blind = extract(basis, m.points, tie(-0.2), l, key, nonce, kMethod2);
      EXPECT_EQ(blind.message, msg);
    }
  }
}

TEST(Watermark, SameCallTwiceGivesIdenticalBytes) {
  const Mesh m = torus();
  const auto msg = seeded_message(40, 10);
  for (const EmbedParams& p : {kMethod1, kMethod2}) {
    const Points a = embed(compute_basis(m), m.points, msg, seeded_key(10), seeded_nonce(10), p);
    const Points b = embed(compute_basis(m), m.points, msg, seeded_key(10), seeded_nonce(10), p);
    EXPECT_TRUE(same_bytes(a, b));
    const SpectralBasis basis = compute_basis(m);
    const Extraction x = extract(basis, m.points, a, 40, seeded_key(10), seeded_nonce(10), p, &msg);
    const Extraction y = extract(basis, m.points, b, 40, seeded_key(10), seeded_nonce(10), p, &msg);
    EXPECT_EQ(std::memcmp(&x.correlation, &y.correlation, sizeof(double)), 0);
    EXPECT_EQ(x.p_value, y.p_value);
    EXPECT_EQ(x.agreements, y.agreements);
  }
  // Different nonces give different copies.
  const SpectralBasis basis = compute_basis(m);
  EXPECT_FALSE(same_bytes(embed(basis, m.points, msg, seeded_key(10), seeded_nonce(10), kMethod2),
                          embed(basis, m.points, msg, seeded_key(10), seeded_nonce(11), kMethod2)));
}

TEST(Watermark, RejectsBadParametersAndSuspects) {
  const Mesh m = torus();
  const SpectralBasis basis = compute_basis(m);
  const auto msg = seeded_message(8, 12);
  const Key key = seeded_key(12);
  const Nonce nonce = seeded_nonce(12);
  for (double a : {0.0, 1.0, -0.1, std::nan("")})
    EXPECT_THROW(embed(basis, m.points, msg, key, nonce, {Method::Additive, a, 0.05}),
                 std::invalid_argument);
  EXPECT_THROW(embed(basis, m.points, msg, key, nonce, {Method::Additive, 0.01, -1}),
               std::invalid_argument);
  EXPECT_THROW(embed(basis, m.points.topRows(10), msg, key, nonce, kMethod2), std::invalid_argument);
  EXPECT_THROW(embed(basis, m.points, seeded_message(usable_coefficients(basis) + 1, 1), key, nonce,
                     kMethod2),
               std::invalid_argument);
  EXPECT_THROW(extract(basis, m.points, m.points.topRows(10), 8, key, nonce, kMethod2), InputError);
  Points nan = m.points;
  nan(3, 1) = std::nan("");
  EXPECT_THROW(extract(basis, m.points, nan, 8, key, nonce, kMethod2), InputError);
}

}  // namespace
}  // namespace mm

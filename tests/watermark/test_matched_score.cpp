// The matched score (watermark/matched_score.h): an exact copy scores sqrt(m); wrong keys stay
// under Hoeffding's bound; averaged copies and shrunk copies keep their marks.
#include <gtest/gtest.h>

#include <cmath>

#include "common/seeded_keys.h"
#include "meshio/normalize.h"
#include "spectral/synthetic_meshes.h"
#include "watermark/matched_score.h"

namespace mm {
namespace {

using test::seeded_key;
using test::seeded_message;
using test::seeded_nonce;

struct Torus {
  Mesh mesh = test::quad_torus(16, 12, 5);
  SpectralBasis basis;
  Torus() {
    apply(unit_box_normalization(mesh.points), mesh.points);
    basis = compute_basis(mesh);
  }
};

const EmbedParams kMethod1{Method::Multiplicative, 0.01, 0.05};
const EmbedParams kMethod2{Method::Additive, 0.01, 0.05};

MatchedScore score(const Torus& t, const Points& suspect, const EmbedParams& params, std::uint64_t key_seed,
                   const std::vector<bool>& message) {
  const CoefficientEvidence ev = coefficient_evidence(t.basis, t.mesh.points, suspect, 32, params);
  return matched_score(ev, seeded_key(key_seed), seeded_nonce(key_seed), message, usable_coefficients(t.basis));
}

TEST(MatchedScore, AnExactCopyScoresTheSquareRootOfItsCoefficientsAndDecodes) {
  const Torus t;
  for (const EmbedParams& params : {kMethod1, kMethod2}) {
    const auto msg = seeded_message(32, 3);
    const Points marked = embed(t.basis, t.mesh.points, msg, seeded_key(3), seeded_nonce(3), params);
    const MatchedScore s = score(t, marked, params, 3, msg);
    const int m = usable_coefficients(t.basis) / 32 * 32;
    // Every coefficient at its move: each weighs about alike (the noise floor aside).
    EXPECT_GT(s.statistic, 0.97 * std::sqrt(double(m)));
    EXPECT_LE(s.statistic, std::sqrt(double(m)) * (1 + 1e-12));
    EXPECT_NEAR(s.neg_log10_p, s.statistic * s.statistic / (2 * std::log(10.0)), 1e-9);
    EXPECT_EQ(s.message, msg);
  }
}

// Wrong keys: Hoeffding's bound holds whatever the suspect, so a p below alpha happens at most
// alpha of the time (the bound is conservative: less often).
TEST(MatchedScore, WrongKeysStayUnderTheBound) {
  const Torus t;
  const auto msg = seeded_message(32, 13);
  Points marked = embed(t.basis, t.mesh.points, msg, seeded_key(13), seeded_nonce(13), kMethod2);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0, 0.002);
  for (Eigen::Index i = 0; i < marked.size(); ++i) marked.data()[i] += noise(rng);
  int below_1pc = 0, below_10pc = 0;
  double smallest = 1;
  for (int s = 0; s < 400; ++s) {
    const MatchedScore w = score(t, marked, kMethod2, 1000 + s, msg);
    below_1pc += w.p < 0.01;
    below_10pc += w.p < 0.1;
    smallest = std::min(smallest, w.p);
  }
  EXPECT_LE(below_1pc, 4);    // Binomial(400, 0.01) exceeds 11 with probability < 0.001
  EXPECT_LE(below_10pc, 40);
  EXPECT_GT(smallest, 1e-4);
}

// Two copies averaged: where their marks disagree the coefficients are back at the original (up
// to rounding), which the weights ignore; where they agree both marks are whole. Both copies
// score far beyond any threshold, a third customer's not.
TEST(MatchedScore, BothCopiesOfAnAverageScore) {
  const Torus t;
  const auto a_msg = seeded_message(32, 1), b_msg = seeded_message(32, 2);
  const Points a = embed(t.basis, t.mesh.points, a_msg, seeded_key(1), seeded_nonce(1), kMethod1);
  const Points b = embed(t.basis, t.mesh.points, b_msg, seeded_key(2), seeded_nonce(2), kMethod1);
  const Points mean = (a + b) / 2;
  EXPECT_GT(score(t, mean, kMethod1, 1, a_msg).neg_log10_p, 20);
  EXPECT_GT(score(t, mean, kMethod1, 2, b_msg).neg_log10_p, 20);
  EXPECT_LT(score(t, mean, kMethod1, 3, seeded_message(32, 3)).neg_log10_p, 3);
}

// A copy shrunk towards its centre by 5 % (a systematic change 5 times the mark's strength in
// every coefficient): the bands' gain is taken out and the mark is found.
TEST(MatchedScore, ASystematicShrinkIsTakenOut) {
  const Torus t;
  const auto msg = seeded_message(32, 4);
  const Points marked = embed(t.basis, t.mesh.points, msg, seeded_key(4), seeded_nonce(4), kMethod1);
  const Eigen::RowVector3d centre = t.mesh.points.colwise().mean();
  const Points shrunk = (marked.rowwise() - centre) * 0.95;
  const Points suspect = shrunk.rowwise() + centre;
  const CoefficientEvidence ev = coefficient_evidence(t.basis, t.mesh.points, suspect, 32, kMethod1);
  EXPECT_GT(ev.bias_bands, 0);
  const MatchedScore s = matched_score(ev, seeded_key(4), seeded_nonce(4), msg, usable_coefficients(t.basis));
  EXPECT_GT(s.neg_log10_p, 50);
  EXPECT_EQ(s.message, msg);
}

TEST(MatchedScore, RefusesSuspectsOfAnotherSize) {
  const Torus t;
  EXPECT_THROW(coefficient_evidence(t.basis, t.mesh.points, t.mesh.points.topRows(10), 32, kMethod1), InputError);
  const CoefficientEvidence ev = coefficient_evidence(t.basis, t.mesh.points, t.mesh.points, 32, kMethod1);
  EXPECT_THROW(matched_score(ev, seeded_key(1), seeded_nonce(1), seeded_message(16, 1), usable_coefficients(t.basis)),
               std::invalid_argument);
  // An unmarked copy: nothing moved, nothing scored.
  EXPECT_EQ(matched_score(ev, seeded_key(1), seeded_nonce(1), seeded_message(32, 1), usable_coefficients(t.basis)).p, 1);
}

}  // namespace
}  // namespace mm

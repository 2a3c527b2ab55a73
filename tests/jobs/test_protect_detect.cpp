// Protect and detect handlers as pure functions: a copy is attributed to its own copy (also after
// noise, rescaling and vertex reordering), never to another customer's, and an unmarked or
// foreign mesh is attributed to nobody.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

#include "common/shared_meshes.h"
#include "jobs/detect.h"
#include "jobs/payload.h"
#include "jobs/protect.h"
#include "jobs/registration.h"
#include "meshio/read_mesh.h"

namespace mm::jobs {
namespace {

Key key_from(int seed) {
  Key k{};
  std::mt19937 g(static_cast<unsigned>(seed));
  for (auto& b : k) b = static_cast<std::uint8_t>(g());
  return k;
}
Nonce nonce_from(int seed) {
  Nonce n{};
  std::mt19937 g(static_cast<unsigned>(seed) * 7919u);
  for (auto& b : n) b = static_cast<std::uint8_t>(g());
  return n;
}

struct ProtectDetect : ::testing::Test {
  void SetUp() override {
    MM_REQUIRE_SHARED_MESHES();
    original = read_mesh(test::shared_mesh("fandisk_quads.off"));
    asset = prepare_asset(original, {}, "fandisk_quads.off");
    for (int i = 0; i < 3; ++i) {
      CopyCandidate c;
      c.copy_id = 100 + i;
      c.key = key_from(i + 1);
      c.nonce = nonce_from(i + 1);
      c.payload = 0x1000u + static_cast<unsigned>(i) * 0x3377u;
      copies.push_back(c);
    }
  }
  Mesh copy_of(int i) {
    return make_copy(asset, copies[i].key, copies[i].nonce, copies[i].payload, copies[i].settings);
  }
  Mesh original;
  PreparedAsset asset;
  std::vector<CopyCandidate> copies;
};

TEST_F(ProtectDetect, CopyKeepsConnectivityAndUnits) {
  Mesh c = copy_of(0);
  EXPECT_EQ(c.faces, original.faces);
  double diag = (original.points.colwise().maxCoeff() - original.points.colwise().minCoeff()).norm();
  double moved = (c.points - original.points).rowwise().norm().maxCoeff();
  EXPECT_GT(moved, 0);
  EXPECT_LT(moved, 0.05 * diag);  // imperceptible relative to the part, in the part's units
}

TEST_F(ProtectDetect, AttributesExactCopyToItsCopyOnly) {
  for (int i = 0; i < 3; ++i) {
    Registration r = register_suspect(asset, copy_of(i));
    EXPECT_EQ(r.method, "identity");
    Verdict v = detect_copy(asset, r.points, copies, 1e-6);
    ASSERT_TRUE(v.attributed) << i;
    EXPECT_EQ(v.best.copy_id, copies[i].copy_id);
    EXPECT_LT(v.best.corrected_p, 1e-9);
    EXPECT_EQ(v.best.decoded_payload, copies[i].payload);
    for (const auto& s : v.scores)
      if (s.copy_id != copies[i].copy_id) EXPECT_GT(s.corrected_p, 1e-6);
  }
}

TEST_F(ProtectDetect, NoisyRescaledReorderedCopyIsStillAttributed) {
  Mesh c = copy_of(1);
  double diag = (original.points.colwise().maxCoeff() - original.points.colwise().minCoeff()).norm();
  std::mt19937 g(42);
  std::normal_distribution<double> noise(0, 2e-4 * diag);
  for (Eigen::Index i = 0; i < c.points.rows(); ++i)
    for (int k = 0; k < 3; ++k) c.points(i, k) += noise(g);
  c.points *= 2.0;  // the leaker rescaled the part
  // Reorder the vertices (a different exporter): the faces follow.
  std::vector<int> perm(static_cast<std::size_t>(c.num_vertices()));
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), g);
  Mesh shuffled = c;
  for (int i = 0; i < c.num_vertices(); ++i) shuffled.points.row(perm[static_cast<std::size_t>(i)]) = c.points.row(i);
  for (auto& f : shuffled.faces)
    for (auto& v : f) v = perm[static_cast<std::size_t>(v)];
  Registration r = register_suspect(asset, shuffled);
  EXPECT_EQ(r.method, "nearest-neighbour");
  EXPECT_GT(r.matched_fraction, 0.99);
  Verdict v = detect_copy(asset, r.points, copies, 1e-6);
  ASSERT_TRUE(v.attributed);
  EXPECT_EQ(v.best.copy_id, copies[1].copy_id);
  EXPECT_LT(v.best.corrected_p, 1e-9);
}

TEST_F(ProtectDetect, UnmarkedOriginalAndNoisyOriginalAreNotAttributed) {
  Registration r = register_suspect(asset, original);
  Verdict v = detect_copy(asset, r.points, copies, 1e-6);
  EXPECT_FALSE(v.attributed);
  Mesh noisy = original;
  double diag = (original.points.colwise().maxCoeff() - original.points.colwise().minCoeff()).norm();
  std::mt19937 g(7);
  std::normal_distribution<double> noise(0, 1e-3 * diag);
  for (Eigen::Index i = 0; i < noisy.points.rows(); ++i)
    for (int k = 0; k < 3; ++k) noisy.points(i, k) += noise(g);
  r = register_suspect(asset, noisy);
  v = detect_copy(asset, r.points, copies, 1e-6);
  EXPECT_FALSE(v.attributed);
  EXPECT_GT(v.best.corrected_p, 1e-6);
}

TEST_F(ProtectDetect, ForeignMeshIsNotAttributed) {
  Mesh foreign = read_mesh(test::shared_mesh("abc9.stl"));
  Registration r = register_suspect(asset, foreign);
  Verdict v = detect_copy(asset, r.points, copies, 1e-6);
  EXPECT_FALSE(v.attributed);
}

TEST_F(ProtectDetect, WrongPayloadOrWrongKeyIsNotAttributed) {
  Mesh c = copy_of(2);
  Registration r = register_suspect(asset, c);
  // Right key and nonce but a record claiming another payload: the payload check refuses.
  auto lying = copies;
  lying[2].payload ^= 0x5;
  Verdict v = detect_copy(asset, r.points, lying, 1e-6);
  EXPECT_FALSE(v.attributed);
  EXPECT_FALSE(v.best.payload_matches);
  // Only other customers' keys on record: nothing passes.
  std::vector<CopyCandidate> others = {copies[0], copies[1]};
  v = detect_copy(asset, r.points, others, 1e-6);
  EXPECT_FALSE(v.attributed);
}

}  // namespace
}  // namespace mm::jobs

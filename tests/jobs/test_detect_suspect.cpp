// The detect job's whole rule (jobs::detect_suspect) over an in-memory DetectionStore: how the
// candidates are found, the correction for every copy tried over every polyhedron, the best copy
// and the verdict -- the same code the daemon runs over its SQLite store. And the copy identity
// every issued copy and `meshmark embed` derive their nonce from.
#include <gtest/gtest.h>
#include <sodium.h>

#include <cmath>
#include <map>
#include <set>
#include <random>

#include "common/seeded_keys.h"
#include "jobs/copy_identity.h"
#include "jobs/detect_suspect.h"
#include "attacks/crop.h"
#include "jobs/payload.h"
#include "samples/chamfered_block.h"
#include "samples/flanged_cylinder.h"

namespace mm::jobs {
namespace {

using test::key_from;

std::string sha_of(const std::string& label) {  // stand-in content address
  unsigned char h[32];
  crypto_generichash(h, sizeof h, reinterpret_cast<const unsigned char*>(label.data()), label.size(), nullptr, 0);
  static const char* d = "0123456789abcdef";
  std::string s;
  for (unsigned char c : h) s += d[c >> 4], s += d[c & 15];
  return s;
}

class MemoryStore : public DetectionStore {
 public:
  std::vector<IssuedCopyRecord> copies;
  std::map<std::string, std::int64_t> assets;  // original sha -> id
  std::map<std::pair<std::int64_t, std::string>, PolyhedronRecord> polyhedra;
  std::map<std::string, std::vector<std::uint8_t>> blobs;
  std::map<std::pair<std::int64_t, int>, Key> keys;
  int key_reads = 0;

  std::vector<IssuedCopyRecord> issued_copies() override { return copies; }
  std::optional<std::int64_t> asset_with_sha256(const std::string& sha) override {
    auto it = assets.find(sha);
    return it == assets.end() ? std::nullopt : std::optional<std::int64_t>(it->second);
  }
  std::optional<PolyhedronRecord> polyhedron(std::int64_t asset, const std::string& key) override {
    auto it = polyhedra.find({asset, key});
    return it == polyhedra.end() ? std::nullopt : std::optional<PolyhedronRecord>(it->second);
  }
  std::vector<std::uint8_t> blob(const std::string& sha) override { return blobs.at(sha); }
  Key customer_key(std::int64_t customer, int version) override {
    ++key_reads;
    return keys.at({customer, version});
  }
};

struct Issued {
  IssuedCopyRecord record;
  Mesh decoded;
};

// One prepared part with copies issued the way the daemon issues them.
struct Part {
  Mesh original;
  PreparedAsset asset;
  MemoryStore store;
  std::vector<Issued> issued;

  // Copies under `prepare_key`: the polyhedron row is stored once per key.
  void issue(std::int64_t copy_id, std::int64_t customer, const std::string& prepare_key) {
    if (!store.polyhedra.count({1, prepare_key})) {
      PolyhedronRecord row;
      row.id = static_cast<std::int64_t>(store.polyhedra.size()) + 1;
      row.polyhedron_blob = sha_of("poly");
      row.basis_blob = sha_of("basis");
      row.meta_json = "{\"signature\": " + asset.signature.to_json() + ", \"footprint\": " +
                      surface_footprint(original).to_json() + "}";
      store.blobs[row.polyhedron_blob] = encode_polyhedron(asset);
      store.blobs[row.basis_blob] = serialize_basis(asset.basis);
      store.polyhedra[{1, prepare_key}] = row;
    }
    store.keys[{customer, 1}] = key_from(static_cast<int>(customer));
    WatermarkSettings ws;
    std::set<std::string> taken;
    for (const auto& c : store.copies) taken.insert(c.payload_hex);
    const CopyIdentity id = issue_copy_identity(sha_of("original"), customer, 1, "copy:" + std::to_string(copy_id),
                                                ws.message_bits, taken);
    IssuedCopyRecord r;
    r.id = copy_id;
    r.asset_id = 1;
    r.customer_id = customer;
    r.key_version = 1;
    r.nonce.assign(id.nonce.begin(), id.nonce.end());
    r.payload_hex = payload_hex(id.payload, ws.message_bits);
    r.params_json = copy_params_json(ws, prepare_key, sha_of("basis"));
    r.outputs_json = "{\"files\": [{\"role\": \"decoded\", \"sha256\": \"" + sha_of("decoded " + std::to_string(copy_id)) +
                     "\"}]}";
    Mesh marked = make_copy(asset, store.keys[{customer, 1}], id.nonce, id.payload, ws);
    issued.push_back({r, make_copy_files(asset, marked, {}, false).decoded});
    store.copies.push_back(r);
  }
};

Part* part = nullptr;

struct DetectSuspect : ::testing::Test {
  static void SetUpTestSuite() {
    if (part) return;
    part = new Part;
    part->original = samples::chamfered_block();
    part->asset = prepare_asset(part->original, {}, "block");
    part->store.assets[sha_of("original")] = 1;
    part->issue(11, 1, "a");
    part->issue(12, 2, "a");
    part->issue(13, 1, "b");  // a later copy under other compression options
  }
  static void TearDownTestSuite() {
    delete part;
    part = nullptr;
  }
  static Suspect suspect(const Mesh& m, const std::string& sha) { return {m, "suspect.off", sha, {}}; }
};

TEST_F(DetectSuspect, AnIssuedFileIsFoundByItsHashAndAttributedToItsCopy) {
  const Detection d = detect_suspect(part->store, suspect(part->issued[1].decoded, sha_of("decoded 12")), {});
  EXPECT_EQ(d.match, "hash of issued copy 12 (decoded)");
  EXPECT_EQ(d.verdict, "attributed");
  ASSERT_TRUE(d.copy_id && d.customer_id && d.asset_id);
  EXPECT_EQ(*d.copy_id, 12);
  EXPECT_EQ(*d.customer_id, 2);
  EXPECT_EQ(*d.asset_id, 1);
  EXPECT_EQ(d.decoded_payload_hex, part->issued[1].record.payload_hex);
  EXPECT_TRUE(d.reason.empty());
}

TEST_F(DetectSuspect, EveryCopyOfEveryPolyhedronIsCountedInTheCorrection) {
  const Detection d = detect_suspect(part->store, suspect(part->issued[0].decoded, "unknown"), {});
  EXPECT_EQ(d.match, "surface footprint");  // an issued copy lies on the original, in its units
  ASSERT_EQ(d.tried.size(), 2u);  // prepare keys "a" and "b"
  EXPECT_EQ(d.tried[0].scores.size(), 2u);
  EXPECT_EQ(d.tried[1].scores.size(), 1u);
  EXPECT_EQ(d.copies_tried, 3);
  for (const auto& t : d.tried)
    for (const auto& s : t.scores) EXPECT_EQ(s.corrected_p, std::min(1.0, s.p_value * 3)) << s.copy_id;
  ASSERT_TRUE(d.best);
  EXPECT_EQ(d.best->copy_id, 11);
  EXPECT_EQ(d.best_tried, 0);
  EXPECT_EQ(d.verdict, "attributed");
  EXPECT_NEAR(d.best_neg_log10_corrected_p, d.best->neg_log10_p - std::log10(3.0), 1e-12);
}

TEST_F(DetectSuspect, TheUnmarkedOriginalIsNoWatermarkAndAForeignPartAnUnknownAsset) {
  const Detection o = detect_suspect(part->store, suspect(part->original, sha_of("original")), {});
  EXPECT_EQ(o.match, "hash of original asset 1");
  EXPECT_EQ(o.verdict, "no watermark found");
  EXPECT_FALSE(o.copy_id || o.customer_id);
  ASSERT_TRUE(o.asset_id);
  EXPECT_EQ(*o.asset_id, 1);
  EXPECT_EQ(o.copies_tried, 3);

  const Detection f = detect_suspect(part->store, suspect(samples::flanged_cylinder(), "foreign"), {});
  EXPECT_EQ(f.verdict, "unknown asset");
  EXPECT_TRUE(f.candidates.empty());
  EXPECT_EQ(f.copies_tried, 0);
  EXPECT_FALSE(f.asset_id);
}

TEST_F(DetectSuspect, AMovedCopyOrARowWithoutAFootprintIsFoundByItsShapeSignature) {
  Mesh moved = part->issued[0].decoded;
  moved.points = (moved.points * 2.5).rowwise() + Eigen::RowVector3d(40, -3, 7);
  const Detection d = detect_suspect(part->store, suspect(moved, "unknown"), {});
  EXPECT_EQ(d.match, "shape signature");
  EXPECT_EQ(d.verdict, "attributed");

  MemoryStore st = part->store;  // polyhedra kept before footprints were
  for (auto& [key, row] : st.polyhedra) row.meta_json = "{\"signature\": " + part->asset.signature.to_json() + "}";
  const Detection old = detect_suspect(st, suspect(part->issued[0].decoded, "unknown"), {});
  EXPECT_EQ(old.match, "shape signature");
  EXPECT_EQ(old.verdict, "attributed");
}

TEST_F(DetectSuspect, AHalfCropOfAnIssuedCopyIsFoundAmongAThousandAssetsAndAttributed) {
  // 999 other assets: the part at random places and sizes, and ten revisions of it shifted by
  // 3 % of its size (a footprint holds much of a crop of those). Their rows share the real
  // polyhedron, so any that is tried is aligned and scored like the real one.
  MemoryStore st = part->store;
  const PolyhedronRecord real = st.polyhedra.at({1, "a"});
  const Eigen::RowVector3d size = part->original.points.colwise().maxCoeff() - part->original.points.colwise().minCoeff();
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> u(-1, 1);
  for (std::int64_t id = 2; id <= 1000; ++id) {
    Mesh other = part->original;
    if (id <= 11) {
      other.points.rowwise() += 0.03 * Eigen::RowVector3d(u(rng), u(rng), u(rng)).normalized().cwiseProduct(size);
    } else {
      const double scale = std::exp(0.25 * u(rng));
      other.points = (other.points * scale).rowwise() + Eigen::RowVector3d(u(rng), u(rng), u(rng)).cwiseProduct(size);
    }
    PolyhedronRecord row = real;
    row.id = id + 100;
    row.meta_json = "{\"signature\": " + shape_signature(other).to_json() + ", \"footprint\": " +
                    surface_footprint(other).to_json() + "}";
    st.polyhedra[{id, "a"}] = row;
    IssuedCopyRecord c = part->issued[1].record;
    c.id = 1000 + id;
    c.asset_id = id;
    st.copies.push_back(c);
  }
  const Mesh half = attacks::crop_along_longest_axis(part->issued[0].decoded, 0.5);
  const Detection d = detect_suspect(st, suspect(half, "unknown"), {});
  EXPECT_EQ(d.match, "surface footprint");
  ASSERT_FALSE(d.candidates.empty());
  EXPECT_EQ(d.candidates.front(), 1);
  EXPECT_EQ(d.verdict, "attributed") << d.best_neg_log10_corrected_p;
  ASSERT_TRUE(d.copy_id);
  EXPECT_EQ(*d.copy_id, 11);
  for (const auto& a : d.attributed) EXPECT_EQ(a.customer_id, 1);
}

TEST_F(DetectSuspect, AssetsAlikeOverACropAreAllTriedAndOnlyTheIssuingCopyIsNamed) {
  // Five more assets with the part's own footprint (a family whose members share the cropped
  // region): they tie with the part, so all are tried even with max_candidates 1, and each
  // copy tried counts in the correction.
  MemoryStore st = part->store;
  const PolyhedronRecord real = st.polyhedra.at({1, "a"});
  for (std::int64_t id = 2; id <= 6; ++id) {
    PolyhedronRecord row = real;
    row.id = id + 100;
    st.polyhedra[{id, "a"}] = row;
    IssuedCopyRecord c = part->issued[1].record;  // customer 2's copy, as if issued for this asset
    c.id = 1000 + id;
    c.asset_id = id;
    st.copies.push_back(c);
  }
  DetectOptions one;
  one.max_candidates = 1;
  const Mesh half = attacks::crop_along_longest_axis(part->issued[0].decoded, 0.5);
  const Detection d = detect_suspect(st, suspect(half, "unknown"), one);
  EXPECT_EQ(d.match, "surface footprint");
  ASSERT_EQ(d.candidates.size(), 6u);
  ASSERT_EQ(d.region_agreement.size(), 6u);
  for (const auto& [id, a] : d.region_agreement) EXPECT_EQ(a, d.region_agreement.at(1)) << id;
  EXPECT_GT(d.region_agreement.at(1), 0.8);  // the mark moves some of the surface across cell boundaries
  EXPECT_EQ(d.copies_tried, 3 + 5);
  EXPECT_EQ(d.verdict, "attributed") << d.best_neg_log10_corrected_p;
  ASSERT_EQ(d.attributed.size(), 1u);
  EXPECT_EQ(d.attributed[0].copy_id, 11);
}

TEST_F(DetectSuspect, AStreamIsFoundByTheAssetItNames) {
  Suspect s = suspect(part->issued[2].decoded, "unknown");
  s.stream_metadata["asset"] = sha_of("original");
  const Detection d = detect_suspect(part->store, s, {});
  EXPECT_EQ(d.match, "stream metadata");
  EXPECT_EQ(d.verdict, "attributed");
  ASSERT_TRUE(d.copy_id);
  EXPECT_EQ(*d.copy_id, 13);
}

TEST_F(DetectSuspect, CopiesOfAPolyhedronNotKeptAreReportedAndNotScored) {
  MemoryStore st = part->store;
  st.polyhedra.erase({1, "b"});
  const Detection d = detect_suspect(st, suspect(part->issued[2].decoded, "unknown"), {});
  EXPECT_EQ(d.copies_tried, 2);
  ASSERT_EQ(d.warnings.size(), 1u);
  EXPECT_NE(d.warnings[0].find("not cached (\"b\")"), std::string::npos) << d.warnings[0];
  EXPECT_NE(d.verdict, "attributed");  // copy 13's polyhedron is gone: it cannot be named
}

TEST_F(DetectSuspect, TheContextSourceIsAskedOncePerPolyhedronByItsContentAddress) {
  std::vector<std::string> asked;
  DetectOptions o;
  o.contexts = [&](const std::string& key, const std::function<ResyncContext()>& build) {
    asked.push_back(key);
    return std::make_shared<const ResyncContext>(build());
  };
  detect_suspect(part->store, suspect(part->issued[0].decoded, "unknown"), o);
  EXPECT_EQ(asked, (std::vector<std::string>{sha_of("poly"), sha_of("poly")}));
}

TEST(CopyIdentity, IsBlake2bOfTheNamedFieldsKeyedWhenAKeyIsGiven) {
  const std::string msg = "meshmark-copy-v1|abc|7|2|job:5|0";
  unsigned char h[32];
  crypto_generichash(h, sizeof h, reinterpret_cast<const unsigned char*>(msg.data()), msg.size(), nullptr, 0);
  const CopyIdentity id = derive_copy_identity({"abc", "7", "2", "job:5", "0"});
  EXPECT_TRUE(std::equal(id.nonce.begin(), id.nonce.end(), h));
  std::uint64_t payload = 0;
  for (int i = 0; i < 8; ++i) payload |= std::uint64_t(h[24 + i]) << (8 * i);
  EXPECT_EQ(id.payload, payload);

  const Key k = key_from(3);
  const CopyIdentity keyed = derive_copy_identity({"abc", "7", "2", "job:5", "0"}, &k);
  EXPECT_NE(keyed.nonce, id.nonce);
  const Key k2 = key_from(4);
  EXPECT_NE(derive_copy_identity({"abc", "7", "2", "job:5", "0"}, &k2).nonce, keyed.nonce);
}

TEST(CopyIdentity, IssuedPayloadsHaveTheWidthAskedAndSkipThoseTaken) {
  const CopyIdentity first = issue_copy_identity("abc", 7, 2, "job:5", 16, {});
  EXPECT_LT(first.payload, 1u << 16);
  EXPECT_EQ(first.payload, derive_copy_identity({"abc", "7", "2", "job:5", "0"}).payload & 0xffffu);
  const CopyIdentity second = issue_copy_identity("abc", 7, 2, "job:5", 16, {payload_hex(first.payload, 16)});
  EXPECT_NE(second.payload, first.payload);
  EXPECT_EQ(second.nonce, derive_copy_identity({"abc", "7", "2", "job:5", "1"}).nonce);
  EXPECT_EQ(issue_copy_identity("abc", 7, 2, "job:5", 64, {}).payload,
            derive_copy_identity({"abc", "7", "2", "job:5", "0"}).payload);
}

}  // namespace
}  // namespace mm::jobs

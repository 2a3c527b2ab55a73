#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <thread>

#include "store_backends.h"
#include "store_test_util.h"
#include "support/sha256.h"

using namespace mm;
using namespace mm::test;
using store::JobState;

namespace {

struct Fixture {
  BackendStores stores;
  TempDir dir;
  StepClock clock;
  std::string fault_at;  // the injection point that throws ("" = none)
  std::unique_ptr<store::Store> s;
  store::Customer acme;
  store::Asset asset;

  explicit Fixture(Backend b) : stores(b) {
    auto o = options(dir, &clock);
    o.fault_injection = [this](const std::string& point) {
      if (point == fault_at) throw std::runtime_error("injected failure at " + point);
    };
    s = stores.open_store(dir, o);
    acme = s->add_customer("acme");
    asset = s->put_asset_bytes({1, 2, 3, 4}, "part.stl");
  }

  store::NewCopy copy(const std::string& idem) const {
    store::NewCopy c;
    c.asset_id = asset.id;
    c.customer_id = acme.id;
    c.key_version = 1;
    c.idempotency_key = idem;
    c.nonce = std::vector<std::uint8_t>(24, 7);
    c.payload_hex = "deadbeef";
    c.params_json = R"({"strength":0.002})";
    c.outputs_json = R"({"stream":"0123"})";
    return c;
  }

  std::string count(const std::string& table) {
    return stores.raw(dir, "SELECT COUNT(*) FROM " + table)[0];
  }
};

// The records' contract, on each backend.
class Records : public BackendTest {};
MM_BACKENDS(Records);

}  // namespace

TEST_P(Records, CompleteWritesJobAndRecordsTogether) {
  Fixture f(GetParam());
  auto id = f.s->enqueue({"protect", "{}", 0, 5, "job-1", {}}).job.id;
  ASSERT_TRUE(f.s->claim("w", 1000));
  store::JobRecords r;
  r.copies = {f.copy("job-1")};
  store::NewDetection d;
  d.suspect_sha256 = f.asset.sha256;
  d.verdict = "attributed";
  d.customer_id = f.acme.id;
  d.correlation = 0.9;
  d.p_value = 1e-12;
  r.detections = {d};
  r.audit = {{"w", "custom.event", "job:" + std::to_string(id), "{}"}};
  r.result_json = R"({"copies":1})";
  auto res = f.s->complete(id, "w", r);
  ASSERT_EQ(res.copy_ids.size(), 1u);
  ASSERT_EQ(res.detection_ids.size(), 1u);
  auto c = f.s->get_copy(res.copy_ids[0]);
  ASSERT_TRUE(c);
  EXPECT_EQ(*c->job_id, id);
  EXPECT_EQ(c->nonce, std::vector<std::uint8_t>(24, 7));
  EXPECT_EQ(c->params_json, R"({"strength":0.002})");
  auto ds = f.s->list_detections();
  ASSERT_EQ(ds.size(), 1u);
  EXPECT_EQ(*ds[0].job_id, id);
  EXPECT_DOUBLE_EQ(*ds[0].p_value, 1e-12);
  EXPECT_EQ(f.s->get_job(id)->state, JobState::completed);
}

class CompleteFault : public ::testing::TestWithParam<std::tuple<Backend, const char*>> {
 protected:
  void SetUp() override {
    if (std::get<0>(GetParam()) == Backend::postgres) MM_REQUIRE_POSTGRES();
  }
};

TEST_P(CompleteFault, FailureMidTransactionWritesNothing) {
  Fixture f(std::get<0>(GetParam()));
  auto id = f.s->enqueue({"protect", "{}", 0, 5, "job-1", {}}).job.id;
  ASSERT_TRUE(f.s->claim("w", 60'000));
  std::string audit_before = f.count("audit_log");
  store::JobRecords r;
  r.copies = {f.copy("job-1")};
  store::NewDetection d;
  d.suspect_sha256 = f.asset.sha256;
  d.verdict = "no watermark found";
  r.detections = {d};
  r.audit = {{"w", "custom.event", "x", "{}"}};
  f.fault_at = std::get<1>(GetParam());
  EXPECT_THROW(f.s->complete(id, "w", r), std::runtime_error);
  EXPECT_EQ(f.count("issued_copies"), "0");
  EXPECT_EQ(f.count("detections"), "0");
  EXPECT_EQ(f.count("audit_log"), audit_before);
  auto j = f.s->get_job(id);
  EXPECT_EQ(j->state, JobState::running) << "the job must still be held, not completed";
  // The worker can still finish it properly afterwards, exactly once.
  f.fault_at.clear();
  auto res = f.s->complete(id, "w", r);
  EXPECT_EQ(res.copies_already_existed, 0);
  EXPECT_EQ(f.count("issued_copies"), "1");
  EXPECT_EQ(f.count("detections"), "1");
}
INSTANTIATE_TEST_SUITE_P(
    Points, CompleteFault,
    ::testing::Combine(::testing::Values(Backend::sqlite, Backend::postgres),
                       ::testing::Values("complete.after_job_update", "complete.after_copies",
                                         "complete.after_detections", "complete.before_commit")),
    [](const auto& info) {
      std::string point = std::get<1>(info.param);
      for (char& ch : point)
        if (ch == '.') ch = '_';
      return (std::get<0>(info.param) == Backend::sqlite ? "sqlite_" : "postgres_") + point;
    });

TEST_P(Records, ConstraintViolationInRecordsRollsBackCompletion) {
  Fixture f(GetParam());
  auto id = f.s->enqueue({"protect", "{}", 0, 5, "", {}}).job.id;
  ASSERT_TRUE(f.s->claim("w", 60'000));
  store::JobRecords r;
  r.copies = {f.copy("a"), f.copy("b")};
  r.copies[1].key_version = 9;  // no such key version: foreign key violation on the 2nd record
  EXPECT_THROW(f.s->complete(id, "w", r), store::StoreError);
  EXPECT_EQ(f.count("issued_copies"), "0");
  EXPECT_EQ(f.s->get_job(id)->state, JobState::running);
}

TEST_P(Records, IssuedCopyIsUniquePerAssetCustomerKeyVersionAndIdempotencyKey) {
  Fixture f(GetParam());
  auto a = f.s->issue_copy(f.copy("req-1"));
  auto b = f.s->issue_copy(f.copy("req-1"));
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(f.count("issued_copies"), "1");
  // A re-run job completing with the same copy keeps the first one.
  auto id = f.s->enqueue({"protect", "{}", 0, 5, "", {}}).job.id;
  ASSERT_TRUE(f.s->claim("w", 1000));
  store::JobRecords r;
  r.copies = {f.copy("req-1"), f.copy("req-2")};
  auto res = f.s->complete(id, "w", r);
  EXPECT_EQ(res.copies_already_existed, 1);
  EXPECT_EQ(res.copy_ids[0], a.id);
  EXPECT_EQ(f.count("issued_copies"), "2");
  // After a key rotation the same request is a new copy under the new version; old copies keep v1.
  EXPECT_EQ(f.s->rotate_key(f.acme.id), 2);
  auto c = f.copy("req-1");
  c.key_version = 2;
  auto v2 = f.s->issue_copy(c);
  EXPECT_NE(v2.id, a.id);
  EXPECT_EQ(f.s->get_copy(a.id)->key_version, 1);
  EXPECT_TRUE(f.s->find_copy(f.asset.id, f.acme.id, 2, "req-1"));
  EXPECT_FALSE(f.s->find_copy(f.asset.id, f.acme.id, 3, "req-1"));
}

TEST_P(Records, AssetsAreDeduplicatedByContent) {
  Fixture f(GetParam());
  std::string p = f.dir / "copy-of-part.stl";
  {
    std::ofstream out(p, std::ios::binary);
    out.write("\x01\x02\x03\x04", 4);
  }
  auto again = f.s->put_asset_file(p, "renamed.STL");
  EXPECT_EQ(again.id, f.asset.id);
  EXPECT_EQ(again.name, "part.stl") << "the first name is kept";
  EXPECT_EQ(f.asset.format, "stl");
  EXPECT_EQ(f.asset.size, 4u);
  EXPECT_EQ(f.s->list_assets().size(), 1u);
  EXPECT_EQ(f.s->find_asset(f.asset.sha256)->id, f.asset.id);
  EXPECT_EQ(f.s->blobs().get(f.asset.sha256), (std::vector<std::uint8_t>{1, 2, 3, 4}));
  auto other = f.s->put_asset_bytes({9}, "b.obj");
  EXPECT_NE(other.id, f.asset.id);
  EXPECT_THROW(f.s->put_asset_file(f.dir / "missing.stl", "missing.stl"), store::BlobError);
}

// Blobs of several megabytes (several chunks on PostgreSQL) come back whole, as bytes and as a
// file; a missing one is an error, never empty bytes; the same bytes put by many threads at once
// are one blob.
TEST_P(Records, BlobsComeBackWholeAsBytesAndAsFiles) {
  Fixture f(GetParam());
  std::mt19937 rng(11);
  std::vector<std::uint8_t> data(3 * 1024 * 1024 + 17);
  for (auto& b : data) b = static_cast<std::uint8_t>(rng());
  const std::string src = f.dir / "big.bin";
  std::ofstream(src, std::ios::binary).write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
  const std::string h = f.s->blobs().put_file(src);
  EXPECT_EQ(h, support::sha256_hex(data));
  EXPECT_TRUE(f.s->blobs().contains(h));
  EXPECT_EQ(f.s->blobs().size(h), data.size());
  EXPECT_EQ(f.s->blobs().get(h), data);
  std::ifstream file(f.s->blobs().path(h), std::ios::binary);
  EXPECT_EQ(std::vector<std::uint8_t>(std::istreambuf_iterator<char>(file), {}), data);
  if (GetParam() == Backend::postgres) {
    EXPECT_EQ(f.stores.raw(f.dir, "SELECT COUNT(*) FROM blob_chunks WHERE sha256 = '" + h + "'")[0], "4");
  }

  const std::string absent(64, 'a');
  EXPECT_FALSE(f.s->blobs().contains(absent));
  EXPECT_THROW(f.s->blobs().get(absent), store::BlobError);
  EXPECT_THROW(f.s->blobs().size(absent), store::BlobError);

  std::vector<std::thread> threads;
  std::vector<std::string> got(4);
  for (int i = 0; i < 4; ++i) threads.emplace_back([&, i] { got[i] = f.s->blobs().put(std::string("shared bytes")); });
  for (auto& t : threads) t.join();
  for (const auto& g : got) EXPECT_EQ(g, got[0]);
  EXPECT_EQ(f.s->blobs().get(got[0]), (std::vector<std::uint8_t>{'s', 'h', 'a', 'r', 'e', 'd', ' ', 'b', 'y', 't', 'e', 's'}));
}

// A blob whose stored bytes were changed is refused on read, naming the blob.
TEST(PostgresBlobs, AChangedChunkIsRefusedOnRead) {
  MM_REQUIRE_POSTGRES();
  Fixture f(Backend::postgres);
  const std::string h = f.s->blobs().put(std::string("original bytes"));
  f.stores.raw(f.dir, "UPDATE blob_chunks SET data = '\\x00' WHERE sha256 = '" + h + "'");
  try {
    f.s->blobs().get(h);
    FAIL() << "changed blob returned";
  } catch (const store::BlobError& e) {
    EXPECT_NE(std::string(e.what()).find(h), std::string::npos) << e.what();
  }
}

TEST_P(Records, PolyhedraAreCachedPerAssetAndParameters) {
  Fixture f(GetParam());
  std::string poly = f.s->blobs().put(std::string("control polyhedron"));
  std::string basis = f.s->blobs().put(std::string("basis"));
  store::Polyhedron p;
  p.asset_id = f.asset.id;
  p.params_key = "loop;levels=2;tol=1e-3";
  p.polyhedron_blob = poly;
  p.basis_blob = basis;
  auto a = f.s->put_polyhedron(p);
  p.basis_blob = "";  // a second put with the same key returns the cached row unchanged
  auto b = f.s->put_polyhedron(p);
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(b.basis_blob, basis);
  EXPECT_TRUE(f.s->find_polyhedron(f.asset.id, "loop;levels=2;tol=1e-3"));
  EXPECT_FALSE(f.s->find_polyhedron(f.asset.id, "other"));
  store::Polyhedron missing = p;
  missing.params_key = "x";
  missing.polyhedron_blob = std::string(64, 'a');
  EXPECT_THROW(f.s->put_polyhedron(missing), store::StoreError) << "a row must never point at a missing blob";
}

TEST_P(Records, AuditLogIsAppendOnly) {
  Fixture f(GetParam());
  auto id = f.s->append_audit({"test", "custom.event", "x", R"({"n":1})"});
  auto entries = f.s->list_audit();
  ASSERT_FALSE(entries.empty());
  EXPECT_EQ(entries[0].id, id);
  // The store itself recorded the customer and asset.
  bool saw_customer = false;
  for (auto& e : entries) saw_customer |= e.action == "customer.add";
  EXPECT_TRUE(saw_customer);
  std::string err;
  f.stores.raw(f.dir, "UPDATE audit_log SET action = 'forged'", &err);
  EXPECT_NE(err.find("append-only"), std::string::npos) << err;
  f.stores.raw(f.dir, "DELETE FROM audit_log", &err);
  EXPECT_NE(err.find("append-only"), std::string::npos) << err;
  EXPECT_EQ(f.s->list_audit().size(), entries.size());
  EXPECT_EQ(f.s->list_audit()[0].action, "custom.event");
}

#include <gtest/gtest.h>

#include <regex>
#include <thread>

#include "store/migrations.h"
#include "store_test_util.h"

using namespace mm;
using namespace mm::test;

TEST(Migrations, EmbeddedFilesAreNumberedAndOrdered) {
  const auto& ms = store::embedded_migrations();
  ASSERT_FALSE(ms.empty());
  int last = 0;
  for (const auto& m : ms) {
    EXPECT_GT(m.version, last) << m.name;
    last = m.version;
    EXPECT_TRUE(std::regex_match(std::string(m.name), std::regex("[0-9]{4}_[A-Za-z0-9_]+\\.sql"))) << m.name;
    EXPECT_GT(std::string(m.sql).size(), 10u);
  }
}

TEST(Migrations, AppliedOnceAndRecordedWithVersion) {
  TempDir dir;
  const auto& ms = store::embedded_migrations();
  auto o = options(dir);
  {
    auto s = store::open_sqlite_store(o);
    EXPECT_EQ(s->schema_version(), ms.back().version);
  }
  auto applied = raw_query(o.db_path, "SELECT version || ':' || name || ':' || applied_at FROM schema_version ORDER BY version");
  ASSERT_EQ(applied.size(), ms.size());
  // Reopening applies nothing again: same rows, same times.
  for (int i = 0; i < 3; ++i) {
    auto s = store::open_sqlite_store(o);
    EXPECT_EQ(s->schema_version(), ms.back().version);
  }
  EXPECT_EQ(raw_query(o.db_path, "SELECT version || ':' || name || ':' || applied_at FROM schema_version ORDER BY version"),
            applied);
}

TEST(Migrations, ConcurrentOpenersApplyEachMigrationOnce) {
  TempDir dir;
  auto o = options(dir);
  std::vector<std::thread> ts;
  std::atomic<int> failures{0};
  for (int i = 0; i < 4; ++i)
    ts.emplace_back([&] {
      try {
        auto s = store::open_sqlite_store(o);
      } catch (...) {
        ++failures;
      }
    });
  for (auto& t : ts) t.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(raw_query(o.db_path, "SELECT COUNT(*) FROM schema_version")[0],
            std::to_string(store::embedded_migrations().size()));
}

TEST(Migrations, PragmasWalAndForeignKeys) {
  TempDir dir;
  auto o = options(dir);
  auto s = store::open_sqlite_store(o);
  EXPECT_EQ(raw_query(o.db_path, "PRAGMA journal_mode")[0], "wal");
  // Foreign keys are enforced on the store's own connection: a copy for an unknown asset fails.
  store::NewCopy c;
  c.asset_id = 999;
  c.customer_id = 999;
  c.key_version = 1;
  c.nonce = std::vector<std::uint8_t>(24, 1);
  c.payload_hex = "00";
  EXPECT_THROW(s->issue_copy(c), store::StoreError);
  EXPECT_TRUE(s->integrity_ok());
}

// A database created by the first schema (with a detection row from a build that kept the resync
// method only in details_json) is upgraded in place: columns added, row back-filled, nothing lost.
TEST(Migrations, UpgradesAVersion1DatabaseWithRows) {
  TempDir dir;
  auto o = options(dir);
  const auto& ms = store::embedded_migrations();
  ASSERT_GE(ms.size(), 2u);
  ASSERT_EQ(ms[0].version, 1);
  raw_query(o.db_path, std::string("CREATE TABLE schema_version (version INTEGER PRIMARY KEY, name TEXT NOT NULL, "
                                   "applied_at INTEGER NOT NULL);") +
                           ms[0].sql + "; INSERT INTO schema_version VALUES (1, '" + ms[0].name + "', 0);" +
                           "INSERT INTO detections(suspect_sha256, verdict, details_json, created_at) VALUES "
                           "('aa', 'attributed', '{\"resync_method\": \"subdivided\", \"resync_residual\": 0.25}', 1),"
                           "('bb', 'unknown asset', '{}', 2);");
  auto s = store::open_sqlite_store(o);
  EXPECT_EQ(s->schema_version(), ms.back().version);
  auto dets = s->list_detections();
  ASSERT_EQ(dets.size(), 2u);
  for (const auto& d : dets) {
    if (d.suspect_sha256 == "aa") {
      EXPECT_EQ(d.resync_method, "subdivided");
      ASSERT_TRUE(d.resync_residual);
      EXPECT_EQ(*d.resync_residual, 0.25);
    } else {
      EXPECT_EQ(d.resync_method, "");
      EXPECT_FALSE(d.resync_residual);
    }
  }
  // New rows carry the columns.
  store::NewDetection n;
  n.suspect_sha256 = "cc";
  n.verdict = "attributed";
  n.resync_method = "polyhedron";
  n.resync_residual = 0.5;
  auto back = s->record_detection(n);
  EXPECT_EQ(back.resync_method, "polyhedron");
  EXPECT_EQ(*back.resync_residual, 0.5);
  EXPECT_TRUE(s->integrity_ok());
}

TEST(Migrations, RefusesDatabaseFromNewerVersion) {
  TempDir dir;
  auto o = options(dir);
  store::open_sqlite_store(o);
  raw_query(o.db_path, "INSERT INTO schema_version VALUES (9999, '9999_future.sql', 0)");
  try {
    store::open_sqlite_store(o);
    FAIL() << "opened a database from the future";
  } catch (const store::StoreError& e) {
    EXPECT_NE(std::string(e.what()).find("9999"), std::string::npos) << e.what();
  }
}

TEST(Migrations, UnopenableDatabaseGivesClearError) {
  TempDir dir;
  store::StoreOptions o;
  o.db_path = dir / "no/such/folder/meshmark.db";
  o.blob_dir = dir / "blobs";
  try {
    store::open_sqlite_store(o);
    FAIL();
  } catch (const store::StoreError& e) {
    EXPECT_NE(std::string(e.what()).find(o.db_path), std::string::npos) << e.what();
  }
}

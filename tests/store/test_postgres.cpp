// The store's PostgreSQL layer against a real PostgreSQL 15 (tests/common/postgres_server.h):
// the connection (errors, transactions, LISTEN/NOTIFY), the migrations kept in step with
// SQLite's, and the schema's triggers and claim index doing in PostgreSQL what they do in SQLite.
#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <mutex>
#include <set>
#include <thread>

#include "common/postgres_server.h"
#include "store/migrations.h"
#include "store/pg_db.h"
#include "store/pg_store.h"
#include "store_test_util.h"

namespace {

using mm::store::pg::Connection;
using mm::store::pg::PgError;

class Postgres : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (mm::test::postgres_available()) server_ = std::make_unique<mm::test::PostgresServer>();
  }
  static void TearDownTestSuite() { server_.reset(); }
  void SetUp() override {
    if (!server_) return;
    db_ = std::string("t_") + ::testing::UnitTest::GetInstance()->current_test_info()->name();
    for (auto& ch : db_) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    Connection admin(server_->conninfo());
    admin.exec("DROP DATABASE IF EXISTS " + db_);
    admin.exec("CREATE DATABASE " + db_);
  }
  std::string conninfo() const { return server_->conninfo(db_); }
  static std::unique_ptr<mm::test::PostgresServer> server_;
  std::string db_;
};
std::unique_ptr<mm::test::PostgresServer> Postgres::server_;

TEST(PostgresMigrations, AreKeptInStepWithTheSQLiteOnes) {
  const auto& sqlite = mm::store::embedded_migrations();
  const auto& pg = mm::store::embedded_postgres_migrations();
  ASSERT_EQ(pg.size(), sqlite.size());
  for (std::size_t k = 0; k < pg.size(); ++k) {
    EXPECT_EQ(pg[k].version, sqlite[k].version);
    EXPECT_STREQ(pg[k].name, sqlite[k].name) << "the same file name in schema/ and schema/postgres/";
  }
}

TEST_F(Postgres, MigratesOnceAndRecordsEachVersionWhenNodesStartTogether) {
  MM_REQUIRE_POSTGRES();
  const int latest = mm::store::embedded_postgres_migrations().back().version;
  std::vector<std::thread> nodes;
  std::atomic<int> agreed{0};
  for (int k = 0; k < 3; ++k)
    nodes.emplace_back([&] {
      Connection c(conninfo());
      if (mm::store::pg::migrate(c) == latest) ++agreed;
    });
  for (auto& t : nodes) t.join();
  EXPECT_EQ(agreed.load(), 3);
  Connection c(conninfo());
  EXPECT_EQ(c.exec("SELECT COUNT(*) FROM schema_version").i64(0, 0), latest) << "each migration recorded once";
  EXPECT_EQ(mm::store::pg::migrate(c), latest) << "nothing left to apply";
  for (const char* table : {"customers", "customer_keys", "assets", "polyhedra", "jobs", "issued_copies", "detections",
                            "audit_log", "master_key_check", "api_tokens", "job_counters", "job_events", "event_cursors"})
    EXPECT_EQ(c.exec("SELECT to_regclass($1) IS NOT NULL", {std::string(table)}).text(0, 0), "t") << table;
  // A database from a newer meshmark is refused, not written to.
  c.exec("INSERT INTO schema_version VALUES (9999, '9999_future.sql', 0)");
  EXPECT_THROW(mm::store::pg::migrate(c), mm::store::StoreError);
}

TEST_F(Postgres, TriggersCountStatesAndRecordFinalEventsAsInSQLite) {
  MM_REQUIRE_POSTGRES();
  Connection c(conninfo());
  mm::store::pg::migrate(c);
  const auto id = c.exec("INSERT INTO jobs(kind) VALUES ('protect') RETURNING id").i64(0, 0);
  const auto hook = c.exec("INSERT INTO jobs(kind) VALUES ('webhook') RETURNING id").i64(0, 0);
  const std::string sid = std::to_string(id), shook = std::to_string(hook);
  c.exec("UPDATE jobs SET state = 'running', lease_until = mm_now_ms() + 1000, attempt = 1 WHERE id = $1", {sid});
  c.exec("UPDATE jobs SET rescues = rescues + 1, state = 'available', lease_until = NULL WHERE id = $1", {sid});
  c.exec("UPDATE jobs SET state = 'running', lease_until = mm_now_ms() + 1000 WHERE id = $1", {sid});
  c.exec("UPDATE jobs SET state = 'completed', finished_at = 42, lease_until = NULL WHERE id = $1", {sid});
  c.exec("UPDATE jobs SET state = 'cancelled' WHERE id = $1", {shook});
  const auto count = [&](const std::string& kind, const std::string& event) {
    const auto r = c.exec("SELECT n FROM job_counters WHERE kind = $1 AND event = $2", {kind, event});
    return r.rows() ? r.i64(0, 0) : 0;
  };
  EXPECT_EQ(count("protect", "available"), 2);
  EXPECT_EQ(count("protect", "running"), 2);
  EXPECT_EQ(count("protect", "completed"), 1);
  EXPECT_EQ(count("protect", "rescue"), 1);
  EXPECT_EQ(count("webhook", "cancelled"), 1);
  const auto events = c.exec("SELECT job_id, kind, state, at FROM job_events ORDER BY id");
  ASSERT_EQ(events.rows(), 1) << "webhook jobs raise no events";
  EXPECT_EQ(events.i64(0, 0), id);
  EXPECT_EQ(events.text(0, 2), "completed");
  EXPECT_EQ(events.i64(0, 3), 42);
  // Bad JSON, an unknown state and a change to the audit log are refused by the schema itself.
  EXPECT_THROW(c.exec("INSERT INTO jobs(kind, payload_json) VALUES ('x', '{oops')"), PgError);
  EXPECT_THROW(c.exec("UPDATE jobs SET state = 'lost' WHERE id = $1", {sid}), PgError);
  c.exec("INSERT INTO audit_log(at, actor, action) VALUES (1, 'test', 'x')");
  EXPECT_THROW(c.exec("UPDATE audit_log SET actor = 'someone else'"), PgError);
  EXPECT_THROW(c.exec("DELETE FROM audit_log"), PgError);
}

// The claim fleets of nodes will make: the best available job, skipping rows another claimer
// holds locked, marked running in the same statement on the database's clock. Four claimers
// on their own connections take 200 jobs: each exactly once.
TEST_F(Postgres, SkipLockedClaimsHandEachJobToExactlyOneClaimer) {
  MM_REQUIRE_POSTGRES();
  {
    Connection c(conninfo());
    mm::store::pg::migrate(c);
    c.exec("INSERT INTO jobs(kind, priority) SELECT 'detect', g % 3 FROM generate_series(1, 200) g");
  }
  std::mutex m;
  std::multiset<long long> taken;
  std::vector<std::thread> claimers;
  for (int k = 0; k < 4; ++k)
    claimers.emplace_back([&, k] {
      Connection c(conninfo());
      for (;;) {
        const auto r = c.exec(
            "WITH next AS (SELECT id FROM jobs WHERE state = 'available' AND scheduled_at <= mm_now_ms() "
            "ORDER BY priority DESC, scheduled_at, id LIMIT 1 FOR UPDATE SKIP LOCKED) "
            "UPDATE jobs SET state = 'running', attempt = attempt + 1, worker_id = $1, attempted_at = mm_now_ms(), "
            "lease_until = mm_now_ms() + 30000 FROM next WHERE jobs.id = next.id RETURNING jobs.id",
            {"node-" + std::to_string(k)}, "claiming");
        if (r.rows() == 0) break;
        std::lock_guard<std::mutex> l(m);
        taken.insert(r.i64(0, 0));
      }
    });
  for (auto& t : claimers) t.join();
  EXPECT_EQ(taken.size(), 200u);
  EXPECT_EQ(std::set<long long>(taken.begin(), taken.end()).size(), 200u) << "no job claimed twice";
  Connection c(conninfo());
  EXPECT_EQ(c.exec("SELECT COUNT(*) FROM jobs WHERE state = 'running' AND attempt = 1").i64(0, 0), 200);
}

TEST_F(Postgres, ErrorsNameWhatWasDoneAndKeepTheSqlState) {
  MM_REQUIRE_POSTGRES();
  Connection c(conninfo());
  mm::store::pg::migrate(c);
  c.exec("INSERT INTO customers(name, created_at) VALUES ('acme', 1)");
  try {
    c.exec("INSERT INTO customers(name, created_at) VALUES ('acme', 2)", {}, "adding customer acme");
    FAIL() << "a second acme was accepted";
  } catch (const PgError& e) {
    EXPECT_EQ(e.sqlstate, "23505");
    EXPECT_NE(std::string(e.what()).find("adding customer acme"), std::string::npos) << e.what();
  }
  // A transaction that throws leaves nothing behind, and the connection goes on.
  EXPECT_THROW(mm::store::pg::in_transaction(c, [&] {
                 c.exec("INSERT INTO customers(name, created_at) VALUES ('beta', 3)");
                 throw mm::store::StoreError("stop");
               }),
               mm::store::StoreError);
  EXPECT_EQ(c.exec("SELECT COUNT(*) FROM customers WHERE name = 'beta'").i64(0, 0), 0);
  EXPECT_EQ(c.exec("SELECT $1::text || $2::text", {std::string("it's"), std::nullopt}).is_null(0, 0), true);
  // A refused connection names the reason, never the password.
  try {
    Connection bad("host=/nonexistent-folder port=5432 user=postgres password=hunter2 dbname=x");
    FAIL();
  } catch (const mm::store::StoreError& e) {
    EXPECT_EQ(std::string(e.what()).find("hunter2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cannot connect"), std::string::npos) << e.what();
  }
}

TEST_F(Postgres, ANotificationWakesAListenerAndSilenceTimesOut) {
  MM_REQUIRE_POSTGRES();
  Connection listener(conninfo()), sender(conninfo());
  listener.listen("meshmark_jobs");
  EXPECT_EQ(listener.wait_notification(100), std::nullopt);
  std::thread later([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    sender.exec("NOTIFY meshmark_jobs");
  });
  const auto t0 = std::chrono::steady_clock::now();
  const auto got = listener.wait_notification(10000);
  later.join();
  EXPECT_EQ(got, std::optional<std::string>("meshmark_jobs"));
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5)) << "woken, not timed out";
}

// A restart of the server (a failover, an upgrade) ends every session. The next statement outside
// a transaction connects again, LISTENs included; a transaction cut by it fails whole, and the
// one after it runs.
TEST_F(Postgres, AConnectionOutlivesARestartOfTheServer) {
  MM_REQUIRE_POSTGRES();
  Connection c(conninfo());
  c.listen("mm_jobs");
  c.exec("CREATE TABLE t (x integer)");
  mm::store::pg::in_transaction(c, [&] { c.exec("INSERT INTO t VALUES (1)"); });
  server_->stop();
  EXPECT_THROW(c.exec("SELECT 1"), PgError) << "the server is down";
  server_->start();
  EXPECT_EQ(c.exec("SELECT COUNT(*) FROM t").i64(0, 0), 1);
  Connection sender(conninfo());
  sender.exec("NOTIFY mm_jobs, 'protect'");
  EXPECT_EQ(c.wait_notification(5000), std::optional<std::string>("mm_jobs")) << "listening again after the restart";

  EXPECT_THROW(mm::store::pg::in_transaction(c,
                                             [&] {
                                               c.exec("INSERT INTO t VALUES (2)");
                                               server_->stop();
                                               server_->start();
                                               c.exec("INSERT INTO t VALUES (3)");
                                             }),
               PgError);
  mm::store::pg::in_transaction(c, [&] { c.exec("INSERT INTO t VALUES (4)"); });
  EXPECT_EQ(c.exec("SELECT string_agg(x::text, ',' ORDER BY x) FROM t").text(0, 0), "1,4")
      << "nothing of the cut transaction, and none of it outside a transaction";
}

// A store's job survives a restart between its claim and its completion (the lease is on the
// database's clock, so it still holds), and its blobs are read again through new connections.
TEST_F(Postgres, AStoreCompletesAJobClaimedBeforeARestart) {
  MM_REQUIRE_POSTGRES();
  mm::test::TempDir dir;
  mm::store::StoreOptions o;
  o.blob_dir = dir / "cache";
  auto st = mm::store::open_postgres_store(conninfo(), o);
  const std::string blob = st->blobs().put(std::string("part bytes"));
  mm::store::JobSpec spec;
  spec.kind = "noop";
  st->enqueue(spec);
  const auto job = st->claim("w1", 60000);
  ASSERT_TRUE(job);
  server_->stop();
  server_->start();
  st->heartbeat(job->id, "w1", 60000);
  st->complete(job->id, "w1", {});
  EXPECT_EQ(st->get_job(job->id)->state, mm::store::JobState::completed);
  EXPECT_EQ(st->blobs().get(blob).size(), 10u);
}

}  // namespace

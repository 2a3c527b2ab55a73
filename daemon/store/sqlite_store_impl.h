// Internal to the store: the SQLite implementation of Store, its row readers and queries. Its
// methods are defined in sqlite_store.cpp (construction), sqlite_records.cpp (customers, keys,
// assets, polyhedra, copies, detections, audit) and sqlite_queue.cpp (the job queue).
// SQLite implementation of the Store. Every public method takes the object's mutex and, when it
// changes anything, runs in one BEGIN IMMEDIATE transaction: the write lock is taken up front, so
// two connections never both read "available" and then both write "running".
#pragma once
#include <sodium.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>

#include "store/migrations.h"
#include "store/sqlite_db.h"
#include "store/store.h"
#include "store/store_rules.h"

namespace mm::store::sqlite_detail {

using namespace mm::store::rules;
using sql::Db;
using sql::Stmt;
using sql::Tx;

inline Job read_job(const Stmt& s) {
  Job j;
  j.id = s.i64(0);
  j.kind = s.text(1);
  j.payload_json = s.text(2);
  j.state = job_state_from_string(s.text(3));
  j.priority = static_cast<int>(s.i64(4));
  j.attempt = static_cast<int>(s.i64(5));
  j.max_attempts = static_cast<int>(s.i64(6));
  j.idempotency_key = s.text(7);
  j.created_at = s.i64(8);
  j.scheduled_at = s.i64(9);
  j.attempted_at = s.opt_i64(10);
  j.finished_at = s.opt_i64(11);
  j.worker_id = s.text(12);
  j.lease_until = s.opt_i64(13);
  j.errors = parse_errors(s.text(14));
  j.result_json = s.text(15);
  j.rescues = static_cast<int>(s.i64(16));
  return j;
}

inline Customer read_customer(const Stmt& s) {
  return {s.i64(0), s.text(1), static_cast<int>(s.i64(2)), s.i64(3)};
}

inline Asset read_asset(const Stmt& s) {
  return {s.i64(0), s.text(1), static_cast<std::uint64_t>(s.i64(2)), s.text(3), s.text(4), s.i64(5)};
}

inline Polyhedron read_poly(const Stmt& s) {
  return {s.i64(0), s.i64(1), s.text(2), s.text(3), s.text(4), s.text(5), s.i64(6)};
}

inline IssuedCopy read_copy(const Stmt& s) {
  IssuedCopy c;
  c.id = s.i64(0);
  c.asset_id = s.i64(1);
  c.customer_id = s.i64(2);
  c.key_version = static_cast<int>(s.i64(3));
  c.idempotency_key = s.text(4);
  c.nonce = s.blob(5);
  c.payload_hex = s.text(6);
  c.params_json = s.text(7);
  c.outputs_json = s.text(8);
  c.polyhedron_id = s.opt_i64(9);
  c.job_id = s.opt_i64(10);
  c.created_at = s.i64(11);
  return c;
}

inline Detection read_detection(const Stmt& s) {
  Detection d;
  d.id = s.i64(0);
  d.job_id = s.opt_i64(1);
  d.suspect_sha256 = s.text(2);
  d.suspect_name = s.text(3);
  d.verdict = s.text(4);
  d.asset_id = s.opt_i64(5);
  d.copy_id = s.opt_i64(6);
  d.customer_id = s.opt_i64(7);
  d.correlation = s.opt_f64(8);
  d.p_value = s.opt_f64(9);
  d.decoded_payload_hex = s.text(10);
  d.details_json = s.text(11);
  d.created_at = s.i64(12);
  d.resync_method = s.text(13);
  d.resync_residual = s.opt_f64(14);
  return d;
}


class SqliteStore final : public Store {
 public:
  explicit SqliteStore(StoreOptions o)
      : opt_(std::move(o)), db_(opt_.db_path, opt_.busy_timeout_ms), blobs_(blob_dir(opt_)) {
    if (!opt_.clock) opt_.clock = system_clock_millis;
    std::uint64_t seed = opt_.jitter_seed;
    if (seed == 0) seed = (static_cast<std::uint64_t>(randombytes_random()) << 32) | randombytes_random();
    rng_.seed(seed);
    // WAL: readers never block the writer and a commit is one sequential append. synchronous=FULL
    // fsyncs the WAL on every commit, so a completed job stays completed across power loss, not
    // only across process crashes (NORMAL would be enough for the latter); see docs/store.md.
    db_.exec_retrying_busy("PRAGMA journal_mode=WAL", "enabling WAL");
    db_.exec(opt_.synchronous_full ? "PRAGMA synchronous=FULL" : "PRAGMA synchronous=NORMAL",
             "setting synchronous");
    db_.exec("PRAGMA foreign_keys=ON", "enabling foreign keys");
    migrate();
    if (opt_.master_key) check_master_key(*opt_.master_key);
  }

  int schema_version() override {
    std::lock_guard<std::mutex> l(m_);
    return current_version();
  }
  BlobStore& blobs() override { return blobs_; }
  Millis now() override { return opt_.clock(); }

  // ------------------------------------------------------------ customers and keys
  Customer add_customer(const std::string& name, const std::string& actor) override;

  std::vector<Customer> list_customers() override;

  std::optional<Customer> find_customer(const std::string& name) override;

  std::optional<Customer> get_customer(std::int64_t id) override;

  int rotate_key(std::int64_t customer_id, const std::string& actor) override;

  CustomerKey customer_key(std::int64_t customer_id, int version) override;

  std::vector<KeyInfo> list_keys(std::int64_t customer_id) override;

  // ------------------------------------------------------------ assets and polyhedra
  Asset put_asset_file(const std::string& path, const std::string& name) override;

  Asset put_asset_bytes(const std::vector<std::uint8_t>& bytes, const std::string& name) override;

  std::optional<Asset> get_asset(std::int64_t id) override;

  std::optional<Asset> find_asset(const std::string& sha256) override;

  std::vector<Asset> list_assets(int limit) override;

  Polyhedron put_polyhedron(const Polyhedron& p) override;

  std::optional<Polyhedron> find_polyhedron(std::int64_t asset_id, const std::string& params_key) override;

  // ------------------------------------------------------------ copies and detections
  IssuedCopy issue_copy(const NewCopy& c) override;

  std::optional<IssuedCopy> find_copy(std::int64_t asset_id, std::int64_t customer_id, int key_version, const std::string& idempotency_key) override;

  std::optional<IssuedCopy> get_copy(std::int64_t id) override;

  std::vector<IssuedCopy> list_copies(std::optional<std::int64_t> asset_id, int limit) override;

  Detection record_detection(const NewDetection& d) override;

  std::vector<Detection> list_detections(int limit) override;
  std::optional<Detection> get_detection(std::int64_t id) override;
  std::optional<Detection> detection_of_job(std::int64_t job_id) override;

  // ------------------------------------------------------------ audit
  std::int64_t append_audit(const NewAudit& a) override;

  std::vector<AuditEntry> list_audit(int limit) override;

  // ------------------------------------------------------------ API tokens
  NewToken create_token(const std::string& name, TokenRole role, const std::string& actor) override;
  std::vector<ApiToken> list_tokens() override;
  bool revoke_token(const std::string& name, const std::string& actor) override;
  std::optional<ApiToken> token_for_secret(const std::string& secret) override;

  StoreMetrics metrics(const std::vector<double>& bucket_seconds) override;
  int consume_job_events(const std::string& consumer, int limit,
                         const std::function<std::vector<JobSpec>(const JobEvent&)>& jobs_for) override;

  // ------------------------------------------------------------ queue
  EnqueueResult enqueue(const JobSpec& spec, const std::string& actor) override;

  std::optional<Job> claim(const std::string& worker_id, Millis lease, const std::vector<std::string>& kinds) override;

  void heartbeat(std::int64_t job_id, const std::string& worker_id, Millis lease) override;

  CompleteResult complete(std::int64_t job_id, const std::string& worker_id, const JobRecords& r) override;
  std::vector<CompletionOutcome> complete_batch(const std::vector<Completion>& batch) override;

  JobState fail(std::int64_t job_id, const std::string& worker_id, const std::string& error, bool retryable) override;

  void release(std::int64_t job_id, const std::string& worker_id) override;

  bool cancel(std::int64_t job_id, const std::string& actor) override;

  bool retry(std::int64_t job_id, const std::string& actor) override;

  int reap_expired_leases() override;
  int prune_jobs(Millis finished_before, int limit) override;

  std::optional<Job> get_job(std::int64_t id) override;

  std::vector<Job> list_jobs(const JobFilter& f) override;

  QueueCounts counts() override;

  std::optional<Millis> next_scheduled() override;

  bool integrity_ok() override;

  bool beat_node(const std::string& node, int workers, Millis lease_ms) override;
  std::vector<FleetNode> list_nodes() override;
  void leave_fleet(const std::string& node) override;

 private:
  static std::string blob_dir(const StoreOptions& o) {
    if (!o.blob_dir.empty()) return o.blob_dir;
    auto slash = o.db_path.find_last_of('/');
    return (slash == std::string::npos ? std::string(".") : o.db_path.substr(0, slash)) + "/blobs";
  }

  const keys::SecretKey& need_master() const { return rules::need_master(opt_.master_key); }

  // Commits inside its scope are not fsynced (synchronous=NORMAL): for claims and heartbeats,
  // whose loss in a power cut only makes a job claimable again. The next FULL commit (a
  // completion, an enqueue) fsyncs the log with them.
  struct UnsyncedCommits {
    Db& db;
    bool full;
    UnsyncedCommits(Db& d, bool f) : db(d), full(f) {
      if (full) db.exec("PRAGMA synchronous=NORMAL", "setting synchronous");
    }
    ~UnsyncedCommits() {
      if (full) sqlite3_exec(db.get(), "PRAGMA synchronous=FULL", nullptr, nullptr, nullptr);
    }
  };

  void fault(const char* point) {
    if (opt_.fault_injection) opt_.fault_injection(point);
  }

  EnqueueResult insert_job(const JobSpec& spec, const std::string& actor);  // inside a transaction
  CompleteResult complete_in_tx(std::int64_t job_id, const std::string& worker_id, const JobRecords& r);

  LeaseLost lease_lost(std::int64_t job_id, const std::string& worker_id) {
    return lease_lost_error(job_id, worker_id, job_by_id(job_id));
  }

  Millis backoff(int attempt) { return backoff_delay(opt_.backoff, attempt, rng_); }

  int current_version() {
    Stmt q(db_, "SELECT COALESCE(MAX(version), 0) FROM schema_version");
    q.step();
    return static_cast<int>(q.i64(0));
  }

  // Refuses a master key other than the one this store's keys are sealed under, before anything
  // is sealed with it. A store without a check value yet (new, or older than migration 3) gets
  // one, after a customer key, if any, proves the key right.
  void check_master_key(const keys::SecretKey& master) {
    const auto want = keys::master_key_check(master);
    const std::string refusal =
        "wrong master key: it is not the key this store's customer keys are sealed under (" + opt_.db_path +
        "); check MESHMARK_MASTER_KEY or the home's master.key";
    {
      Stmt q(db_, "SELECT check_value FROM master_key_check WHERE id = 1");
      if (q.step()) {
        const auto have = q.blob(0);
        if (have.size() != want.size() || sodium_memcmp(have.data(), want.data(), want.size()) != 0)
          throw keys::KeyError(refusal);
        return;
      }
    }
    Tx tx(db_);
    Stmt q(db_, "SELECT customer_id, version, nonce, ciphertext FROM customer_keys ORDER BY customer_id, version LIMIT 1");
    if (q.step()) {
      try {
        keys::open_customer_key(master, {q.blob(2), q.blob(3)}, q.i64(0), static_cast<int>(q.i64(1)));
      } catch (const keys::KeyError&) {
        throw keys::KeyError(refusal);
      }
    }
    Stmt ins(db_, "INSERT OR IGNORE INTO master_key_check(id, check_value, created_at) VALUES(1, ?, ?)");
    ins.bind(1, std::vector<std::uint8_t>(want.begin(), want.end())).bind(2, now()).run();
    tx.commit();
  }

  // Every migration already applied? A plain read (no write lock), so opening a current store
  // for a read-only command never waits for, or fails on, another process's write transaction.
  bool schema_current() {
    const auto& ms = embedded_migrations();
    Stmt t(db_, "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'schema_version'");
    if (!t.step()) return false;
    Stmt q(db_, "SELECT COUNT(*), COALESCE(MAX(version), 0) FROM schema_version");
    q.step();
    return static_cast<std::size_t>(q.i64(0)) >= ms.size() && (ms.empty() || q.i64(1) >= ms.back().version);
  }

  void migrate() {
    if (schema_current()) {
      const auto& ms = embedded_migrations();
      const int v = current_version(), latest = ms.empty() ? 0 : ms.back().version;
      if (v > latest)
        throw StoreError("database " + opt_.db_path + " has schema version " + std::to_string(v) +
                         ", newer than this meshmark knows (" + std::to_string(latest) + "); upgrade meshmark");
      return;
    }
    {
      Tx tx(db_);
      db_.exec("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER PRIMARY KEY, "
               "name TEXT NOT NULL, applied_at INTEGER NOT NULL)",
               "creating schema_version");
      tx.commit();
    }
    const auto& ms = embedded_migrations();
    int latest = ms.empty() ? 0 : ms.back().version;
    for (const Migration& m : ms) {
      Tx tx(db_);  // IMMEDIATE: two processes starting together apply each migration once
      Stmt q(db_, "SELECT 1 FROM schema_version WHERE version = ?");
      if (q.bind(1, m.version).step()) continue;
      db_.exec(m.sql, (std::string("applying migration ") + m.name).c_str());
      Stmt ins(db_, "INSERT INTO schema_version(version, name, applied_at) VALUES(?,?,?)");
      ins.bind(1, m.version).bind(2, m.name).bind(3, now()).run();
      tx.commit();
    }
    int v = current_version();
    if (v > latest)
      throw StoreError("database " + opt_.db_path + " has schema version " + std::to_string(v) +
                       ", newer than this meshmark knows (" + std::to_string(latest) + "); upgrade meshmark");
  }

  void insert_key(const keys::SecretKey& master, std::int64_t customer_id, int version, Millis t) {
    keys::SecretKey k = keys::SecretKey::random();
    keys::SealedKey s = keys::seal_customer_key(master, k, customer_id, version);
    Stmt ins(db_, "INSERT INTO customer_keys(customer_id, version, nonce, ciphertext, created_at) VALUES(?,?,?,?,?)");
    ins.bind(1, customer_id).bind(2, version).bind(3, s.nonce).bind(4, s.ciphertext).bind(5, t).run();
  }

  std::int64_t insert_audit(const NewAudit& a) {
    require_json(a.details_json, "audit details");
    Stmt ins(db_, "INSERT INTO audit_log(at, actor, action, subject, details_json) VALUES(?,?,?,?,?) RETURNING id");
    ins.bind(1, now()).bind(2, a.actor).bind(3, a.action).bind(4, a.subject).bind(5, a.details_json).step();
    return ins.i64(0);
  }

  Asset upsert_asset(const std::string& sha, std::uint64_t size, const std::string& name) {
    std::lock_guard<std::mutex> l(m_);
    Tx tx(db_);
    Stmt ins(db_,
             "INSERT INTO assets(sha256, size, name, format, created_at) VALUES(?,?,?,?,?) "
             "ON CONFLICT(sha256) DO NOTHING");
    ins.bind(1, sha).bind(2, static_cast<std::int64_t>(size)).bind(3, name).bind(4, format_from_name(name))
        .bind(5, now()).run();
    bool created = ins.changes() > 0;
    Stmt q(db_, sel(kAssetCols, "FROM assets WHERE sha256 = ?").c_str());
    q.bind(1, sha).step();
    Asset a = read_asset(q);
    if (created)
      insert_audit({"store", "asset.add", "asset:" + std::to_string(a.id), json{{"sha256", sha}, {"name", name}}.dump()});
    tx.commit();
    return a;
  }

  std::int64_t insert_copy(const NewCopy& c, std::optional<std::int64_t> job_id, const std::string& actor,
                           bool& existed) {
    require_json(c.params_json, "copy params_json");
    require_json(c.outputs_json, "copy outputs_json");
    Stmt ins(db_,
             "INSERT INTO issued_copies(asset_id, customer_id, key_version, idempotency_key, nonce, "
             "payload_hex, params_json, outputs_json, polyhedron_id, job_id, created_at) "
             "VALUES(?,?,?,?,?,?,?,?,?,?,?) "
             "ON CONFLICT(asset_id, customer_id, key_version, idempotency_key) DO NOTHING RETURNING id");
    ins.bind(1, c.asset_id).bind(2, c.customer_id).bind(3, c.key_version).bind(4, c.idempotency_key)
        .bind(5, c.nonce).bind(6, c.payload_hex).bind(7, c.params_json).bind(8, c.outputs_json)
        .bind(9, c.polyhedron_id).bind(10, job_id).bind(11, now());
    if (ins.step()) {
      std::int64_t id = ins.i64(0);
      ins.run();
      existed = false;
      insert_audit({actor, "copy.issue", "copy:" + std::to_string(id),
                    json{{"asset_id", c.asset_id}, {"customer_id", c.customer_id},
                         {"key_version", c.key_version}}.dump()});
      return id;
    }
    existed = true;
    Stmt q(db_, "SELECT id FROM issued_copies WHERE asset_id = ? AND customer_id = ? AND key_version = ? "
                "AND idempotency_key = ?");
    q.bind(1, c.asset_id).bind(2, c.customer_id).bind(3, c.key_version).bind(4, c.idempotency_key).step();
    return q.i64(0);
  }

  std::int64_t insert_detection(const NewDetection& d, std::optional<std::int64_t> job_id, const std::string& actor) {
    require_json(d.details_json, "detection details_json");
    Stmt ins(db_,
             "INSERT INTO detections(job_id, suspect_sha256, suspect_name, verdict, asset_id, copy_id, "
             "customer_id, correlation, p_value, decoded_payload_hex, details_json, created_at, resync_method, "
             "resync_residual) VALUES(?,?,?,?,?,?,?,?,?,?,?,?,?,?) RETURNING id");
    ins.bind(1, job_id).bind(2, d.suspect_sha256).bind(3, d.suspect_name).bind(4, d.verdict)
        .bind(5, d.asset_id).bind(6, d.copy_id).bind(7, d.customer_id).bind(8, d.correlation)
        .bind(9, d.p_value).bind(10, d.decoded_payload_hex).bind(11, d.details_json).bind(12, now())
        .bind(13, d.resync_method).bind(14, d.resync_residual).step();
    std::int64_t id = ins.i64(0);
    ins.run();
    insert_audit({actor, "detection.record", "detection:" + std::to_string(id),
                  json{{"verdict", d.verdict}}.dump()});
    return id;
  }

  int reap(Millis t) {
    Stmt u(db_,
           "UPDATE jobs SET "
           "state = CASE WHEN rescues + 1 >= ?2 THEN 'discarded' ELSE 'available' END, "
           "finished_at = CASE WHEN rescues + 1 >= ?2 THEN ?1 ELSE NULL END, "
           "rescues = rescues + 1, "
           "errors_json = json_insert(errors_json, '$[#]', json_object('attempt', attempt, 'at', ?1, "
           "'error', 'lease expired: worker ' || worker_id || ' stopped heartbeating (rescue ' || "
           "(rescues + 1) || ' of at most ' || ?2 || ')')), "
           "lease_until = NULL "
           "WHERE state = 'running' AND lease_until < ?1");
    u.bind(1, t).bind(2, kMaxRescues).run();
    return u.changes();
  }

  std::optional<Job> job_by_id(std::int64_t id) {
    Stmt q(db_, sel(kJobCols, "FROM jobs WHERE id = ?").c_str());
    if (!q.bind(1, id).step()) return std::nullopt;
    return read_job(q);
  }

  std::optional<IssuedCopy> copy_by_id(std::int64_t id) {
    Stmt q(db_, sel(kCopyCols, "FROM issued_copies WHERE id = ?").c_str());
    if (!q.bind(1, id).step()) return std::nullopt;
    return read_copy(q);
  }

  StoreOptions opt_;
  std::mutex m_;
  Db db_;
  FsBlobStore blobs_;
  std::mt19937_64 rng_;
};


}  // namespace mm::store::sqlite_detail

// PostgreSQL implementation of the Store (pg_store.h). Statements mirror the SQLite backend's
// (sqlite_records.cpp, sqlite_queue.cpp, sqlite_tokens.cpp) in PostgreSQL's dialect; every method
// that changes anything is one READ COMMITTED transaction whose row locks (the claim's SKIP
// LOCKED, the guarded UPDATEs) keep two nodes from both moving one job.
#include "store/pg_store.h"

#include <sodium.h>

#include <cstdio>
#include <mutex>

#include "store/pg_blob_store.h"
#include "store/pg_db.h"
#include "store/store_rules.h"
#include "support/hex.h"
#include "support/sha256.h"

namespace mm::store {
namespace {

using namespace mm::store::rules;
using pg::Connection;
using pg::Param;
using pg::Result;

// Parameters and values as text (pg_db.h hands every value over as text).
Param p(std::int64_t v) { return std::to_string(v); }
Param p(const std::string& v) { return v; }
Param p(const char* v) { return std::string(v); }
Param p(std::optional<std::int64_t> v) { return v ? p(*v) : std::nullopt; }
Param p(std::optional<double> v) {
  if (!v) return std::nullopt;
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", *v);
  return std::string(buf);
}
Param bytea(const std::vector<std::uint8_t>& b) { return "\\x" + support::to_hex(b.data(), b.size()); }

std::vector<std::uint8_t> bytes_of(const Result& r, int row, int col) {
  const std::string t = r.text(row, col);
  return t.rfind("\\x", 0) == 0 ? support::from_hex(t.substr(2)) : std::vector<std::uint8_t>(t.begin(), t.end());
}
std::optional<std::int64_t> opt_i64(const Result& r, int row, int col) {
  if (r.is_null(row, col)) return std::nullopt;
  return r.i64(row, col);
}
std::optional<double> opt_f64(const Result& r, int row, int col) {
  if (r.is_null(row, col)) return std::nullopt;
  return std::stod(r.text(row, col));
}

Job read_job(const Result& r, int i) {
  Job j;
  j.id = r.i64(i, 0);
  j.kind = r.text(i, 1);
  j.payload_json = r.text(i, 2);
  j.state = job_state_from_string(r.text(i, 3));
  j.priority = static_cast<int>(r.i64(i, 4));
  j.attempt = static_cast<int>(r.i64(i, 5));
  j.max_attempts = static_cast<int>(r.i64(i, 6));
  j.idempotency_key = r.text(i, 7);
  j.created_at = r.i64(i, 8);
  j.scheduled_at = r.i64(i, 9);
  j.attempted_at = opt_i64(r, i, 10);
  j.finished_at = opt_i64(r, i, 11);
  j.worker_id = r.text(i, 12);
  j.lease_until = opt_i64(r, i, 13);
  j.errors = parse_errors(r.text(i, 14));
  j.result_json = r.text(i, 15);
  j.rescues = static_cast<int>(r.i64(i, 16));
  return j;
}
Customer read_customer(const Result& r, int i) {
  return {r.i64(i, 0), r.text(i, 1), static_cast<int>(r.i64(i, 2)), r.i64(i, 3)};
}
Asset read_asset(const Result& r, int i) {
  return {r.i64(i, 0), r.text(i, 1), static_cast<std::uint64_t>(r.i64(i, 2)), r.text(i, 3), r.text(i, 4), r.i64(i, 5)};
}
Polyhedron read_poly(const Result& r, int i) {
  return {r.i64(i, 0), r.i64(i, 1), r.text(i, 2), r.text(i, 3), r.text(i, 4), r.text(i, 5), r.i64(i, 6)};
}
IssuedCopy read_copy(const Result& r, int i) {
  IssuedCopy c;
  c.id = r.i64(i, 0);
  c.asset_id = r.i64(i, 1);
  c.customer_id = r.i64(i, 2);
  c.key_version = static_cast<int>(r.i64(i, 3));
  c.idempotency_key = r.text(i, 4);
  c.nonce = bytes_of(r, i, 5);
  c.payload_hex = r.text(i, 6);
  c.params_json = r.text(i, 7);
  c.outputs_json = r.text(i, 8);
  c.polyhedron_id = opt_i64(r, i, 9);
  c.job_id = opt_i64(r, i, 10);
  c.created_at = r.i64(i, 11);
  return c;
}
Detection read_detection(const Result& r, int i) {
  Detection d;
  d.id = r.i64(i, 0);
  d.job_id = opt_i64(r, i, 1);
  d.suspect_sha256 = r.text(i, 2);
  d.suspect_name = r.text(i, 3);
  d.verdict = r.text(i, 4);
  d.asset_id = opt_i64(r, i, 5);
  d.copy_id = opt_i64(r, i, 6);
  d.customer_id = opt_i64(r, i, 7);
  d.correlation = opt_f64(r, i, 8);
  d.p_value = opt_f64(r, i, 9);
  d.decoded_payload_hex = r.text(i, 10);
  d.details_json = r.text(i, 11);
  d.created_at = r.i64(i, 12);
  d.resync_method = r.text(i, 13);
  d.resync_residual = opt_f64(r, i, 14);
  return d;
}
ApiToken read_token(const Result& r, int i) {
  return {r.i64(i, 0), r.text(i, 1), token_role_from_string(r.text(i, 2)), r.i64(i, 3), opt_i64(r, i, 4)};
}

// Appends {attempt, at, error} to a job's errors_json (text holding a JSON array).
constexpr const char* kAppendError =
    "(errors_json::jsonb || jsonb_build_array(jsonb_build_object('attempt', attempt, 'at', %s, 'error', %s)))::text";
std::string append_error(const std::string& at, const std::string& error) {
  char buf[256];
  std::snprintf(buf, sizeof buf, kAppendError, at.c_str(), error.c_str());
  return buf;
}

class PgStore final : public Store {
 public:
  PgStore(const std::string& conninfo, StoreOptions o)
      : opt_(std::move(o)), c_(conninfo), blobs_(conninfo, opt_.blob_dir) {
    std::uint64_t seed = opt_.jitter_seed;
    if (seed == 0) seed = (static_cast<std::uint64_t>(randombytes_random()) << 32) | randombytes_random();
    rng_.seed(seed);
    pg::migrate(c_);
    if (opt_.master_key) check_master_key(*opt_.master_key);
  }

  // pg::in_transaction, with now()'s reading kept for the transaction's length.
  template <class F>
  auto in_transaction(Connection& c, F&& fn, const std::string& isolation = "READ COMMITTED") {
    struct Scope {
      PgStore& s;
      explicit Scope(PgStore& st) : s(st) { s.in_tx_ = true; }
      ~Scope() {
        s.in_tx_ = false;
        s.tx_now_.reset();
      }
    } scope(*this);
    return pg::in_transaction(c, std::forward<F>(fn), isolation);
  }

  int schema_version() override {
    std::lock_guard<std::mutex> l(m_);
    return static_cast<int>(c_.exec("SELECT COALESCE(MAX(version), 0) FROM schema_version").i64(0, 0));
  }
  BlobStore& blobs() override { return blobs_; }
  // Inside a transaction, one reading of the database clock serves every timestamp it writes:
  // one round trip, and one instant per state transition.
  Millis now() override {
    if (opt_.clock) return opt_.clock();
    if (tx_now_) return *tx_now_;
    const Millis t = c_.exec("SELECT mm_now_ms()", {}, "reading the database clock").i64(0, 0);
    if (in_tx_) tx_now_ = t;
    return t;
  }

  // ------------------------------------------------------------ customers and keys
  Customer add_customer(const std::string& name, const std::string& actor) override {
    if (!valid_customer_name(name))
      throw StoreError("invalid customer name '" + clip(name, 64) +
                       "': use 1-64 letters, digits, '.', '_' or '-', not starting with '.'");
    const keys::SecretKey& master = need_master();
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      const Millis t = now();
      const Result ins = c_.exec(
          "INSERT INTO customers(name, current_key_version, created_at) VALUES($1, 1, $2) "
          "ON CONFLICT (name) DO NOTHING RETURNING id",
          {p(name), p(t)}, "adding a customer");
      if (ins.rows() == 0) throw StoreError("customer '" + name + "' already exists");
      const std::int64_t id = ins.i64(0, 0);
      insert_key(master, id, 1, t);
      insert_audit({actor, "customer.add", "customer:" + std::to_string(id),
                    json{{"name", name}, {"key_version", 1}}.dump()});
      return Customer{id, name, 1, t};
    });
  }

  std::vector<Customer> list_customers() override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kCustomerCols, "FROM customers ORDER BY id"));
    std::vector<Customer> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(read_customer(r, i));
    return out;
  }

  std::optional<Customer> find_customer(const std::string& name) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kCustomerCols, "FROM customers WHERE name = $1"), {p(name)});
    if (r.rows() == 0) return std::nullopt;
    return read_customer(r, 0);
  }

  std::optional<Customer> get_customer(std::int64_t id) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kCustomerCols, "FROM customers WHERE id = $1"), {p(id)});
    if (r.rows() == 0) return std::nullopt;
    return read_customer(r, 0);
  }

  int rotate_key(std::int64_t customer_id, const std::string& actor) override {
    const keys::SecretKey& master = need_master();
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      // The row lock makes two rotations of one customer take turns.
      const Result r = c_.exec("UPDATE customers SET current_key_version = current_key_version + 1 WHERE id = $1 "
                               "RETURNING current_key_version",
                               {p(customer_id)}, "rotating a key");
      if (r.rows() == 0) throw StoreError("no customer with id " + std::to_string(customer_id));
      const int v = static_cast<int>(r.i64(0, 0));
      insert_key(master, customer_id, v, now());
      insert_audit({actor, "key.rotate", "customer:" + std::to_string(customer_id), json{{"key_version", v}}.dump()});
      return v;
    });
  }

  CustomerKey customer_key(std::int64_t customer_id, int version) override {
    const keys::SecretKey& master = need_master();
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(
        "SELECT k.version, k.nonce, k.ciphertext FROM customer_keys k JOIN customers c ON c.id = k.customer_id "
        "WHERE k.customer_id = $1 AND k.version = CASE WHEN $2::integer = 0 THEN c.current_key_version ELSE $2::integer END",
        {p(customer_id), p(std::int64_t{version})}, "reading a customer key");
    if (r.rows() == 0)
      throw keys::KeyError("no key version " + (version == 0 ? std::string("(current)") : std::to_string(version)) +
                           " for customer " + std::to_string(customer_id));
    const int v = static_cast<int>(r.i64(0, 0));
    keys::SealedKey sealed{bytes_of(r, 0, 1), bytes_of(r, 0, 2)};
    return {customer_id, v, keys::open_customer_key(master, sealed, customer_id, v)};
  }

  std::vector<KeyInfo> list_keys(std::int64_t customer_id) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(
        "SELECT customer_id, version, created_at FROM customer_keys WHERE customer_id = $1 ORDER BY version",
        {p(customer_id)});
    std::vector<KeyInfo> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back({r.i64(i, 0), static_cast<int>(r.i64(i, 1)), r.i64(i, 2)});
    return out;
  }

  // ------------------------------------------------------------ assets and polyhedra
  // The original's bytes and its row commit in one transaction.
  Asset put_asset_file(const std::string& path, const std::string& name) override {
    return upsert_asset(name, [&] { return pg::put_blob_file(c_, path); });
  }
  Asset put_asset_bytes(const std::vector<std::uint8_t>& bytes, const std::string& name) override {
    return upsert_asset(name, [&] { return pg::put_blob(c_, bytes.data(), bytes.size()); });
  }

  std::optional<Asset> get_asset(std::int64_t id) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kAssetCols, "FROM assets WHERE id = $1"), {p(id)});
    if (r.rows() == 0) return std::nullopt;
    return read_asset(r, 0);
  }
  std::optional<Asset> find_asset(const std::string& sha256) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kAssetCols, "FROM assets WHERE sha256 = $1"), {p(sha256)});
    if (r.rows() == 0) return std::nullopt;
    return read_asset(r, 0);
  }
  std::vector<Asset> list_assets(int limit) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kAssetCols, "FROM assets ORDER BY id DESC LIMIT $1"), {p(std::int64_t{limit})});
    std::vector<Asset> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(read_asset(r, i));
    return out;
  }

  Polyhedron put_polyhedron(const Polyhedron& poly) override {
    if (!blobs_.contains(poly.polyhedron_blob))
      throw StoreError("polyhedron blob " + clip(poly.polyhedron_blob, 64) + " is not in the blob store");
    if (!poly.basis_blob.empty() && !blobs_.contains(poly.basis_blob))
      throw StoreError("basis blob " + clip(poly.basis_blob, 64) + " is not in the blob store");
    require_json(poly.meta_json, "polyhedron meta_json");
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      c_.exec("INSERT INTO polyhedra(asset_id, params_key, polyhedron_blob, basis_blob, meta_json, created_at) "
              "VALUES($1, $2, $3, $4, $5, $6) ON CONFLICT (asset_id, params_key) DO NOTHING",
              {p(poly.asset_id), p(poly.params_key), p(poly.polyhedron_blob), p(poly.basis_blob), p(poly.meta_json),
               p(now())},
              "caching a polyhedron");
      const Result r = c_.exec(sel(kPolyCols, "FROM polyhedra WHERE asset_id = $1 AND params_key = $2"),
                               {p(poly.asset_id), p(poly.params_key)});
      return read_poly(r, 0);
    });
  }

  std::optional<Polyhedron> find_polyhedron(std::int64_t asset_id, const std::string& params_key) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kPolyCols, "FROM polyhedra WHERE asset_id = $1 AND params_key = $2"),
                             {p(asset_id), p(params_key)});
    if (r.rows() == 0) return std::nullopt;
    return read_poly(r, 0);
  }

  // ------------------------------------------------------------ copies and detections
  IssuedCopy issue_copy(const NewCopy& c) override {
    std::lock_guard<std::mutex> l(m_);
    const std::int64_t id = in_transaction(c_, [&] {
      bool existed = false;
      return insert_copy(c, std::nullopt, "cli", existed);
    });
    return *copy_by_id(id);
  }

  std::optional<IssuedCopy> find_copy(std::int64_t asset_id, std::int64_t customer_id, int key_version,
                                      const std::string& idempotency_key) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kCopyCols, "FROM issued_copies WHERE asset_id = $1 AND customer_id = $2 AND "
                                            "key_version = $3 AND idempotency_key = $4"),
                             {p(asset_id), p(customer_id), p(std::int64_t{key_version}), p(idempotency_key)});
    if (r.rows() == 0) return std::nullopt;
    return read_copy(r, 0);
  }

  std::optional<IssuedCopy> get_copy(std::int64_t id) override {
    std::lock_guard<std::mutex> l(m_);
    return copy_by_id(id);
  }

  std::vector<IssuedCopy> list_copies(std::optional<std::int64_t> asset_id, int limit) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kCopyCols, "FROM issued_copies WHERE ($1::bigint IS NULL OR asset_id = $1::bigint) "
                                            "ORDER BY id DESC LIMIT $2"),
                             {p(asset_id), p(std::int64_t{limit})});
    std::vector<IssuedCopy> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(read_copy(r, i));
    return out;
  }

  Detection record_detection(const NewDetection& d) override {
    std::lock_guard<std::mutex> l(m_);
    const std::int64_t id = in_transaction(c_, [&] { return insert_detection(d, std::nullopt, "cli"); });
    return read_detection(c_.exec(sel(kDetectionCols, "FROM detections WHERE id = $1"), {p(id)}), 0);
  }

  std::vector<Detection> list_detections(int limit) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r =
        c_.exec(sel(kDetectionCols, "FROM detections ORDER BY id DESC LIMIT $1"), {p(std::int64_t{limit})});
    std::vector<Detection> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(read_detection(r, i));
    return out;
  }
  std::optional<Detection> get_detection(std::int64_t id) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kDetectionCols, "FROM detections WHERE id = $1"), {p(id)});
    if (r.rows() == 0) return std::nullopt;
    return read_detection(r, 0);
  }
  std::optional<Detection> detection_of_job(std::int64_t job_id) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r =
        c_.exec(sel(kDetectionCols, "FROM detections WHERE job_id = $1 ORDER BY id DESC LIMIT 1"), {p(job_id)});
    if (r.rows() == 0) return std::nullopt;
    return read_detection(r, 0);
  }

  // ------------------------------------------------------------ audit
  std::int64_t append_audit(const NewAudit& a) override {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] { return insert_audit(a); });
  }

  std::vector<AuditEntry> list_audit(int limit) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec("SELECT id, at, actor, action, subject, details_json FROM audit_log ORDER BY id DESC LIMIT $1",
                             {p(std::int64_t{limit})});
    std::vector<AuditEntry> out;
    for (int i = 0; i < r.rows(); ++i) {
      AuditEntry e;
      e.id = r.i64(i, 0);
      e.at = r.i64(i, 1);
      e.actor = r.text(i, 2);
      e.action = r.text(i, 3);
      e.subject = r.text(i, 4);
      e.details_json = r.text(i, 5);
      out.push_back(std::move(e));
    }
    return out;
  }

  // ------------------------------------------------------------ API tokens
  NewToken create_token(const std::string& name, TokenRole role, const std::string& actor) override {
    if (!valid_customer_name(name))
      throw StoreError("invalid token name '" + clip(name, 64) +
                       "': use 1-64 letters, digits, '.', '_' or '-', not starting with '.'");
    unsigned char raw[32];
    randombytes_buf(raw, sizeof raw);
    NewToken out;
    out.secret = "mmt_" + support::to_hex(raw, sizeof raw);
    sodium_memzero(raw, sizeof raw);
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      const Millis t = now();
      const Result r = c_.exec(
          "INSERT INTO api_tokens(name, role, token_sha256, created_at) VALUES($1, $2, $3, $4) "
          "ON CONFLICT (name) DO NOTHING RETURNING id",
          {p(name), p(to_string(role)), p(support::sha256_hex(out.secret.data(), out.secret.size())), p(t)},
          "creating a token");
      if (r.rows() == 0) throw StoreError("token '" + name + "' already exists");
      out.token = {r.i64(0, 0), name, role, t, std::nullopt};
      insert_audit({actor, "token.create", "token:" + std::to_string(out.token.id),
                    json{{"name", name}, {"role", to_string(role)}}.dump()});
      return out;
    });
  }

  std::vector<ApiToken> list_tokens() override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kTokenCols, "FROM api_tokens ORDER BY id"));
    std::vector<ApiToken> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(read_token(r, i));
    return out;
  }

  bool revoke_token(const std::string& name, const std::string& actor) override {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      const Result r = c_.exec("UPDATE api_tokens SET revoked_at = $1 WHERE name = $2 AND revoked_at IS NULL RETURNING id",
                               {p(now()), p(name)}, "revoking a token");
      if (r.rows() == 0) return false;
      insert_audit({actor, "token.revoke", "token:" + std::to_string(r.i64(0, 0)), json{{"name", name}}.dump()});
      return true;
    });
  }

  std::optional<ApiToken> token_for_secret(const std::string& secret) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kTokenCols, "FROM api_tokens WHERE token_sha256 = $1 AND revoked_at IS NULL"),
                             {p(support::sha256_hex(secret.data(), secret.size()))});
    if (r.rows() == 0) return std::nullopt;
    return read_token(r, 0);
  }

  // ------------------------------------------------------------ queue
  EnqueueResult enqueue(const JobSpec& spec, const std::string& actor) override {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] { return insert_job(spec, actor); });
  }

  std::optional<Job> claim(const std::string& worker_id, Millis lease, const std::vector<std::string>& kinds) override {
    if (worker_id.empty()) throw StoreError("claim: worker id is empty");
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&]() -> std::optional<Job> {
      const Millis t = now();
      reap(t);
      // The best job's row, skipping rows another node's claim holds: that node takes it.
      static const std::string q = std::string(
          "UPDATE jobs SET state = 'running', attempt = attempt + 1, attempted_at = $1, worker_id = $2, "
          "lease_until = $3 WHERE id = (SELECT id FROM jobs WHERE state IN ('available', 'retryable') "
          "AND scheduled_at <= $1 AND ($4::json IS NULL OR kind IN (SELECT json_array_elements_text($4::json))) "
          "ORDER BY priority DESC, scheduled_at, id LIMIT 1 FOR UPDATE SKIP LOCKED) RETURNING ") + kJobCols;
      const Result r = c_.exec(q, {p(t), p(worker_id), p(t + lease), kinds.empty() ? Param() : Param(json(kinds).dump())},
                               "claiming a job");
      if (r.rows() == 0) return std::nullopt;
      return read_job(r, 0);
    });
  }

  void heartbeat(std::int64_t job_id, const std::string& worker_id, Millis lease) override {
    std::lock_guard<std::mutex> l(m_);
    in_transaction(c_, [&] {
      const Result r = c_.exec("UPDATE jobs SET lease_until = $1 WHERE id = $2 AND state = 'running' AND worker_id = $3",
                               {p(now() + lease), p(job_id), p(worker_id)}, "extending a lease");
      if (r.affected() == 0) throw lease_lost(job_id, worker_id);
    });
  }

  CompleteResult complete(std::int64_t job_id, const std::string& worker_id, const JobRecords& r) override {
    require_json(r.result_json, "job result");
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      CompleteResult out = complete_in_tx(job_id, worker_id, r);
      fault("complete.before_commit");
      return out;
    });
  }

  std::vector<CompletionOutcome> complete_batch(const std::vector<Completion>& batch) override {
    std::vector<CompletionOutcome> out(batch.size());
    std::lock_guard<std::mutex> l(m_);
    in_transaction(c_, [&] {
      for (std::size_t i = 0; i < batch.size(); ++i) {
        c_.exec("SAVEPOINT completion", {}, "complete");
        try {
          require_json(batch[i].records->result_json, "job result");
          out[i].result = complete_in_tx(batch[i].job_id, batch[i].worker_id, *batch[i].records);
          c_.exec("RELEASE SAVEPOINT completion", {}, "complete");
        } catch (const std::exception&) {
          out[i].error = std::current_exception();
          c_.exec("ROLLBACK TO SAVEPOINT completion", {}, "complete");
          c_.exec("RELEASE SAVEPOINT completion", {}, "complete");
        }
      }
      fault("complete.before_commit");
    });
    return out;
  }

  JobState fail(std::int64_t job_id, const std::string& worker_id, const std::string& error, bool retryable) override {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      const Result q = c_.exec(
          "SELECT attempt, max_attempts, rescues FROM jobs WHERE id = $1 AND state = 'running' AND worker_id = $2 "
          "FOR UPDATE",
          {p(job_id), p(worker_id)}, "failing a job");
      if (q.rows() == 0) throw lease_lost(job_id, worker_id);
      const int attempt = static_cast<int>(q.i64(0, 0));
      const int max_attempts = static_cast<int>(q.i64(0, 1));
      const int failures = attempt - static_cast<int>(q.i64(0, 2));  // rescues spend no attempt
      const Millis t = now();
      const JobState next = retryable && failures < max_attempts ? JobState::retryable : JobState::discarded;
      const bool again = next == JobState::retryable;
      c_.exec("UPDATE jobs SET state = $1, scheduled_at = $2, finished_at = $3, lease_until = NULL, errors_json = " +
                  append_error("$4::bigint", "$5::text") + " WHERE id = $6",
              {p(to_string(next)), p(again ? t + backoff_delay(opt_.backoff, failures, rng_) : t),
               again ? Param() : p(t), p(t), p(clip(error, 4000)), p(job_id)},
              "failing a job");
      if (!again)
        insert_audit({worker_id, "job.discard", "job:" + std::to_string(job_id), json{{"attempt", attempt}}.dump()});
      return next;
    });
  }

  void release(std::int64_t job_id, const std::string& worker_id) override {
    std::lock_guard<std::mutex> l(m_);
    in_transaction(c_, [&] {
      const Result r = c_.exec(
          "UPDATE jobs SET state = 'available', attempt = GREATEST(attempt - 1, 0), lease_until = NULL "
          "WHERE id = $1 AND state = 'running' AND worker_id = $2",
          {p(job_id), p(worker_id)}, "releasing a job");
      if (r.affected() == 0) throw lease_lost(job_id, worker_id);
    });
  }

  bool cancel(std::int64_t job_id, const std::string& actor) override {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      const Result r = c_.exec(
          "UPDATE jobs SET state = 'cancelled', finished_at = $1, lease_until = NULL "
          "WHERE id = $2 AND state IN ('available', 'retryable', 'running')",
          {p(now()), p(job_id)}, "cancelling a job");
      if (r.affected() == 0) return false;
      insert_audit({actor, "job.cancel", "job:" + std::to_string(job_id), "{}"});
      return true;
    });
  }

  bool retry(std::int64_t job_id, const std::string& actor) override {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      const Result r = c_.exec(
          "UPDATE jobs SET state = 'available', scheduled_at = $1, finished_at = NULL, "
          "max_attempts = GREATEST(max_attempts, attempt - rescues + 1), rescues = 0 "
          "WHERE id = $2 AND state IN ('retryable', 'discarded', 'cancelled')",
          {p(now()), p(job_id)}, "retrying a job");
      if (r.affected() == 0) return false;
      insert_audit({actor, "job.retry", "job:" + std::to_string(job_id), "{}"});
      notify_job();
      return true;
    });
  }

  int reap_expired_leases() override {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] { return reap(now()); });
  }

  int prune_jobs(Millis finished_before, int limit) override {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      return static_cast<int>(
          c_.exec(kPruneJobs, {p(finished_before), p(std::int64_t{limit})}, "pruning finished jobs").affected());
    });
  }

  std::optional<Job> get_job(std::int64_t id) override {
    std::lock_guard<std::mutex> l(m_);
    return job_by_id(id);
  }

  std::vector<Job> list_jobs(const JobFilter& f) override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(sel(kJobCols, "FROM jobs WHERE ($1::text IS NULL OR state = $1::text) AND "
                                           "($2 = '' OR kind = $2) AND ($3::bigint = 0 OR id < $3::bigint) "
                                           "ORDER BY id DESC LIMIT $4"),
                             {f.state ? p(to_string(*f.state)) : Param(), p(f.kind), p(f.before_id),
                              p(std::int64_t{f.limit})});
    std::vector<Job> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(read_job(r, i));
    return out;
  }

  QueueCounts counts() override {
    std::lock_guard<std::mutex> l(m_);
    QueueCounts c;
    const Result r = c_.exec("SELECT state, COUNT(*) FROM jobs GROUP BY state");
    for (int i = 0; i < r.rows(); ++i) {
      const std::int64_t n = r.i64(i, 1);
      switch (job_state_from_string(r.text(i, 0))) {
        case JobState::available: c.available = n; break;
        case JobState::running: c.running = n; break;
        case JobState::completed: c.completed = n; break;
        case JobState::retryable: c.retryable = n; break;
        case JobState::discarded: c.discarded = n; break;
        case JobState::cancelled: c.cancelled = n; break;
      }
    }
    return c;
  }

  std::optional<Millis> next_scheduled() override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec("SELECT MIN(scheduled_at) FROM jobs WHERE state IN ('available', 'retryable')");
    return opt_i64(r, 0, 0);
  }

  int consume_job_events(const std::string& consumer, int limit,
                         const std::function<std::vector<JobSpec>(const JobEvent&)>& jobs_for) override {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      // The cursor's row lock makes two nodes consuming for one consumer take turns.
      c_.exec("INSERT INTO event_cursors(consumer, last_event_id) "
              "SELECT $1, COALESCE(MAX(id), 0) FROM job_events ON CONFLICT (consumer) DO NOTHING",
              {p(consumer)}, "starting an event cursor");
      std::int64_t cursor =
          c_.exec("SELECT last_event_id FROM event_cursors WHERE consumer = $1 FOR UPDATE", {p(consumer)}).i64(0, 0);
      const Result r = c_.exec("SELECT id, job_id, kind, state, at FROM job_events WHERE id > $1 ORDER BY id LIMIT $2",
                               {p(cursor), p(std::int64_t{limit})}, "reading job events");
      for (int i = 0; i < r.rows(); ++i) {
        const JobEvent e{r.i64(i, 0), r.i64(i, 1), r.text(i, 2), job_state_from_string(r.text(i, 3)), r.i64(i, 4)};
        for (const auto& spec : jobs_for(e)) insert_job(spec, "events:" + consumer);
        cursor = e.id;
      }
      c_.exec("UPDATE event_cursors SET last_event_id = $2 WHERE consumer = $1", {p(consumer), p(cursor)});
      c_.exec("DELETE FROM job_events WHERE id <= (SELECT MIN(last_event_id) FROM event_cursors) AND at < $1",
              {p(static_cast<std::int64_t>(now() - Millis{7} * 24 * 3600 * 1000))}, "pruning job events");
      return r.rows();
    });
  }

  StoreMetrics metrics(const std::vector<double>& bucket_seconds) override {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(
        c_,
        [&] {
          StoreMetrics out;
          const Result counters = c_.exec("SELECT kind, event, n FROM job_counters ORDER BY kind, event");
          for (int i = 0; i < counters.rows(); ++i)
            out.counters.push_back({counters.text(i, 0), counters.text(i, 1), counters.i64(i, 2)});
          const Result depth = c_.exec(
              "SELECT kind, COUNT(*) FROM jobs WHERE state IN ('available', 'retryable') GROUP BY kind ORDER BY kind");
          for (int i = 0; i < depth.rows(); ++i) out.queue_depth.emplace_back(depth.text(i, 0), depth.i64(i, 1));
          const Result verdicts = c_.exec("SELECT verdict, COUNT(*) FROM detections GROUP BY verdict ORDER BY verdict");
          for (int i = 0; i < verdicts.rows(); ++i) out.detections.emplace_back(verdicts.text(i, 0), verdicts.i64(i, 1));
          std::string sql = "SELECT kind, COUNT(*), COALESCE(SUM(d), 0) / 1000.0";
          std::vector<Param> bounds;
          for (std::size_t b = 0; b < bucket_seconds.size(); ++b) {
            sql += ", COUNT(*) FILTER (WHERE d <= $" + std::to_string(b + 1) + "::bigint)";
            bounds.push_back(p(static_cast<std::int64_t>(std::llround(bucket_seconds[b] * 1000))));
          }
          sql += " FROM (SELECT kind, GREATEST(0, finished_at - attempted_at) AS d FROM jobs WHERE state = 'completed' "
                 "AND attempted_at IS NOT NULL AND finished_at IS NOT NULL) AS done GROUP BY kind ORDER BY kind";
          const Result h = c_.exec(sql, bounds, "reading job durations");
          for (int i = 0; i < h.rows(); ++i) {
            DurationHistogram d;
            d.kind = h.text(i, 0);
            d.count = h.i64(i, 1);
            d.sum_seconds = std::stod(h.text(i, 2));
            for (std::size_t b = 0; b < bucket_seconds.size(); ++b) d.cumulative.push_back(h.i64(i, static_cast<int>(b + 3)));
            out.durations.push_back(std::move(d));
          }
          return out;
        },
        "REPEATABLE READ");  // one snapshot
  }

  bool beat_node(const std::string& node, int workers, Millis lease_ms) override {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      const Millis t = now();
      c_.exec(kBeatNode, {p(node), p(std::int64_t{workers}), p(t)}, "recording the node's beat");
      const bool leads = c_.exec(kTakeLead, {p(node), p(t + lease_ms), p(t)}, "renewing the leader lease").rows() > 0;
      if (leads) c_.exec(kForgetNodes, {p(t - kForgetNodeAfter)}, "forgetting nodes gone for a day");
      return leads;
    });
  }

  std::vector<FleetNode> list_nodes() override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec(kListNodes, {p(now())}, "listing the fleet");
    std::vector<FleetNode> out;
    for (int i = 0; i < r.rows(); ++i)
      out.push_back({r.text(i, 0), static_cast<int>(r.i64(i, 1)), r.i64(i, 2), r.i64(i, 3), r.i64(i, 4) != 0,
                     r.i64(i, 5)});
    return out;
  }

  void leave_fleet(const std::string& node) override {
    std::lock_guard<std::mutex> l(m_);
    in_transaction(c_, [&] {
      c_.exec("DELETE FROM nodes WHERE name = $1", {p(node)}, "leaving the fleet");
      c_.exec("DELETE FROM leader WHERE node = $1", {p(node)}, "giving up the leader lease");
    });
  }

  // No invalid index and the schema this binary expects (PostgreSQL checks its pages itself).
  bool integrity_ok() override {
    std::lock_guard<std::mutex> l(m_);
    const Result r = c_.exec("SELECT COUNT(*) FROM pg_index i JOIN pg_class c ON c.oid = i.indrelid "
                             "JOIN pg_namespace n ON n.oid = c.relnamespace "
                             "WHERE n.nspname = current_schema() AND NOT (i.indisvalid AND i.indisready)");
    return r.i64(0, 0) == 0;
  }

 private:
  const keys::SecretKey& need_master() const { return rules::need_master(opt_.master_key); }

  void fault(const char* point) {
    if (opt_.fault_injection) opt_.fault_injection(point);
  }

  void notify_job() { c_.exec("NOTIFY mm_jobs", {}, "waking idle nodes"); }

  LeaseLost lease_lost(std::int64_t job_id, const std::string& worker_id) {
    return lease_lost_error(job_id, worker_id, job_by_id(job_id));
  }

  // As SqliteStore::check_master_key: a wrong key is refused before anything is sealed with it.
  void check_master_key(const keys::SecretKey& master) {
    const auto want = keys::master_key_check(master);
    const std::string refusal =
        "wrong master key: it is not the key this store's customer keys are sealed under (PostgreSQL); check "
        "MESHMARK_MASTER_KEY or the home's master.key";
    in_transaction(c_, [&] {
      const Result have = c_.exec("SELECT check_value FROM master_key_check WHERE id = 1");
      if (have.rows() > 0) {
        const auto bytes = bytes_of(have, 0, 0);
        if (bytes.size() != want.size() || sodium_memcmp(bytes.data(), want.data(), want.size()) != 0)
          throw keys::KeyError(refusal);
        return;
      }
      const Result k = c_.exec(
          "SELECT customer_id, version, nonce, ciphertext FROM customer_keys ORDER BY customer_id, version LIMIT 1");
      if (k.rows() > 0) {
        try {
          keys::open_customer_key(master, {bytes_of(k, 0, 2), bytes_of(k, 0, 3)}, k.i64(0, 0),
                                  static_cast<int>(k.i64(0, 1)));
        } catch (const keys::KeyError&) {
          throw keys::KeyError(refusal);
        }
      }
      c_.exec("INSERT INTO master_key_check(id, check_value, created_at) VALUES(1, $1, $2) ON CONFLICT (id) DO NOTHING",
              {bytea(std::vector<std::uint8_t>(want.begin(), want.end())), p(now())}, "recording the master key check");
    });
  }

  void insert_key(const keys::SecretKey& master, std::int64_t customer_id, int version, Millis t) {
    const keys::SecretKey k = keys::SecretKey::random();
    const keys::SealedKey s = keys::seal_customer_key(master, k, customer_id, version);
    c_.exec("INSERT INTO customer_keys(customer_id, version, nonce, ciphertext, created_at) VALUES($1, $2, $3, $4, $5)",
            {p(customer_id), p(std::int64_t{version}), bytea(s.nonce), bytea(s.ciphertext), p(t)}, "sealing a key");
  }

  std::int64_t insert_audit(const NewAudit& a) {
    require_json(a.details_json, "audit details");
    return c_.exec("INSERT INTO audit_log(at, actor, action, subject, details_json) VALUES($1, $2, $3, $4, $5) RETURNING id",
                   {p(now()), p(a.actor), p(a.action), p(a.subject), p(a.details_json)}, "appending to the audit log")
        .i64(0, 0);
  }

  template <class PutBlob>
  Asset upsert_asset(const std::string& name, PutBlob put_blob) {
    std::lock_guard<std::mutex> l(m_);
    return in_transaction(c_, [&] {
      const std::string sha = put_blob();
      const std::int64_t size = c_.exec("SELECT size FROM blobs WHERE sha256 = $1", {p(sha)}).i64(0, 0);
      const Result ins = c_.exec(
          "INSERT INTO assets(sha256, size, name, format, created_at) VALUES($1, $2, $3, $4, $5) "
          "ON CONFLICT (sha256) DO NOTHING RETURNING id",
          {p(sha), p(size), p(name), p(format_from_name(name)), p(now())}, "adding an asset");
      const Asset a = read_asset(c_.exec(sel(kAssetCols, "FROM assets WHERE sha256 = $1"), {p(sha)}), 0);
      if (ins.rows() > 0)
        insert_audit({"store", "asset.add", "asset:" + std::to_string(a.id), json{{"sha256", sha}, {"name", name}}.dump()});
      return a;
    });
  }

  std::int64_t insert_copy(const NewCopy& c, std::optional<std::int64_t> job_id, const std::string& actor,
                           bool& existed) {
    require_json(c.params_json, "copy params_json");
    require_json(c.outputs_json, "copy outputs_json");
    const Result ins = c_.exec(
        "INSERT INTO issued_copies(asset_id, customer_id, key_version, idempotency_key, nonce, payload_hex, "
        "params_json, outputs_json, polyhedron_id, job_id, created_at) VALUES($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11) "
        "ON CONFLICT (asset_id, customer_id, key_version, idempotency_key) DO NOTHING RETURNING id",
        {p(c.asset_id), p(c.customer_id), p(std::int64_t{c.key_version}), p(c.idempotency_key), bytea(c.nonce),
         p(c.payload_hex), p(c.params_json), p(c.outputs_json), p(c.polyhedron_id), p(job_id), p(now())},
        "issuing a copy");
    if (ins.rows() > 0) {
      const std::int64_t id = ins.i64(0, 0);
      existed = false;
      insert_audit({actor, "copy.issue", "copy:" + std::to_string(id),
                    json{{"asset_id", c.asset_id}, {"customer_id", c.customer_id}, {"key_version", c.key_version}}.dump()});
      return id;
    }
    existed = true;
    return c_.exec("SELECT id FROM issued_copies WHERE asset_id = $1 AND customer_id = $2 AND key_version = $3 "
                   "AND idempotency_key = $4",
                   {p(c.asset_id), p(c.customer_id), p(std::int64_t{c.key_version}), p(c.idempotency_key)})
        .i64(0, 0);
  }

  std::int64_t insert_detection(const NewDetection& d, std::optional<std::int64_t> job_id, const std::string& actor) {
    require_json(d.details_json, "detection details_json");
    const std::int64_t id =
        c_.exec("INSERT INTO detections(job_id, suspect_sha256, suspect_name, verdict, asset_id, copy_id, customer_id, "
                "correlation, p_value, decoded_payload_hex, details_json, created_at, resync_method, resync_residual) "
                "VALUES($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14) RETURNING id",
                {p(job_id), p(d.suspect_sha256), p(d.suspect_name), p(d.verdict), p(d.asset_id), p(d.copy_id),
                 p(d.customer_id), p(d.correlation), p(d.p_value), p(d.decoded_payload_hex), p(d.details_json),
                 p(now()), p(d.resync_method), p(d.resync_residual)},
                "recording a detection")
            .i64(0, 0);
    insert_audit({actor, "detection.record", "detection:" + std::to_string(id), json{{"verdict", d.verdict}}.dump()});
    return id;
  }

  EnqueueResult insert_job(const JobSpec& spec, const std::string& actor) {
    if (spec.kind.empty()) throw StoreError("enqueue: job kind is empty");
    if (spec.max_attempts < 1) throw StoreError("enqueue: max_attempts must be at least 1");
    require_json(spec.payload_json, "job payload");
    const Millis t = now();
    // ON CONFLICT: two nodes submitting one key together get the one job.
    const Result ins = c_.exec(
        "INSERT INTO jobs(kind, payload_json, priority, max_attempts, idempotency_key, created_at, scheduled_at) "
        "VALUES($1, $2, $3, $4, $5, $6, $7) ON CONFLICT (idempotency_key) DO NOTHING RETURNING id",
        {p(spec.kind), p(spec.payload_json), p(std::int64_t{spec.priority}), p(std::int64_t{spec.max_attempts}),
         spec.idempotency_key.empty() ? Param() : p(spec.idempotency_key), p(t), p(spec.scheduled_at.value_or(t))},
        "enqueueing a job");
    if (ins.rows() == 0) {
      const Result q = c_.exec(sel(kJobCols, "FROM jobs WHERE idempotency_key = $1"), {p(spec.idempotency_key)});
      return {read_job(q, 0), false};
    }
    const std::int64_t id = ins.i64(0, 0);
    insert_audit({actor, "job.enqueue", "job:" + std::to_string(id), json{{"kind", spec.kind}}.dump()});
    notify_job();
    return {job_by_id(id).value(), true};
  }

  CompleteResult complete_in_tx(std::int64_t job_id, const std::string& worker_id, const JobRecords& r) {
    const Result u = c_.exec(
        "UPDATE jobs SET state = 'completed', finished_at = $1, lease_until = NULL, result_json = $2 "
        "WHERE id = $3 AND state = 'running' AND worker_id = $4",
        {p(now()), p(r.result_json), p(job_id), p(worker_id)}, "completing a job");
    if (u.affected() == 0) throw lease_lost(job_id, worker_id);
    fault("complete.after_job_update");
    CompleteResult out;
    for (const NewCopy& c : r.copies) {
      bool existed = false;
      out.copy_ids.push_back(insert_copy(c, job_id, worker_id, existed));
      if (existed) ++out.copies_already_existed;
    }
    fault("complete.after_copies");
    for (const NewDetection& d : r.detections) out.detection_ids.push_back(insert_detection(d, job_id, worker_id));
    fault("complete.after_detections");
    for (const NewAudit& a : r.audit) insert_audit(a);
    for (const JobSpec& f : r.follow_ups) insert_job(f, worker_id);
    insert_audit({worker_id, "job.complete", "job:" + std::to_string(job_id), "{}"});
    return out;
  }

  int reap(Millis t) {
    const Result r = c_.exec(
        "UPDATE jobs SET "
        "state = CASE WHEN rescues + 1 >= $2 THEN 'discarded' ELSE 'available' END, "
        "finished_at = CASE WHEN rescues + 1 >= $2 THEN $1::bigint ELSE NULL END, "
        "rescues = rescues + 1, errors_json = " +
            append_error("$1::bigint",
                         "'lease expired: worker ' || worker_id || ' stopped heartbeating (rescue ' || (rescues + 1) "
                         "|| ' of at most ' || $2 || ')'") +
            ", lease_until = NULL WHERE state = 'running' AND lease_until < $1::bigint",
        {p(t), p(std::int64_t{kMaxRescues})}, "rescuing expired leases");
    return static_cast<int>(r.affected());
  }

  std::optional<Job> job_by_id(std::int64_t id) {
    const Result r = c_.exec(sel(kJobCols, "FROM jobs WHERE id = $1"), {p(id)});
    if (r.rows() == 0) return std::nullopt;
    return read_job(r, 0);
  }

  std::optional<IssuedCopy> copy_by_id(std::int64_t id) {
    const Result r = c_.exec(sel(kCopyCols, "FROM issued_copies WHERE id = $1"), {p(id)});
    if (r.rows() == 0) return std::nullopt;
    return read_copy(r, 0);
  }

  StoreOptions opt_;
  std::mutex m_;
  Connection c_;
  bool in_tx_ = false;  // guarded by m_, as c_ is
  std::optional<Millis> tx_now_;
  PgBlobStore blobs_;
  std::mt19937_64 rng_;
};

}  // namespace

std::unique_ptr<Store> open_postgres_store(const std::string& conninfo, StoreOptions options) {
  if (options.blob_dir.empty()) throw StoreError("open PostgreSQL store: no blob cache folder given");
  return std::make_unique<PgStore>(conninfo, std::move(options));
}

struct JobWakeups::Impl {
  explicit Impl(const std::string& conninfo) : c(conninfo) { c.listen("mm_jobs"); }
  Connection c;
};
JobWakeups::JobWakeups(const std::string& conninfo) : impl_(std::make_unique<Impl>(conninfo)) {}
JobWakeups::~JobWakeups() = default;
bool JobWakeups::wait(int timeout_ms) { return impl_->c.wait_notification(timeout_ms).has_value(); }

}  // namespace mm::store

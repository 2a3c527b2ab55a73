// The store: customers and their keys, assets, cached control polyhedra, issued copies, the job
// queue, detections and an append-only audit log. One narrow interface (this abstract class) so a
// PostgreSQL backend (claims with FOR UPDATE SKIP LOCKED) could later serve a fleet of daemons
// without touching job handlers; today's implementation is SQLite (open_sqlite_store).
//
// Queue guarantees (docs/store.md, docs/queue-contract.md):
//  - states available / running / completed / retryable / discarded / cancelled; every transition
//    (table in job_transition_allowed) is one transaction;
//  - claim is atomic: one job goes to exactly one worker, with a lease; a worker keeps the lease
//    alive with heartbeat(); a job whose lease expired is rescued: claimable again without
//    spending an attempt, up to kMaxRescues rescues, then discarded (it may be what kills workers);
//  - fail() makes a job retryable after exponential backoff with jitter, until max_attempts
//    failures, then discarded; every error is kept in the job's error list;
//  - complete() writes the job's records (copies, detections, audit entries, result) in the same
//    transaction that marks it completed: after a crash a job is done exactly once in effect;
//  - an idempotency key makes a duplicate submission return the existing job, and issued copies are
//    unique per (asset, customer, key version, idempotency key), so a re-run never issues a second.
//
// Threads and processes: a Store object may be shared by threads (calls are serialized on its one
// connection); for parallel database work open one Store per thread. Several processes may open
// the same database. Time comes from StoreOptions::clock (milliseconds since the Unix epoch) so
// tests can step it.
#pragma once
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "keys/keys.h"
#include "store/blob_store.h"

namespace mm::store {

using Millis = std::int64_t;              // milliseconds since the Unix epoch
using Clock = std::function<Millis()>;    // injectable time
Millis system_clock_millis();
// "2026-12-05T10:33:36Z": a record time as every report and listing shows it.
std::string iso_utc(Millis ms);

// Any store failure: I/O, constraint, busy beyond the timeout, unknown ids. Messages name the
// operation and ids, never key bytes.
struct StoreError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
// The calling worker no longer holds the job (lease expired and reclaimed, cancelled, ...).
struct LeaseLost : StoreError {
  using StoreError::StoreError;
};

// ---------------------------------------------------------------- customers and keys
struct Customer {
  std::int64_t id = 0;
  std::string name;  // unique; [A-Za-z0-9._-]{1,64} (it names drop folders)
  int current_key_version = 0;
  Millis created_at = 0;
};

struct CustomerKey {  // decrypted in memory only
  std::int64_t customer_id = 0;
  int version = 0;
  keys::SecretKey key;
};

struct KeyInfo {  // what may be shown: no key material
  std::int64_t customer_id = 0;
  int version = 0;
  Millis created_at = 0;
};

// ---------------------------------------------------------------- assets and polyhedra
struct Asset {
  std::int64_t id = 0;
  std::string sha256;  // content address of the original in the blob store
  std::uint64_t size = 0;
  std::string name;    // the first file name it arrived under
  std::string format;  // "stl", "obj", "off", "ply", ... (from the name; informative)
  Millis created_at = 0;
};

// A compressed control polyhedron and its exact spectral basis, cached per asset and parameters.
struct Polyhedron {
  std::int64_t id = 0;
  std::int64_t asset_id = 0;
  std::string params_key;       // canonical string of the compression parameters (cache key)
  std::string polyhedron_blob;  // sha256 of the serialized control polyhedron
  std::string basis_blob;       // sha256 of the serialized spectral basis ("" if none yet)
  std::string meta_json = "{}";
  Millis created_at = 0;
};

// ---------------------------------------------------------------- issued copies and detections
struct NewCopy {
  std::int64_t asset_id = 0;
  std::int64_t customer_id = 0;
  int key_version = 0;
  std::string idempotency_key;     // e.g. the job's key; UNIQUE with the three above
  std::vector<std::uint8_t> nonce; // per-copy watermark nonce (24 bytes)
  std::string payload_hex;         // the embedded message bits, hex (identifies the copy)
  std::string params_json = "{}";  // embedding parameters (strength, coefficients, ...)
  std::string outputs_json = "{}"; // output files and their sha256
  std::optional<std::int64_t> polyhedron_id;
};
struct IssuedCopy : NewCopy {
  std::int64_t id = 0;
  std::optional<std::int64_t> job_id;
  Millis created_at = 0;
};

struct NewDetection {
  std::string suspect_sha256;
  std::string suspect_name;
  std::string verdict;  // "attributed", "inconclusive", "no watermark found", "unknown asset"
  std::optional<std::int64_t> asset_id;
  std::optional<std::int64_t> copy_id;
  std::optional<std::int64_t> customer_id;
  std::optional<double> correlation;
  std::optional<double> p_value;  // corrected for the number of copies tried
  std::string decoded_payload_hex;
  std::string details_json = "{}";
  std::string resync_method;                // best candidate's: polyhedron | subdivided | surface-fit
  std::optional<double> resync_residual;    // its residual RMS / control diagonal
};
struct Detection : NewDetection {
  std::int64_t id = 0;
  std::optional<std::int64_t> job_id;
  Millis created_at = 0;
};

// ---------------------------------------------------------------- audit log (append-only)
struct NewAudit {
  std::string actor;   // "cli", "worker-3", "pdm", ...
  std::string action;  // "customer.add", "key.rotate", "job.cancel", "copy.issue", ...
  std::string subject; // "customer:3", "job:17", ...
  std::string details_json = "{}";
};
struct AuditEntry : NewAudit {
  std::int64_t id = 0;
  Millis at = 0;
};

// ---------------------------------------------------------------- API tokens
// Bearer tokens of meshmarkd's HTTP API. Roles, each including the one before: read (status,
// lists, downloads), submit (uploads, submissions, cancel), admin (retry, everything).
enum class TokenRole { read, submit, admin };
const char* to_string(TokenRole r);
TokenRole token_role_from_string(const std::string& s);  // StoreError if unknown

struct ApiToken {  // what may be shown: the token itself is never stored
  std::int64_t id = 0;
  std::string name;  // unique, [A-Za-z0-9._-]{1,64}
  TokenRole role = TokenRole::read;
  Millis created_at = 0;
  std::optional<Millis> revoked_at;
};

struct NewToken {
  ApiToken token;
  std::string secret;  // "mmt_" + 64 hex digits; shown once, only its SHA-256 is kept
};

// ---------------------------------------------------------------- jobs
enum class JobState { available, running, completed, retryable, discarded, cancelled };
const char* to_string(JobState s);
JobState job_state_from_string(const std::string& s);  // StoreError if unknown
// The transition table; every Store method changes state only along these edges:
//   available  -> running (claim), cancelled (cancel)
//   retryable  -> running (claim once scheduled), available (retry), cancelled (cancel)
//   running    -> completed (complete), retryable (fail, attempts left), discarded (fail, none
//                 left, or not retryable; also lease expired for the kMaxRescues-th time),
//                 available (lease expired, or release on shutdown), cancelled (cancel)
//   discarded  -> available (retry), cancelled -> available (retry); completed is final.
// Worker ids must be unique per worker thread and process (e.g. "host:pid:thread").
bool job_transition_allowed(JobState from, JobState to);

// A job taken back this many times from workers that stopped heartbeating is discarded: a kill
// storm or a host crash does not use up a job's attempts, but a job that itself kills its worker
// (out of memory, a crash in a library) must not cycle forever.
constexpr int kMaxRescues = 20;

struct JobSpec {
  std::string kind;                // "protect", "detect", "noop", ... (handlers registered by kind)
  std::string payload_json = "{}"; // handler input; never put keys here
  int priority = 0;                // higher runs first
  int max_attempts = 5;
  std::string idempotency_key;     // optional; duplicate submission returns the existing job
  std::optional<Millis> scheduled_at;  // default now
};

struct JobError {
  int attempt = 0;
  Millis at = 0;
  std::string error;
};

struct Job {
  std::int64_t id = 0;
  std::string kind;
  std::string payload_json;
  JobState state = JobState::available;
  int priority = 0;
  int attempt = 0;  // claims so far (incremented by each claim)
  int max_attempts = 0;  // failures allowed: attempt - rescues reaching it discards the job
  int rescues = 0;       // claims lost to a worker that stopped heartbeating (see kMaxRescues)
  std::string idempotency_key;
  Millis created_at = 0;
  Millis scheduled_at = 0;
  std::optional<Millis> attempted_at;
  std::optional<Millis> finished_at;  // completed, discarded or cancelled
  std::string worker_id;              // last claimer
  std::optional<Millis> lease_until;  // while running
  std::vector<JobError> errors;       // one per failed attempt, oldest first
  std::string result_json;            // set by complete()
};

struct EnqueueResult {
  Job job;
  bool created = false;  // false: the idempotency key already existed, `job` is that job
};

struct JobFilter {
  std::optional<JobState> state;
  std::string kind;  // "" = any
  int limit = 100;
  std::int64_t before_id = 0;  // paging: only ids < before_id (0 = from the newest)
};

// Everything a job produced, written atomically with its completion.
struct JobRecords {
  std::vector<NewCopy> copies;         // ON CONFLICT of the unique key: the existing copy is kept
  std::vector<NewDetection> detections;
  std::vector<NewAudit> audit;
  std::vector<JobSpec> follow_ups;     // jobs this one's outcome calls for (idempotent by key)
  std::string result_json = "{}";
};
struct CompleteResult {
  std::vector<std::int64_t> copy_ids;  // in the order of JobRecords::copies (existing id if dup)
  std::vector<std::int64_t> detection_ids;
  int copies_already_existed = 0;
};

// One completion of a batch (Store::complete_batch) and what became of it.
struct Completion {
  std::int64_t job_id = 0;
  std::string worker_id;
  const JobRecords* records = nullptr;
};
struct CompletionOutcome {
  CompleteResult result;
  std::exception_ptr error;  // LeaseLost or StoreError of this completion alone; null when done
};

struct QueueCounts {
  std::int64_t available = 0, running = 0, completed = 0, retryable = 0, discarded = 0,
               cancelled = 0;
};

// What /metrics reports (daemon/service/api.h), read in one snapshot.
struct JobCounter {
  std::string kind;
  std::string event;  // a job state (to_string(JobState)) it entered, or "rescue"
  std::int64_t count = 0;
};
struct DurationHistogram {  // completed jobs of one kind: completion minus their last claim
  std::string kind;
  std::vector<std::int64_t> cumulative;  // jobs at or under each bound (StoreMetrics' bounds)
  std::int64_t count = 0;
  double sum_seconds = 0;
};
struct StoreMetrics {
  std::vector<JobCounter> counters;                             // since the store was created
  std::vector<std::pair<std::string, std::int64_t>> queue_depth;  // kind -> available + retryable now
  std::vector<std::pair<std::string, std::int64_t>> detections;   // verdict -> detections recorded
  std::vector<DurationHistogram> durations;
};

// A job reaching a final state (completed, discarded, cancelled), as the store's trigger records
// it; webhook jobs raise none.
struct JobEvent {
  std::int64_t id = 0;  // increasing
  std::int64_t job_id = 0;
  std::string kind;
  JobState state = JobState::completed;
  Millis at = 0;
};

// A daemon sharing the store (meshmark fleet status).
struct FleetNode {
  std::string name;  // host:pid, the prefix of its workers' ids
  int workers = 0;
  Millis started_at = 0;
  Millis seen_at = 0;      // its last beat
  bool leader = false;     // holds the leader lease now
  Millis leader_until = 0; // when that lease runs out (0 when not the leader)
};

struct BackoffPolicy {
  Millis base = 1000;         // delay after the 1st failure; doubles per attempt
  Millis max = 3600 * 1000;   // cap
  double jitter = 0.1;        // + uniform [0, jitter * delay)
};

struct StoreOptions {
  std::string db_path;                   // SQLite file (created if missing)
  std::string blob_dir;                  // "" = <db folder>/blobs
  std::optional<keys::SecretKey> master_key;  // needed only for key operations
  Clock clock;                           // default system_clock_millis
  BackoffPolicy backoff;
  std::uint64_t jitter_seed = 0;         // 0 = random
  int busy_timeout_ms = 10000;
  bool synchronous_full = true;          // FULL: every commit durable (docs/store.md)
  // Tests only: called at named points inside transactions ("complete.after_job_update",
  // "complete.after_copies", ...); throwing from it aborts and rolls back the transaction.
  std::function<void(const std::string& point)> fault_injection;
};

class Store {
 public:
  virtual ~Store() = default;

  virtual int schema_version() = 0;
  virtual BlobStore& blobs() = 0;
  virtual Millis now() = 0;

  // Customers and keys. add_customer creates the customer with key version 1 (one transaction).
  virtual Customer add_customer(const std::string& name, const std::string& actor = "cli") = 0;
  virtual std::vector<Customer> list_customers() = 0;
  virtual std::optional<Customer> find_customer(const std::string& name) = 0;
  virtual std::optional<Customer> get_customer(std::int64_t id) = 0;
  virtual int rotate_key(std::int64_t customer_id, const std::string& actor = "cli") = 0;  // new version
  virtual CustomerKey customer_key(std::int64_t customer_id, int version = 0) = 0;  // 0 = current
  virtual std::vector<KeyInfo> list_keys(std::int64_t customer_id) = 0;

  // Assets: the original goes into the blob store first, then the row (deduplicated by sha256).
  virtual Asset put_asset_file(const std::string& path, const std::string& name) = 0;
  virtual Asset put_asset_bytes(const std::vector<std::uint8_t>& bytes, const std::string& name) = 0;
  virtual std::optional<Asset> get_asset(std::int64_t id) = 0;
  virtual std::optional<Asset> find_asset(const std::string& sha256) = 0;
  virtual std::vector<Asset> list_assets(int limit = 1000) = 0;

  // Polyhedron cache: put returns the existing row if (asset_id, params_key) is already cached.
  // The referenced blobs must already be in blobs().
  virtual Polyhedron put_polyhedron(const Polyhedron& p) = 0;
  virtual std::optional<Polyhedron> find_polyhedron(std::int64_t asset_id,
                                                    const std::string& params_key) = 0;

  // Copies and detections (normally written through complete(); direct calls for tools/tests).
  virtual IssuedCopy issue_copy(const NewCopy& c) = 0;  // existing copy if the unique key exists
  virtual std::optional<IssuedCopy> find_copy(std::int64_t asset_id, std::int64_t customer_id,
                                              int key_version,
                                              const std::string& idempotency_key) = 0;
  virtual std::optional<IssuedCopy> get_copy(std::int64_t id) = 0;
  virtual std::vector<IssuedCopy> list_copies(std::optional<std::int64_t> asset_id = {},
                                              int limit = 1000) = 0;
  virtual Detection record_detection(const NewDetection& d) = 0;
  virtual std::vector<Detection> list_detections(int limit = 1000) = 0;
  virtual std::optional<Detection> get_detection(std::int64_t id) = 0;
  virtual std::optional<Detection> detection_of_job(std::int64_t job_id) = 0;  // the job's latest

  // Audit log.
  virtual std::int64_t append_audit(const NewAudit& a) = 0;
  virtual std::vector<AuditEntry> list_audit(int limit = 1000) = 0;

  // API tokens. create_token refuses a name in use (revoked ones included); revoke_token returns
  // false for an unknown or already revoked name. token_for_secret: the live token with that
  // secret, compared by its SHA-256.
  virtual NewToken create_token(const std::string& name, TokenRole role, const std::string& actor = "cli") = 0;
  virtual std::vector<ApiToken> list_tokens() = 0;
  virtual bool revoke_token(const std::string& name, const std::string& actor = "cli") = 0;
  virtual std::optional<ApiToken> token_for_secret(const std::string& secret) = 0;

  // Queue.
  virtual EnqueueResult enqueue(const JobSpec& spec, const std::string& actor = "cli") = 0;
  // Claims the best available job: state available, or retryable with scheduled_at <= now;
  // priority DESC, scheduled_at, id. Expired leases are reaped first. kinds empty = any kind.
  virtual std::optional<Job> claim(const std::string& worker_id, Millis lease,
                                   const std::vector<std::string>& kinds = {}) = 0;
  // Extends the lease; throws LeaseLost if the job is no longer running under this worker.
  virtual void heartbeat(std::int64_t job_id, const std::string& worker_id, Millis lease) = 0;
  // running -> completed with its records, one transaction; LeaseLost if not held (then nothing
  // is written).
  virtual CompleteResult complete(std::int64_t job_id, const std::string& worker_id,
                                  const JobRecords& records) = 0;
  // Several complete()s in one durable commit (group commit: one fsync for the batch). Each
  // completion is all or nothing on its own: one that fails (LeaseLost, a record refused) is
  // rolled back alone and reported in its outcome; the others still commit. A failure of the
  // commit itself throws, and none is done.
  virtual std::vector<CompletionOutcome> complete_batch(const std::vector<Completion>& batch) = 0;
  // running -> retryable (after backoff) or discarded; returns the new state. LeaseLost if not held.
  virtual JobState fail(std::int64_t job_id, const std::string& worker_id, const std::string& error,
                        bool retryable = true) = 0;
  // running -> available without spending the attempt (graceful shutdown). LeaseLost if not held.
  virtual void release(std::int64_t job_id, const std::string& worker_id) = 0;
  // available/retryable/running -> cancelled. Returns false for any other state. A running job's
  // worker finds out at its next heartbeat/complete/fail (LeaseLost) and must drop its results.
  virtual bool cancel(std::int64_t job_id, const std::string& actor = "cli") = 0;
  // retryable/discarded/cancelled -> available now; grants one more attempt if none are left.
  virtual bool retry(std::int64_t job_id, const std::string& actor = "cli") = 0;
  // Running jobs whose lease expired -> available (attempts left) or discarded. Returns count.
  virtual int reap_expired_leases() = 0;
  virtual std::optional<Job> get_job(std::int64_t id) = 0;
  virtual std::vector<Job> list_jobs(const JobFilter& f = {}) = 0;
  virtual QueueCounts counts() = 0;
  // Deletes up to `limit` finished jobs (completed, discarded, cancelled) that finished before
  // `finished_before` and that no issued copy or detection points at (those keep their job, the
  // record of how they were made), oldest first, in one transaction. Returns how many.
  virtual int prune_jobs(Millis finished_before, int limit) = 0;
  // Earliest scheduled_at of a retryable job (to sleep until), if any.
  virtual std::optional<Millis> next_scheduled() = 0;

  // The job events after `consumer`'s cursor (at most `limit`, oldest first), each turned into
  // jobs by `jobs_for` (enqueued, idempotent by their keys) and the cursor moved past them, in one
  // transaction. A new consumer starts after the newest event. Events every consumer has read
  // and older than a week are deleted. Returns how many events were consumed.
  virtual int consume_job_events(const std::string& consumer, int limit,
                                 const std::function<std::vector<JobSpec>(const JobEvent&)>& jobs_for) = 0;

  // The counters, gauges and histograms of /metrics; bucket_seconds ascending.
  virtual StoreMetrics metrics(const std::vector<double>& bucket_seconds) = 0;

  // Fleet: `node` is alive (its row made or refreshed, seen now) and takes the leader lease for
  // lease_ms when the lease is free, run out, or already its own; one transaction. True while it
  // leads. leave_fleet removes the node's row and gives its lease up (a clean stop).
  virtual bool beat_node(const std::string& node, int workers, Millis lease_ms) = 0;
  virtual std::vector<FleetNode> list_nodes() = 0;
  virtual void leave_fleet(const std::string& node) = 0;

  // PRAGMA integrity_check == "ok" (or the backend's equivalent).
  virtual bool integrity_ok() = 0;
};

// Opens (creating if needed) a SQLite store and applies pending migrations (embedded in the
// binary from schema/NNNN_name.sql), each in its own transaction, recorded in schema_version.
std::unique_ptr<Store> open_sqlite_store(StoreOptions options);

}  // namespace mm::store

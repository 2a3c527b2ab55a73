// What both store backends (SQLite, PostgreSQL) check the same way: names, JSON, what is shown
// of long strings, the format a file name gives, the column lists rows are read in, and the retry
// backoff.
#pragma once
#include <algorithm>
#include <cctype>
#include <cmath>
#include <optional>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <string>

#include "store/store.h"

namespace mm::store::rules {

using nlohmann::json;

constexpr const char* kJobCols =
    "id, kind, payload_json, state, priority, attempt, max_attempts, "
    "COALESCE(idempotency_key, ''), created_at, scheduled_at, attempted_at, finished_at, "
    "worker_id, lease_until, errors_json, result_json, rescues";
constexpr const char* kCustomerCols = "id, name, current_key_version, created_at";
constexpr const char* kAssetCols = "id, sha256, size, name, format, created_at";
constexpr const char* kPolyCols = "id, asset_id, params_key, polyhedron_blob, basis_blob, meta_json, created_at";
constexpr const char* kCopyCols =
    "id, asset_id, customer_id, key_version, idempotency_key, nonce, payload_hex, params_json, "
    "outputs_json, polyhedron_id, job_id, created_at";
constexpr const char* kDetectionCols =
    "id, job_id, suspect_sha256, suspect_name, verdict, asset_id, copy_id, customer_id, "
    "correlation, p_value, decoded_payload_hex, details_json, created_at, resync_method, resync_residual";
constexpr const char* kTokenCols = "id, name, role, created_at, revoked_at";

inline std::string sel(const char* cols, const char* rest) { return std::string("SELECT ") + cols + " " + rest; }

// A job's error list as stored (a JSON array of {attempt, at, error}).
inline std::vector<JobError> parse_errors(const std::string& text) {
  std::vector<JobError> out;
  json errs = json::parse(text, nullptr, false);
  if (errs.is_array())
    for (const auto& e : errs)
      out.push_back({e.value("attempt", 0), e.value("at", Millis{0}), e.value("error", std::string())});
  return out;
}

inline void require_json(const std::string& text, const char* what) {
  if (!json::accept(text)) throw StoreError(std::string(what) + " is not valid JSON");
}

inline std::string clip(const std::string& s, std::size_t n) { return s.size() <= n ? s : s.substr(0, n) + "..."; }

// The drop folders' rule too (service/drop_watcher.h): a leading '.' would name a hidden folder
// that the watcher ignores, so such a customer could never be protected through it.
inline bool valid_customer_name(const std::string& n) {
  static const std::regex re("[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}");
  return std::regex_match(n, re);
}

inline std::string format_from_name(const std::string& name) {
  auto slash = name.find_last_of('/');
  std::string base = slash == std::string::npos ? name : name.substr(slash + 1);
  auto dot = base.find_last_of('.');
  if (dot == std::string::npos || dot + 1 == base.size()) return "";
  std::string ext = base.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext.size() <= 8 ? ext : "";
}


// The fleet's statements, the same in both dialects ($1.. as SQLite reads ?NNN too): a node's
// beat ($1 name, $2 workers, $3 now), the leader lease taken when free, run out or already its
// own ($1 name, $2 until, $3 now; a row back when this node leads), nodes not seen for a day
// forgotten ($1 before), the nodes with the lease ($1 now).
constexpr const char* kBeatNode =
    "INSERT INTO nodes(name, workers, started_at, seen_at) VALUES($1, $2, $3, $3) "
    "ON CONFLICT(name) DO UPDATE SET workers = excluded.workers, seen_at = excluded.seen_at";
constexpr const char* kTakeLead =
    "INSERT INTO leader(id, node, until) VALUES(1, $1, $2) ON CONFLICT(id) DO UPDATE SET node = excluded.node, "
    "until = excluded.until WHERE leader.node = excluded.node OR leader.until < $3 RETURNING node";
constexpr const char* kForgetNodes = "DELETE FROM nodes WHERE seen_at < $1";
constexpr const char* kListNodes =
    "SELECT n.name, n.workers, n.started_at, n.seen_at, "
    "CASE WHEN l.node = n.name AND l.until >= $1 THEN 1 ELSE 0 END, "
    "CASE WHEN l.node = n.name AND l.until >= $1 THEN l.until ELSE 0 END "
    "FROM nodes n LEFT JOIN leader l ON l.id = 1 ORDER BY n.name";
constexpr Millis kForgetNodeAfter = Millis{24} * 3600 * 1000;

// The master key a key operation needs; KeyError saying how to provide it when none is loaded.
inline const keys::SecretKey& need_master(const std::optional<keys::SecretKey>& master) {
  if (!master)
    throw keys::KeyError("no master key loaded: set MESHMARK_MASTER_KEY or create the home's "
                         "master.key (meshmark init)");
  return *master;
}

// The refusal of a heartbeat, completion, failure or release by a worker that no longer holds
// the job; `job` as the store has it now (nullopt: no such job).
inline LeaseLost lease_lost_error(std::int64_t job_id, const std::string& worker_id, const std::optional<Job>& job) {
  const std::string state = job ? to_string(job->state) : "missing";
  return LeaseLost("job " + std::to_string(job_id) + " is no longer held by worker " + clip(worker_id, 80) +
                   " (state " + state + (job && job->state == JobState::running ? ", worker " + job->worker_id : "") +
                   ")");
}

// Store::prune_jobs in both dialects ($1 finished before, $2 the batch; SQLite binds $N by position).
constexpr const char* kPruneJobs =
    "DELETE FROM jobs WHERE id IN (SELECT j.id FROM jobs j WHERE j.state IN ('completed', 'discarded', 'cancelled') "
    "AND j.finished_at < $1 AND NOT EXISTS (SELECT 1 FROM issued_copies c WHERE c.job_id = j.id) "
    "AND NOT EXISTS (SELECT 1 FROM detections d WHERE d.job_id = j.id) ORDER BY j.finished_at, j.id LIMIT $2)";

// Delay before the next attempt after `attempt` failures: base doubling per attempt, capped, plus
// jitter.
inline Millis backoff_delay(const BackoffPolicy& b, int attempt, std::mt19937_64& rng) {
  double d = static_cast<double>(b.base) * std::pow(2.0, std::max(0, attempt - 1));
  d = std::min(d, static_cast<double>(b.max));
  double j = b.jitter > 0 ? std::uniform_real_distribution<double>(0.0, b.jitter * d)(rng) : 0.0;
  return static_cast<Millis>(d + j);
}

}  // namespace mm::store::rules

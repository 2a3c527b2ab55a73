// The job queue: every state transition one BEGIN IMMEDIATE transaction (docs/queue-contract.md).
#include "store/sqlite_store_impl.h"

#include <cmath>

namespace mm::store::sqlite_detail {

EnqueueResult SqliteStore::enqueue(const JobSpec& spec, const std::string& actor) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  EnqueueResult r = insert_job(spec, actor);
  tx.commit();
  return r;
}

EnqueueResult SqliteStore::insert_job(const JobSpec& spec, const std::string& actor) {
  if (spec.kind.empty()) throw StoreError("enqueue: job kind is empty");
  if (spec.max_attempts < 1) throw StoreError("enqueue: max_attempts must be at least 1");
  require_json(spec.payload_json, "job payload");
  if (!spec.idempotency_key.empty()) {
    Stmt q(db_, sel(kJobCols, "FROM jobs WHERE idempotency_key = ?").c_str());
    if (q.bind(1, spec.idempotency_key).step()) return {read_job(q), false};
  }
  Millis t = now();
  Stmt ins(db_,
           "INSERT INTO jobs(kind, payload_json, priority, max_attempts, idempotency_key, created_at, "
           "scheduled_at) VALUES(?,?,?,?,?,?,?) RETURNING id");
  ins.bind(1, spec.kind).bind(2, spec.payload_json).bind(3, spec.priority).bind(4, spec.max_attempts);
  if (spec.idempotency_key.empty()) ins.bind_null(5); else ins.bind(5, spec.idempotency_key);
  ins.bind(6, t).bind(7, spec.scheduled_at.value_or(t)).step();
  std::int64_t id = ins.i64(0);
  insert_audit({actor, "job.enqueue", "job:" + std::to_string(id), json{{"kind", spec.kind}}.dump()});
  return {job_by_id(id).value(), true};
}

std::optional<Job> SqliteStore::claim(const std::string& worker_id, Millis lease, const std::vector<std::string>& kinds) {
  if (worker_id.empty()) throw StoreError("claim: worker id is empty");
  std::lock_guard<std::mutex> l(m_);
  UnsyncedCommits unsynced(db_, opt_.synchronous_full);
  Tx tx(db_);
  Millis t = now();
  reap(t);
  static const std::string q = std::string(
      "UPDATE jobs SET state = 'running', attempt = attempt + 1, attempted_at = ?1, worker_id = ?2, "
      "lease_until = ?3 WHERE id = (SELECT id FROM jobs WHERE state IN ('available', 'retryable') "
      "AND scheduled_at <= ?1 AND (?4 IS NULL OR kind IN (SELECT value FROM json_each(?4))) "
      "ORDER BY priority DESC, scheduled_at, id LIMIT 1) RETURNING ") + kJobCols;
  Stmt s(db_, q.c_str());
  s.bind(1, t).bind(2, worker_id).bind(3, t + lease);
  if (kinds.empty()) s.bind_null(4); else s.bind(4, json(kinds).dump());
  std::optional<Job> j;
  if (s.step()) j = read_job(s);
  s.run();
  tx.commit();
  return j;
}

void SqliteStore::heartbeat(std::int64_t job_id, const std::string& worker_id, Millis lease) {
  std::lock_guard<std::mutex> l(m_);
  UnsyncedCommits unsynced(db_, opt_.synchronous_full);
  Tx tx(db_);
  Stmt u(db_, "UPDATE jobs SET lease_until = ? WHERE id = ? AND state = 'running' AND worker_id = ?");
  u.bind(1, now() + lease).bind(2, job_id).bind(3, worker_id).run();
  if (u.changes() == 0) throw lease_lost(job_id, worker_id);
  tx.commit();
}

CompleteResult SqliteStore::complete(std::int64_t job_id, const std::string& worker_id, const JobRecords& r) {
  require_json(r.result_json, "job result");
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  CompleteResult out = complete_in_tx(job_id, worker_id, r);
  fault("complete.before_commit");
  tx.commit();
  return out;
}

std::vector<CompletionOutcome> SqliteStore::complete_batch(const std::vector<Completion>& batch) {
  std::vector<CompletionOutcome> out(batch.size());
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  for (std::size_t i = 0; i < batch.size(); ++i) {
    db_.exec("SAVEPOINT completion", "complete");
    try {
      require_json(batch[i].records->result_json, "job result");
      out[i].result = complete_in_tx(batch[i].job_id, batch[i].worker_id, *batch[i].records);
      db_.exec("RELEASE completion", "complete");
    } catch (const std::exception&) {
      out[i].error = std::current_exception();
      db_.exec("ROLLBACK TO completion", "complete");
      db_.exec("RELEASE completion", "complete");
    }
  }
  fault("complete.before_commit");
  tx.commit();
  return out;
}

CompleteResult SqliteStore::complete_in_tx(std::int64_t job_id, const std::string& worker_id, const JobRecords& r) {
  Millis t = now();
  Stmt u(db_,
         "UPDATE jobs SET state = 'completed', finished_at = ?, lease_until = NULL, result_json = ? "
         "WHERE id = ? AND state = 'running' AND worker_id = ?");
  u.bind(1, t).bind(2, r.result_json).bind(3, job_id).bind(4, worker_id).run();
  if (u.changes() == 0) throw lease_lost(job_id, worker_id);
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

JobState SqliteStore::fail(std::int64_t job_id, const std::string& worker_id, const std::string& error, bool retryable) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  Stmt q(db_, "SELECT attempt, max_attempts, rescues FROM jobs WHERE id = ? AND state = 'running' AND worker_id = ?");
  if (!q.bind(1, job_id).bind(2, worker_id).step()) throw lease_lost(job_id, worker_id);
  int attempt = static_cast<int>(q.i64(0));
  int max_attempts = static_cast<int>(q.i64(1));
  int failures = attempt - static_cast<int>(q.i64(2));  // rescues from dead workers spend no attempt
  Millis t = now();
  JobState next = retryable && failures < max_attempts ? JobState::retryable : JobState::discarded;
  Stmt u(db_,
         "UPDATE jobs SET state = ?1, scheduled_at = ?2, finished_at = ?3, lease_until = NULL, "
         "errors_json = json_insert(errors_json, '$[#]', json_object('attempt', attempt, 'at', ?4, 'error', ?5)) "
         "WHERE id = ?6");
  u.bind(1, to_string(next));
  if (next == JobState::retryable) u.bind(2, t + backoff(failures)).bind_null(3);
  else u.bind(2, t).bind(3, t);
  u.bind(4, t).bind(5, clip(error, 4000)).bind(6, job_id).run();
  if (next == JobState::discarded)
    insert_audit({worker_id, "job.discard", "job:" + std::to_string(job_id),
                  json{{"attempt", attempt}}.dump()});
  tx.commit();
  return next;
}

void SqliteStore::release(std::int64_t job_id, const std::string& worker_id) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  Stmt u(db_,
         "UPDATE jobs SET state = 'available', attempt = MAX(attempt - 1, 0), lease_until = NULL "
         "WHERE id = ? AND state = 'running' AND worker_id = ?");
  u.bind(1, job_id).bind(2, worker_id).run();
  if (u.changes() == 0) throw lease_lost(job_id, worker_id);
  tx.commit();
}

bool SqliteStore::cancel(std::int64_t job_id, const std::string& actor) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  Stmt u(db_,
         "UPDATE jobs SET state = 'cancelled', finished_at = ?, lease_until = NULL "
         "WHERE id = ? AND state IN ('available', 'retryable', 'running')");
  u.bind(1, now()).bind(2, job_id).run();
  if (u.changes() == 0) return false;
  insert_audit({actor, "job.cancel", "job:" + std::to_string(job_id), "{}"});
  tx.commit();
  return true;
}

bool SqliteStore::retry(std::int64_t job_id, const std::string& actor) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  Stmt u(db_,
         "UPDATE jobs SET state = 'available', scheduled_at = ?, finished_at = NULL, "
         "max_attempts = MAX(max_attempts, attempt - rescues + 1), rescues = 0 "
         "WHERE id = ? AND state IN ('retryable', 'discarded', 'cancelled')");
  u.bind(1, now()).bind(2, job_id).run();
  if (u.changes() == 0) return false;
  insert_audit({actor, "job.retry", "job:" + std::to_string(job_id), "{}"});
  tx.commit();
  return true;
}

int SqliteStore::reap_expired_leases() {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  int n = reap(now());
  tx.commit();
  return n;
}

int SqliteStore::prune_jobs(Millis finished_before, int limit) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  Stmt d(db_, rules::kPruneJobs);
  d.bind(1, static_cast<std::int64_t>(finished_before)).bind(2, limit).run();
  const int n = d.changes();
  tx.commit();
  return n;
}

std::optional<Job> SqliteStore::get_job(std::int64_t id) {
  std::lock_guard<std::mutex> l(m_);
  return job_by_id(id);
}

std::vector<Job> SqliteStore::list_jobs(const JobFilter& f) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kJobCols, "FROM jobs WHERE (?1 IS NULL OR state = ?1) AND (?2 = '' OR kind = ?2) "
                            "AND (?3 = 0 OR id < ?3) ORDER BY id DESC LIMIT ?4").c_str());
  if (f.state) q.bind(1, to_string(*f.state)); else q.bind_null(1);
  q.bind(2, f.kind).bind(3, f.before_id).bind(4, f.limit);
  std::vector<Job> out;
  while (q.step()) out.push_back(read_job(q));
  return out;
}

QueueCounts SqliteStore::counts() {
  std::lock_guard<std::mutex> l(m_);
  QueueCounts c;
  Stmt q(db_, "SELECT state, COUNT(*) FROM jobs GROUP BY state");
  while (q.step()) {
    std::int64_t n = q.i64(1);
    switch (job_state_from_string(q.text(0))) {
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

std::optional<Millis> SqliteStore::next_scheduled() {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, "SELECT MIN(scheduled_at) FROM jobs WHERE state IN ('available', 'retryable')");
  q.step();
  return q.opt_i64(0);
}

int SqliteStore::consume_job_events(const std::string& consumer, int limit,
                                    const std::function<std::vector<JobSpec>(const JobEvent&)>& jobs_for) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  std::int64_t cursor = 0;
  {
    Stmt q(db_, "SELECT last_event_id FROM event_cursors WHERE consumer = ?");
    if (q.bind(1, consumer).step()) {
      cursor = q.i64(0);
    } else {
      Stmt m(db_, "SELECT COALESCE(MAX(id), 0) FROM job_events");
      m.step();
      cursor = m.i64(0);
    }
  }
  std::vector<JobEvent> events;
  {
    Stmt q(db_, "SELECT id, job_id, kind, state, at FROM job_events WHERE id > ? ORDER BY id LIMIT ?");
    q.bind(1, cursor).bind(2, limit);
    while (q.step()) events.push_back({q.i64(0), q.i64(1), q.text(2), job_state_from_string(q.text(3)), q.i64(4)});
  }
  for (const auto& e : events) {
    for (const auto& spec : jobs_for(e)) insert_job(spec, "events:" + consumer);
    cursor = e.id;
  }
  Stmt u(db_, "INSERT INTO event_cursors(consumer, last_event_id) VALUES(?, ?) "
              "ON CONFLICT(consumer) DO UPDATE SET last_event_id = excluded.last_event_id");
  u.bind(1, consumer).bind(2, cursor).run();
  Stmt prune(db_, "DELETE FROM job_events WHERE id <= (SELECT MIN(last_event_id) FROM event_cursors) AND at < ?");
  prune.bind(1, static_cast<std::int64_t>(now() - Millis{7} * 24 * 3600 * 1000)).run();
  tx.commit();
  return static_cast<int>(events.size());
}

StoreMetrics SqliteStore::metrics(const std::vector<double>& bucket_seconds) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_, false);  // one snapshot; a read, so writers are not held up
  StoreMetrics out;
  {
    Stmt q(db_, "SELECT kind, event, n FROM job_counters ORDER BY kind, event");
    while (q.step()) out.counters.push_back({q.text(0), q.text(1), q.i64(2)});
  }
  {
    Stmt q(db_, "SELECT kind, COUNT(*) FROM jobs WHERE state IN ('available', 'retryable') GROUP BY kind ORDER BY kind");
    while (q.step()) out.queue_depth.emplace_back(q.text(0), q.i64(1));
  }
  {
    Stmt q(db_, "SELECT verdict, COUNT(*) FROM detections GROUP BY verdict ORDER BY verdict");
    while (q.step()) out.detections.emplace_back(q.text(0), q.i64(1));
  }
  // Bucket counts in SQL: one row per kind whatever the number of jobs.
  std::string sql = "SELECT kind, COUNT(*), TOTAL(d) / 1000.0";
  for (std::size_t b = 0; b < bucket_seconds.size(); ++b) sql += ", TOTAL(d <= ?" + std::to_string(b + 1) + ")";
  sql += " FROM (SELECT kind, MAX(0, finished_at - attempted_at) AS d FROM jobs WHERE state = 'completed' "
         "AND attempted_at IS NOT NULL AND finished_at IS NOT NULL) GROUP BY kind ORDER BY kind";
  Stmt q(db_, sql.c_str());
  for (std::size_t b = 0; b < bucket_seconds.size(); ++b)
    q.bind(static_cast<int>(b + 1), static_cast<std::int64_t>(std::llround(bucket_seconds[b] * 1000)));
  while (q.step()) {
    DurationHistogram h;
    h.kind = q.text(0);
    h.count = q.i64(1);
    h.sum_seconds = q.f64(2);
    for (std::size_t b = 0; b < bucket_seconds.size(); ++b) h.cumulative.push_back(std::llround(q.f64(static_cast<int>(b + 3))));
    out.durations.push_back(std::move(h));
  }
  return out;
}

bool SqliteStore::integrity_ok() {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, "PRAGMA integrity_check");
  return q.step() && q.text(0) == "ok" && !q.step();
}

}  // namespace mm::store::sqlite_detail

namespace mm::store::sqlite_detail {

bool SqliteStore::beat_node(const std::string& node, int workers, Millis lease_ms) {
  std::lock_guard<std::mutex> l(m_);
  UnsyncedCommits unsynced(db_, opt_.synchronous_full);
  Tx tx(db_);
  const Millis t = now();
  Stmt(db_, kBeatNode).bind(1, node).bind(2, workers).bind(3, t).run();
  Stmt lead(db_, kTakeLead);
  lead.bind(1, node).bind(2, t + lease_ms).bind(3, t);
  const bool leads = lead.step();
  if (leads) {
    lead.run();
    Stmt(db_, kForgetNodes).bind(1, t - kForgetNodeAfter).run();
  }
  tx.commit();
  return leads;
}

std::vector<FleetNode> SqliteStore::list_nodes() {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, kListNodes);
  q.bind(1, now());
  std::vector<FleetNode> out;
  while (q.step())
    out.push_back({q.text(0), static_cast<int>(q.i64(1)), q.i64(2), q.i64(3), q.i64(4) != 0, q.i64(5)});
  return out;
}

void SqliteStore::leave_fleet(const std::string& node) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  Stmt(db_, "DELETE FROM nodes WHERE name = ?").bind(1, node).run();
  Stmt(db_, "DELETE FROM leader WHERE node = ?").bind(1, node).run();
  tx.commit();
}

}  // namespace mm::store::sqlite_detail

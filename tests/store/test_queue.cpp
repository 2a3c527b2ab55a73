#include <gtest/gtest.h>

#include <map>
#include <mutex>
#include <thread>

#include "store/sqlite_db.h"
#include "store_backends.h"
#include "store_test_util.h"

using namespace mm;
using namespace mm::test;
using store::JobSpec;
using store::JobState;

namespace {
JobSpec spec(const std::string& kind = "noop", int priority = 0, int max_attempts = 5,
             const std::string& idem = "") {
  JobSpec s;
  s.kind = kind;
  s.priority = priority;
  s.max_attempts = max_attempts;
  s.idempotency_key = idem;
  return s;
}

// The queue contract, on each backend.
class Queue : public BackendTest {};
MM_BACKENDS(Queue);

}  // namespace

TEST_P(Queue, EnqueueClaimComplete) {
  TempDir dir;
  StepClock clock;
  auto s = open_store(dir, options(dir, &clock));
  auto e = s->enqueue(spec());
  ASSERT_TRUE(e.created);
  EXPECT_EQ(e.job.state, JobState::available);
  EXPECT_EQ(e.job.attempt, 0);
  auto j = s->claim("w1", 30'000);
  ASSERT_TRUE(j);
  EXPECT_EQ(j->id, e.job.id);
  EXPECT_EQ(j->state, JobState::running);
  EXPECT_EQ(j->attempt, 1);
  EXPECT_EQ(j->worker_id, "w1");
  EXPECT_EQ(*j->lease_until, clock.now() + 30'000);
  EXPECT_FALSE(s->claim("w2", 30'000)) << "a running job must not be claimed twice";
  store::JobRecords r;
  r.result_json = R"({"ok":true})";
  s->complete(j->id, "w1", r);
  auto done = s->get_job(j->id);
  EXPECT_EQ(done->state, JobState::completed);
  EXPECT_EQ(done->result_json, R"({"ok":true})");
  EXPECT_EQ(*done->finished_at, clock.now());
  EXPECT_FALSE(done->lease_until);
  EXPECT_THROW(s->complete(j->id, "w1", r), store::LeaseLost) << "completing twice must fail";
  EXPECT_FALSE(s->claim("w1", 1000));
}

// A batch commits together, but each completion is all or nothing on its own: one whose lease
// is gone (or whose result is not JSON) is rolled back alone and reported; the others complete.
TEST_P(Queue, CompleteBatchCommitsTogetherAndFailsEachCompletionAlone) {
  TempDir dir;
  StepClock clock;
  auto s = open_store(dir, options(dir, &clock));
  std::vector<std::int64_t> ids;
  for (int i = 0; i < 4; ++i) {
    s->enqueue(spec());
    ids.push_back(s->claim("w" + std::to_string(i), 30'000)->id);
  }
  const std::size_t audit_before = s->list_audit(100000).size();
  store::JobRecords ok, follow, bad;
  ok.result_json = R"({"ok":true})";
  follow.result_json = "{}";
  follow.follow_ups.push_back(spec("later"));
  bad.result_json = "not json";
  std::vector<store::Completion> batch = {{ids[0], "w0", &ok},
                                          {ids[1], "someone else", &follow},  // not its lease
                                          {ids[2], "w2", &follow},
                                          {ids[3], "w3", &bad}};
  auto out = s->complete_batch(batch);
  ASSERT_EQ(out.size(), 4u);
  EXPECT_FALSE(out[0].error);
  EXPECT_FALSE(out[2].error);
  ASSERT_TRUE(out[1].error);
  EXPECT_THROW(std::rethrow_exception(out[1].error), store::LeaseLost);
  ASSERT_TRUE(out[3].error);
  EXPECT_THROW(std::rethrow_exception(out[3].error), store::StoreError);
  EXPECT_EQ(s->get_job(ids[0])->state, JobState::completed);
  EXPECT_EQ(s->get_job(ids[0])->result_json, R"({"ok":true})");
  EXPECT_EQ(s->get_job(ids[1])->state, JobState::running);
  EXPECT_EQ(s->get_job(ids[2])->state, JobState::completed);
  EXPECT_EQ(s->get_job(ids[3])->state, JobState::running);
  // One follow-up (of the completion that went through) and its audit entries only.
  store::JobFilter f;
  f.kind = "later";
  EXPECT_EQ(s->list_jobs(f).size(), 1u);
  EXPECT_EQ(s->list_audit(100000).size(), audit_before + 3);  // 2 x job.complete + 1 x job.enqueue
}

TEST_P(Queue, RejectsBadSpecs) {
  TempDir dir;
  auto s = open_store(dir, options(dir));
  EXPECT_THROW(s->enqueue(spec("")), store::StoreError);
  EXPECT_THROW(s->enqueue(spec("noop", 0, 0)), store::StoreError);
  JobSpec bad = spec();
  bad.payload_json = "{not json";
  EXPECT_THROW(s->enqueue(bad), store::StoreError);
  EXPECT_EQ(s->list_jobs().size(), 0u);
}

TEST_P(Queue, ConcurrentClaimsGiveEachJobToExactlyOneWorker) {
  TempDir dir;
  auto o = options(dir);
  const int kJobs = 300;
  {
    auto s = open_store(dir, o);
    for (int i = 0; i < kJobs; ++i) s->enqueue(spec());
  }
  std::mutex m;
  std::map<std::int64_t, int> claimed;  // job id -> times claimed
  auto worker = [&](store::Store& st, const std::string& id) {
    while (auto j = st.claim(id, 60'000)) {
      {
        std::lock_guard<std::mutex> l(m);
        ++claimed[j->id];
      }
      st.complete(j->id, id, {});
    }
  };
  // Four threads with their own connections (the cross-connection lock is what is tested), plus
  // two threads sharing one Store object.
  std::vector<std::unique_ptr<store::Store>> own;
  for (int i = 0; i < 4; ++i) own.push_back(open_store(dir, o));
  auto shared = open_store(dir, o);
  std::vector<std::thread> ts;
  for (int i = 0; i < 4; ++i) ts.emplace_back(worker, std::ref(*own[i]), "own-" + std::to_string(i));
  for (int i = 0; i < 2; ++i) ts.emplace_back(worker, std::ref(*shared), "shared-" + std::to_string(i));
  for (auto& t : ts) t.join();
  ASSERT_EQ(claimed.size(), static_cast<std::size_t>(kJobs));
  for (auto& [id, n] : claimed) EXPECT_EQ(n, 1) << "job " << id;
  auto c = shared->counts();
  EXPECT_EQ(c.completed, kJobs);
  EXPECT_EQ(c.available + c.running + c.retryable + c.discarded, 0);
}

TEST_P(Queue, ExpiredLeaseIsClaimableAgainAndOldWorkerLosesIt) {
  TempDir dir;
  StepClock clock;
  auto s = open_store(dir, options(dir, &clock));
  auto id = s->enqueue(spec()).job.id;
  auto j = s->claim("w1", 1000);
  ASSERT_TRUE(j);
  clock.advance(800);
  s->heartbeat(id, "w1", 1000);  // lease now until +1800
  clock.advance(900);
  EXPECT_FALSE(s->claim("w2", 1000)) << "heartbeat must keep the lease alive";
  clock.advance(200);  // past the lease
  auto again = s->claim("w2", 1000);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->id, id);
  EXPECT_EQ(again->attempt, 2);
  EXPECT_EQ(again->worker_id, "w2");
  ASSERT_EQ(again->errors.size(), 1u);
  EXPECT_NE(again->errors[0].error.find("lease expired"), std::string::npos);
  EXPECT_THROW(s->heartbeat(id, "w1", 1000), store::LeaseLost);
  EXPECT_THROW(s->complete(id, "w1", {}), store::LeaseLost);
  EXPECT_THROW(s->fail(id, "w1", "x"), store::LeaseLost);
  s->complete(id, "w2", {});
  EXPECT_EQ(s->get_job(id)->state, JobState::completed);
}

TEST_P(Queue, KillStormDoesNotUseUpAttempts) {
  TempDir dir;
  StepClock clock;
  auto s = open_store(dir, options(dir, &clock));
  auto id = s->enqueue(spec("noop", 0, 2)).job.id;
  for (int kill = 0; kill < 10; ++kill) {  // ten workers die holding the job
    ASSERT_TRUE(s->claim("w" + std::to_string(kill), 100)) << "kill " << kill;
    clock.advance(101);
    EXPECT_EQ(s->reap_expired_leases(), 1);
    EXPECT_EQ(s->get_job(id)->state, JobState::available) << "kill " << kill;
  }
  // Its own failures still count: with max_attempts 2, one failure is retried, the second discards.
  ASSERT_TRUE(s->claim("w", 100));
  EXPECT_EQ(s->fail(id, "w", "first"), JobState::retryable);
  clock.advance(1'000'000);
  ASSERT_TRUE(s->claim("w", 100));
  EXPECT_EQ(s->fail(id, "w", "second"), JobState::discarded);
  auto j = s->get_job(id);
  EXPECT_EQ(j->rescues, 10);
  EXPECT_EQ(j->attempt, 12);
  EXPECT_EQ(j->errors.size(), 12u);
}

TEST_P(Queue, JobThatKeepsKillingItsWorkerIsDiscardedAfterMaxRescues) {
  TempDir dir;
  StepClock clock;
  auto s = open_store(dir, options(dir, &clock));
  auto id = s->enqueue(spec("noop", 0, 5)).job.id;
  for (int kill = 0; kill < store::kMaxRescues; ++kill) {
    ASSERT_TRUE(s->claim("w", 100)) << "kill " << kill;
    clock.advance(101);
    EXPECT_EQ(s->reap_expired_leases(), 1);
  }
  auto j = s->get_job(id);
  EXPECT_EQ(j->state, JobState::discarded);
  EXPECT_EQ(j->rescues, store::kMaxRescues);
  ASSERT_EQ(j->errors.size(), static_cast<size_t>(store::kMaxRescues));
  EXPECT_NE(j->errors.back().error.find("rescue 20 of at most 20"), std::string::npos) << j->errors.back().error;
  EXPECT_FALSE(s->claim("w", 100));
  // An operator's retry gives it a fresh rescue allowance.
  EXPECT_TRUE(s->retry(id, "admin"));
  EXPECT_EQ(s->get_job(id)->rescues, 0);
  ASSERT_TRUE(s->claim("w", 100));
  clock.advance(101);
  EXPECT_EQ(s->reap_expired_leases(), 1);
  EXPECT_EQ(s->get_job(id)->state, JobState::available);
}

TEST_P(Queue, RetriesWithExponentialBackoffAndJitterThenDiscardsKeepingErrors) {
  TempDir dir;
  StepClock clock;
  auto o = options(dir, &clock);
  o.backoff.base = 1000;
  o.backoff.max = 1'000'000;
  o.backoff.jitter = 0.1;
  auto s = open_store(dir, o);
  auto id = s->enqueue(spec("noop", 0, 4)).job.id;
  store::Millis expected_delay = 1000;
  for (int attempt = 1; attempt <= 3; ++attempt) {
    auto j = s->claim("w", 10'000);
    ASSERT_TRUE(j) << attempt;
    EXPECT_EQ(j->attempt, attempt);
    EXPECT_EQ(s->fail(id, "w", "boom " + std::to_string(attempt)), JobState::retryable);
    auto r = s->get_job(id);
    store::Millis delay = r->scheduled_at - clock.now();
    EXPECT_GE(delay, expected_delay) << attempt;
    EXPECT_LT(delay, expected_delay + expected_delay / 10 + 1) << attempt;
    clock.advance(delay - 1);
    EXPECT_FALSE(s->claim("w", 10'000)) << "claimed before its backoff ended, attempt " << attempt;
    clock.advance(1);
    expected_delay *= 2;
  }
  ASSERT_TRUE(s->claim("w", 10'000));
  EXPECT_EQ(s->fail(id, "w", "boom 4"), JobState::discarded);
  auto j = s->get_job(id);
  EXPECT_EQ(j->state, JobState::discarded);
  EXPECT_EQ(j->attempt, 4);
  ASSERT_EQ(j->errors.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(j->errors[i].attempt, i + 1);
    EXPECT_EQ(j->errors[i].error, "boom " + std::to_string(i + 1));
  }
  EXPECT_TRUE(j->finished_at);
  clock.advance(10'000'000);
  EXPECT_FALSE(s->claim("w", 1000));
}

TEST_P(Queue, JitterSpreadsRetries) {
  TempDir dir;
  StepClock clock;
  auto o = options(dir, &clock);
  o.backoff.base = 10'000;
  o.backoff.jitter = 0.5;
  auto s = open_store(dir, o);
  std::set<store::Millis> delays;
  for (int i = 0; i < 20; ++i) {
    auto id = s->enqueue(spec()).job.id;
    ASSERT_TRUE(s->claim("w", 1000));
    s->fail(id, "w", "e");
    delays.insert(s->get_job(id)->scheduled_at - clock.now());
  }
  EXPECT_GT(delays.size(), 15u) << "jitter should make retry times differ";
  for (auto d : delays) {
    EXPECT_GE(d, 10'000);
    EXPECT_LT(d, 15'000);
  }
}

TEST_P(Queue, NonRetryableFailureDiscardsAtOnce) {
  TempDir dir;
  auto s = open_store(dir, options(dir));
  auto id = s->enqueue(spec("noop", 0, 10)).job.id;
  ASSERT_TRUE(s->claim("w", 1000));
  EXPECT_EQ(s->fail(id, "w", "malformed mesh", false), JobState::discarded);
  EXPECT_EQ(s->get_job(id)->errors.at(0).error, "malformed mesh");
}

TEST_P(Queue, CancelAndRetry) {
  TempDir dir;
  StepClock clock;
  auto s = open_store(dir, options(dir, &clock));
  auto a = s->enqueue(spec()).job.id;
  EXPECT_TRUE(s->cancel(a));
  EXPECT_EQ(s->get_job(a)->state, JobState::cancelled);
  EXPECT_FALSE(s->claim("w", 1000)) << "cancelled job claimed";
  EXPECT_FALSE(s->cancel(a)) << "already cancelled";
  EXPECT_TRUE(s->retry(a));
  EXPECT_EQ(s->get_job(a)->state, JobState::available);

  // Cancelling a running job: its worker finds out and cannot complete it.
  auto j = s->claim("w", 1000);
  ASSERT_TRUE(j);
  EXPECT_TRUE(s->cancel(j->id));
  EXPECT_THROW(s->heartbeat(j->id, "w", 1000), store::LeaseLost);
  EXPECT_THROW(s->complete(j->id, "w", {}), store::LeaseLost);
  EXPECT_EQ(s->get_job(j->id)->state, JobState::cancelled);

  // Completed jobs cannot be cancelled or retried.
  auto b = s->enqueue(spec()).job.id;
  ASSERT_TRUE(s->claim("w", 1000));
  s->complete(b, "w", {});
  EXPECT_FALSE(s->cancel(b));
  EXPECT_FALSE(s->retry(b));
  EXPECT_EQ(s->get_job(b)->state, JobState::completed);

  // Retrying a discarded job grants one more attempt.
  auto c = s->enqueue(spec("noop", 0, 1)).job.id;
  ASSERT_TRUE(s->claim("w", 1000));
  EXPECT_EQ(s->fail(c, "w", "x"), JobState::discarded);
  EXPECT_TRUE(s->retry(c));
  auto cj = s->claim("w", 1000);
  ASSERT_TRUE(cj);
  EXPECT_EQ(cj->attempt, 2);
  EXPECT_EQ(cj->max_attempts, 2);
  EXPECT_EQ(s->fail(c, "w", "y"), JobState::discarded);
}

TEST_P(Queue, PrioritiesThenScheduleThenId) {
  TempDir dir;
  StepClock clock;
  auto s = open_store(dir, options(dir, &clock));
  auto low = s->enqueue(spec("noop", -5)).job.id;
  auto mid1 = s->enqueue(spec("noop", 0)).job.id;
  auto high = s->enqueue(spec("noop", 10)).job.id;
  auto mid2 = s->enqueue(spec("noop", 0)).job.id;
  JobSpec later = spec("noop", 100);
  later.scheduled_at = clock.now() + 5000;
  auto future = s->enqueue(later).job.id;
  std::vector<std::int64_t> order;
  while (auto j = s->claim("w", 1'000'000)) order.push_back(j->id);
  EXPECT_EQ(order, (std::vector<std::int64_t>{high, mid1, mid2, low}));
  clock.advance(5000);
  auto f = s->claim("w", 1000);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->id, future);
  EXPECT_EQ(s->next_scheduled(), std::nullopt);
}

TEST_P(Queue, IdempotencyKeyReturnsTheExistingJob) {
  TempDir dir;
  auto s = open_store(dir, options(dir));
  auto a = s->enqueue(spec("protect", 0, 5, "asset-abc/customer-1"));
  auto b = s->enqueue(spec("protect", 7, 5, "asset-abc/customer-1"));
  EXPECT_TRUE(a.created);
  EXPECT_FALSE(b.created);
  EXPECT_EQ(a.job.id, b.job.id);
  EXPECT_EQ(b.job.priority, 0) << "the duplicate must not change the existing job";
  // Still deduplicated after the job completed.
  ASSERT_TRUE(s->claim("w", 1000));
  s->complete(a.job.id, "w", {});
  auto c = s->enqueue(spec("protect", 0, 5, "asset-abc/customer-1"));
  EXPECT_FALSE(c.created);
  EXPECT_EQ(c.job.state, JobState::completed);
  EXPECT_EQ(s->list_jobs().size(), 1u);
  // Jobs without a key are never deduplicated.
  EXPECT_TRUE(s->enqueue(spec()).created);
  EXPECT_TRUE(s->enqueue(spec()).created);
}

TEST_P(Queue, KindFilterAndRelease) {
  TempDir dir;
  auto s = open_store(dir, options(dir));
  auto p = s->enqueue(spec("protect")).job.id;
  auto d = s->enqueue(spec("detect", 5)).job.id;
  auto j = s->claim("w", 1000, {"protect"});
  ASSERT_TRUE(j);
  EXPECT_EQ(j->id, p);
  EXPECT_FALSE(s->claim("w2", 1000, {"protect"}));
  s->release(p, "w");  // graceful shutdown: back to available, attempt not spent
  auto again = s->claim("w3", 1000, {"protect", "other"});
  ASSERT_TRUE(again);
  EXPECT_EQ(again->id, p);
  EXPECT_EQ(again->attempt, 1);
  auto dj = s->claim("w4", 1000);
  ASSERT_TRUE(dj);
  EXPECT_EQ(dj->id, d);
}

TEST(QueueRules, TransitionTable) {
  using S = JobState;
  EXPECT_TRUE(store::job_transition_allowed(S::available, S::running));
  EXPECT_TRUE(store::job_transition_allowed(S::running, S::completed));
  EXPECT_TRUE(store::job_transition_allowed(S::running, S::retryable));
  EXPECT_TRUE(store::job_transition_allowed(S::retryable, S::running));
  EXPECT_TRUE(store::job_transition_allowed(S::discarded, S::available));
  EXPECT_FALSE(store::job_transition_allowed(S::completed, S::available));
  EXPECT_FALSE(store::job_transition_allowed(S::completed, S::cancelled));
  EXPECT_FALSE(store::job_transition_allowed(S::available, S::completed));
  EXPECT_FALSE(store::job_transition_allowed(S::discarded, S::running));
  for (auto st : {S::available, S::running, S::completed, S::retryable, S::discarded, S::cancelled})
    EXPECT_EQ(store::job_state_from_string(store::to_string(st)), st);
  EXPECT_THROW(store::job_state_from_string("bogus"), store::StoreError);
}

TEST(QueueOnSqlite, RowsInsertedDirectlyByAnotherSystemFollowTheContract) {
  // docs/queue-contract.md: a PDM system inserts (kind, payload_json[, priority, max_attempts,
  // idempotency_key, scheduled_at]) and the defaults make the row claimable.
  TempDir dir;
  auto o = options(dir);
  auto s = store::open_sqlite_store(o);
  raw_query(o.db_path,
            "INSERT INTO jobs(kind, payload_json, priority, idempotency_key) "
            "VALUES('protect', '{\"file\":\"/pdm/part.stl\",\"customers\":[\"acme\"]}', 3, 'pdm-42')");
  auto j = s->claim("w", 1000);
  ASSERT_TRUE(j);
  EXPECT_EQ(j->kind, "protect");
  EXPECT_EQ(j->priority, 3);
  EXPECT_EQ(j->max_attempts, 5);
  EXPECT_EQ(j->idempotency_key, "pdm-42");
  // A duplicate insert with the same key is refused by the database, and enqueue() sees it.
  std::string err;
  raw_query(o.db_path, "INSERT INTO jobs(kind, idempotency_key) VALUES('protect', 'pdm-42')", &err);
  EXPECT_NE(err.find("UNIQUE"), std::string::npos) << err;
  EXPECT_FALSE(s->enqueue(spec("protect", 0, 5, "pdm-42")).created);
  // Malformed rows are refused by CHECK constraints, not discovered later by a worker.
  raw_query(o.db_path, "INSERT INTO jobs(kind, payload_json) VALUES('protect', 'not json')", &err);
  EXPECT_NE(err.find("CHECK"), std::string::npos) << err;
  raw_query(o.db_path, "INSERT INTO jobs(kind, state) VALUES('protect', 'weird')", &err);
  EXPECT_NE(err.find("CHECK"), std::string::npos) << err;
  raw_query(o.db_path, "INSERT INTO jobs(kind, state) VALUES('protect', 'running')", &err);
  EXPECT_NE(err.find("CHECK"), std::string::npos) << "running without a lease: " << err;
}

TEST_P(Queue, NextScheduledTellsASleepingWorkerWhenToWake) {
  TempDir dir;
  StepClock clock;
  auto o = options(dir, &clock);
  o.backoff.base = 4000;
  o.backoff.jitter = 0;
  auto s = open_store(dir, o);
  EXPECT_EQ(s->next_scheduled(), std::nullopt);
  auto id = s->enqueue(spec()).job.id;
  EXPECT_EQ(s->next_scheduled(), clock.now());
  ASSERT_TRUE(s->claim("w", 1000));
  EXPECT_EQ(s->next_scheduled(), std::nullopt) << "running jobs are not waiting";
  s->fail(id, "w", "later");
  EXPECT_EQ(s->next_scheduled(), clock.now() + 4000);
}

// Reads (opening a current store, listing jobs, copies, detections) never take the write lock:
// they work while another program holds a write transaction.
TEST(QueueOnSqlite, ReadsWorkWhileAnotherConnectionHoldsTheWriteLock) {
  TempDir dir;
  store::StoreOptions o;
  o.db_path = dir / "q.db";
  {
    auto st = store::open_sqlite_store(o);
    st->enqueue(spec());
  }
  store::sql::Db writer(o.db_path, 100);
  writer.exec("BEGIN IMMEDIATE", "begin");
  writer.exec("INSERT INTO jobs(kind) VALUES('noop')", "insert");
  o.busy_timeout_ms = 200;
  std::unique_ptr<store::Store> reader;
  ASSERT_NO_THROW(reader = store::open_sqlite_store(o));
  EXPECT_NO_THROW({
    EXPECT_EQ(reader->list_jobs({}).size(), 1u);
    reader->list_copies();
    reader->list_detections();
    reader->list_customers();
    reader->list_audit();
    reader->counts();
  });
  writer.exec("COMMIT", "commit");
  EXPECT_EQ(reader->list_jobs({}).size(), 2u);
}

// The fleet's nodes and leader lease (meshmark fleet status): one leader at a time, on the
// store's clock; a leader that stops beating is replaced once its lease has run out, one that
// leaves gives the lease up at once.
TEST_P(Queue, OneNodeLeadsUntilItsLeaseRunsOutOrItLeaves) {
  TempDir dir;
  StepClock clock;
  auto a = open_store(dir, options(dir, &clock));
  auto b = open_store(dir, options(dir, &clock));
  EXPECT_TRUE(a->beat_node("host-a:11", 2, 10'000));
  EXPECT_FALSE(b->beat_node("host-b:22", 4, 10'000)) << "the lease is a's";
  clock.advance(6'000);
  EXPECT_TRUE(a->beat_node("host-a:11", 2, 10'000)) << "the leader renews its own lease";
  EXPECT_FALSE(b->beat_node("host-b:22", 4, 10'000));
  auto nodes = b->list_nodes();
  ASSERT_EQ(nodes.size(), 2u);
  EXPECT_EQ(nodes[0].name, "host-a:11");
  EXPECT_TRUE(nodes[0].leader);
  EXPECT_EQ(nodes[0].leader_until, clock.now() + 10'000);
  EXPECT_EQ(nodes[0].workers, 2);
  EXPECT_EQ(nodes[0].started_at, clock.now() - 6'000);
  EXPECT_EQ(nodes[1].name, "host-b:22");
  EXPECT_FALSE(nodes[1].leader);
  EXPECT_EQ(nodes[1].workers, 4);
  EXPECT_EQ(nodes[1].seen_at, clock.now());
  // a is killed: it beats no more. Within the lease b still waits; after it, b leads.
  clock.advance(9'999);
  EXPECT_FALSE(b->beat_node("host-b:22", 4, 10'000));
  clock.advance(2);
  EXPECT_TRUE(b->beat_node("host-b:22", 4, 10'000)) << "replaced once the lease ran out";
  EXPECT_FALSE(a->beat_node("host-a:11", 2, 10'000)) << "a stale leader does not take it back";
  nodes = a->list_nodes();
  ASSERT_EQ(nodes.size(), 2u);
  EXPECT_FALSE(nodes[0].leader);
  EXPECT_TRUE(nodes[1].leader);
  // b stops cleanly: the lease is free at once.
  b->leave_fleet("host-b:22");
  EXPECT_EQ(a->list_nodes().size(), 1u);
  EXPECT_TRUE(a->beat_node("host-a:11", 2, 10'000));
  // Nodes gone for a day are forgotten by the leader.
  auto c = open_store(dir, options(dir, &clock));
  EXPECT_FALSE(c->beat_node("host-c:33", 1, 10'000));
  clock.advance(25LL * 3600 * 1000);
  EXPECT_TRUE(a->beat_node("host-a:11", 2, 10'000));
  nodes = a->list_nodes();
  ASSERT_EQ(nodes.size(), 1u);
  EXPECT_EQ(nodes[0].name, "host-a:11");
}

// Finished jobs past the retention go, oldest first and in batches; a job that issued a copy or
// recorded a detection stays with its records, as do running and recent ones.
TEST_P(Queue, PruningDeletesOldFinishedJobsThatNoRecordPointsAt) {
  TempDir dir;
  StepClock clock;
  auto s = open_store(dir, options(dir, &clock));
  const auto acme = s->add_customer("acme");
  const auto asset = s->put_asset_bytes({1, 2, 3}, "part.stl");
  auto finish = [&](const std::string& idem, const store::JobRecords& r) {
    const auto id = s->enqueue(spec("noop", 0, 5, idem)).job.id;
    EXPECT_EQ(s->claim("w", 60000)->id, id);
    s->complete(id, "w", r);
    clock.advance(10);
    return id;
  };
  store::JobRecords with_copy;
  store::NewCopy c;
  c.asset_id = asset.id;
  c.customer_id = acme.id;
  c.key_version = 1;
  c.idempotency_key = "copy";
  c.nonce = std::vector<std::uint8_t>(24, 1);
  c.payload_hex = "00";
  with_copy.copies = {c};
  store::JobRecords with_detection;
  store::NewDetection d;
  d.suspect_sha256 = asset.sha256;
  d.verdict = "no_match";
  with_detection.detections = {d};

  const auto old1 = finish("old1", {});
  const auto issued = finish("issued", with_copy);
  const auto detected = finish("detected", with_detection);
  const auto old2 = finish("old2", {});
  const auto discarded = s->enqueue(spec("noop", 0, 1, "discarded")).job.id;
  ASSERT_EQ(s->claim("w", 60000)->id, discarded);
  EXPECT_EQ(s->fail(discarded, "w", "bad input", false), JobState::discarded);
  const auto cancelled = s->enqueue(spec("noop", 0, 5, "cancelled")).job.id;
  EXPECT_TRUE(s->cancel(cancelled));
  const auto running = s->enqueue(spec("noop", 0, 5, "running")).job.id;
  ASSERT_EQ(s->claim("w", 60000)->id, running);
  clock.advance(1000);
  const store::Millis cutoff = clock.now();
  clock.advance(1000);
  const auto recent = finish("recent", {});
  const auto waiting = s->enqueue(spec("noop", 0, 5, "waiting")).job.id;

  EXPECT_EQ(s->prune_jobs(cutoff, 1), 1);
  EXPECT_FALSE(s->get_job(old1)) << "the oldest goes first";
  EXPECT_TRUE(s->get_job(old2));
  EXPECT_EQ(s->prune_jobs(cutoff, 100), 3);
  for (auto id : {old2, discarded, cancelled}) EXPECT_FALSE(s->get_job(id)) << id;
  for (auto id : {issued, detected, running, waiting, recent}) EXPECT_TRUE(s->get_job(id)) << id;
  EXPECT_EQ(s->prune_jobs(cutoff, 100), 0);
  EXPECT_EQ(s->list_copies().at(0).job_id, issued);
  EXPECT_EQ(s->detection_of_job(detected)->verdict, "no_match");
}

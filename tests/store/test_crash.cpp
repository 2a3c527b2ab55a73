// Kill -9 a worker process in the middle of claiming and completing, several times, then check
// that the database is intact and every completed job wrote its records exactly once. On each
// backend: SQLite's file, and PostgreSQL, whose server sees the killed worker's session vanish.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include "store_backends.h"
#include "store_test_util.h"

using namespace mm;
using namespace mm::test;

namespace {

constexpr store::Millis kLease = 300;

// The child: claim, write two records with the completion, repeat until the queue is empty.
[[noreturn]] void worker_process(BackendStores& stores, const TempDir& dir, const store::StoreOptions& o,
                                 const std::string& worker) {
  try {
    auto s = stores.open_store(dir, o);
    auto acme = s->find_customer("acme");
    auto asset = s->list_assets().at(0);
    for (;;) {
      auto j = s->claim(worker, kLease);
      if (!j) {
        if (s->counts().running == 0) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));  // wait for expired leases
        continue;
      }
      // The job's work: a kill often lands while the job is held (claims commit without fsync,
      // so without it the claim-to-completion window is a few microseconds).
      std::this_thread::sleep_for(std::chrono::microseconds(500));
      store::JobRecords r;
      store::NewCopy c;
      c.asset_id = asset.id;
      c.customer_id = acme->id;
      c.key_version = 1;
      c.idempotency_key = j->idempotency_key;
      c.nonce = std::vector<std::uint8_t>(24, static_cast<std::uint8_t>(j->id));
      c.payload_hex = "00";
      r.copies = {c};
      store::NewDetection d;
      d.suspect_sha256 = asset.sha256;
      d.verdict = "crash-test";
      r.detections = {d};
      r.result_json = "{\"job\":" + std::to_string(j->id) + "}";
      s->complete(j->id, worker, r);
    }
    _exit(0);
  } catch (const std::exception& e) {
    fprintf(stderr, "worker %s: %s\n", worker.c_str(), e.what());
    _exit(1);
  }
}

class Crash : public BackendTest {};
MM_BACKENDS(Crash);

}  // namespace

TEST_P(Crash, KillNineMidBatchThenEveryJobCompletesExactlyOnce) {
  TempDir dir;
  auto o = options(dir);
  const int kJobs = 400;
  const auto query = [&](const std::string& sql) { return stores().raw(dir, sql); };
  {
    auto s = open_store(dir, o);
    s->add_customer("acme");
    s->put_asset_bytes({1, 2, 3}, "part.stl");
    for (int i = 0; i < kJobs; ++i)
      s->enqueue({"protect", "{}", 0, 100, "job-" + std::to_string(i), {}});
  }
  auto completed = [&] {
    return std::stoi(query("SELECT COUNT(*) FROM jobs WHERE state = 'completed'")[0]);
  };
  int kills = 0, orphaned = 0;  // kills that left a job running under the dead worker
  for (int round = 0; round < 12 && (kills < 3 || orphaned < 1); ++round) {
    int before = completed();
    if (before == kJobs) break;
    pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) worker_process(stores(), dir, o, "crash-worker-" + std::to_string(round));
    // Let it complete some jobs, then kill it without warning, mid-work.
    auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (completed() < before + 25 && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    std::this_thread::sleep_for(std::chrono::microseconds(700 * (round + 1)));
    kill(pid, SIGKILL);
    int status = 0;
    waitpid(pid, &status, 0);
    if (WIFSIGNALED(status)) ++kills;
    if (query("SELECT COUNT(*) FROM jobs WHERE state = 'running'")[0] != "0") ++orphaned;
  }
  EXPECT_GE(kills, 3) << "the worker should have been killed mid-batch";
  ASSERT_GE(orphaned, 1) << "no kill landed while a job was held; the test proved nothing";
  {
    // After the crashes the database is intact.
    auto s = open_store(dir, o);
    EXPECT_TRUE(s->integrity_ok());
  }
  // A last worker finishes the batch (it reclaims the jobs whose worker died, after the lease).
  pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) worker_process(stores(), dir, o, "final-worker");
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);

  auto s = open_store(dir, o);
  EXPECT_TRUE(s->integrity_ok());
  if (GetParam() == Backend::sqlite) EXPECT_EQ(query("PRAGMA integrity_check")[0], "ok");
  EXPECT_EQ(s->counts().completed, kJobs);
  // Exactly one copy and one detection per job, each pointing at its job.
  EXPECT_EQ(query("SELECT COUNT(*) FROM issued_copies")[0], std::to_string(kJobs));
  EXPECT_EQ(query("SELECT COUNT(*) FROM detections")[0], std::to_string(kJobs));
  EXPECT_EQ(query("SELECT COUNT(*) FROM jobs j WHERE (SELECT COUNT(*) FROM issued_copies c "
                  "WHERE c.job_id = j.id AND c.idempotency_key = j.idempotency_key) <> 1 "
                  "OR (SELECT COUNT(*) FROM detections d WHERE d.job_id = j.id) <> 1")[0],
            "0");
  // Jobs whose worker was killed were retried: at least one has an attempt > 1 and a lease error.
  EXPECT_NE(query("SELECT COUNT(*) FROM jobs WHERE attempt > 1")[0], "0");
}

// A pool of N worker threads over the store's queue. Each thread has its own Store connection for
// its handlers, claims one job at a time with a lease (on one connection the workers share), runs
// its handler, and completes it with its records or fails it (retry with backoff, or discard for
// PermanentError). Completions go through one completer thread that commits whatever has
// gathered in one durable transaction (group commit, River's batch completer): the worker goes on
// to its next job meanwhile. A crash before that commit leaves the job running under a lease
// that expires, and it is run again, as after a crash during the job itself. A handler that
// throws never takes its thread down: one bad file never stops the others. A separate heartbeat
// thread extends the leases of running jobs every heartbeat interval.
//
// Shutdown (drain): stop_claiming(), then wait_idle(deadline); jobs still running after the
// deadline are released (back to available without spending an attempt) by release_running().
#pragma once
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "service/config.h"
#include "service/handlers.h"
#include "store/store.h"

namespace mm::service {

using StoreFactory = std::function<std::unique_ptr<store::Store>()>;

struct PoolStats {
  std::int64_t completed = 0, failed = 0, discarded = 0, lease_lost = 0, released = 0, cancelled = 0;
};

class WorkerPool {
 public:
  // config() is read at every claim, so a SIGHUP reload reaches the next job.
  WorkerPool(int workers, StoreFactory stores, HandlerMap handlers,
             std::function<std::shared_ptr<const Config>()> config, std::string id_prefix,
             bool exit_when_empty = false);
  ~WorkerPool();

  void start();
  void notify();         // wake idle workers (a job was just submitted)
  void stop_claiming();  // drain: workers exit after their current job
  // Waits until every worker has exited and every completion is recorded, or the deadline
  // passes; true if so.
  bool wait_idle(std::chrono::steady_clock::time_point deadline);
  // After a missed deadline: gives the running jobs back to the queue. Returns how many.
  int release_running();
  void join();  // only when all workers exited (wait_idle returned true) or exit_when_empty
  PoolStats stats() const;
  int running_jobs() const;

 private:
  void worker_main(int index);
  void heartbeat_main();
  void completer_main();
  struct PendingCompletion;
  // Hands a finished job to the completer (waiting only while too many are queued already).
  void submit_completion(std::unique_ptr<PendingCompletion> p);
  void record_completion(const PendingCompletion& p, const store::CompletionOutcome& o);
  std::string lease_lost_outcome(store::Store& st, const store::Job& job, const store::JobRecords& records,
                                 const store::LeaseLost& e);
  void count_outcome(const std::string& outcome);  // under m_
  void stop_completer();  // after the workers: commits what is left, then ends

  int workers_;
  StoreFactory stores_;
  HandlerMap handlers_;
  std::function<std::shared_ptr<const Config>()> config_;
  std::string id_prefix_;
  bool exit_when_empty_;

  std::atomic<bool> stop_{false};
  std::atomic<int> alive_{0};
  mutable std::mutex m_;
  std::condition_variable cv_;       // idle workers wait here
  std::condition_variable done_cv_;  // wait_idle
  std::uint64_t wakeups_ = 0;
  std::map<std::string, std::int64_t> running_;  // worker id -> job id
  PoolStats stats_;
  std::vector<std::thread> threads_;
  std::thread heartbeat_;
  std::unique_ptr<store::Store> hb_store_;
  bool heartbeat_stop_ = false;

  std::unique_ptr<store::Store> claim_store_;  // claims of every worker (serialized inside)
  std::unique_ptr<store::Store> completer_store_;
  std::thread completer_;
  std::mutex completer_m_;
  std::condition_variable completer_cv_;
  std::vector<std::unique_ptr<PendingCompletion>> pending_;
  bool completer_stop_ = false;
  int in_flight_ = 0;  // handed to the completer, not yet recorded (under m_)
};

}  // namespace mm::service

// A pool of N worker threads over the store's queue. Each thread has its own Store connection,
// claims one job at a time with a lease, runs its handler, and completes it with its records (one
// transaction) or fails it (retry with backoff, or discard for PermanentError). A handler that
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
  // Waits until every worker has exited or the deadline passes; true if all exited.
  bool wait_idle(std::chrono::steady_clock::time_point deadline);
  // After a missed deadline: gives the running jobs back to the queue. Returns how many.
  int release_running();
  void join();  // only when all workers exited (wait_idle returned true) or exit_when_empty
  PoolStats stats() const;
  int running_jobs() const;

 private:
  void worker_main(int index);
  void heartbeat_main();

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
};

}  // namespace mm::service

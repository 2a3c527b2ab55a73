// meshmarkd's main loop: drop-folder watcher, submissions, the worker pool, signals.
//
// One thread (the caller of run()) waits in poll() on a signalfd and the inotify descriptor, so
// signals are handled synchronously (the HTTP API, when configured, serves from its own threads): SIGTERM/SIGINT drain (stop claiming, let running jobs finish
// within shutdown_grace_seconds, else release them to the queue), SIGHUP reloads the config and
// logs what changed. Dropped files are moved to done/ or failed/ when their job is final.
#pragma once
#include <atomic>
#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "http/server.h"
#include "service/api.h"
#include "service/config.h"
#include "service/drop_watcher.h"
#include "service/worker_pool.h"
#include "store/store.h"

namespace mm::service {

void setup_logging(const Config& cfg);  // spdlog: stderr or log_file, level from cfg

// Opens the store of cfg.home with the master key (cfg.master_key_path(), or the environment).
std::unique_ptr<store::Store> open_store(const Config& cfg);

struct BatchSummary {
  int submitted_from_drops = 0;
  PoolStats pool;
  store::QueueCounts counts;
};

// host:pid of this process: the prefix of its workers' ids and its name in the fleet.
std::string host_prefix();

class Daemon {
 public:
  explicit Daemon(Config cfg);
  ~Daemon();
  int run();  // resident; returns the process exit code after a drain
  // meshmark run --until-empty: optional one-shot drop scan, process every claimable job, move
  // drop files, return. progress: redraw a progress line on stderr.
  BatchSummary run_until_empty(bool scan_drops, bool progress);

 private:
  std::shared_ptr<const Config> config() const;
  void reload();
  void handle_drop(const DropItem& item);
  void check_inflight();
  void finalize(const DropItem& item, const store::Job& job);
  void start_api();
  void deliver_webhooks(const Config& cfg);  // job events -> webhook delivery jobs
  // This node's beat in the store's fleet (every heartbeat_seconds); true while it holds the
  // leader lease.
  bool beat_fleet(const Config& cfg);
  // On PostgreSQL: a thread LISTENing for enqueues on any node, waking idle workers at once
  // (polling every poll_interval_ms stays the fallback). Stopped by stop_wakeups().
  void start_wakeups(const Config& cfg);
  // The leader's pruning of finished jobs past job_retention_days, at most once a minute.
  void prune_jobs(const Config& cfg);
  void stop_wakeups();

  mutable std::mutex cfg_m_;
  std::shared_ptr<const Config> cfg_;
  std::unique_ptr<store::Store> store_;
  std::unique_ptr<DropWatcher> watcher_;
  std::unique_ptr<WorkerPool> pool_;
  std::unique_ptr<store::Store> api_store_;
  std::unique_ptr<Api> api_;
  std::unique_ptr<http::Server> http_;
  std::map<std::int64_t, DropItem> inflight_;  // job id -> dropped file
  int submitted_ = 0;
  std::string node_ = host_prefix();  // host:pid, the prefix of this daemon's worker ids
  bool leader_ = false;
  std::chrono::steady_clock::time_point next_beat_{};
  std::chrono::steady_clock::time_point next_prune_{};
  std::thread wakeups_;
  std::atomic<bool> wakeups_stop_{false};
};

}  // namespace mm::service

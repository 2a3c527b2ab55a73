#include "service/worker_pool.h"

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "service/memory.h"

#include <spdlog/spdlog.h>

#include "meshio/mesh.h"

namespace mm::service {

WorkerPool::WorkerPool(int workers, StoreFactory stores, HandlerMap handlers,
                       std::function<std::shared_ptr<const Config>()> config, std::string id_prefix,
                       bool exit_when_empty)
    : workers_(workers),
      stores_(std::move(stores)),
      handlers_(std::move(handlers)),
      config_(std::move(config)),
      id_prefix_(std::move(id_prefix)),
      exit_when_empty_(exit_when_empty) {}

struct WorkerPool::PendingCompletion {
  store::Job job;
  std::string worker_id;
  store::JobRecords records;
  double seconds = 0;
};

WorkerPool::~WorkerPool() {
  stop_claiming();
  {
    std::lock_guard<std::mutex> l(m_);
    heartbeat_stop_ = true;
  }
  cv_.notify_all();
  for (auto& t : threads_)
    if (t.joinable()) t.join();
  if (heartbeat_.joinable()) heartbeat_.join();
  stop_completer();
}

void WorkerPool::start() {
  hb_store_ = stores_();
  claim_store_ = stores_();
  completer_store_ = stores_();
  completer_ = std::thread([this] { completer_main(); });
  alive_ = workers_;
  for (int i = 0; i < workers_; ++i) threads_.emplace_back([this, i] { worker_main(i); });
  heartbeat_ = std::thread([this] { heartbeat_main(); });
}

void WorkerPool::stop_completer() {
  {
    std::lock_guard<std::mutex> l(completer_m_);
    completer_stop_ = true;
  }
  completer_cv_.notify_all();
  if (completer_.joinable()) completer_.join();
}

// Takes everything that gathered while the last commit ran, commits it at once, then logs and
// counts each outcome.
void WorkerPool::completer_main() {
  for (;;) {
    std::vector<std::unique_ptr<PendingCompletion>> batch;
    {
      std::unique_lock<std::mutex> l(completer_m_);
      completer_cv_.wait(l, [this] { return completer_stop_ || !pending_.empty(); });
      if (pending_.empty()) return;  // stopped, nothing left
      batch.swap(pending_);
    }
    completer_cv_.notify_all();  // room again for workers held back
    std::vector<store::Completion> items;
    for (const auto& p : batch) items.push_back({p->job.id, p->worker_id, &p->records});
    std::vector<store::CompletionOutcome> outcomes(batch.size());
    try {
      outcomes = completer_store_->complete_batch(items);
    } catch (const std::exception&) {  // the commit failed: none of them is done
      for (auto& o : outcomes) o.error = std::current_exception();
    }
    for (std::size_t i = 0; i < batch.size(); ++i) record_completion(*batch[i], outcomes[i]);
    {
      std::lock_guard<std::mutex> l(m_);
      in_flight_ -= static_cast<int>(batch.size());
    }
    done_cv_.notify_all();
  }
}

void WorkerPool::submit_completion(std::unique_ptr<PendingCompletion> p) {
  {
    std::lock_guard<std::mutex> l(m_);
    ++in_flight_;
  }
  std::unique_lock<std::mutex> l(completer_m_);
  // Bounded: a worker waits while a few batches' worth are still waiting for their commit.
  completer_cv_.wait(l, [this] { return pending_.size() < static_cast<std::size_t>(4 * workers_ + 16); });
  pending_.push_back(std::move(p));
  l.unlock();
  completer_cv_.notify_all();
}

void WorkerPool::notify() {
  {
    std::lock_guard<std::mutex> l(m_);
    ++wakeups_;
  }
  cv_.notify_all();
}

void WorkerPool::stop_claiming() {
  stop_ = true;
  notify();
}

bool WorkerPool::wait_idle(std::chrono::steady_clock::time_point deadline) {
  std::unique_lock<std::mutex> l(m_);
  return done_cv_.wait_until(l, deadline, [this] { return alive_ == 0 && in_flight_ == 0; });
}

int WorkerPool::release_running() {
  std::map<std::string, std::int64_t> running;
  {
    std::lock_guard<std::mutex> l(m_);
    running = running_;
  }
  int n = 0;
  for (const auto& [worker, job] : running) {
    try {
      hb_store_->release(job, worker);
      spdlog::warn("job {} released by {} (shutdown deadline passed)", job, worker);
      ++n;
    } catch (const std::exception& e) {
      spdlog::warn("job {}: release failed: {}", job, e.what());
    }
  }
  std::lock_guard<std::mutex> l(m_);
  stats_.released += n;
  return n;
}

void WorkerPool::join() {
  for (auto& t : threads_)
    if (t.joinable()) t.join();
  {
    std::lock_guard<std::mutex> l(m_);
    heartbeat_stop_ = true;
  }
  cv_.notify_all();
  if (heartbeat_.joinable()) heartbeat_.join();
  stop_completer();
}

PoolStats WorkerPool::stats() const {
  std::lock_guard<std::mutex> l(m_);
  return stats_;
}

int WorkerPool::running_jobs() const {
  std::lock_guard<std::mutex> l(m_);
  return static_cast<int>(running_.size());
}

void WorkerPool::heartbeat_main() {
  std::unique_lock<std::mutex> l(m_);
  while (!heartbeat_stop_) {
    auto cfg = config_();
    cv_.wait_for(l, std::chrono::seconds(cfg->heartbeat_seconds), [this] { return heartbeat_stop_; });
    if (heartbeat_stop_) break;
    auto running = running_;
    l.unlock();
    for (const auto& [worker, job] : running) {
      try {
        hb_store_->heartbeat(job, worker, store::Millis(cfg->lease_seconds) * 1000);
      } catch (const store::LeaseLost&) {
        // The worker may have completed the job since the snapshot: only a lease lost while it
        // still runs the job is worth a warning.
        std::lock_guard<std::mutex> g(m_);
        const auto still = running_.find(worker);
        if (still != running_.end() && still->second == job)
          spdlog::warn("job {}: lease lost by {} (reclaimed or cancelled)", job, worker);
      } catch (const std::exception& e) {
        spdlog::warn("job {}: heartbeat failed: {}", job, e.what());
      }
    }
    l.lock();
  }
}

namespace {

// The output files a job's records name (issued copies' outputs), removed; how many were.
int remove_outputs(const store::JobRecords& records) {
  int n = 0;
  for (const auto& c : records.copies) {
    const auto outputs = nlohmann::json::parse(c.outputs_json, nullptr, false);
    if (!outputs.is_object()) continue;
    for (const auto& f : outputs.value("files", nlohmann::json::array())) {
      std::error_code ec;
      if (f.contains("path") && f["path"].is_string() && std::filesystem::remove(f["path"].get<std::string>(), ec)) ++n;
    }
  }
  return n;
}

}  // namespace

// The job was no longer ours to complete or fail. Cancelled between its last step and its
// completion: nothing was issued, so the files it wrote go too.
std::string WorkerPool::lease_lost_outcome(store::Store& st, const store::Job& job, const store::JobRecords& records,
                                           const store::LeaseLost& e) {
  const auto now = st.get_job(job.id);
  if (now && now->state == store::JobState::cancelled) {
    const int removed = remove_outputs(records);
    spdlog::info("job {} {} cancelled before it completed; {} output file(s) removed", job.id, job.kind, removed);
    return "cancelled";
  }
  spdlog::warn("job {}: result dropped, lease lost: {}", job.id, e.what());
  return "lease_lost";
}

void WorkerPool::count_outcome(const std::string& outcome) {
  if (outcome == "completed") ++stats_.completed;
  else if (outcome == "discarded") ++stats_.discarded;
  else if (outcome == "lease_lost") ++stats_.lease_lost;
  else if (outcome == "cancelled") ++stats_.cancelled;
  else ++stats_.failed;
}

void WorkerPool::record_completion(const PendingCompletion& p, const store::CompletionOutcome& o) {
  std::string outcome = "completed";
  if (!o.error) {
    spdlog::info("job {} {} completed in {:.2f} s (attempt {})", p.job.id, p.job.kind, p.seconds, p.job.attempt);
  } else {
    try {
      std::rethrow_exception(o.error);
    } catch (const store::LeaseLost& e) {
      outcome = lease_lost_outcome(*completer_store_, p.job, p.records, e);
    } catch (const std::exception& e) {
      outcome = "failed";
      spdlog::error("job {}: cannot record outcome: {}", p.job.id, e.what());
    }
  }
  std::lock_guard<std::mutex> l(m_);
  count_outcome(outcome);
}

void WorkerPool::worker_main(int index) {
  const std::string worker_id = id_prefix_ + ":w" + std::to_string(index);
  std::unique_ptr<store::Store> st;
  try {
    st = stores_();
  } catch (const std::exception& e) {
    spdlog::error("{}: cannot open the store: {}", worker_id, e.what());
  }
  // Every kind is claimed: a job of a kind no handler runs (a row another system inserted) is
  // discarded at once with that reason, as the queue contract says, instead of waiting forever.
  std::string known;
  for (const auto& [k, h] : handlers_) known += (known.empty() ? "" : ", ") + k;
  bool trim_pending = false;
  while (st && !stop_) {
    auto cfg = config_();
    std::optional<store::Job> job;
    try {
      job = claim_store_->claim(worker_id, store::Millis(cfg->lease_seconds) * 1000);
    } catch (const std::exception& e) {
      spdlog::warn("{}: claim failed: {}", worker_id, e.what());
    }
    if (!job) {
      if (trim_pending) {  // idle: what the last short jobs freed goes back too
        return_freed_memory();
        trim_pending = false;
      }
      if (exit_when_empty_) {
        // A completion still in flight may enqueue a follow-up job: look once more after it.
        std::unique_lock<std::mutex> l(m_);
        if (in_flight_ == 0) break;
        done_cv_.wait(l, [this] { return in_flight_ == 0; });
        continue;
      }
      std::unique_lock<std::mutex> l(m_);
      auto seen = wakeups_;
      cv_.wait_for(l, std::chrono::milliseconds(cfg->poll_interval_ms),
                   [&] { return stop_ || wakeups_ != seen; });
      continue;
    }
    {
      std::lock_guard<std::mutex> l(m_);
      running_[worker_id] = job->id;
    }
    auto t0 = std::chrono::steady_clock::now();
    std::string error;
    bool permanent = false;
    store::JobRecords records;
    bool cancelled = false;
    try {
      HandlerContext ctx{*cfg, worker_id};
      ctx.check_cancelled = [&st, id = job->id] {
        const auto now = st->get_job(id);
        if (now && now->state == store::JobState::cancelled)
          throw JobCancelled("job " + std::to_string(id) + " was cancelled while running");
      };
      const auto handler = handlers_.find(job->kind);
      if (handler == handlers_.end())
        throw PermanentError("unknown job kind '" + job->kind.substr(0, 64) + "' (this meshmarkd runs " + known + ")");
      records = handler->second(*st, *job, ctx);
    } catch (const JobCancelled& e) {
      cancelled = true;
      error = e.what();
    } catch (const PermanentError& e) {
      error = e.what();
      permanent = true;
    } catch (const InputError& e) {
      error = e.what();
      permanent = true;
    } catch (const std::exception& e) {
      error = e.what();
    } catch (...) {
      error = "unknown exception";
    }
    double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    // malloc_trim walks the heap: after a job of a tenth of a second or more (a real part), not
    // after every one of a burst of tiny jobs, which are trimmed once the worker is idle.
    trim_pending = secs < 0.1;
    if (!trim_pending) return_freed_memory();
    if (!cancelled && error.empty()) {  // recorded by the completer; the worker goes on
      {
        std::lock_guard<std::mutex> l(m_);
        running_.erase(worker_id);
      }
      auto p = std::make_unique<PendingCompletion>();
      p->job = *job;
      p->worker_id = worker_id;
      p->records = std::move(records);
      p->seconds = secs;
      submit_completion(std::move(p));
      continue;
    }
    std::string outcome;
    try {
      if (cancelled) {
        outcome = "cancelled";
        spdlog::info("job {} {} stopped after {:.2f} s: {}", job->id, job->kind, secs, error);
      } else {
        auto state = st->fail(job->id, worker_id, error, !permanent);
        outcome = state == store::JobState::discarded ? "discarded" : "failed";
        if (state == store::JobState::discarded) {
          spdlog::warn("job {} {} discarded after {:.2f} s (attempt {}/{}): {}", job->id, job->kind, secs,
                       job->attempt, job->max_attempts, error);
        } else {
          const auto again = st->get_job(job->id);
          const double wait = again ? static_cast<double>(again->scheduled_at - st->now()) / 1000 : 0;
          spdlog::warn("job {} {} failed after {:.2f} s (attempt {}/{}), retrying in {:.1f} s: {}", job->id,
                       job->kind, secs, job->attempt, job->max_attempts, std::max(0.0, wait), error);
        }
      }
    } catch (const store::LeaseLost& e) {
      outcome = lease_lost_outcome(*st, *job, records, e);
    } catch (const std::exception& e) {
      outcome = "failed";
      spdlog::error("job {}: cannot record outcome: {}", job->id, e.what());
    }
    std::lock_guard<std::mutex> l(m_);
    running_.erase(worker_id);
    count_outcome(outcome);
  }
  std::lock_guard<std::mutex> l(m_);
  --alive_;
  done_cv_.notify_all();
}

}  // namespace mm::service

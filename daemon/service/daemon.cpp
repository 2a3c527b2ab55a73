#include "service/daemon.h"
#include "service/systemd_notify.h"
#include "service/webhooks.h"

#include <poll.h>
#include <signal.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string_view>
#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "service/handlers.h"
#include "support/atomic_file.h"
#include "store/home.h"
#include "store/pg_store.h"

namespace mm::service {

using nlohmann::json;
namespace fs = std::filesystem;

namespace {

std::int64_t now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// Temporary files a writer leaves when a process dies mid-write (support/atomic_file.h) in
// <output>/<customer>/. Only this daemon writes there, and none of its workers is running yet.
int remove_stale_output_temps(const std::string& output_dir) {
  namespace fs = std::filesystem;
  int n = 0;
  std::error_code ec;
  for (fs::directory_iterator d(output_dir, ec), end; !ec && d != end; d.increment(ec)) {
    if (!d->is_directory() || d->is_symlink()) continue;
    std::error_code ec2;
    for (fs::directory_iterator f(d->path(), ec2), fend; !ec2 && f != fend; f.increment(ec2)) {
      std::string name = f->path().filename().string();
      if (support::is_atomic_write_temporary(name) && f->is_regular_file() && !f->is_symlink()) {
        std::error_code ec3;
        if (fs::remove(f->path(), ec3)) ++n;
      }
    }
  }
  return n;
}

// The message with every control character escaped (\n, \r, \t, \xNN): a file name carrying a
// newline cannot forge a log line, whatever code logged it.
class EscapedMessage final : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
    static const char* hex = "0123456789abcdef";
    for (char c : std::string_view(msg.payload.data(), msg.payload.size())) {
      const auto u = static_cast<unsigned char>(c);
      if (u >= 0x20 && u != 0x7f) {
        dest.push_back(c);
        continue;
      }
      const char* named = u == '\n' ? "\\n" : u == '\r' ? "\\r" : u == '\t' ? "\\t" : nullptr;
      if (named) {
        dest.append(named, named + 2);
      } else {
        const char esc[4] = {'\\', 'x', hex[u >> 4], hex[u & 15]};
        dest.append(esc, esc + 4);
      }
    }
  }
  std::unique_ptr<custom_flag_formatter> clone() const override { return std::make_unique<EscapedMessage>(); }
};

}  // namespace

std::string host_prefix() {
  char host[256] = {0};
  ::gethostname(host, sizeof host - 1);
  return std::string(host) + ":" + std::to_string(::getpid());
}

void setup_logging(const Config& cfg) {
  std::shared_ptr<spdlog::logger> logger;
  if (cfg.log_file.empty())
    logger = spdlog::stderr_color_mt("meshmarkd-" + std::to_string(now_ms()));
  else
    logger = spdlog::basic_logger_mt("meshmarkd-" + std::to_string(now_ms()), cfg.log_file);
  auto formatter = std::make_unique<spdlog::pattern_formatter>();
  formatter->add_flag<EscapedMessage>('*').set_pattern("%Y-%m-%d %H:%M:%S.%e [%l] %*");
  logger->set_formatter(std::move(formatter));
  logger->set_level(spdlog::level::from_str(cfg.log_level));
  logger->flush_on(spdlog::level::info);
  spdlog::set_default_logger(logger);
}

store::HomePaths home_of(const Config& cfg) {
  auto home = store::resolve_home(cfg.home);
  home.master_key = cfg.master_key_path();
  if (!cfg.store_postgres.empty()) home.store_url = cfg.store_postgres;
  return home;
}

std::unique_ptr<store::Store> open_store(const Config& cfg) { return store::open_home(home_of(cfg), true); }

Daemon::Daemon(Config cfg) : cfg_(std::make_shared<const Config>(std::move(cfg))) {
  store_ = open_store(*cfg_);
}

Daemon::~Daemon() { stop_wakeups(); }

std::shared_ptr<const Config> Daemon::config() const {
  std::lock_guard<std::mutex> l(cfg_m_);
  return cfg_;
}

void Daemon::reload() {
  auto old = config();
  Config fresh;
  try {
    fresh = load_config(old->source);
  } catch (const std::exception& e) {
    spdlog::error("SIGHUP: configuration not reloaded, keeping the running one: {}", e.what());
    return;
  }
  auto changes = config_changes(*old, fresh);
  if (changes.empty()) {
    spdlog::info("SIGHUP: configuration reloaded, nothing changed");
    return;
  }
  // Keys that need a restart keep their running values.
  fresh.home = old->home;
  fresh.drop_dir = old->drop_dir;
  fresh.output_dir = old->output_dir;
  fresh.master_key_file = old->master_key_file;
  fresh.workers = old->workers;
  fresh.use_inotify = old->use_inotify;
  fresh.log_file = old->log_file;
  for (const auto& c : changes)
    spdlog::info("SIGHUP: {}{}", c, needs_restart(c) ? " (takes effect after a restart)" : "");
  spdlog::set_level(spdlog::level::from_str(fresh.log_level));
  if (watcher_) watcher_->set_settle_ms(fresh.settle_ms);
  std::lock_guard<std::mutex> l(cfg_m_);
  cfg_ = std::make_shared<const Config>(std::move(fresh));
}

void Daemon::handle_drop(const DropItem& item) {
  auto cfg = config();
  auto fail_now = [&](const std::string& reason) {
    try {
      auto dest = DropWatcher::finish(cfg->drop_dir, item, false,
                                      json{{"file", item.relative}, {"state", "rejected"}, {"reason", reason}}.dump(2));
      spdlog::warn("drop {} rejected: {} -> {}", item.relative, reason, dest);
    } catch (const std::exception& e) {
      spdlog::error("drop {}: cannot move to failed/: {}", item.relative, e.what());
    }
    watcher_->forget(item.path);
  };
  try {
    store::EnqueueResult r;
    if (item.kind == DropKind::protect) {
      if (!store_->find_customer(item.customer))
        return fail_now("unknown customer \"" + item.customer + "\" (add it with: meshmark customer add " +
                        item.customer + ")");
      r = submit_protect(*store_, item.customer, item.path, item.name, cfg->max_attempts, "drop");
    } else {
      r = submit_detect(*store_, item.path, item.name, cfg->max_attempts, "drop");
    }
    ++submitted_;
    spdlog::info("drop {} -> job {} {}{}", item.relative, r.job.id, r.job.kind, r.created ? "" : " (already submitted)");
    inflight_[r.job.id] = item;
    if (pool_) pool_->notify();
  } catch (const store::BlobError& e) {
    spdlog::warn("drop {}: cannot read: {}", item.relative, e.what());
    watcher_->forget(item.path);
  } catch (const std::exception& e) {
    spdlog::error("drop {}: cannot submit: {}", item.relative, e.what());
    watcher_->forget(item.path);
  }
}

void Daemon::finalize(const DropItem& item, const store::Job& job) {
  auto cfg = config();
  bool ok = job.state == store::JobState::completed;
  json reason{{"file", item.relative}, {"job_id", job.id}, {"kind", job.kind}, {"state", store::to_string(job.state)},
              {"attempts", job.attempt}};
  if (ok) {
    try {
      reason["result"] = json::parse(job.result_json.empty() ? "{}" : job.result_json);
    } catch (const json::exception&) {
    }
  } else {
    reason["reason"] = job.errors.empty() ? std::string(job.state == store::JobState::cancelled ? "cancelled" : "failed")
                                          : job.errors.back().error;
  }
  try {
    auto dest = DropWatcher::finish(cfg->drop_dir, item, ok, reason.dump(2));
    spdlog::info("drop {} ({} job {}) -> {}", item.relative, store::to_string(job.state), job.id, dest);
  } catch (const std::exception& e) {
    spdlog::error("drop {}: cannot move: {}", item.relative, e.what());
  }
  if (watcher_) watcher_->forget(item.path);
}

void Daemon::check_inflight() {
  for (auto it = inflight_.begin(); it != inflight_.end();) {
    std::optional<store::Job> job;
    try {
      job = store_->get_job(it->first);
    } catch (const std::exception& e) {
      spdlog::warn("job {}: cannot read state: {}", it->first, e.what());
      ++it;
      continue;
    }
    if (!job) {
      ++it;
      continue;
    }
    auto s = job->state;
    if (s == store::JobState::completed || s == store::JobState::discarded || s == store::JobState::cancelled) {
      finalize(it->second, *job);
      it = inflight_.erase(it);
    } else {
      ++it;
    }
  }
}

void Daemon::start_wakeups(const Config& cfg) {
  const std::string url = home_of(cfg).store_url;
  if (url.empty()) return;  // SQLite: enqueues on this machine notify the pool directly
  const int retry_ms = std::min(cfg.poll_interval_ms, 1000);
  wakeups_ = std::thread([this, url, retry_ms] {
    std::unique_ptr<store::JobWakeups> w;
    bool warned = false;
    while (!wakeups_stop_) {
      try {
        if (!w) {
          w = std::make_unique<store::JobWakeups>(url);
          if (warned) spdlog::info("fleet: job wake-ups resumed");
          warned = false;
        }
        if (w->wait(500)) pool_->notify();
      } catch (const std::exception& e) {
        // The database restarting: polling carries on meanwhile; listen again once it is back.
        if (!warned) spdlog::warn("fleet: job wake-ups paused: {}", e.what());
        warned = true;
        w.reset();
        std::this_thread::sleep_for(std::chrono::milliseconds(retry_ms));
      }
    }
  });
}

void Daemon::stop_wakeups() {
  wakeups_stop_ = true;
  if (wakeups_.joinable()) wakeups_.join();
}

bool Daemon::beat_fleet(const Config& cfg) {
  const auto now = std::chrono::steady_clock::now();
  if (now < next_beat_) return leader_;
  // A beat every heartbeat_seconds, a lease of three: a killed leader is replaced within that.
  next_beat_ = now + std::chrono::seconds(cfg.heartbeat_seconds);
  try {
    const bool leads = store_->beat_node(node_, cfg.workers, store::Millis(3) * cfg.heartbeat_seconds * 1000);
    if (leads != leader_) spdlog::info("fleet: {} {} the leader", node_, leads ? "is now" : "is no longer");
    leader_ = leads;
  } catch (const std::exception& e) {
    spdlog::warn("fleet: beat failed: {}", e.what());
  }
  return leader_;
}

void Daemon::deliver_webhooks(const Config& cfg) {
  try {
    if (int n = dispatch_webhooks(*store_, cfg); n > 0 && !cfg.webhooks.empty())
      spdlog::info("{} job event(s) queued for {} webhook endpoint(s)", n, cfg.webhooks.size());
  } catch (const std::exception& e) {
    spdlog::warn("webhooks: {}", e.what());
  }
}

void Daemon::prune_jobs(const Config& cfg) {
  const auto now = std::chrono::steady_clock::now();
  if (cfg.job_retention_days == 0 || now < next_prune_) return;
  next_prune_ = now + std::chrono::minutes(1);
  try {
    const store::Millis before = store_->now() - store::Millis(cfg.job_retention_days) * 24 * 3600 * 1000;
    // Batches of 1,000, each its own short transaction, so claims never wait long behind it.
    int total = 0;
    for (int batch = 0; batch < 10; ++batch) {
      const int n = store_->prune_jobs(before, 1000);
      total += n;
      if (n < 1000) break;
    }
    if (total > 0) spdlog::info("pruned {} finished job(s) older than {} days", total, cfg.job_retention_days);
  } catch (const std::exception& e) {
    spdlog::warn("pruning finished jobs: {}", e.what());
  }
}

void Daemon::start_api() {
  auto cfg = config();
  if (cfg->http_listen.empty()) return;
  const std::string uploads = (fs::path(cfg->home) / "uploads").string();
  fs::create_directories(uploads);
  // Uploads cut off by a crash or a kill are never finished; their temporary files go.
  for (const auto& e : fs::directory_iterator(uploads)) {
    std::error_code ec;
    if (e.path().filename().string().rfind(".upload-", 0) == 0) fs::remove(e.path(), ec);
  }
  api_store_ = open_store(*cfg);
  api_ = std::make_unique<Api>(*api_store_, [this] { return config(); });
  http::Limits limits;
  limits.threads = cfg->http_threads;
  limits.max_body_bytes = static_cast<std::size_t>(cfg->http_max_body_bytes);
  if (cfg->max_input_bytes > 0) limits.max_upload_bytes = static_cast<std::uint64_t>(cfg->max_input_bytes);
  http_ = std::make_unique<http::Server>(http::parse_listen(cfg->http_listen), limits, api_->routes(uploads));
  http_->start();
  spdlog::info("HTTP API listening on {}", http_->address());
}

int Daemon::run() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGHUP);
  // Blocked before any thread starts, so every thread inherits the mask and only the signalfd
  // sees these signals.
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  int sfd = ::signalfd(-1, &set, SFD_NONBLOCK | SFD_CLOEXEC);
  if (sfd < 0) {
    spdlog::critical("signalfd failed");
    return 1;
  }
  auto cfg = config();
  watcher_ = std::make_unique<DropWatcher>(cfg->drop_dir, cfg->use_inotify, cfg->settle_ms);
  auto cfg_fn = [this] { return config(); };
  auto factory = [this] { return open_store(*config()); };
  pool_ = std::make_unique<WorkerPool>(cfg->workers, factory, default_handlers(), cfg_fn, host_prefix());
  int reaped = store_->reap_expired_leases();
  if (int stale = remove_stale_output_temps(cfg->output_dir))
    spdlog::info("removed {} half-written temporary output file(s) left by a previous crash", stale);
  if (int stale = remove_stale_reason_temps(cfg->drop_dir))
    spdlog::info("removed {} half-written reason file(s) left by a previous crash", stale);
  spdlog::info("meshmarkd started: {} workers, drop {}, output {}, inotify {}, schema v{}{}", cfg->workers,
               cfg->drop_dir, cfg->output_dir, watcher_->inotify_active() ? "on" : "off", store_->schema_version(),
               reaped ? ", " + std::to_string(reaped) + " expired leases reaped" : "");
  pool_->start();
  start_wakeups(*cfg);
  start_api();
  // Under systemd (Type=notify): ready once the workers and the API are up; the watchdog is fed
  // from this loop, so a main loop that hangs gets the daemon restarted.
  notify_systemd("READY=1\nSTATUS=serving: " + std::to_string(cfg->workers) + " workers" +
                 (http_ ? ", API on " + http_->address() : std::string()));
  const auto watchdog = watchdog_interval();
  auto fed = std::chrono::steady_clock::now();

  bool stopping = false;
  while (!stopping) {
    cfg = config();
    struct pollfd fds[2] = {{sfd, POLLIN, 0}, {watcher_->fd(), POLLIN, 0}};
    int nfds = watcher_->fd() >= 0 ? 2 : 1;
    int timeout = cfg->poll_interval_ms;
    if (watchdog.count() > 0) timeout = static_cast<int>(std::min<long long>(timeout, watchdog.count()));
    ::poll(fds, static_cast<nfds_t>(nfds), timeout);
    if (watchdog.count() > 0 && std::chrono::steady_clock::now() - fed >= watchdog) {
      notify_systemd("WATCHDOG=1");
      fed = std::chrono::steady_clock::now();
    }
    struct signalfd_siginfo si;
    while (::read(sfd, &si, sizeof si) == static_cast<ssize_t>(sizeof si)) {
      if (si.ssi_signo == SIGHUP) {
        spdlog::info("SIGHUP: reloading {}", cfg->source);
        reload();
      } else {
        spdlog::info("{}: draining (no new claims; running jobs get {} s)", si.ssi_signo == SIGTERM ? "SIGTERM" : "SIGINT",
                     cfg->shutdown_grace_seconds);
        stopping = true;
      }
    }
    if (stopping) break;
    for (const auto& item : watcher_->poll(now_ms())) handle_drop(item);
    check_inflight();
    // The leader alone turns job events into webhook deliveries; the others would only queue
    // behind its lock on the event cursor.
    if (beat_fleet(*cfg)) {
      deliver_webhooks(*cfg);
      prune_jobs(*cfg);
    }
  }
  try {
    store_->leave_fleet(node_);
  } catch (const std::exception& e) {
    spdlog::warn("fleet: cannot leave: {}", e.what());
  }

  cfg = config();
  notify_systemd("STOPPING=1");
  if (http_) http_->stop();  // requests in progress finish; no new ones
  stop_wakeups();
  pool_->stop_claiming();
  auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(cfg->shutdown_grace_seconds);
  bool drained = pool_->wait_idle(deadline);
  check_inflight();
  auto st = pool_->stats();
  if (!drained) {
    int released = pool_->release_running();
    spdlog::warn("shutdown deadline passed: {} running job(s) released to the queue; exiting", released);
    spdlog::default_logger()->flush();
    ::close(sfd);
    // Worker threads are still inside handlers; their results would be refused (lease released).
    std::_Exit(0);
  }
  pool_->join();
  spdlog::info("meshmarkd stopped: {} completed, {} discarded, {} failed (will retry) in this run", st.completed,
               st.discarded, st.failed);
  spdlog::default_logger()->flush();
  ::close(sfd);
  return 0;
}

BatchSummary Daemon::run_until_empty(bool scan_drops, bool progress) {
  BatchSummary s;
  auto cfg = config();
  if (scan_drops) {
    watcher_ = std::make_unique<DropWatcher>(cfg->drop_dir, false, cfg->settle_ms);
    for (const auto& item : watcher_->scan_once(now_ms())) handle_drop(item);
  }
  s.submitted_from_drops = submitted_;
  auto cfg_fn = [this] { return config(); };
  auto factory = [this] { return open_store(*config()); };
  store_->reap_expired_leases();
  auto before = store_->counts();
  std::int64_t total = before.available + before.retryable;
  pool_ = std::make_unique<WorkerPool>(cfg->workers, factory, default_handlers(), cfg_fn, host_prefix() + ":batch",
                                       true);
  pool_->start();
  bool tty = progress && ::isatty(2);
  while (!pool_->wait_idle(std::chrono::steady_clock::now() + std::chrono::milliseconds(200))) {
    if (tty) {
      auto st = pool_->stats();
      std::int64_t done = st.completed + st.discarded + st.failed;
      int width = 30;
      int filled = total > 0 ? static_cast<int>(width * std::min<std::int64_t>(done, total) / total) : width;
      std::cerr << "\r[" << std::string(static_cast<std::size_t>(filled), '#')
                << std::string(static_cast<std::size_t>(width - filled), '.') << "] " << done << "/" << total
                << " jobs" << std::flush;
    }
  }
  pool_->join();
  if (tty) std::cerr << "\r" << std::string(60, ' ') << "\r" << std::flush;
  check_inflight();
  deliver_webhooks(*cfg);  // queued here, sent by the next run or the resident daemon
  s.pool = pool_->stats();
  s.counts = store_->counts();
  return s;
}

}  // namespace mm::service

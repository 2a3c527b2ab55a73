// submit protect|detect (enqueue files as jobs) and run --until-empty (a cron-style batch without
// a resident daemon). See docs/daemon.md.
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "keys/keys.h"
#include "meshio/read_mesh.h"
#include "service/config.h"
#include "service/daemon.h"
#include "service/handlers.h"
#include "service/webhooks.h"
#include "store/home.h"

namespace mm::cli {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

struct SubmitOptions {
  std::string home, config, customer, format, object;
  std::vector<std::string> files;
  int max_attempts = 5;
  bool json = false;
};

// --config gives home and max_attempts; otherwise --home (or $MESHMARK_HOME).
std::unique_ptr<store::Store> open_for_submit(SubmitOptions& o) {
  if (!o.config.empty()) {
    auto cfg = service::load_config(o.config, false);
    o.max_attempts = cfg.max_attempts;
    return service::open_store(cfg);
  }
  return store::open_home(store::resolve_home(o.home), false);
}

void submit(SubmitOptions& o, bool protect) {
  try {
    refusing_store_errors([&] {
      auto st = open_for_submit(o);
      if (protect && !st->find_customer(o.customer))
        throw CommandFailed(1, "unknown customer \"" + o.customer + "\" (add it with: meshmark customer add " +
                                   o.customer + ")");
      json out = json::array();
      for (const auto& f : o.files) {
        std::string name = fs::path(f).filename().string();
        auto r = protect ? service::submit_protect(*st, o.customer, f, name, o.max_attempts, "cli", o.format, o.object)
                         : service::submit_detect(*st, f, name, o.max_attempts, "cli");
        if (o.json)
          out.push_back({{"file", f}, {"job_id", r.job.id}, {"kind", r.job.kind}, {"created", r.created},
                         {"state", store::to_string(r.job.state)}});
        else
          std::cout << "job " << r.job.id << " " << r.job.kind << " " << f
                    << (r.created ? "" : " (already submitted, state " + std::string(store::to_string(r.job.state)) + ")")
                    << "\n";
      }
      if (o.json) std::cout << out.dump(2) << "\n";
    });
  } catch (const service::ConfigError& e) {
    throw CommandFailed(78, e.what());
  }
}

// meshmark fleet status: the daemons sharing the store, the leader, what each is running, and
// the queue's depth per kind.
void fleet_status(SubmitOptions& o) {
  try {
    refusing_store_errors([&] {
      auto st = open_for_submit(o);
      const store::Millis now = st->now();
      const auto nodes = st->list_nodes();
      std::map<std::string, int> running;  // node -> running jobs (worker ids are node:wN)
      for (const auto& j : st->list_jobs({store::JobState::running, "", 100000, 0})) {
        const auto w = j.worker_id.rfind(":w");
        ++running[w == std::string::npos ? j.worker_id : j.worker_id.substr(0, w)];
      }
      const auto depth = st->metrics({}).queue_depth;
      if (o.json) {
        json jn = json::array(), jd = json::object();
        for (const auto& n : nodes)
          jn.push_back({{"name", n.name}, {"workers", n.workers}, {"started_at", store::iso_utc(n.started_at)},
                        {"seen_seconds_ago", (now - n.seen_at) / 1000}, {"leader", n.leader},
                        {"running", running.count(n.name) ? running[n.name] : 0}});
        for (const auto& [kind, n] : depth) jd[kind] = n;
        std::cout << json{{"nodes", jn}, {"queue_depth", jd}}.dump(2) << "\n";
        return;
      }
      std::cout << "nodes: " << nodes.size() << "\n";
      for (const auto& n : nodes)
        std::cout << "  " << n.name << (n.leader ? "  leader" : "") << "  " << n.workers << " workers, running "
                  << (running.count(n.name) ? running[n.name] : 0) << ", seen " << (now - n.seen_at) / 1000
                  << " s ago, up since " << store::iso_utc(n.started_at) << "\n";
      std::cout << "queue (available and retryable):";
      if (depth.empty()) std::cout << " empty";
      for (const auto& [kind, n] : depth) std::cout << " " << kind << " " << n;
      std::cout << "\n";
    });
  } catch (const service::ConfigError& e) {
    throw CommandFailed(78, e.what());
  }
}

}  // namespace

void add_run_commands(CLI::App& app) {
  {
    auto o = std::make_shared<SubmitOptions>();
    auto* fleet = app.add_subcommand("fleet", "The daemons sharing the store (a fleet on PostgreSQL)");
    fleet->require_subcommand(1);
    auto* status = fleet->add_subcommand("status", "Nodes, their beats, the leader, running jobs, queue depth per kind");
    status->add_option("--home", o->home, "meshmark home folder (default: $MESHMARK_HOME or ./meshmark-home)");
    status->add_option("--config", o->config, "take the home and store from this meshmarkd configuration");
    status->add_flag("--json", o->json, "print JSON for scripts");
    status->callback([o] { fleet_status(*o); });
  }
  auto* grp = app.add_subcommand("submit", "Enqueue files as protect or detect jobs");
  grp->require_subcommand(1);
  for (bool protect : {true, false}) {
    auto o = std::make_shared<SubmitOptions>();
    auto* cmd = grp->add_subcommand(protect ? "protect" : "detect",
                                    protect ? "Enqueue meshes to watermark for a customer"
                                            : "Enqueue suspect meshes to trace");
    cmd->add_option("--home", o->home, "meshmark home folder (default: $MESHMARK_HOME or ./meshmark-home)");
    cmd->add_option("--config", o->config, "take home and max_attempts from this meshmarkd configuration");
    cmd->add_flag("--json", o->json, "print JSON for scripts");
    if (protect) {
      cmd->add_option("--customer", o->customer, "customer name")->required();
      cmd->add_option("--format", o->format, "output format (default: output_format of the config at run time)")
          ->check(CLI::IsMember(mesh_formats()));
      cmd->add_option("--object", o->object, "3MF parts: protect only the build items whose object has this name");
    }
    cmd->add_option("files", o->files, "mesh files (STL, OBJ, OFF, PLY, 3MF, glTF, GLB)")->required()->check(CLI::ExistingFile);
    cmd->callback([o, protect] { submit(*o, protect); });
  }

  auto* hooks = app.add_subcommand("webhook", "Webhook endpoints' secrets (docs/api.md, Webhooks)");
  hooks->require_subcommand(1);
  hooks->add_subcommand("secret", "Print a new random secret for an endpoint's secret_file (whsec_...)")
      ->callback([] { std::cout << service::new_webhook_secret() << "\n"; });

  auto* run = app.add_subcommand("run", "Process queued jobs without a resident daemon");
  auto cfg_path = std::make_shared<std::string>();
  auto until_empty = std::make_shared<bool>(false);
  auto no_drops = std::make_shared<bool>(false);
  auto as_json = std::make_shared<bool>(false);
  auto workers = std::make_shared<int>(0);
  run->add_option("-c,--config", *cfg_path, "meshmarkd configuration (JSON)")->required();
  run->add_flag("--until-empty", *until_empty, "process every claimable job, then exit (required)")->required();
  run->add_flag("--no-drops", *no_drops, "do not scan the drop folders first");
  run->add_option("--workers", *workers, "worker threads (default: the config's workers)")->check(CLI::Range(1, 64));
  run->add_flag("--json", *as_json, "print the summary as JSON");
  run->callback([=] {
    service::Config cfg;
    try {
      cfg = service::load_config(*cfg_path);
    } catch (const service::ConfigError& e) {
      throw CommandFailed(78, e.what());
    }
    if (*workers > 0) cfg.workers = *workers;
    if (*as_json) cfg.log_level = cfg.log_level == "info" || cfg.log_level == "debug" || cfg.log_level == "trace"
                                      ? "warn" : cfg.log_level;  // keep stdout clean for scripts
    service::setup_logging(cfg);
    try {
      service::Daemon d(cfg);
      auto s = d.run_until_empty(!*no_drops, !*as_json);
      json j{{"submitted_from_drops", s.submitted_from_drops},
             {"completed", s.pool.completed},
             {"discarded", s.pool.discarded},
             {"failed_will_retry", s.pool.failed},
             {"queue", {{"available", s.counts.available}, {"running", s.counts.running},
                        {"retryable", s.counts.retryable}, {"completed", s.counts.completed},
                        {"discarded", s.counts.discarded}, {"cancelled", s.counts.cancelled}}}};
      if (*as_json)
        std::cout << j.dump(2) << "\n";
      else
        std::cout << "run: " << s.submitted_from_drops << " dropped file(s) submitted; " << s.pool.completed
                  << " completed, " << s.pool.discarded << " discarded, " << s.pool.failed
                  << " failed (will retry); queue now " << s.counts.available << " available, "
                  << s.counts.retryable << " retryable, " << s.counts.running << " running\n";
      if (s.pool.discarded > 0 || s.pool.failed > 0) throw CommandFailed(4, "some jobs did not complete (see meshmark jobs list)");
    } catch (const keys::KeyError& e) {
      throw CommandFailed(1, e.what());
    } catch (const store::StoreError& e) {
      throw CommandFailed(1, e.what());
    }
  });
}

}  // namespace mm::cli

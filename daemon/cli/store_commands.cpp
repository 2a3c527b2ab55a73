// Store-facing commands: init, store migrate, customer add|list|rotate-key, jobs list|show|retry|cancel, assets,
// copies, detections. Each takes --home (else $MESHMARK_HOME, else ./meshmark-home) and --json.
// Nothing here ever prints key material: customers show key versions only.
#include <unistd.h>

#include <cstdio>
#include <ctime>
#include <functional>
#include <map>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "store/copy_to_postgres.h"
#include "store/home.h"

namespace mm::cli {
namespace {

using nlohmann::json;
using store::Millis;

struct Common {
  std::string home;
  bool json = false;
};

void add_common(CLI::App* cmd, Common& c) {
  cmd->add_option("--home", c.home, "meshmark home folder (default: $MESHMARK_HOME or ./meshmark-home)");
  cmd->add_flag("--json", c.json, "print JSON for scripts");
}

// Store and key failures as refusals (refusing_store_errors).
template <class F>
std::function<void()> guarded(F f) {
  return [f] { refusing_store_errors(f); };
}

std::unique_ptr<store::Store> open(const Common& c, bool need_key = false) {
  return store::open_home(store::resolve_home(c.home), need_key);
}

std::string iso_time(store::Millis ms) { return store::iso_utc(ms); }

json opt_time(const std::optional<Millis>& t) { return t ? json(iso_time(*t)) : json(nullptr); }
template <class T>
json opt(const std::optional<T>& v) {
  return v ? json(*v) : json(nullptr);
}
json parse_or_string(const std::string& s) {
  json j = json::parse(s, nullptr, false);
  return j.is_discarded() ? json(s) : j;
}

json to_json(const store::Customer& c) {
  return {{"id", c.id}, {"name", c.name}, {"key_version", c.current_key_version},
          {"created_at", iso_time(c.created_at)}};
}

json to_json(const store::ApiToken& t) {
  return {{"id", t.id}, {"name", t.name}, {"role", store::to_string(t.role)}, {"created_at", iso_time(t.created_at)},
          {"revoked_at", opt_time(t.revoked_at)}};
}

json to_json(const store::Job& j) {
  json errors = json::array();
  for (const auto& e : j.errors) errors.push_back({{"attempt", e.attempt}, {"at", iso_time(e.at)}, {"error", e.error}});
  return {{"id", j.id},
          {"kind", j.kind},
          {"state", store::to_string(j.state)},
          {"priority", j.priority},
          {"attempt", j.attempt},
          {"max_attempts", j.max_attempts},
          {"rescues", j.rescues},
          {"idempotency_key", j.idempotency_key},
          {"payload", parse_or_string(j.payload_json)},
          {"created_at", iso_time(j.created_at)},
          {"scheduled_at", iso_time(j.scheduled_at)},
          {"attempted_at", opt_time(j.attempted_at)},
          {"finished_at", opt_time(j.finished_at)},
          {"worker_id", j.worker_id},
          {"lease_until", opt_time(j.lease_until)},
          {"errors", errors},
          {"result", j.result_json.empty() ? json(nullptr) : parse_or_string(j.result_json)}};
}

json to_json(const store::Asset& a) {
  return {{"id", a.id}, {"sha256", a.sha256}, {"size", a.size}, {"name", a.name},
          {"format", a.format}, {"created_at", iso_time(a.created_at)}};
}

std::string hex(const std::vector<std::uint8_t>& b) {
  std::string s;
  char buf[3];
  for (auto x : b) {
    std::snprintf(buf, sizeof buf, "%02x", x);
    s += buf;
  }
  return s;
}

json to_json(const store::IssuedCopy& c) {
  return {{"id", c.id},
          {"asset_id", c.asset_id},
          {"customer_id", c.customer_id},
          {"key_version", c.key_version},
          {"idempotency_key", c.idempotency_key},
          {"nonce", hex(c.nonce)},
          {"payload_hex", c.payload_hex},
          {"params", parse_or_string(c.params_json)},
          {"outputs", parse_or_string(c.outputs_json)},
          {"polyhedron_id", opt(c.polyhedron_id)},
          {"job_id", opt(c.job_id)},
          {"created_at", iso_time(c.created_at)}};
}

json to_json(const store::Detection& d) {
  return {{"id", d.id},
          {"job_id", opt(d.job_id)},
          {"suspect_sha256", d.suspect_sha256},
          {"suspect_name", d.suspect_name},
          {"verdict", d.verdict},
          {"asset_id", opt(d.asset_id)},
          {"copy_id", opt(d.copy_id)},
          {"customer_id", opt(d.customer_id)},
          {"correlation", opt(d.correlation)},
          {"p_value", opt(d.p_value)},
          {"decoded_payload_hex", d.decoded_payload_hex},
          {"resync_method", d.resync_method},
          {"resync_residual", opt(d.resync_residual)},
          {"details", parse_or_string(d.details_json)},
          {"created_at", iso_time(d.created_at)}};
}

template <class T>
void print_list(const std::vector<T>& items, bool as_json, const std::string& empty,
                const std::function<void(const T&)>& line) {
  if (as_json) {
    json a = json::array();
    for (const auto& i : items) a.push_back(to_json(i));
    std::cout << a.dump(2) << "\n";
    return;
  }
  if (items.empty()) std::cout << empty << "\n";
  for (const auto& i : items) line(i);
}

std::string short_hash(const std::string& h) { return h.size() > 12 ? h.substr(0, 12) : h; }

store::Customer need_customer(store::Store& s, const std::string& name) {
  auto c = s.find_customer(name);
  if (!c) throw CommandFailed(1, "no customer named '" + name + "' (see: meshmark customer list)");
  return *c;
}

void add_init(CLI::App& app) {
  auto c = std::make_shared<Common>();
  auto* cmd = app.add_subcommand("init", "Create the home folder: database, blob folder, master key (0600)");
  add_common(cmd, *c);
  cmd->callback(guarded([c] {
    auto home = store::resolve_home(c->home);
    bool created = store::init_home(home);
    bool key_from_env = keys::master_key_from_env().has_value();
    // Check the key file is usable now rather than at the first protect job.
    if (!key_from_env) keys::load_master_key_file(home.master_key);
    auto s = open(*c);
    const std::string database = home.store_url.empty() ? home.db : store::redacted_conninfo(home.store_url);
    if (c->json) {
      std::cout << json{{"home", home.root}, {"database", database}, {"blobs", home.blobs},
                        {"master_key", key_from_env ? std::string("$") + keys::kMasterKeyEnv : home.master_key},
                        {"schema_version", s->schema_version()}, {"created", created}}
                       .dump(2)
                << "\n";
    } else {
      std::cout << (created ? "initialized " : "already initialized ") << home.root << "\n"
                << "  database    " << database << " (schema version " << s->schema_version() << ")\n"
                << "  blobs       " << home.blobs << "\n"
                << "  master key  "
                << (key_from_env ? std::string("from $") + keys::kMasterKeyEnv : home.master_key + " (mode 0600; back it up)")
                << "\n";
    }
  }));
}

void add_customer(CLI::App& app) {
  auto* grp = app.add_subcommand("customer", "Manage customers and their keys");
  grp->require_subcommand(1);

  auto ca = std::make_shared<Common>();
  auto name = std::make_shared<std::string>();
  auto* add = grp->add_subcommand("add", "Add a customer with a new random 256-bit key (version 1)");
  add->add_option("name", *name, "customer name: 1-64 letters, digits, '.', '_' or '-'")->required();
  add_common(add, *ca);
  add->callback(guarded([ca, name] {
    auto s = open(*ca, true);
    auto cust = s->add_customer(*name);
    if (ca->json) std::cout << to_json(cust).dump(2) << "\n";
    else std::cout << "customer " << cust.name << " (id " << cust.id << ") added with key version 1\n";
  }));

  auto cl = std::make_shared<Common>();
  auto* list = grp->add_subcommand("list", "List customers and their current key versions");
  add_common(list, *cl);
  list->callback(guarded([cl] {
    auto s = open(*cl);
    print_list<store::Customer>(s->list_customers(), cl->json, "no customers", [](const store::Customer& c) {
      std::printf("%6lld  %-24s key v%d  since %s\n", static_cast<long long>(c.id), c.name.c_str(),
                  c.current_key_version, iso_time(c.created_at).c_str());
    });
  }));

  auto cr = std::make_shared<Common>();
  auto rname = std::make_shared<std::string>();
  auto* rot = grp->add_subcommand("rotate-key", "Give a customer a new key version; old copies keep theirs");
  rot->add_option("name", *rname, "customer name")->required();
  add_common(rot, *cr);
  rot->callback(guarded([cr, rname] {
    auto s = open(*cr, true);
    auto cust = need_customer(*s, *rname);
    int v = s->rotate_key(cust.id);
    if (cr->json) std::cout << json{{"customer", cust.name}, {"id", cust.id}, {"key_version", v}}.dump(2) << "\n";
    else std::cout << "customer " << cust.name << " now uses key version " << v << "\n";
  }));
}

// API tokens of meshmarkd's HTTP API (docs/api.md). The token is printed once, by create.
void add_tokens(CLI::App& app) {
  auto* grp = app.add_subcommand("token", "Manage API tokens for meshmarkd's HTTP API");
  grp->require_subcommand(1);

  auto cc = std::make_shared<Common>();
  auto name = std::make_shared<std::string>();
  auto role = std::make_shared<std::string>("read");
  auto* create = grp->add_subcommand("create", "Create a token; it is printed once and only its hash is kept");
  create->add_option("name", *name, "token name (the client it is for): 1-64 letters, digits, '.', '_' or '-'")->required();
  create->add_option("--role", *role, "read (status, downloads), submit (also uploads, jobs, cancel) or admin")
      ->check(CLI::IsMember({"read", "submit", "admin"}));
  add_common(create, *cc);
  create->callback(guarded([cc, name, role] {
    auto s = open(*cc);
    auto t = s->create_token(*name, store::token_role_from_string(*role));
    if (cc->json) {
      json j = to_json(t.token);
      j["token"] = t.secret;
      std::cout << j.dump(2) << "\n";
    } else {
      std::cout << "token " << t.token.name << " (" << store::to_string(t.token.role) << "): " << t.secret
                << "\n  send it as 'Authorization: Bearer <token>'; it is not shown again\n";
    }
  }));

  auto cl = std::make_shared<Common>();
  auto* list = grp->add_subcommand("list", "List tokens (names and roles; never the tokens)");
  add_common(list, *cl);
  list->callback(guarded([cl] {
    auto s = open(*cl);
    print_list<store::ApiToken>(s->list_tokens(), cl->json, "no tokens", [](const store::ApiToken& t) {
      std::printf("%6lld  %-24s %-7s since %s%s\n", static_cast<long long>(t.id), t.name.c_str(),
                  store::to_string(t.role), iso_time(t.created_at).c_str(),
                  t.revoked_at ? ("  revoked " + iso_time(*t.revoked_at)).c_str() : "");
    });
  }));

  auto cr = std::make_shared<Common>();
  auto rname = std::make_shared<std::string>();
  auto* revoke = grp->add_subcommand("revoke", "Revoke a token: requests sending it are refused from now on");
  revoke->add_option("name", *rname, "token name")->required();
  add_common(revoke, *cr);
  revoke->callback(guarded([cr, rname] {
    auto s = open(*cr);
    if (!s->revoke_token(*rname)) throw CommandFailed(1, "no live token named '" + *rname + "' (see: meshmark token list)");
    if (cr->json) std::cout << json{{"name", *rname}, {"revoked", true}}.dump(2) << "\n";
    else std::cout << "token " << *rname << " revoked\n";
  }));
}

std::string job_line(const store::Job& j) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%6lld  %-8s %-10s prio %3d  attempt %d/%d  %s", static_cast<long long>(j.id),
                j.kind.c_str(), store::to_string(j.state), j.priority, j.attempt, j.max_attempts,
                iso_time(j.created_at).c_str());
  std::string s = buf;
  if (!j.errors.empty()) s += "  last error: " + j.errors.back().error.substr(0, 80);
  return s;
}

void add_jobs(CLI::App& app) {
  auto* grp = app.add_subcommand("jobs", "Inspect and steer the job queue");
  grp->require_subcommand(1);

  auto cl = std::make_shared<Common>();
  auto state = std::make_shared<std::string>();
  auto kind = std::make_shared<std::string>();
  auto limit = std::make_shared<int>(50);
  auto* list = grp->add_subcommand("list", "List jobs, newest first, with queue counts");
  list->add_option("--state", *state, "only this state")
      ->check(CLI::IsMember({"available", "running", "completed", "retryable", "discarded", "cancelled"}));
  list->add_option("--kind", *kind, "only this kind (protect, detect, ...)");
  list->add_option("--limit", *limit, "at most this many")->check(CLI::Range(1, 1000000));
  add_common(list, *cl);
  list->callback(guarded([cl, state, kind, limit] {
    auto s = open(*cl);
    store::JobFilter f;
    if (!state->empty()) f.state = store::job_state_from_string(*state);
    f.kind = *kind;
    f.limit = *limit;
    auto jobs = s->list_jobs(f);
    auto n = s->counts();
    if (cl->json) {
      json a = json::array();
      for (auto& j : jobs) a.push_back(to_json(j));
      std::cout << json{{"counts",
                         {{"available", n.available}, {"running", n.running}, {"completed", n.completed},
                          {"retryable", n.retryable}, {"discarded", n.discarded}, {"cancelled", n.cancelled}}},
                        {"jobs", a}}
                       .dump(2)
                << "\n";
      return;
    }
    std::cout << "available " << n.available << ", running " << n.running << ", retryable " << n.retryable
              << ", completed " << n.completed << ", discarded " << n.discarded << ", cancelled "
              << n.cancelled << "\n";
    for (auto& j : jobs) std::cout << job_line(j) << "\n";
  }));

  auto cs = std::make_shared<Common>();
  auto sid = std::make_shared<std::int64_t>(0);
  auto* show = grp->add_subcommand("show", "Show one job with its payload, errors and result");
  show->add_option("id", *sid, "job id")->required();
  add_common(show, *cs);
  show->callback(guarded([cs, sid] {
    auto s = open(*cs);
    auto j = s->get_job(*sid);
    if (!j) throw CommandFailed(1, "no job " + std::to_string(*sid));
    if (cs->json) {
      std::cout << to_json(*j).dump(2) << "\n";
      return;
    }
    std::cout << job_line(*j) << "\n";
    json full = to_json(*j);
    for (const char* k : {"idempotency_key", "worker_id", "scheduled_at", "attempted_at", "finished_at", "lease_until"})
      if (!full[k].is_null() && full[k] != "") std::cout << "  " << k << ": " << full[k].get<std::string>() << "\n";
    std::cout << "  payload: " << full["payload"].dump() << "\n";
    for (auto& e : j->errors) std::cout << "  error (attempt " << e.attempt << ", " << iso_time(e.at) << "): " << e.error << "\n";
    if (!full["result"].is_null()) std::cout << "  result: " << full["result"].dump() << "\n";
  }));

  for (bool is_retry : {true, false}) {
    auto c = std::make_shared<Common>();
    auto id = std::make_shared<std::int64_t>(0);
    auto* cmd = grp->add_subcommand(is_retry ? "retry" : "cancel",
                                    is_retry ? "Make a retryable, discarded or cancelled job available now"
                                             : "Cancel an available, retryable or running job");
    cmd->add_option("id", *id, "job id")->required();
    add_common(cmd, *c);
    cmd->callback(guarded([c, id, is_retry] {
      auto s = open(*c);
      auto before = s->get_job(*id);
      if (!before) throw CommandFailed(1, "no job " + std::to_string(*id));
      bool ok = is_retry ? s->retry(*id) : s->cancel(*id);
      if (!ok)
        throw CommandFailed(1, "job " + std::to_string(*id) + " is " + store::to_string(before->state) +
                                   "; cannot " + (is_retry ? "retry" : "cancel") + " it");
      auto after = s->get_job(*id);
      if (c->json) std::cout << to_json(*after).dump(2) << "\n";
      else std::cout << "job " << *id << " " << store::to_string(before->state) << " -> "
                     << store::to_string(after->state) << "\n";
    }));
  }
}

void add_listings(CLI::App& app) {
  auto ca = std::make_shared<Common>();
  auto alimit = std::make_shared<int>(100);
  auto* assets = app.add_subcommand("assets", "List stored originals (content addressed), newest first");
  assets->add_option("--limit", *alimit, "at most this many")->check(CLI::Range(1, 1000000));
  add_common(assets, *ca);
  assets->callback(guarded([ca, alimit] {
    auto s = open(*ca);
    print_list<store::Asset>(s->list_assets(*alimit), ca->json, "no assets", [](const store::Asset& a) {
      std::printf("%6lld  %s  %10llu bytes  %s\n", static_cast<long long>(a.id), short_hash(a.sha256).c_str(),
                  static_cast<unsigned long long>(a.size), a.name.c_str());
    });
  }));

  auto cc = std::make_shared<Common>();
  auto asset = std::make_shared<std::string>();
  auto climit = std::make_shared<int>(100);
  auto* copies = app.add_subcommand("copies", "List issued watermarked copies, newest first");
  copies->add_option("--asset", *asset, "only copies of this asset (id or sha256)");
  copies->add_option("--limit", *climit, "at most this many")->check(CLI::Range(1, 1000000));
  add_common(copies, *cc);
  copies->callback(guarded([cc, asset, climit] {
    auto s = open(*cc);
    std::optional<std::int64_t> aid;
    if (!asset->empty()) {
      std::optional<store::Asset> a;
      if (asset->find_first_not_of("0123456789") == std::string::npos && asset->size() < 19)
        a = s->get_asset(std::stoll(*asset));
      else
        a = s->find_asset(*asset);
      if (!a) throw CommandFailed(1, "no asset '" + *asset + "'");
      aid = a->id;
    }
    std::map<std::int64_t, std::string> names;
    for (auto& c : s->list_customers()) names[c.id] = c.name;
    print_list<store::IssuedCopy>(s->list_copies(aid, *climit), cc->json, "no copies",
                                  [&](const store::IssuedCopy& c) {
                                    std::printf("%6lld  asset %-5lld %-20s key v%d  %s\n",
                                                static_cast<long long>(c.id), static_cast<long long>(c.asset_id),
                                                names[c.customer_id].c_str(), c.key_version,
                                                iso_time(c.created_at).c_str());
                                  });
  }));

  auto cd = std::make_shared<Common>();
  auto dlimit = std::make_shared<int>(100);
  auto* dets = app.add_subcommand("detections", "List detection verdicts, newest first");
  dets->add_option("--limit", *dlimit, "at most this many")->check(CLI::Range(1, 1000000));
  add_common(dets, *cd);
  dets->callback(guarded([cd, dlimit] {
    auto s = open(*cd);
    std::map<std::int64_t, std::string> names;
    for (auto& c : s->list_customers()) names[c.id] = c.name;
    print_list<store::Detection>(s->list_detections(*dlimit), cd->json, "no detections",
                                 [&](const store::Detection& d) {
                                   std::string who = d.customer_id ? names[*d.customer_id] : "-";
                                   char p[32] = "-";
                                   if (d.p_value) std::snprintf(p, sizeof p, "%.3g", *d.p_value);
                                   std::printf("%6lld  %-22s customer %-16s p %-10s %-12s %s\n",
                                               static_cast<long long>(d.id), d.verdict.c_str(), who.c_str(), p,
                                               d.resync_method.empty() ? "-" : d.resync_method.c_str(),
                                               d.suspect_name.c_str());
                                 });
  }));
}

}  // namespace

void refusing_store_errors(const std::function<void()>& f) {
  try {
    f();
  } catch (const keys::KeyError& e) {
    throw CommandFailed(1, e.what());
  } catch (const store::StoreError& e) {
    throw CommandFailed(1, e.what());
  } catch (const store::BlobError& e) {
    throw CommandFailed(1, e.what());
  }
}

// meshmark store migrate --to postgresql://...: the home's SQLite store moved into PostgreSQL
// (docs/store.md); the home keeps meshmark.db as it was, and nodes then name the database.
void add_store_migrate(CLI::App& app) {
  auto* grp = app.add_subcommand("store", "The store itself");
  grp->require_subcommand(1);
  auto c = std::make_shared<Common>();
  auto to = std::make_shared<std::string>();
  auto* mig = grp->add_subcommand("migrate", "Copy the home's SQLite store into an empty PostgreSQL database, ids kept");
  mig->add_option("--to", *to, "the PostgreSQL database (postgresql://... or host=... dbname=...)")->required();
  add_common(mig, *c);
  mig->callback(guarded([c, to] {
    const auto home = store::resolve_home(c->home);
    if (::access(home.db.c_str(), F_OK) != 0)
      throw CommandFailed(1, "no SQLite store at " + home.db + " to move (run: meshmark init --home " + home.root + ")");
    const auto tables = store::copy_sqlite_to_postgres(home.db, home.blobs, *to);
    if (c->json) {
      json j = json::object();
      for (const auto& t : tables) j[t.table] = t.rows;
      std::cout << json{{"from", home.db}, {"to", store::redacted_conninfo(*to)}, {"rows", j}}.dump(2) << "\n";
      return;
    }
    std::cout << "moved " << home.db << " into " << store::redacted_conninfo(*to) << "\n";
    for (const auto& t : tables) std::cout << "  " << t.table << " " << t.rows << "\n";
    std::cout << "nodes now name it: store.postgres in meshmarkd.json, MESHMARK_STORE for the CLI\n";
  }));
}

void add_store_commands(CLI::App& app) {
  add_init(app);
  add_store_migrate(app);
  add_customer(app);
  add_tokens(app);
  add_jobs(app);
  add_listings(app);
}

}  // namespace mm::cli

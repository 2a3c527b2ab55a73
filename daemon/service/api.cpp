#include "service/api.h"

#include <sodium.h>

#include <algorithm>
#include <filesystem>
#include <variant>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "meshio/read_mesh.h"
#include "service/build_info.h"
#include "service/handlers.h"
#include "service/run_program.h"
#include "service/status_page.h"
#include "keys/signing.h"
#include "support/hex.h"
#include "support/sha256.h"
#include "support/printable.h"

namespace mm::service {
namespace {

using http::Request;
using http::Response;
using nlohmann::json;
namespace fs = std::filesystem;

constexpr int kMaxCustomersPerRequest = 100;
constexpr int kMaxListLimit = 500;
constexpr int kListScan = 5000;  // rows a filtered list reads at most for one page

const char* title_of(int status) {
  switch (status) {
    case 400: return "Bad Request";
    case 401: return "Unauthorized";
    case 403: return "Forbidden";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 409: return "Conflict";
    case 410: return "Gone";
    case 413: return "Content Too Large";
    case 415: return "Unsupported Media Type";
    case 422: return "Unprocessable Content";
    case 503: return "Service Unavailable";
    default: return "Error";
  }
}

Response fail(int status, const std::string& detail, const std::string& field = "") {
  return http::problem(status, title_of(status), detail, field.empty() ? "{}" : json{{"field", field}}.dump());
}

Response reply(int status, const json& j) {
  Response r;
  r.status = status;
  r.body = j.dump();
  return r;
}

// The page's one inline script is allowed by its hash, nothing else runs: a name or reason that
// slipped into the DOM as markup still could not execute.
Response status_page() {
  static const std::string csp = [] {
    const std::string page = kStatusPageHtml;
    const auto begin = page.find("<script>") + 8;
    const std::string script = page.substr(begin, page.find("</script>") - begin);
    unsigned char h[crypto_hash_sha256_BYTES];
    crypto_hash_sha256(h, reinterpret_cast<const unsigned char*>(script.data()), script.size());
    const std::string b64 = keys::to_base64(std::string(reinterpret_cast<const char*>(h), sizeof h));
    return "default-src 'none'; script-src 'sha256-" + b64 +
           "'; style-src 'unsafe-inline'; connect-src 'self'; img-src 'self'; base-uri 'none'; "
           "form-action 'none'; frame-ancestors 'none'";
  }();
  Response r;
  r.content_type = "text/html; charset=utf-8";
  r.body = kStatusPageHtml;
  r.headers = {{"Content-Security-Policy", csp}, {"X-Frame-Options", "DENY"},
               {"Referrer-Policy", "no-referrer"}, {"Cache-Control", "no-store"}};
  return r;
}

std::string sha256_hex(const std::string& text) { return support::sha256_hex(text.data(), text.size()); }

std::optional<std::int64_t> parse_id(const std::string& s) {
  if (s.empty() || s.size() > 18 || s.find_first_not_of("0123456789") != std::string::npos) return std::nullopt;
  return std::stoll(s);
}

std::vector<std::string> segments(const std::string& path) {
  std::vector<std::string> out;
  std::size_t i = 1;
  while (i <= path.size()) {
    const auto j = path.find('/', i);
    out.push_back(path.substr(i, j == std::string::npos ? std::string::npos : j - i));
    if (j == std::string::npos) break;
    i = j + 1;
  }
  return out;
}

json iso_or_null(const std::optional<store::Millis>& t) { return t ? json(store::iso_utc(*t)) : json(nullptr); }

json job_json(const store::Job& j) {
  const json p = json::parse(j.payload_json, nullptr, false);
  json out{{"id", j.id},
           {"kind", j.kind},
           {"state", api_state(j.state)},
           {"attempts", j.attempt},
           {"max_attempts", j.max_attempts},
           {"created_at", store::iso_utc(j.created_at)},
           {"scheduled_at", store::iso_utc(j.scheduled_at)},
           {"started_at", iso_or_null(j.attempted_at)},
           {"finished_at", iso_or_null(j.finished_at)}};
  // What the job is about, never the rest of its payload.
  if (p.is_object()) {
    for (const char* k : {"name", "customer"})
      if (p.contains(k) && p[k].is_string()) out[k] = p[k];
  }
  json errors = json::array();
  for (const auto& e : j.errors) errors.push_back({{"attempt", e.attempt}, {"at", store::iso_utc(e.at)}, {"error", e.error}});
  out["errors"] = errors;
  out["error"] = j.errors.empty() || j.state == store::JobState::completed ? json(nullptr) : json(j.errors.back().error);
  const json result = j.result_json.empty() ? json(nullptr) : json::parse(j.result_json, nullptr, false);
  out["result"] = result.is_discarded() ? json(nullptr) : result;
  json links{{"self", "/v1/jobs/" + std::to_string(j.id)}};
  if (j.state == store::JobState::completed && j.kind == "protect") {
    links["copy"] = "/v1/jobs/" + std::to_string(j.id) + "/copy";
    links["stream"] = "/v1/jobs/" + std::to_string(j.id) + "/stream";
  }
  if (j.state == store::JobState::completed && j.kind == "detect")
    links["detection"] = "/v1/jobs/" + std::to_string(j.id) + "/detection";
  out["links"] = links;
  return out;
}

std::optional<store::JobState> state_from_api(const std::string& s) {
  using S = store::JobState;
  for (S x : {S::available, S::running, S::retryable, S::completed, S::discarded, S::cancelled})
    if (s == api_state(x)) return x;
  return std::nullopt;
}

// Text a client sent that goes into records and logs as it is: UTF-8 without control characters.
bool plain_text(const std::string& s) {
  for (unsigned char c : s)
    if (c < 32 || c == 127) return false;
  try {
    (void)json(s).dump();  // throws on invalid UTF-8
  } catch (const json::exception&) {
    return false;
  }
  return true;
}

// A file name as a client gives it: plain text, no folder, an extension, at most 255 bytes.
std::optional<std::string> bad_name(const std::string& name) {
  if (name.empty()) return "is empty";
  if (name.size() > 255) return "is longer than 255 bytes";
  if (!plain_text(name)) return "has control characters or is not UTF-8";
  if (name.find('/') != std::string::npos || name.find('\\') != std::string::npos) return "must be a file name, not a path";
  if (name == "." || name == "..") return "must be a file name";
  if (fs::path(name).extension().string().size() < 2) return "needs an extension that names its format (.stl, .step, ...)";
  return std::nullopt;
}

// The Idempotency-Key header: an sf-string ("...") or a bare token, 1-255 printable characters.
std::optional<std::string> idempotency_key(const Request& req, std::string* error) {
  std::string k = req.header("idempotency-key");
  if (k.empty()) return std::string();
  if (k.size() >= 2 && k.front() == '"' && k.back() == '"') k = k.substr(1, k.size() - 2);
  if (k.empty() || k.size() > 255 || !std::all_of(k.begin(), k.end(), [](char c) { return c >= 32 && c < 127; })) {
    *error = "Idempotency-Key must be 1-255 printable characters";
    return std::nullopt;
  }
  return k;
}

const char* content_type_of(const std::string& format) {
  if (format == "stl") return "model/stl";
  if (format == "obj") return "model/obj";
  if (format == "3mf") return "model/3mf";
  if (format == "glb") return "model/gltf-binary";
  if (format == "gltf") return "model/gltf+json";
  return "application/octet-stream";
}

}  // namespace

const char* api_state(store::JobState s) {
  switch (s) {
    case store::JobState::available: return "queued";
    case store::JobState::running: return "running";
    case store::JobState::retryable: return "retrying";
    case store::JobState::completed: return "succeeded";
    case store::JobState::discarded: return "failed";
    case store::JobState::cancelled: return "cancelled";
  }
  return "?";
}

Api::Api(store::Store& st, std::function<std::shared_ptr<const Config>()> config) : st_(st), config_(std::move(config)) {}

http::Routes Api::routes(const std::string& upload_dir) {
  http::Routes r;
  r.upload_dir = upload_dir;
  r.streams_body = [](const Request& req) { return req.method == "POST" && req.path == "/v1/parts"; };
  r.handle = [this](Request& req) { return handle(req); };
  return r;
}

namespace {

// A path against a template ("/v1/jobs/{id}"): the values of its {parameters}, in order.
std::optional<std::vector<std::string>> match(const std::string& pattern, const std::vector<std::string>& seg) {
  const auto pat = segments(pattern);
  if (pat.size() != seg.size()) return std::nullopt;
  std::vector<std::string> params;
  for (std::size_t i = 0; i < pat.size(); ++i) {
    if (pat[i].size() > 2 && pat[i].front() == '{') params.push_back(seg[i]);
    else if (pat[i] != seg[i]) return std::nullopt;
  }
  return params;
}

}  // namespace

// Every route; docs/openapi.json documents exactly these (tests/daemon/test_api.cpp checks it).
const std::vector<Api::Route>& Api::route_table() {
  using R = store::TokenRole;
  static const std::vector<Route> table = {
      {"GET", "/", std::nullopt, [](Api&, Request&, const Caller&, const Params&) { return status_page(); }},
      {"GET", "/healthz", std::nullopt, [](Api&, Request&, const Caller&, const Params&) { return reply(200, {{"status", "ok"}}); }},
      {"GET", "/readyz", std::nullopt, [](Api& a, Request&, const Caller&, const Params&) { return a.ready(); }},
      {"GET", "/metrics", R::read, [](Api& a, Request&, const Caller&, const Params&) { return a.metrics(); }},
      {"GET", "/v1/me", R::read, [](Api&, Request&, const Caller& w, const Params&) {
         return reply(200, {{"name", w.name}, {"role", store::to_string(w.role)}});
       }},
      {"GET", "/v1/queue", R::read, [](Api& a, Request&, const Caller&, const Params&) { return a.queue(); }},
      {"POST", "/v1/parts", R::submit, [](Api& a, Request& q, const Caller&, const Params&) { return a.upload_part(q); }},
      {"GET", "/v1/parts/{sha256}", R::read, [](Api& a, Request&, const Caller&, const Params& p) { return a.part(p[0]); }},
      {"POST", "/v1/jobs/protect", R::submit, [](Api& a, Request& q, const Caller& w, const Params&) { return a.submit(q, w, "protect"); }},
      {"POST", "/v1/jobs/detect", R::submit, [](Api& a, Request& q, const Caller& w, const Params&) { return a.submit(q, w, "detect"); }},
      {"GET", "/v1/jobs", R::read, [](Api& a, Request& q, const Caller&, const Params&) { return a.jobs(q); }},
      {"GET", "/v1/jobs/{id}", R::read, [](Api& a, Request&, const Caller&, const Params& p) { return a.job(p[0]); }},
      {"POST", "/v1/jobs/{id}/cancel", R::submit,
       [](Api& a, Request&, const Caller& w, const Params& p) { return a.job_action(p[0], "cancel", w); }},
      {"POST", "/v1/jobs/{id}/retry", R::admin,
       [](Api& a, Request&, const Caller& w, const Params& p) { return a.job_action(p[0], "retry", w); }},
      {"GET", "/v1/jobs/{id}/copy", R::read, [](Api& a, Request& q, const Caller&, const Params& p) { return a.job_file(p[0], "copy", q); }},
      {"GET", "/v1/jobs/{id}/stream", R::read,
       [](Api& a, Request& q, const Caller&, const Params& p) { return a.job_file(p[0], "stream", q); }},
      {"GET", "/v1/jobs/{id}/detection", R::read, [](Api& a, Request&, const Caller&, const Params& p) { return a.detection_of(p[0]); }},
      {"GET", "/v1/jobs/{id}/evidence", R::read, [](Api& a, Request& q, const Caller&, const Params& p) { return a.evidence(p[0], q); }},
      {"POST", "/v1/jobs/{id}/evidence", R::submit,
       [](Api& a, Request&, const Caller& w, const Params& p) { return a.request_evidence(p[0], w); }},
  };
  return table;
}

Response Api::handle(Request& req) {
  const auto seg = segments(req.path);
  const Route* found = nullptr;
  std::vector<std::string> params;
  std::string allow;
  for (const auto& r : route_table()) {
    auto p = match(r.path, seg);
    if (!p) continue;
    allow += std::string(allow.empty() ? "" : ", ") + r.method + (std::string(r.method) == "GET" ? ", HEAD" : "");
    if (req.method == r.method || (req.method == "HEAD" && std::string(r.method) == "GET")) {
      found = &r;
      params = std::move(*p);
    }
  }
  if (!found && allow.empty()) return fail(404, "no such route: " + support::printable(req.path, 200));
  if (!found) {
    Response r = fail(405, "allowed here: " + allow);
    r.headers.emplace_back("Allow", allow);
    return r;
  }
  Caller who;
  if (found->role) {
    // Bearer tokens (RFC 6750); the token itself is never logged or echoed.
    const std::string auth = req.header("authorization");
    const auto unauthorized = [](const std::string& detail) {
      Response r = fail(401, detail);
      r.headers.emplace_back("WWW-Authenticate", "Bearer realm=\"meshmark\"");
      return r;
    };
    if (auth.size() < 8 || !std::equal(auth.begin(), auth.begin() + 7, "bearer ", [](char a, char b) {
          return std::tolower(static_cast<unsigned char>(a)) == b;
        }))
      return unauthorized("send an API token as 'Authorization: Bearer <token>' (meshmark token create)");
    std::string secret = auth.substr(7);
    secret.erase(0, secret.find_first_not_of(' '));
    const auto token = secret.size() <= 200 ? st_.token_for_secret(secret) : std::nullopt;
    if (!token) return unauthorized("the token is unknown or revoked");
    who = Caller{token->name, token->role};
    if (!who.allows(*found->role))
      return fail(403, "token '" + who.name + "' has role " + store::to_string(who.role) + "; this needs " +
                           store::to_string(*found->role));
  }
  try {
    return found->fn(*this, req, who, params);
  } catch (const store::StoreError& e) {
    spdlog::error("api: {} {}: {}", req.method, support::printable(req.path, 200), e.what());
    return fail(503, "the store refused the request; retry later");
  }
}

Response Api::queue() {
  const auto c = st_.counts();
  return reply(200, {{"queued", c.available}, {"running", c.running}, {"retrying", c.retryable},
                     {"succeeded", c.completed}, {"failed", c.discarded}, {"cancelled", c.cancelled}});
}

Response Api::ready() {
  try {
    st_.counts();
    return reply(200, {{"status", "ready"}});
  } catch (const std::exception& e) {
    return fail(503, std::string("the store does not answer: ") + e.what());
  }
}

Response Api::part(const std::string& sha) {
  if (!store::is_sha256_hex(sha) || !st_.blobs().contains(sha)) return fail(404, "no part with this SHA-256");
  return reply(200, {{"sha256", sha}, {"size", st_.blobs().size(sha)}});
}

namespace {

// A Prometheus label value, escaped as the text format 0.0.4 asks.
std::string label(const std::string& v) {
  std::string out;
  for (char c : v) {
    if (c == '\\' || c == '"') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out;
}

std::string number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Seconds from a job's last claim to its completion.
const std::vector<double> kDurationBuckets = {0.1, 0.5, 1, 2, 5, 10, 30, 60, 300, 1800};

}  // namespace

Response Api::metrics() {
  const auto m = st_.metrics(kDurationBuckets);
  std::string t;
  t += "# HELP meshmark_build_info The running meshmarkd: release version and the SHA-256 of its executable.\n";
  t += "# TYPE meshmark_build_info gauge\n";
  t += "meshmark_build_info{version=\"" + label(meshmark_version()) + "\",build_sha256=\"" + label(build_sha256()) + "\"} 1\n";
  t += "# HELP meshmark_jobs_total Jobs that entered each state, by kind (a retried job enters queued again).\n";
  t += "# TYPE meshmark_jobs_total counter\n";
  for (const auto& c : m.counters) {
    if (c.event == "rescue") continue;
    const char* state = "?";
    try {
      state = api_state(store::job_state_from_string(c.event));
    } catch (const store::StoreError&) {
      continue;
    }
    t += "meshmark_jobs_total{kind=\"" + label(c.kind) + "\",state=\"" + state + "\"} " + std::to_string(c.count) + "\n";
  }
  t += "# HELP meshmark_lease_rescues_total Jobs taken back from workers that stopped heartbeating, by kind.\n";
  t += "# TYPE meshmark_lease_rescues_total counter\n";
  for (const auto& c : m.counters)
    if (c.event == "rescue") t += "meshmark_lease_rescues_total{kind=\"" + label(c.kind) + "\"} " + std::to_string(c.count) + "\n";
  t += "# HELP meshmark_queue_depth Jobs waiting to run (queued or retrying), by kind.\n";
  t += "# TYPE meshmark_queue_depth gauge\n";
  for (const auto& [kind, n] : m.queue_depth) t += "meshmark_queue_depth{kind=\"" + label(kind) + "\"} " + std::to_string(n) + "\n";
  t += "# HELP meshmark_detections_total Detections recorded, by verdict.\n";
  t += "# TYPE meshmark_detections_total counter\n";
  for (const auto& [verdict, n] : m.detections)
    t += "meshmark_detections_total{verdict=\"" + label(verdict) + "\"} " + std::to_string(n) + "\n";
  t += "# HELP meshmark_job_duration_seconds Succeeded jobs' time from their last claim to completion, by kind.\n";
  t += "# TYPE meshmark_job_duration_seconds histogram\n";
  for (const auto& h : m.durations) {
    const std::string k = "kind=\"" + label(h.kind) + "\"";
    for (std::size_t b = 0; b < kDurationBuckets.size(); ++b)
      t += "meshmark_job_duration_seconds_bucket{" + k + ",le=\"" + number(kDurationBuckets[b]) + "\"} " +
           std::to_string(h.cumulative[b]) + "\n";
    t += "meshmark_job_duration_seconds_bucket{" + k + ",le=\"+Inf\"} " + std::to_string(h.count) + "\n";
    t += "meshmark_job_duration_seconds_sum{" + k + "} " + number(h.sum_seconds) + "\n";
    t += "meshmark_job_duration_seconds_count{" + k + "} " + std::to_string(h.count) + "\n";
  }
  Response r;
  r.content_type = "text/plain; version=0.0.4; charset=utf-8";
  r.body = std::move(t);
  return r;
}

Response Api::upload_part(Request& req) {
  const auto it = req.query.find("name");
  if (it == req.query.end()) return fail(422, "give the part's file name as ?name=<file>.<ext>", "name");
  if (auto why = bad_name(it->second)) return fail(422, "name " + *why, "name");
  if (req.body_file.empty() || req.body_size == 0) return fail(422, "the body (the part's bytes) is empty", "body");
  const std::string sha = st_.blobs().put_file(req.body_file);
  if (sha != req.body_sha256) return fail(503, "the part changed while it was stored; send it again");
  Response r = reply(201, {{"sha256", sha}, {"size", req.body_size}, {"name", it->second}});
  r.headers.emplace_back("Location", "/v1/parts/" + sha);
  return r;
}

Response Api::submit(Request& req, const Caller& who, const std::string& kind) {
  const auto cfg = config_();
  const std::string ctype = req.header("content-type");
  if (!ctype.empty() && ctype.rfind("application/json", 0) != 0)
    return fail(415, "send the request as application/json", "Content-Type");
  std::string key_error;
  const auto key = idempotency_key(req, &key_error);
  if (!key) return fail(400, key_error, "Idempotency-Key");
  const json body = json::parse(req.body, nullptr, false);
  if (body.is_discarded() || !body.is_object()) return fail(400, "the body is not a JSON object", "body");
  for (const auto& [k, v] : body.items())
    if (k != "part" && k != "priority" && (kind != "protect" || (k != "customers" && k != "output_format" && k != "object")))
      return fail(422, "unknown field", k.substr(0, 64));
  if (!body.contains("part") || !body["part"].is_object())
    return fail(422, "needs an object {\"sha256\", \"name\"} (an uploaded part) or {\"path\"} (a file under input_roots)", "part");
  const json& part = body["part"];
  std::string sha, name;
  if (part.contains("sha256")) {
    if (!part["sha256"].is_string() || !store::is_sha256_hex(part["sha256"].get<std::string>()))
      return fail(422, "must be 64 lower-case hex digits", "part.sha256");
    sha = part["sha256"].get<std::string>();
    if (!st_.blobs().contains(sha)) return fail(422, "no uploaded part has this SHA-256 (POST /v1/parts first)", "part.sha256");
    if (!part.contains("name") || !part["name"].is_string()) return fail(422, "needs the part's file name", "part.name");
    name = part["name"].get<std::string>();
  } else if (part.contains("path")) {
    if (!part["path"].is_string()) return fail(422, "must be a string", "part.path");
    const std::string path = part["path"].get<std::string>();
    std::string real;
    try {
      real = resolve_input_path(path, *cfg, "part.path " + support::printable(path, 200));
    } catch (const PermanentError& e) {
      return fail(422, e.what(), "part.path");
    }
    std::error_code ec;
    const auto size = fs::file_size(real, ec);
    if (ec) return fail(422, "part.path " + support::printable(path, 200) + ": " + ec.message(), "part.path");
    if (cfg->max_input_bytes > 0 && size > static_cast<std::uintmax_t>(cfg->max_input_bytes))
      return fail(413, "part.path is " + std::to_string(size) + " bytes, over max_input_bytes", "part.path");
    name = part.contains("name") && part["name"].is_string() ? part["name"].get<std::string>() : fs::path(real).filename().string();
    sha = st_.blobs().put_file(real);
  } else {
    return fail(422, "needs \"sha256\" (an uploaded part) or \"path\" (a file under input_roots)", "part");
  }
  if (auto why = bad_name(name)) return fail(422, "name " + *why, "part.name");
  int priority = 0;
  if (body.contains("priority")) {
    if (!body["priority"].is_number_integer() || std::abs(body["priority"].get<long long>()) > 1000)
      return fail(422, "must be an integer from -1000 to 1000", "priority");
    priority = body["priority"].get<int>();
  }
  std::vector<std::string> customers;
  std::string format, object;
  if (kind == "protect") {
    if (!body.contains("customers") || !body["customers"].is_array() || body["customers"].empty() ||
        body["customers"].size() > kMaxCustomersPerRequest)
      return fail(422, "needs an array of 1-" + std::to_string(kMaxCustomersPerRequest) + " customer names", "customers");
    for (std::size_t i = 0; i < body["customers"].size(); ++i) {
      const json& c = body["customers"][i];
      const std::string field = "customers[" + std::to_string(i) + "]";
      if (!c.is_string()) return fail(422, "must be a customer name", field);
      if (!st_.find_customer(c.get<std::string>()))
        return fail(422, "no customer named '" + support::printable(c.get<std::string>(), 64) + "'", field);
      if (std::find(customers.begin(), customers.end(), c.get<std::string>()) == customers.end())
        customers.push_back(c.get<std::string>());
    }
    if (body.contains("output_format")) {
      if (!body["output_format"].is_string() || !is_mesh_format(body["output_format"].get<std::string>()))
        return fail(422, "must be one of " + mesh_format_list(), "output_format");
      format = body["output_format"].get<std::string>();
    }
    if (body.contains("object")) {
      if (!body["object"].is_string() || body["object"].get<std::string>().empty() || body["object"].get<std::string>().size() > 256)
        return fail(422, "must be a 3MF object's name (1-256 bytes)", "object");
      object = body["object"].get<std::string>();
    }
  } else {
    customers.push_back("");
  }

  // The same key and body: the same jobs. The fingerprint covers what the request asks for.
  const std::string fingerprint = sha256_hex(kind + "\n" + body.dump());
  const std::string scoped = who.name + "\n" + *key;
  struct InFlight {
    Api* api;
    std::string key;
    ~InFlight() {
      if (key.empty()) return;
      std::lock_guard<std::mutex> l(api->inflight_m_);
      api->inflight_.erase(key);
    }
  } inflight{this, ""};
  if (!key->empty()) {
    std::lock_guard<std::mutex> l(inflight_m_);
    if (!inflight_.insert(scoped).second) {
      Response r = fail(409, "a request with this Idempotency-Key is still being handled", "Idempotency-Key");
      r.headers.emplace_back("Retry-After", "1");
      return r;
    }
    inflight.key = scoped;
  }
  json out = json::array();
  bool any_created = false;
  std::int64_t first = 0;
  for (const auto& customer : customers) {
    json p = kind == "protect" ? json{{"customer", customer}, {"input_sha256", sha}, {"name", name}}
                               : json{{"input_sha256", sha}, {"name", name}};
    if (!format.empty()) p["output_format"] = format;
    if (!object.empty()) p["object"] = object;
    p["request_sha256"] = fingerprint;
    store::JobSpec spec;
    spec.kind = kind;
    spec.payload_json = p.dump();
    spec.priority = priority;
    spec.max_attempts = cfg->max_attempts;
    // Without a key, what the job is decides (as `meshmark submit`): a resubmission finds it.
    spec.idempotency_key =
        !key->empty() ? "api:" + who.name + ":" + *key + (kind == "protect" ? ":" + customer : "")
        : kind == "protect"
            ? "protect:" + customer + ":" + sha + ":" + name + (format.empty() ? "" : ":" + format) +
                  (object.empty() ? "" : ":object=" + object)
            : "detect:" + sha + ":" + name;
    const auto r = st_.enqueue(spec, "api:" + who.name);
    if (!r.created && !key->empty()) {
      const json was = json::parse(r.job.payload_json, nullptr, false);
      if (!was.is_object() || was.value("request_sha256", "") != fingerprint)
        return fail(422, "this Idempotency-Key was used with another request; use a new key for a new request",
                    "Idempotency-Key");
    }
    any_created = any_created || r.created;
    if (!first) first = r.job.id;
    json j = job_json(r.job);
    j["created"] = r.created;
    out.push_back(j);
  }
  Response res = reply(202, {{"jobs", out}});
  res.headers.emplace_back("Location", "/v1/jobs/" + std::to_string(first));
  res.headers.emplace_back("Retry-After", "2");
  if (!any_created) res.headers.emplace_back("Idempotent-Replayed", "true");
  return res;
}

Response Api::job(const std::string& id_text) {
  const auto id = parse_id(id_text);
  if (!id) return fail(404, "a job id is a positive integer");
  const auto j = st_.get_job(*id);
  if (!j) return fail(404, "no job " + std::to_string(*id));
  Response r = reply(200, job_json(*j));
  if (j->state == store::JobState::available || j->state == store::JobState::running || j->state == store::JobState::retryable)
    r.headers.emplace_back("Retry-After", "2");
  return r;
}

Response Api::jobs(const Request& req) {
  store::JobFilter f;
  int limit = 50;
  for (const auto& [k, v] : req.query) {
    if (k == "kind") {
      f.kind = v;
    } else if (k == "state") {
      const auto s = state_from_api(v);
      if (!s) return fail(422, "one of queued, running, retrying, succeeded, failed, cancelled", "state");
      f.state = s;
    } else if (k == "limit") {
      const auto n = parse_id(v);
      if (!n || *n < 1 || *n > kMaxListLimit) return fail(422, "from 1 to " + std::to_string(kMaxListLimit), "limit");
      limit = static_cast<int>(*n);
    } else if (k == "cursor") {
      const auto n = parse_id(v);
      if (!n || *n < 1) return fail(422, "a cursor from a previous page's next_cursor", "cursor");
      f.before_id = *n;
    } else if (k != "name") {
      return fail(422, "unknown query parameter (kind, state, name, limit, cursor)", support::printable(k, 64));
    }
  }
  const auto name_it = req.query.find("name");
  json out = json::array();
  std::int64_t last = 0;
  bool more = false;
  int scanned = 0;
  // Newest first; a name filter reads pages until this one is full (at most kListScan rows).
  while (static_cast<int>(out.size()) < limit && scanned < kListScan) {
    f.limit = name_it == req.query.end() ? limit - static_cast<int>(out.size()) + 1 : 200;
    const auto page = st_.list_jobs(f);
    scanned += static_cast<int>(page.size());
    for (const auto& j : page) {
      if (static_cast<int>(out.size()) == limit) {
        more = true;
        break;
      }
      last = j.id;
      if (name_it != req.query.end()) {
        const json p = json::parse(j.payload_json, nullptr, false);
        if (!p.is_object() || p.value("name", "") != name_it->second) continue;
      }
      out.push_back(job_json(j));
    }
    if (more || static_cast<int>(page.size()) < f.limit) break;
    f.before_id = last;
  }
  if (!more && scanned >= kListScan) more = true;  // the scan stopped; the cursor goes on from there
  return reply(200, {{"jobs", out}, {"next_cursor", more && last > 0 ? json(std::to_string(last)) : json(nullptr)}});
}

Response Api::job_action(const std::string& id_text, const std::string& action, const Caller& who) {
  const auto parsed = parse_id(id_text);
  if (!parsed) return fail(404, "a job id is a positive integer");
  const std::int64_t id = *parsed;
  const auto j = st_.get_job(id);
  if (!j) return fail(404, "no job " + std::to_string(id));
  const bool done = action == "cancel" ? st_.cancel(id, "api:" + who.name) : st_.retry(id, "api:" + who.name);
  if (!done)
    return fail(409, "job " + std::to_string(id) + " is " + api_state(j->state) + "; " +
                         (action == "cancel" ? "only queued, retrying or running jobs can be cancelled"
                                             : "only failed, retrying or cancelled jobs can be retried"));
  return reply(200, job_json(*st_.get_job(id)));
}

Response Api::job_file(const std::string& id_text, const std::string& which, const Request& req) {
  const auto parsed = parse_id(id_text);
  if (!parsed) return fail(404, "a job id is a positive integer");
  const std::int64_t id = *parsed;
  const auto j = st_.get_job(id);
  if (!j) return fail(404, "no job " + std::to_string(id));
  if (j->kind != "protect") return fail(404, "job " + std::to_string(id) + " is a " + j->kind + " job; copies come from protect jobs");
  if (j->state != store::JobState::completed)
    return fail(409, "job " + std::to_string(id) + " is " + api_state(j->state) + "; its copy exists once it has succeeded");
  const json r = json::parse(j->result_json, nullptr, false);
  const std::string path_key = which == "copy" ? "output" : "stream", sha_key = path_key + "_sha256";
  if (!r.is_object() || !r.contains(path_key) || !r[path_key].is_string() || !r.contains(sha_key))
    return fail(410, "job " + std::to_string(id) + " recorded no " + which + " file");
  const std::string path = r[path_key].get<std::string>(), sha = r.value(sha_key, "");
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return fail(410, "the " + which + " of job " + std::to_string(id) + " is no longer in the output folder");
  Response res;
  const std::string etag = "\"" + sha + "\"";
  res.headers.emplace_back("ETag", etag);
  if (req.header("if-none-match") == etag) {
    res.status = 304;
    res.content_type.clear();
    return res;
  }
  res.file = path;
  res.content_type = which == "copy" ? content_type_of(lower_extension(path)) : "application/octet-stream";
  res.headers.emplace_back("Content-Disposition", "attachment; filename=\"" + fs::path(path).filename().string() + "\"");
  return res;
}

Response Api::detection_of(const std::string& id_text) {
  const auto parsed = parse_id(id_text);
  if (!parsed) return fail(404, "a job id is a positive integer");
  const std::int64_t id = *parsed;
  const auto j = st_.get_job(id);
  if (!j) return fail(404, "no job " + std::to_string(id));
  if (j->kind != "detect") return fail(404, "job " + std::to_string(id) + " is a " + j->kind + " job, not a detection");
  if (j->state != store::JobState::completed)
    return fail(409, "job " + std::to_string(id) + " is " + api_state(j->state) + "; its verdict exists once it has succeeded");
  const auto d = st_.detection_of_job(id);
  if (!d) return fail(410, "job " + std::to_string(id) + " recorded no detection");
  json out{{"id", d->id},
           {"job_id", id},
           {"verdict", d->verdict},
           {"suspect_name", d->suspect_name},
           {"suspect_sha256", d->suspect_sha256},
           {"asset_id", d->asset_id ? json(*d->asset_id) : json(nullptr)},
           {"copy_id", d->copy_id ? json(*d->copy_id) : json(nullptr)},
           {"customer", nullptr},
           {"p_value", d->p_value ? json(*d->p_value) : json(nullptr)},
           {"resync_method", d->resync_method},
           {"created_at", store::iso_utc(d->created_at)}};
  if (d->customer_id)
    if (const auto c = st_.get_customer(*d->customer_id)) out["customer"] = c->name;
  const json details = json::parse(d->details_json, nullptr, false);
  out["details"] = details.is_discarded() ? json(nullptr) : details;
  return reply(200, out);
}

namespace {

// The detection a succeeded detect job recorded, or the problem saying why there is none.
std::variant<store::Detection, Response> detection_for(store::Store& st, const std::string& id_text) {
  const auto id = parse_id(id_text);
  if (!id) return fail(404, "a job id is a positive integer");
  const auto j = st.get_job(*id);
  if (!j) return fail(404, "no job " + std::to_string(*id));
  if (j->kind != "detect") return fail(404, "job " + std::to_string(*id) + " is a " + j->kind + " job, not a detection");
  if (j->state != store::JobState::completed)
    return fail(409, "job " + std::to_string(*id) + " is " + api_state(j->state) + "; its verdict exists once it has succeeded");
  const auto d = st.detection_of_job(*id);
  if (!d) return fail(410, "job " + std::to_string(*id) + " recorded no detection");
  return *d;
}

}  // namespace

Response Api::evidence(const std::string& id_text, const Request& req) {
  auto d = detection_for(st_, id_text);
  if (auto* problem = std::get_if<Response>(&d)) return *problem;
  const auto& det = std::get<store::Detection>(d);
  const auto cfg = config_();
  const fs::path dir = evidence_package_dir(*cfg, det);
  std::error_code ec;
  if (!fs::is_regular_file(dir / "statement.dsse.json", ec))
    return fail(404, "detection " + std::to_string(det.id) + " has no evidence package yet (POST this URL to write one)");
  const std::string etag = "\"" + support::sha256_file_hex((dir / "statement.json").string()) + "\"";
  Response res;
  res.headers.emplace_back("ETag", etag);
  if (req.header("if-none-match") == etag) {
    res.status = 304;
    res.content_type.clear();
    return res;
  }
  // The package folder as one tar (the same bytes each time: sorted, owner and times fixed).
  std::uint8_t rnd[8];
  randombytes_buf(rnd, sizeof rnd);
  const std::string tar = (fs::temp_directory_path() / ("meshmark-evidence-" + support::to_hex(rnd, sizeof rnd) + ".tar")).string();
  const int rc = run_program({"tar", "--sort=name", "--owner=0", "--group=0", "--numeric-owner", "--mtime=@0", "-C",
                              dir.parent_path().string(), "-cf", tar, dir.filename().string()});
  if (rc != 0) {
    fs::remove(tar, ec);
    return fail(503, "the evidence package could not be archived; retry later");
  }
  res.file = tar;
  res.remove_file = true;
  res.content_type = "application/x-tar";
  res.headers.emplace_back("Content-Disposition", "attachment; filename=\"" + dir.filename().string() + ".tar\"");
  return res;
}

Response Api::request_evidence(const std::string& id_text, const Caller& who) {
  auto d = detection_for(st_, id_text);
  if (auto* problem = std::get_if<Response>(&d)) return *problem;
  const auto cfg = config_();
  store::JobSpec spec;
  spec.kind = "evidence";
  spec.payload_json = json{{"detect_job", std::get<store::Detection>(d).job_id.value_or(0)}}.dump();
  spec.max_attempts = cfg->max_attempts;
  spec.idempotency_key = "evidence:job:" + id_text;  // as evidence.auto enqueues it
  const auto r = st_.enqueue(spec, "api:" + who.name);
  json j = job_json(r.job);
  j["created"] = r.created;
  Response res = reply(202, {{"jobs", json::array({j})}});
  res.headers.emplace_back("Location", "/v1/jobs/" + std::to_string(r.job.id));
  res.headers.emplace_back("Retry-After", "5");
  return res;
}

}  // namespace mm::service

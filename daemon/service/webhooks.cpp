#include "service/webhooks.h"
#include "keys/signing.h"

#include <sodium.h>
#include <sys/stat.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "service/api.h"
#include "service/run_program.h"
#include "support/printable.h"

namespace mm::service {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

std::string base64(const unsigned char* data, std::size_t n) {
  return keys::to_base64(std::string(reinterpret_cast<const char*>(data), n));
}

const WebhookEndpoint* endpoint_named(const Config& cfg, const std::string& name) {
  for (const auto& e : cfg.webhooks)
    if (e.name == name) return &e;
  return nullptr;
}

}  // namespace

std::vector<std::string> read_webhook_secrets(const std::string& path) {
  struct stat sb{};
  if (::stat(path.c_str(), &sb) != 0) throw PermanentError("webhook secret file " + path + ": cannot be read");
  if (sb.st_mode & (S_IRWXG | S_IRWXO))
    throw PermanentError("webhook secret file " + path + ": others can read it (chmod 600)");
  std::ifstream in(path);
  std::vector<std::string> secrets;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    const std::string where = "webhook secret file " + path + ", line " + std::to_string(n);
    if (line.rfind("whsec_", 0) != 0) throw PermanentError(where + ": a secret starts with whsec_");
    std::string key(line.size(), '\0');
    std::size_t len = 0;
    if (sodium_base642bin(reinterpret_cast<unsigned char*>(key.data()), key.size(), line.data() + 6, line.size() - 6,
                          nullptr, &len, nullptr, sodium_base64_VARIANT_ORIGINAL) != 0 ||
        len < 24 || len > 64)
      throw PermanentError(where + ": not base64 of 24 to 64 bytes");
    key.resize(len);
    secrets.push_back(std::move(key));
  }
  if (secrets.empty()) throw PermanentError("webhook secret file " + path + ": holds no secret");
  return secrets;
}

std::string webhook_signature(const std::vector<std::string>& secrets, const std::string& id,
                              const std::string& timestamp, const std::string& body) {
  const std::string content = id + "." + timestamp + "." + body;
  std::string out;
  for (const auto& key : secrets) {
    crypto_auth_hmacsha256_state st;
    unsigned char mac[crypto_auth_hmacsha256_BYTES];
    crypto_auth_hmacsha256_init(&st, reinterpret_cast<const unsigned char*>(key.data()), key.size());
    crypto_auth_hmacsha256_update(&st, reinterpret_cast<const unsigned char*>(content.data()), content.size());
    crypto_auth_hmacsha256_final(&st, mac);
    out += (out.empty() ? "" : " ") + std::string("v1,") + base64(mac, sizeof mac);
  }
  return out;
}

std::string new_webhook_secret() {
  if (sodium_init() < 0) throw std::runtime_error("libsodium failed to initialise");
  unsigned char key[32];
  randombytes_buf(key, sizeof key);
  std::string s = "whsec_" + base64(key, sizeof key);
  sodium_memzero(key, sizeof key);
  return s;
}

int dispatch_webhooks(store::Store& st, const Config& cfg) {
  return st.consume_job_events("webhooks", 500, [&cfg](const store::JobEvent& e) {
    std::vector<store::JobSpec> specs;
    for (const auto& ep : cfg.webhooks) {
      store::JobSpec s;
      s.kind = "webhook";
      s.payload_json = json{{"endpoint", ep.name}, {"event_id", e.id}, {"job_id", e.job_id},
                            {"kind", e.kind},      {"state", api_state(e.state)}, {"at", e.at}}
                           .dump();
      s.max_attempts = cfg.webhook_max_attempts;
      s.idempotency_key = "webhook:" + ep.name + ":" + std::to_string(e.id);
      specs.push_back(std::move(s));
    }
    return specs;
  });
}

store::JobRecords run_webhook(store::Store& st, const store::Job& job, const HandlerContext& ctx) {
  const json p = json::parse(job.payload_json, nullptr, false);
  const std::string what = "job " + std::to_string(job.id);
  if (!p.is_object() || !p.contains("endpoint") || !p["endpoint"].is_string() || !p.contains("event_id") ||
      !p["event_id"].is_number_integer() || !p.contains("job_id") || !p["job_id"].is_number_integer())
    throw PermanentError(what + ": a webhook payload needs endpoint, event_id and job_id");
  const std::string name = p["endpoint"].get<std::string>();
  const WebhookEndpoint* ep = endpoint_named(ctx.config, name);
  if (!ep) throw PermanentError(what + ": webhook endpoint " + support::printable(name, 64) + " is no longer configured");
  const auto secrets = read_webhook_secrets(ep->secret_file);
  const std::int64_t job_id = p["job_id"].get<std::int64_t>();
  const std::string state = p.value("state", "");
  // Thin: what happened and where to read more; the receiver fetches the rest with its token.
  const json body{{"type", "job." + state},
                  {"timestamp", store::iso_utc(p.value("at", st.now()))},
                  {"data", {{"job_id", job_id}, {"kind", p.value("kind", "")}, {"state", state},
                            {"links", {{"self", "/v1/jobs/" + std::to_string(job_id)}}}}}};
  const std::string text = body.dump();
  const std::string id = "msg_" + std::to_string(p["event_id"].get<std::int64_t>());
  const std::string timestamp = std::to_string(st.now() / 1000);
  const std::string signature = webhook_signature(secrets, id, timestamp, text);

  const fs::path tmp = fs::temp_directory_path() / ("meshmark-webhook-" + std::to_string(job.id) + "-" + ctx.worker_id);
  const std::string body_file = tmp.string() + ".json", log = tmp.string() + ".log";
  std::ofstream(body_file, std::ios::binary) << text;
  // No redirects, http(s) only, bounded time: the endpoint is the configured URL and nothing else.
  const int rc = run_program({"curl", "--silent", "--show-error", "--proto", "=http,https", "--max-time", "30",
                              "--output", "/dev/null", "--write-out", "\nhttp_status=%{http_code}\n", "-H",
                              "content-type: application/json", "-H", "webhook-id: " + id, "-H",
                              "webhook-timestamp: " + timestamp, "-H", "webhook-signature: " + signature,
                              "--data-binary", "@" + body_file, ep->url},
                             log);
  std::ifstream in(log);
  const std::string out((std::istreambuf_iterator<char>(in)), {});
  std::error_code ec;
  fs::remove(body_file, ec);
  fs::remove(log, ec);
  const auto at = out.rfind("http_status=");
  const int status = at == std::string::npos ? 0 : std::atoi(out.c_str() + at + 12);
  if (rc != 0 || status < 200 || status > 299) {
    std::string reason = out.substr(0, at == std::string::npos ? std::string::npos : at);
    while (!reason.empty() && (reason.back() == '\n' || reason.back() == '\r')) reason.pop_back();
    throw std::runtime_error("webhook " + name + ": " +
                             (status > 0 ? "HTTP " + std::to_string(status) : "no answer (" + support::printable(reason, 200) + ")") +
                             "; will retry");
  }
  store::JobRecords rec;
  rec.result_json = json{{"endpoint", name}, {"event", id}, {"status", status}, {"job_id", job_id}}.dump();
  return rec;
}

}  // namespace mm::service

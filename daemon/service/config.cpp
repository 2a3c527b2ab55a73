#include "service/config.h"

#include "http/server.h"
#include "meshio/read_mesh.h"
#include "store/home.h"

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>

namespace mm::service {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

class Checker {
 public:
  Checker(std::string source, std::string base) : source_(std::move(source)), base_(std::move(base)) {}
  void error(const std::string& key, const std::string& why) { errors_.push_back(key + ": " + why); }
  bool ok() const { return errors_.empty(); }
  std::string report() const {
    std::string s = source_ + ": invalid configuration";
    for (const auto& e : errors_) s += "\n  " + e;
    return s;
  }

  void known(const json& obj, const std::string& prefix, const std::set<std::string>& keys) {
    for (auto it = obj.begin(); it != obj.end(); ++it)
      if (!keys.count(it.key()))
        error(prefix + it.key(), "unknown key (see config/config-keys.md)");
  }
  void integer(const json& obj, const std::string& prefix, const char* key, int& out, long lo, long hi) {
    if (!obj.contains(key)) return;
    const json& v = obj[key];
    if (!v.is_number_integer()) return error(prefix + key, "must be an integer, got " + std::string(v.type_name()));
    auto x = v.get<long long>();
    if (x < lo || x > hi)
      return error(prefix + key, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + std::to_string(x));
    out = static_cast<int>(x);
  }
  void integer64(const json& obj, const std::string& prefix, const char* key, std::int64_t& out, long long lo,
                 long long hi) {
    int dummy = 0;
    if (!obj.contains(key)) return;
    if (!obj[key].is_number_integer()) return integer(obj, prefix, key, dummy, lo, hi);  // reports the type
    const auto x = obj[key].get<long long>();
    if (x < lo || x > hi)
      return error(prefix + key, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + std::to_string(x));
    out = x;
  }
  void number(const json& obj, const std::string& prefix, const char* key, double& out, double lo, double hi,
              bool open_lo) {
    if (!obj.contains(key)) return;
    const json& v = obj[key];
    if (!v.is_number()) return error(prefix + key, "must be a number, got " + std::string(v.type_name()));
    double x = v.get<double>();
    if (!(open_lo ? x > lo : x >= lo) || !(x <= hi)) {
      std::ostringstream s;
      s << "must be in " << (open_lo ? "(" : "[") << lo << ", " << hi << "], got " << x;
      return error(prefix + key, s.str());
    }
    out = x;
  }
  // An array of numbers, each in (lo, hi].
  void numbers(const json& obj, const std::string& prefix, const char* key, std::vector<double>& out, double lo,
               double hi) {
    if (!obj.contains(key)) return;
    const json& v = obj[key];
    if (!v.is_array()) return error(prefix + key, "must be an array of numbers, got " + std::string(v.type_name()));
    std::vector<double> list;
    for (const json& x : v) {
      if (!x.is_number()) return error(prefix + key, "must hold numbers only, got " + std::string(x.type_name()));
      const double d = x.get<double>();
      if (!(d > lo && d <= hi)) {
        std::ostringstream s;
        s << "every value must be in (" << lo << ", " << hi << "], got " << d;
        return error(prefix + key, s.str());
      }
      list.push_back(d);
    }
    out = std::move(list);
  }
  void boolean(const json& obj, const std::string& prefix, const char* key, bool& out) {
    if (!obj.contains(key)) return;
    if (!obj[key].is_boolean()) return error(prefix + key, "must be true or false");
    out = obj[key].get<bool>();
  }
  void string(const json& obj, const std::string& prefix, const char* key, std::string& out,
              const std::set<std::string>& allowed = {}) {
    if (!obj.contains(key)) return;
    if (!obj[key].is_string()) return error(prefix + key, "must be a string, got " + std::string(obj[key].type_name()));
    std::string s = obj[key].get<std::string>();
    if (!allowed.empty() && !allowed.count(s)) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      return error(prefix + key, "must be one of " + list + ", got \"" + s + "\"");
    }
    out = s;
  }
  void path(const json& obj, const char* key, std::string& out, bool required) {
    if (!obj.contains(key)) {
      if (required) error(key, "missing (required)");
      return;
    }
    std::string s;
    string(obj, "", key, s);
    if (!obj[key].is_string()) return;
    if (s.empty()) return error(key, "must not be empty");
    fs::path p(s);
    if (p.is_relative() && !base_.empty()) p = fs::path(base_) / p;
    out = p.lexically_normal().string();
  }
  void folder_exists(const std::string& key, const std::string& p) {
    if (p.empty()) return;
    std::error_code ec;
    if (!fs::is_directory(p, ec)) error(key, "folder " + p + " does not exist");
  }

 private:
  std::string source_, base_;
  std::vector<std::string> errors_;
};

}  // namespace

std::string Config::master_key_path() const {
  return master_key_file.empty() ? (fs::path(home) / "master.key").string() : master_key_file;
}

Config parse_config(const std::string& text, const std::string& source, const std::string& base_dir,
                    bool check_folders) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number like 1e999
    throw ConfigError(source + ": not valid JSON: " + e.what());
  }
  if (!j.is_object()) throw ConfigError(source + ": the configuration must be a JSON object");
  Checker c(source, base_dir);
  Config cfg;
  cfg.source = source;
  c.known(j, "", {"home", "drop_dir", "output_dir", "master_key_file", "workers", "lease_seconds",
                  "heartbeat_seconds", "max_attempts", "shutdown_grace_seconds", "job_retention_days", "poll_interval_ms",
                  "settle_ms", "use_inotify", "input_roots", "max_input_bytes", "max_triangles", "output_format", "watermark", "compression", "detect", "evidence", "cad", "http", "webhooks", "store", "log_level",
                  "log_file", "$comment"});
  c.path(j, "home", cfg.home, true);
  c.path(j, "drop_dir", cfg.drop_dir, true);
  c.path(j, "output_dir", cfg.output_dir, true);
  c.path(j, "master_key_file", cfg.master_key_file, false);
  if (j.contains("input_roots")) {
    const json& r = j["input_roots"];
    if (!r.is_array()) {
      c.error("input_roots", "must be an array of folders");
    } else {
      for (const json& x : r) {
        if (!x.is_string() || x.get<std::string>().empty()) {
          c.error("input_roots", "must hold non-empty folder paths only");
          break;
        }
        fs::path p(x.get<std::string>());
        if (p.is_relative() && !base_dir.empty()) p = fs::path(base_dir) / p;
        cfg.input_roots.push_back(p.lexically_normal().string());
      }
    }
  }
  c.integer(j, "", "workers", cfg.workers, 1, 64);
  c.integer(j, "", "lease_seconds", cfg.lease_seconds, 5, 86400);
  c.integer(j, "", "heartbeat_seconds", cfg.heartbeat_seconds, 1, 3600);
  c.integer(j, "", "max_attempts", cfg.max_attempts, 1, 100);
  c.integer(j, "", "shutdown_grace_seconds", cfg.shutdown_grace_seconds, 0, 3600);
  c.integer(j, "", "job_retention_days", cfg.job_retention_days, 0, 36500);
  c.integer(j, "", "poll_interval_ms", cfg.poll_interval_ms, 20, 600000);
  c.integer(j, "", "settle_ms", cfg.settle_ms, 0, 600000);
  c.integer64(j, "", "max_input_bytes", cfg.max_input_bytes, 0, 1ll << 40);
  c.integer64(j, "", "max_triangles", cfg.max_triangles, 0, 1ll << 32);
  c.boolean(j, "", "use_inotify", cfg.use_inotify);
  {
    std::set<std::string> formats{"same"};
    formats.insert(mesh_formats().begin(), mesh_formats().end());
    c.string(j, "", "output_format", cfg.output_format, formats);
  }
  c.string(j, "", "log_level", cfg.log_level, {"trace", "debug", "info", "warn", "error", "critical", "off"});
  if (j.contains("log_file")) {
    std::string lf;
    c.string(j, "", "log_file", lf);
    if (!lf.empty()) {
      fs::path p(lf);
      if (p.is_relative() && !base_dir.empty()) p = fs::path(base_dir) / p;
      cfg.log_file = p.lexically_normal().string();
    }
  }
  if (j.contains("watermark")) {
    const json& w = j["watermark"];
    if (!w.is_object()) {
      c.error("watermark", "must be an object");
    } else {
      c.known(w, "watermark.",
              {"method", "strength", "threshold", "message_bits", "max_vertices", "min_vertices", "share"});
      std::string method = method_name(cfg.watermark.params.method);
      std::set<std::string> methods;
      for (Method m : kMethods) methods.insert(method_name(m));
      c.string(w, "watermark.", "method", method, methods);
      cfg.watermark.params.method = method_from_name(method);
      c.number(w, "watermark.", "strength", cfg.watermark.params.strength, 0, 1, true);
      c.number(w, "watermark.", "threshold", cfg.watermark.params.threshold, 0, 1e9, false);
      c.integer(w, "watermark.", "message_bits", cfg.watermark.message_bits, 8, 64);
      c.integer(w, "watermark.", "max_vertices", cfg.max_vertices, 4, kMaxBasisVertices);
      c.integer(w, "watermark.", "min_vertices", cfg.min_mark_vertices, 0, 20000);
      c.number(w, "watermark.", "share", cfg.mark_share, 0, 0.9, true);
    }
  }
  if (j.contains("compression")) {
    const json& w = j["compression"];
    if (!w.is_object()) {
      c.error("compression", "must be an object");
    } else {
      c.known(w, "compression.", {"tolerance", "max_vertices", "levels", "angle", "fallback_angles", "quads",
                                           "coarsen", "stream_bits"});
      c.number(w, "compression.", "tolerance", cfg.compression.tolerance, 0, 0.5, true);
      c.integer(w, "compression.", "max_vertices", cfg.compression.max_vertices, 8, kMaxBasisVertices);
      c.integer(w, "compression.", "levels", cfg.compression.levels, 1, 5);
      c.number(w, "compression.", "angle", cfg.compression.angle_degrees, 0, 180, true);
      c.numbers(w, "compression.", "fallback_angles", cfg.fallback_angles, 0, 180);
      c.boolean(w, "compression.", "quads", cfg.compression.rail_quads);
      c.boolean(w, "compression.", "coarsen", cfg.compression.coarsen);
      c.integer(w, "compression.", "stream_bits", cfg.stream_bits, 12, 24);
    }
  }
  if (cfg.compression.max_vertices > cfg.max_vertices)
    c.error("compression.max_vertices", "must be at most watermark.max_vertices (" + std::to_string(cfg.max_vertices) +
                                            "), the watermark's limit");
  if (j.contains("cad")) {
    const json& w = j["cad"];
    if (!w.is_object()) {
      c.error("cad", "must be an object");
    } else {
      c.known(w, "cad.", {"linear_deflection", "angular_deflection", "copy_format"});
      c.number(w, "cad.", "linear_deflection", cfg.cad.linear_deflection, 0, 0.1, true);
      c.number(w, "cad.", "angular_deflection", cfg.cad.angular_deflection_degrees, 1, 90, false);
      const std::set<std::string> formats(mesh_formats().begin(), mesh_formats().end());
      c.string(w, "cad.", "copy_format", cfg.cad_copy_format, formats);
    }
  }
  if (j.contains("detect")) {
    const json& d = j["detect"];
    if (!d.is_object()) {
      c.error("detect", "must be an object");
    } else {
      c.known(d, "detect.", {"p_threshold", "max_candidates", "context_cache_mb"});
      c.number(d, "detect.", "p_threshold", cfg.p_threshold, 0, 0.01, true);
      c.integer(d, "detect.", "max_candidates", cfg.max_candidates, 1, 100);
      c.integer(d, "detect.", "context_cache_mb", cfg.context_cache_mb, 0, 1048576);
    }
  }
  if (j.contains("http")) {
    const json& h = j["http"];
    if (!h.is_object()) {
      c.error("http", "must be an object");
    } else {
      c.known(h, "http.", {"listen", "threads", "max_body_bytes"});
      c.string(h, "http.", "listen", cfg.http_listen);
      if (!cfg.http_listen.empty()) {
        try {
          http::parse_listen(cfg.http_listen);
        } catch (const std::invalid_argument& e) {
          c.error("http.listen", e.what());
        }
      }
      c.integer(h, "http.", "threads", cfg.http_threads, 1, 64);
      c.integer(h, "http.", "max_body_bytes", cfg.http_max_body_bytes, 1024, 64 << 20);
    }
  }
  if (j.contains("store")) {
    const json& st = j["store"];
    if (!st.is_object()) {
      c.error("store", "must be an object");
    } else {
      c.known(st, "store.", {"postgres"});
      c.string(st, "store.", "postgres", cfg.store_postgres);
      if (st.contains("postgres") && cfg.store_postgres.empty())
        c.error("store.postgres", "must name a PostgreSQL database (postgresql://... or host=... dbname=...)");
    }
  }
  if (j.contains("webhooks")) {
    const json& w = j["webhooks"];
    if (!w.is_object()) {
      c.error("webhooks", "must be an object");
    } else {
      c.known(w, "webhooks.", {"endpoints", "max_attempts"});
      c.integer(w, "webhooks.", "max_attempts", cfg.webhook_max_attempts, 1, 100);
      if (w.contains("endpoints") && !w["endpoints"].is_array()) c.error("webhooks.endpoints", "must be an array");
      std::set<std::string> names;
      for (std::size_t i = 0; w.contains("endpoints") && w["endpoints"].is_array() && i < w["endpoints"].size(); ++i) {
        const json& e = w["endpoints"][i];
        const std::string at = "webhooks.endpoints[" + std::to_string(i) + "].";
        if (!e.is_object()) {
          c.error(at.substr(0, at.size() - 1), "must be an object {name, url, secret_file}");
          continue;
        }
        c.known(e, at, {"name", "url", "secret_file"});
        WebhookEndpoint ep;
        c.string(e, at, "name", ep.name);
        c.string(e, at, "url", ep.url);
        c.string(e, at, "secret_file", ep.secret_file);
        static const std::regex name_re("[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}");
        if (!std::regex_match(ep.name, name_re)) c.error(at + "name", "must be 1-64 letters, digits, '.', '_' or '-'");
        else if (!names.insert(ep.name).second) c.error(at + "name", "is used by another endpoint");
        if (ep.url.rfind("http://", 0) != 0 && ep.url.rfind("https://", 0) != 0)
          c.error(at + "url", "must be an http:// or https:// URL");
        if (ep.url.find_first_of(" \t\r\n") != std::string::npos) c.error(at + "url", "must not contain white space");
        if (ep.secret_file.empty()) {
          c.error(at + "secret_file", "missing (required): a file of whsec_ secrets (meshmark webhook secret)");
        } else {
          fs::path p(ep.secret_file);
          if (p.is_relative() && !base_dir.empty()) p = fs::path(base_dir) / p;
          ep.secret_file = p.lexically_normal().string();
        }
        cfg.webhooks.push_back(ep);
      }
    }
  }
  if (j.contains("evidence")) {
    const json& e = j["evidence"];
    if (!e.is_object()) {
      c.error("evidence", "must be an object");
    } else {
      c.known(e, "evidence.", {"auto", "pdf", "tsa_url", "tsa_ca_file"});
      c.boolean(e, "evidence.", "auto", cfg.evidence_auto);
      c.boolean(e, "evidence.", "pdf", cfg.evidence_pdf);
      c.string(e, "evidence.", "tsa_url", cfg.tsa_url);
      if (!cfg.tsa_url.empty() && cfg.tsa_url.rfind("http://", 0) != 0 && cfg.tsa_url.rfind("https://", 0) != 0)
        c.error("evidence.tsa_url", "must be an http:// or https:// URL");
      c.string(e, "evidence.", "tsa_ca_file", cfg.tsa_ca_file);
      if (!cfg.tsa_ca_file.empty()) {
        fs::path p(cfg.tsa_ca_file);
        if (p.is_relative() && !base_dir.empty()) p = fs::path(base_dir) / p;
        cfg.tsa_ca_file = p.lexically_normal().string();
      }
    }
  }
  if (cfg.heartbeat_seconds * 2 > cfg.lease_seconds)
    c.error("heartbeat_seconds", "must be at most half of lease_seconds (" + std::to_string(cfg.lease_seconds) +
                                     "), so one missed beat does not lose the lease");
  if (check_folders) {
    c.folder_exists("home", cfg.home);
    c.folder_exists("drop_dir", cfg.drop_dir);
    c.folder_exists("output_dir", cfg.output_dir);
    if (!cfg.log_file.empty()) c.folder_exists("log_file", fs::path(cfg.log_file).parent_path().string());
    for (const auto& r : cfg.input_roots) c.folder_exists("input_roots", r);
  }
  if (!cfg.drop_dir.empty() && cfg.drop_dir == cfg.output_dir)
    c.error("output_dir", "must differ from drop_dir (outputs would be picked up as new drops)");
  if (!cfg.drop_dir.empty() && !cfg.output_dir.empty()) {
    auto rel = fs::path(cfg.output_dir).lexically_relative(cfg.drop_dir);
    if (!rel.empty() && *rel.begin() != ".." && rel != ".")
      c.error("output_dir", "must not lie inside drop_dir");
  }
  if (!c.ok()) throw ConfigError(c.report());
  return cfg;
}

Config load_config(const std::string& path, bool check_folders) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path + ": cannot open configuration file");
  std::stringstream ss;
  ss << in.rdbuf();
  auto base = fs::absolute(fs::path(path)).parent_path().string();
  return parse_config(ss.str(), path, base, check_folders);
}

namespace {
std::map<std::string, std::string> flatten(const Config& c) {
  std::ostringstream d;
  auto num = [](double x) {
    std::ostringstream s;
    s << x;
    return s.str();
  };
  auto nums = [&num](const std::vector<double>& xs) {
    std::string s = "[";
    for (double x : xs) s += (s.size() > 1 ? ", " : "") + num(x);
    return s + "]";
  };
  return {{"home", c.home},
          {"drop_dir", c.drop_dir},
          {"output_dir", c.output_dir},
          {"master_key_file", c.master_key_file},
          {"workers", std::to_string(c.workers)},
          {"lease_seconds", std::to_string(c.lease_seconds)},
          {"heartbeat_seconds", std::to_string(c.heartbeat_seconds)},
          {"max_attempts", std::to_string(c.max_attempts)},
          {"shutdown_grace_seconds", std::to_string(c.shutdown_grace_seconds)},
          {"job_retention_days", std::to_string(c.job_retention_days)},
          {"poll_interval_ms", std::to_string(c.poll_interval_ms)},
          {"settle_ms", std::to_string(c.settle_ms)},
          {"use_inotify", c.use_inotify ? "true" : "false"},
          {"output_format", c.output_format},
          {"cad.linear_deflection", num(c.cad.linear_deflection)},
          {"cad.angular_deflection", num(c.cad.angular_deflection_degrees)},
          {"cad.copy_format", c.cad_copy_format},
          {"watermark.method", method_name(c.watermark.params.method)},
          {"watermark.strength", num(c.watermark.params.strength)},
          {"watermark.threshold", num(c.watermark.params.threshold)},
          {"watermark.message_bits", std::to_string(c.watermark.message_bits)},
          {"watermark.max_vertices", std::to_string(c.max_vertices)},
          {"watermark.min_vertices", std::to_string(c.min_mark_vertices)},
          {"watermark.share", num(c.mark_share)},
          {"compression.tolerance", num(c.compression.tolerance)},
          {"compression.max_vertices", std::to_string(c.compression.max_vertices)},
          {"compression.levels", std::to_string(c.compression.levels)},
          {"compression.angle", num(c.compression.angle_degrees)},
          {"compression.fallback_angles", nums(c.fallback_angles)},
          {"compression.quads", c.compression.rail_quads ? "true" : "false"},
          {"compression.coarsen", c.compression.coarsen ? "true" : "false"},
          {"compression.stream_bits", std::to_string(c.stream_bits)},
          {"detect.p_threshold", num(c.p_threshold)},
          {"detect.max_candidates", std::to_string(c.max_candidates)},
          {"detect.context_cache_mb", std::to_string(c.context_cache_mb)},
          {"max_input_bytes", std::to_string(c.max_input_bytes)},
          {"max_triangles", std::to_string(c.max_triangles)},
          {"http.listen", c.http_listen},
          {"store.postgres", store::redacted_conninfo(c.store_postgres)},
          {"webhooks.endpoints", [&] {
             std::string v;
             for (const auto& e : c.webhooks) v += (v.empty() ? "" : ", ") + e.name + "=" + e.url;
             return v;
           }()},
          {"webhooks.max_attempts", std::to_string(c.webhook_max_attempts)},
          {"http.threads", std::to_string(c.http_threads)},
          {"http.max_body_bytes", std::to_string(c.http_max_body_bytes)},
          {"evidence.auto", c.evidence_auto ? "true" : "false"},
          {"evidence.pdf", c.evidence_pdf ? "true" : "false"},
          {"evidence.tsa_url", c.tsa_url},
          {"evidence.tsa_ca_file", c.tsa_ca_file},
          {"log_level", c.log_level},
          {"log_file", c.log_file}};
}
}  // namespace

std::vector<std::string> config_changes(const Config& before, const Config& after) {
  auto a = flatten(before), b = flatten(after);
  std::vector<std::string> out;
  for (const auto& [k, v] : a)
    if (b[k] != v) out.push_back(k + ": " + v + " -> " + b[k]);
  return out;
}

bool needs_restart(const std::string& line) {
  for (const char* k : {"home:", "drop_dir:", "output_dir:", "master_key_file:", "workers:", "use_inotify:",
                        "log_file:", "http.listen:", "http.threads:", "store.postgres:"})
    if (line.rfind(k, 0) == 0) return true;
  return false;
}

}  // namespace mm::service

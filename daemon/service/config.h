// meshmarkd's configuration: one JSON file, every key documented in config/config-keys.md.
// load_config() validates everything up front (unknown keys, wrong types, out-of-range values,
// missing folders) and reports all problems at once, each naming the key.
#pragma once
#include <stdexcept>
#include <string>
#include <vector>

#include "cad/tessellate.h"
#include "jobs/protect.h"

namespace mm::service {

struct ConfigError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A receiver of job notifications (docs/api.md, Webhooks): signed with every secret in its
// secret_file (one "whsec_..." per line; two during a rotation).
struct WebhookEndpoint {
  std::string name;  // [A-Za-z0-9._-]{1,64}, unique; names its delivery jobs
  std::string url;   // http:// or https://
  std::string secret_file;
};

struct Config {
  std::string source;  // the file it came from ("" for defaults)
  // Paths (relative ones are resolved against the config file's folder).
  std::string home;             // meshmark home: meshmark.db, blobs/, master.key
  std::string drop_dir;         // <drop>/protect/<customer>/, <drop>/detect/, done/, failed/
  std::string output_dir;       // protected copies: <output>/<customer>/<name>
  std::string master_key_file;  // "" = <home>/master.key
  // store.postgres: the fleet's PostgreSQL database (conninfo); "" = the home's SQLite store.
  // The home still holds the master key and the blobs, a folder every node mounts.
  std::string store_postgres;
  // Folders a job's input_path may name a file under (symbolic links resolved first); none: every
  // input_path is refused, so a row in the jobs table cannot make the daemon read any file it can.
  std::vector<std::string> input_roots;
  // Workers and queue.
  int workers = 2;
  int lease_seconds = 300;
  int heartbeat_seconds = 30;
  int max_attempts = 5;
  int shutdown_grace_seconds = 30;
  // Finished jobs no copy or detection points at are deleted this long after they finished, by
  // the leader (0: kept forever).
  int job_retention_days = 14;
  // Drop folders.
  int poll_interval_ms = 1000;
  int settle_ms = 2000;  // polling fallback: a file unchanged this long counts as complete
  bool use_inotify = true;
  // Protect and detect.
  // Inputs refused with their reason above these (0: no limit): a job's time and memory grow with
  // the part (docs/daemon.md, Limits).
  std::int64_t max_input_bytes = 256ll << 20;
  std::int64_t max_triangles = 1000000;
  std::string output_format = "same";  // same (a CAD part: cad.copy_format) | stl | obj | off | ply | 3mf | glb | gltf
  // STEP and IGES parts: cad.linear_deflection (of the diagonal), cad.angular_deflection (degrees),
  // recorded with the asset; cad.copy_format: the mesh format their copies are written in.
  TessellationOptions cad;
  std::string cad_copy_format = "3mf";
  // watermark.{method, strength, threshold, message_bits}: uniform moves, as strong as
  // watermark.share lets them be (the strength is a cap that the share's budget lowers per part).
  jobs::WatermarkSettings watermark{{Method::Uniform, 0.1, 0.05}, 32};
  int max_vertices = 4000;          // watermark.max_vertices: cap on the control polyhedron
  int min_mark_vertices = 200;      // watermark.min_vertices: smaller polyhedra are refined for the mark
  // watermark.share: the part of compression.tolerance the mark may use; the fit gets the rest, so
  // an issued copy lies within compression.tolerance of the original, mark included.
  double mark_share = 0.5;
  CompressOptions compression;      // compression.{tolerance, max_vertices, levels, angle}
  int stream_bits = 16;             // compression.stream_bits: quantisation of the .mmc copies
  // compression.fallback_angles: tried in turn when compression.angle misses the tolerance
  // (jobs::PrepareParams::fallback_angles).
  std::vector<double> fallback_angles = fallback_crease_angles();
  double p_threshold = 1e-9;
  int max_candidates = 3;
  // detect.context_cache_mb: resynchronisation contexts kept between detect jobs, shared by the
  // workers (service/context_cache.h); contexts in use are never evicted.
  int context_cache_mb = 512;
  // Evidence packages (docs/evidence.md): evidence.auto writes one for every attributed detection
  // into <output_dir>/evidence/<case id>/ (an `evidence` job that the detect job's completion
  // enqueues); evidence.pdf prints it with Chromium; evidence.tsa_url / tsa_ca_file timestamp it.
  bool evidence_auto = false;
  bool evidence_pdf = true;
  std::string tsa_url, tsa_ca_file;
  // HTTP API (docs/api.md): http.listen "" (off), "127.0.0.1:8440" or "unix:/run/meshmark/api.sock"
  // (loopback or a socket only behind nginx: config/nginx-meshmark.conf); uploads are capped by
  // max_input_bytes, JSON bodies by http.max_body_bytes.
  std::string http_listen;
  int http_threads = 4;
  int http_max_body_bytes = 1 << 20;
  // webhooks.endpoints: the only places notifications go (no request can add one);
  // webhooks.max_attempts: deliveries tried with backoff before the delivery job fails.
  std::vector<WebhookEndpoint> webhooks;
  int webhook_max_attempts = 10;
  // Logging.
  std::string log_level = "info";  // trace debug info warn error critical off
  std::string log_file;            // "" = stderr (journald under systemd)

  std::string master_key_path() const;
};

// Parses and validates; throws ConfigError listing every problem ("<file>: key: reason").
// check_folders: the folders must exist (the daemon); false for tools that only read settings.
Config load_config(const std::string& path, bool check_folders = true);
Config parse_config(const std::string& json_text, const std::string& source,
                    const std::string& base_dir, bool check_folders);

// Human-readable "key: old -> new" lines for a reload log.
std::vector<std::string> config_changes(const Config& before, const Config& after);
// Keys that only take effect after a restart (listed in changes but not applied live).
bool needs_restart(const std::string& change_line);

}  // namespace mm::service

// Job handlers as the daemon runs them: they read a job's payload, fetch inputs from the store and
// blob store, call the pure functions in workers/jobs, write output files, and return the records
// that Store::complete() writes in the same transaction that completes the job.
//
// Job payload contract (also for rows a PDM system inserts, docs/daemon.md):
//   protect: {"customer": "<name>", "input_sha256": "<blob>" | "input_path": "<abs path>",
//             "name": "<file name, its extension gives the format>", "output_format": "stl"?}
//   detect:  {"input_sha256": "<blob>" | "input_path": "<abs path>", "name": "<file name>"}
//   evidence: {"detect_job": <id>} (enqueued by detect jobs when evidence.auto is set)
//   noop:    {} (queue benchmarks)
// A handler throws PermanentError for problems retrying cannot fix (malformed mesh, unknown
// customer, bad payload): the job is discarded at once with that reason. Any other exception is
// retried with backoff up to max_attempts.
#pragma once
#include <cstddef>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>

#include "meshio/mesh.h"
#include "jobs/detect_suspect.h"
#include "service/config.h"
#include "service/context_cache.h"
#include "store/store.h"

namespace mm::service {

struct PermanentError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Thrown by HandlerContext::check_cancelled when the job was cancelled while it ran: the worker
// stops it there, writes nothing more and removes what it wrote.
struct JobCancelled : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct HandlerContext {
  const Config& config;
  std::string worker_id;
  // Handlers call this between steps (before writing outputs); throws JobCancelled. No-op default.
  std::function<void()> check_cancelled = [] {};
};

using Handler = std::function<store::JobRecords(store::Store&, const store::Job&, const HandlerContext&)>;
using HandlerMap = std::map<std::string, Handler>;

// protect, detect, noop. Every copy of the map (all workers of a pool) shares the protect
// handler's RefusedParts and the detect handler's ContextCache of resynchronisation contexts,
// budgeted by detect.context_cache_mb.
HandlerMap default_handlers();

// Parts whose preparation was refused (compression failed, or the fit missed its share of the
// tolerance), by content hash and preparation key, for the process's lifetime: a later job for
// the same part fails at once with the same reason instead of fitting it again (a nightly run
// protects each part for every customer). At most kMaxEntries, then forgotten.
class RefusedParts {
 public:
  static constexpr std::size_t kMaxEntries = 10000;
  std::optional<std::string> find(const std::string& key) const;
  void add(const std::string& key, const std::string& reason);

 private:
  mutable std::mutex mutex_;
  std::map<std::string, std::string> reasons_;
};

// refused: shared by the workers (null: every job prepares its part itself).
store::JobRecords run_protect(store::Store& st, const store::Job& job, const HandlerContext& ctx,
                              RefusedParts* refused = nullptr);
// evidence: {"detect_job": <id>}: the package of that job's detection, written to
// <output_dir>/evidence/<case id>/ (service/evidence_package.h). Enqueued by detect jobs that
// attribute when evidence.auto is set.
// Where the evidence job writes a detection's package: <output_dir>/evidence/MM-<id>-<12 hex>/.
std::filesystem::path evidence_package_dir(const Config& cfg, const store::Detection& det);
store::JobRecords run_evidence(store::Store& st, const store::Job& job, const HandlerContext& ctx);
// contexts: where resynchronisation contexts are kept between uses (null: built for each use).
store::JobRecords run_detect(store::Store& st, const store::Job& job, const HandlerContext& ctx,
                             ContextCache* contexts = nullptr);

// A detection as the detect job records it (details: every candidate, copy, statistic and the
// parameters it ran with). The one computation behind detect jobs and `meshmark reproduce`.
struct DetectParameters {
  double p_threshold = 1e-9;
  int max_candidates = 3;
};
struct DetectionRecord {
  store::NewDetection detection;
  std::string reason;  // why an inconclusive verdict names no one
};
DetectionRecord detect_record(store::Store& st, const jobs::Suspect& suspect, const DetectParameters& params,
                              ContextCache* contexts = nullptr);

// PermanentError naming the file when the mesh has more triangles (polygons fanned) than
// cfg.max_triangles allows: the work and memory of a job grow with it.
void check_triangles(const Mesh& mesh, const std::string& name, const Config& cfg);

// A part's bytes parsed by the format its name's extension gives (a .mmc stream decoded, a STEP
// or IGES part tessellated with `cad`); PermanentError naming the file and the reason when they
// cannot be. A stream's metadata goes to stream_metadata when given.
Mesh read_named_mesh(const std::vector<std::uint8_t>& bytes, const std::string& name,
                     std::map<std::string, std::string>* stream_metadata = nullptr,
                     const TessellationOptions& cad = {}, const std::string& object = "");

// A preparation key of one 3MF object ends with kObjectKey and the object's name.
inline constexpr const char* kObjectKey = ";object=";
// The 3MF object a preparation key names, or "" (the whole part).
std::string object_of_prepare_key(const std::string& key);

// An input path resolved (symbolic links and `..` included) and checked to lie under one of
// cfg.input_roots, before anything opens it; PermanentError starting with `what` otherwise.
std::string resolve_input_path(const std::string& path, const Config& cfg, const std::string& what);

// Submitting: the file's bytes go into the blob store first (so the job does not depend on the
// file staying where it is), then the job is enqueued with an idempotency key derived from what
// it is (kind, customer, content hash, name): submitting the same thing twice returns the first
// job. output_format "" = from the config at run time; object: a 3MF part's object ("" = all).
store::EnqueueResult submit_protect(store::Store& st, const std::string& customer, const std::string& path,
                                    const std::string& name, int max_attempts, const std::string& actor,
                                    const std::string& output_format = "", const std::string& object = "");
store::EnqueueResult submit_detect(store::Store& st, const std::string& path, const std::string& name,
                                   int max_attempts, const std::string& actor);

// The output files of a protect job, without extension: <output>/<customer>/<stem>-<12 hex>,
// the hex from BLAKE2b of the copy's idempotency key. The job writes <base>.mmc (the watermarked
// stream) and <base>.<format> (the stream decoded).
std::string output_base_for(const Config& cfg, const std::string& customer, const std::string& name,
                            const std::string& copy_key);

}  // namespace mm::service

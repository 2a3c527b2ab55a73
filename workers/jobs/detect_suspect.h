// The detect job: which issued copy, if any, a suspect file is.
//
// 1. Candidate assets: the asset whose issued file (stream or decoded mesh) or original has the
//    suspect's hash, else the asset a stream names in its metadata, else the nearest assets by
//    shape signature (at most max_candidates, distance below 0.5).
// 2. Every copy ever issued for a candidate, grouped by the polyhedron it was embedded in: the
//    suspect is resynchronised once per polyhedron and scored against each copy (score_copies).
// 3. Each p-value is Bonferroni-corrected for every copy tried over every candidate; the best copy
//    is the smallest corrected p (ties: the larger correlation, then the first), and finding_of()
//    gives the verdict. This is the rule the daemon, `meshmark extract` and the tests share.
//
// The store is reached only through DetectionStore, so the daemon's SQLite store and a test's
// in-memory one run the same code.
#pragma once
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "jobs/detect.h"

namespace mm::jobs {

// An issued copy as the store keeps it.
struct IssuedCopyRecord {
  std::int64_t id = 0;
  std::int64_t asset_id = 0;
  std::int64_t customer_id = 0;
  int key_version = 0;
  std::vector<std::uint8_t> nonce;
  std::string payload_hex;
  std::string params_json;   // copy_params_json()
  std::string outputs_json;  // {"files": [{"role": ..., "sha256": ...}, ...]}
};

// A prepared polyhedron as the store keeps it: blob addresses, not bytes.
struct PolyhedronRecord {
  std::int64_t id = 0;
  std::string polyhedron_blob;  // content address; also names its resynchronisation context
  std::string basis_blob;
  std::string meta_json;  // {"signature": ShapeSignature, ...}
};

// What detection reads of the store, and nothing more.
class DetectionStore {
 public:
  virtual ~DetectionStore() = default;
  virtual std::vector<IssuedCopyRecord> issued_copies() = 0;  // every copy, in issue order
  virtual std::optional<std::int64_t> asset_with_sha256(const std::string& sha256) = 0;
  virtual std::optional<PolyhedronRecord> polyhedron(std::int64_t asset_id, const std::string& prepare_key) = 0;
  virtual std::vector<std::uint8_t> blob(const std::string& sha256) = 0;
  virtual Key customer_key(std::int64_t customer_id, int key_version) = 0;  // never logged
};

// Where resynchronisation contexts come from: `build` makes one; a cache keyed by the
// polyhedron's content address may keep it between suspects.
using ContextSource = std::function<std::shared_ptr<const ResyncContext>(
    const std::string& polyhedron_blob, const std::function<ResyncContext()>& build)>;

struct DetectOptions {
  double p_threshold = 1e-9;
  int max_candidates = 3;
  ContextSource contexts;  // empty: a context built for each use
};

// The suspect as it arrived.
struct Suspect {
  Mesh mesh;
  std::string name;    // file name (for messages)
  std::string sha256;  // of its bytes
  std::map<std::string, std::string> stream_metadata;  // a .mmc stream's, else empty
};

// The suspect in one polyhedron's vertex order and normalised frame.
struct Alignment {
  Points points;
  std::string method;  // resynchronize()'s, or "none: <reason>" when it did not fit
  int level = 0;
  double residual = std::numeric_limits<double>::infinity();  // RMS, unit-box units
  double matched_fraction = 0;
  std::string attack_model;    // resynchronize()'s: the attack modelled and taken out, or ""
  SuspectReadings readings;    // what the matched score reads (suspect_readings())
  double context_mb = 0;       // the context's memory after use (for logs)
  std::string levels_built;    // e.g. "012--" (for logs)
};

struct PolyhedronTried {
  std::int64_t asset_id = 0;
  std::int64_t polyhedron_id = 0;
  Alignment alignment;
  std::vector<IssuedCopyRecord> copies;
  std::vector<CopyScore> scores;  // corrected for every copy tried (Detection::copies_tried)
};

struct Detection {
  // "attributed", "inconclusive", "no watermark found" or "unknown asset".
  std::string verdict;
  std::string match;  // how the candidates were found ("" when none was)
  std::string reason;  // why an inconclusive verdict names no one
  std::vector<std::int64_t> candidates;
  std::map<std::int64_t, double> region_agreement;  // candidates found by footprint: region_agreement()
  int copies_tried = 0;
  std::vector<PolyhedronTried> tried;
  std::optional<std::int64_t> asset_id, copy_id, customer_id;  // the best copy's, when attributed
  // Every copy whose corrected p is below the threshold, best first: several when copies were
  // averaged (collusion). Each p is exact on its own key stream, so each names its customer.
  struct Attributed {
    std::int64_t copy_id = 0, customer_id = 0;
    double corrected_p = 1, neg_log10_corrected_p = 0;
  };
  std::vector<Attributed> attributed;
  // The best copy, when any copy was scored.
  std::optional<CopyScore> best;
  int best_tried = -1;  // index into `tried`
  double best_neg_log10_corrected_p = 0;
  std::string decoded_payload_hex;
  std::vector<std::string> warnings;  // records that could not be used (for logs)
};

// Throws InputError when a stored polyhedron cannot be decoded.
Detection detect_suspect(DetectionStore& store, const Suspect& suspect, const DetectOptions& options);

// The suspect resynchronised to a prepared asset, in the asset's normalised frame.
Alignment align_suspect(const PreparedAsset& asset, const std::string& polyhedron_blob, const Mesh& suspect,
                        const std::string& name, const ContextSource& contexts);

// An issued copy's embedding parameters as recorded: the watermark settings, the preparation
// key of its polyhedron and its basis's content address.
std::string copy_params_json(const WatermarkSettings& settings, const std::string& prepare_key,
                             const std::string& basis_sha256);
WatermarkSettings copy_settings(const std::string& params_json);  // throws on malformed
std::string copy_prepare_key(const std::string& params_json);      // "" if malformed

}  // namespace mm::jobs

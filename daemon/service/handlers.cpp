#include "service/handlers.h"
#include "service/webhooks.h"

#include <chrono>
#include <sodium.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <spdlog/spdlog.h>
#include <map>
#include <memory>
#include <string_view>
#include <system_error>

#include "cad/read_part.h"
#include "codec/stream.h"
#include "jobs/copy_identity.h"
#include "jobs/detect_suspect.h"
#include "jobs/payload.h"
#include "jobs/prepared_asset.h"
#include "jobs/protect.h"
#include "meshio/read_mesh.h"
#include "service/build_info.h"
#include "service/detection_store.h"
#include "service/evidence_package.h"
#include "support/atomic_file.h"
#include "support/hex.h"
#include "support/printable.h"
#include "support/sha256.h"

namespace mm::service {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Mesh formats and CAD parts; detect also takes .mmc streams (a leaked compressed copy).
std::string format_of(const std::string& name, bool allow_stream = false) {
  std::string ext = lower(fs::path(name).extension().string());
  if (!ext.empty()) ext.erase(0, 1);
  if (allow_stream && ext == "mmc") return ext;
  if (!is_part_format(ext))
    throw PermanentError(name + ": unsupported format \"" + ext + "\" (expected " + part_format_list() +
                         (allow_stream ? std::string(", or a .mmc stream)") : std::string(")")));
  return ext;
}

json parse_payload(const store::Job& job) {
  try {
    json j = json::parse(job.payload_json);
    if (!j.is_object()) throw PermanentError("job " + std::to_string(job.id) + ": payload is not a JSON object");
    return j;
  } catch (const json::exception& e) {
    throw PermanentError("job " + std::to_string(job.id) + ": payload is not valid JSON: " + e.what());
  }
}

std::string str_field(const json& j, const char* key, const store::Job& job, bool required = true) {
  if (!j.contains(key)) {
    if (required) throw PermanentError("job " + std::to_string(job.id) + ": payload lacks \"" + key + "\"");
    return "";
  }
  if (!j[key].is_string()) throw PermanentError("job " + std::to_string(job.id) + ": payload \"" + key + "\" must be a string");
  return j[key].get<std::string>();
}

// input_path resolved (symbolic links and `..` included) and checked to lie under one of the
// configured input roots, before anything opens it.
std::string allowed_input_path(const std::string& path, const Config& cfg, const store::Job& job) {
  return resolve_input_path(path, cfg, "job " + std::to_string(job.id) + ": input_path " + support::printable(path, 200));
}

}  // namespace

std::string resolve_input_path(const std::string& path, const Config& cfg, const std::string& what) {
  if (cfg.input_roots.empty())
    throw PermanentError(what + " refused: no input_roots are configured (config/config-keys.md)");
  if (!fs::path(path).is_absolute()) throw PermanentError(what + " refused: it must be an absolute path");
  std::error_code ec;
  const fs::path real = fs::canonical(path, ec);
  if (ec) throw PermanentError(what + ": " + ec.message());
  for (const auto& root : cfg.input_roots) {
    const fs::path r = fs::canonical(root, ec);
    if (ec) continue;
    const auto rel = real.lexically_relative(r);
    if (!rel.empty() && *rel.begin() != ".." && rel.is_relative() && rel != ".") return real.string();
  }
  throw PermanentError(what + " refused: it is not under any of input_roots");
}

namespace {

// The input's bytes: from the blob store, or (PDM rows) from a path, which is stored first.
std::vector<std::uint8_t> input_bytes(store::Store& st, const json& p, const store::Job& job, std::string* sha,
                                      const Config& cfg) {
  std::string h = str_field(p, "input_sha256", job, false);
  if (h.empty()) {
    std::string path = str_field(p, "input_path", job, false);
    if (path.empty()) throw PermanentError("job " + std::to_string(job.id) + ": payload needs input_sha256 or input_path");
    path = allowed_input_path(path, cfg, job);
    std::error_code ec;
    const auto size = fs::file_size(path, ec);
    if (!ec && cfg.max_input_bytes > 0 && size > static_cast<std::uintmax_t>(cfg.max_input_bytes))
      throw PermanentError("job " + std::to_string(job.id) + ": input_path " + support::printable(path, 200) + " is " +
                           std::to_string(size) + " bytes, over max_input_bytes (" +
                           std::to_string(cfg.max_input_bytes) + ")");
    try {
      h = st.blobs().put_file(path);
    } catch (const store::BlobError& e) {
      throw PermanentError(e.what());
    }
  }
  if (!store::is_sha256_hex(h)) throw PermanentError("job " + std::to_string(job.id) + ": input_sha256 is not a SHA-256 hex");
  if (!st.blobs().contains(h)) throw PermanentError("job " + std::to_string(job.id) + ": input blob " + h + " is not in the store");
  const std::uint64_t size = st.blobs().size(h);
  if (cfg.max_input_bytes > 0 && size > static_cast<std::uint64_t>(cfg.max_input_bytes))
    throw PermanentError("job " + std::to_string(job.id) + ": the input is " + std::to_string(size) +
                         " bytes, over max_input_bytes (" + std::to_string(cfg.max_input_bytes) + ")");
  *sha = h;
  return st.blobs().get(h);
}

Mesh parse_input(const std::vector<std::uint8_t>& bytes, const std::string& name,
                 std::map<std::string, std::string>* stream_metadata, const TessellationOptions& cad,
                 PartReport* report = nullptr, const std::string& object = "") {
  std::string fmt = format_of(name, stream_metadata != nullptr);
  try {
    if (fmt == "mmc") {
      DecodedStream d = decode(bytes, name);
      *stream_metadata = d.metadata;
      return d.mesh;
    }
    return parse_part(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), fmt, name, cad,
                      report, ReadOptions{object});
  } catch (const InputError& e) {
    throw PermanentError(e.what());
  }
}

// A fraction of the diagonal as a percentage, for messages.
std::string percent(double fraction) { return fmt::format("{:.3f} %", 100 * fraction); }

// How a CAD part's mesh was made: with the stored file, enough to make it again years later.
json tessellation_json(const Tessellation& t, const std::string& source_sha256) {
  return {{"format", t.format},
          {"source_sha256", source_sha256},
          {"occt_version", t.occt_version},
          {"linear_deflection", t.options.linear_deflection},
          {"linear_deflection_mm", t.linear_deflection_mm},
          {"angular_deflection_degrees", t.options.angular_deflection_degrees},
          {"solids", t.solids},
          {"faces", t.faces}};
}

struct LoadedAsset {
  store::Asset asset;
  store::Polyhedron row;
  jobs::PreparedAsset prepared;
};

jobs::PrepareParams prepare_params(const Config& cfg) {
  jobs::PrepareParams pp;
  pp.compression = cfg.compression;
  // The fit gets what the mark does not: a copy lies within compression.tolerance, mark included.
  pp.compression.tolerance = cfg.compression.tolerance * (1 - cfg.mark_share);
  pp.fallback_angles = cfg.fallback_angles;
  pp.max_control_vertices = cfg.max_vertices;
  pp.min_mark_vertices = cfg.min_mark_vertices;
  // A copy detection would refuse is not issued: decoded at fewer levels, or the part refused.
  pp.max_copy_triangles = cfg.max_triangles;
  return pp;
}

jobs::PreparedAsset decode_row(store::Store& st, const store::Polyhedron& row) {
  return jobs::decode_prepared(st.blobs().get(row.polyhedron_blob), st.blobs().get(row.basis_blob),
                               "asset " + std::to_string(row.asset_id) + " polyhedron " + std::to_string(row.id));
}

// The asset's prepared polyhedron and basis: from the cache, or compressed once and stored
// (blobs first, then the row; a concurrent worker doing the same gets the same bytes and row).
// The asset row is made only once the part has compressed, so an input that fails never becomes
// an asset.
// The part prepared, or PermanentError("... compression failed: <reason>").
jobs::PreparedAsset prepare_within_tolerance(const Mesh& mesh, const jobs::PrepareParams& pp,
                                             const std::string& asset_name) {
  jobs::PreparedAsset prepared;
  try {
    prepared = jobs::prepare_asset(mesh, pp, asset_name);
  } catch (const InputError& e) {
    // The error's own source may be a library stage ("quality: ..."): the file is named first.
    const std::string what = e.what();
    throw PermanentError(what.rfind(asset_name, 0) == 0 ? "compression failed: " + what
                                                         : asset_name + ": compression failed: " + what);
  } catch (const std::invalid_argument& e) {
    throw PermanentError(asset_name + ": compression failed: " + e.what());
  }
  const CompressResult& cr = prepared.compression;
  // A copy is issued within compression.tolerance or not at all: the mark is given only what the
  // fit leaves of it.
  if (!cr.tolerance_met)
    throw PermanentError(asset_name + ": compression failed: the fit's Hausdorff distance is " +
                         percent(cr.stats.hausdorff / cr.stats.diagonal) + " of the diagonal, over the " +
                         percent(pp.compression.tolerance) +
                         " left of compression.tolerance by the mark's watermark.share (not met " +
                         tolerance_miss_reason(cr, pp.compression) + ")" +
                         "; raise compression.tolerance or compression.max_vertices, or lower watermark.share");
  return prepared;
}

LoadedAsset get_or_prepare(store::Store& st, const std::string& sha, const std::vector<std::uint8_t>& bytes,
                           const std::string& name, const Mesh& mesh, const PartReport& read, const Config& cfg,
                           RefusedParts* refused, const std::string& object) {
  jobs::PrepareParams pp = prepare_params(cfg);
  // A CAD part's mesh is its tessellation: other options (or another OpenCASCADE) prepare it again.
  // One 3MF object of a build is its own polyhedron; the key ends with its name.
  const std::string key = pp.key() + (read.tessellation ? ";" + tessellation_key(read.tessellation->options) : "") +
                          (object.empty() ? "" : std::string(kObjectKey) + object);
  const std::optional<store::Asset> existing = st.find_asset(sha);
  if (existing)
    if (auto row = st.find_polyhedron(existing->id, key)) return {*existing, *row, decode_row(st, *row)};
  const std::string& asset_name = existing ? existing->name : name;
  // The preparation is deterministic: a part refused once under this key is refused again.
  const std::string refusal_key = sha + "|" + key;
  if (refused)
    if (auto why = refused->find(refusal_key)) throw PermanentError(*why + " (refused before; not fitted again)");
  jobs::PreparedAsset prepared;
  try {
    prepared = prepare_within_tolerance(mesh, pp, asset_name);
  } catch (const PermanentError& e) {
    if (refused) refused->add(refusal_key, e.what());
    throw;
  }
  const CompressResult& cr = prepared.compression;
  spdlog::info("compressed {}: {} -> {} control vertices at a crease angle of {} degrees, Hausdorff {:.3f} %, RMS "
               "{:.3f} % of the diagonal{}",
               asset_name, mesh.num_vertices(), prepared.control.num_vertices(), cr.angle_degrees,
               100 * cr.stats.hausdorff / cr.stats.diagonal, 100 * cr.stats.rms / cr.stats.diagonal,
               cr.tolerance_met ? "" : " (tolerance not met " + tolerance_miss_reason(cr, pp.compression) + ")");
  const store::Asset stored = existing ? *existing : st.put_asset_bytes(bytes, name);
  store::Polyhedron row;
  row.asset_id = stored.id;
  row.params_key = key;
  row.polyhedron_blob = st.blobs().put(jobs::encode_polyhedron(prepared));
  row.basis_blob = st.blobs().put(serialize_basis(prepared.basis));
  json meta{{"signature", json::parse(prepared.signature.to_json())},
                       {"footprint", json::parse(prepared.footprint.to_json())},
                       {"control_vertices", prepared.control.num_vertices()},
                       {"input_vertices", mesh.num_vertices()},
                       {"levels", prepared.levels},
                       {"hausdorff_relative", cr.stats.hausdorff / cr.stats.diagonal},
                       {"rms_relative", cr.stats.rms / cr.stats.diagonal},
                       {"tolerance_met", cr.tolerance_met},
                       {"angle", cr.angle_degrees},
                       {"rounds", cr.rounds}};
  if (read.tessellation) meta["tessellation"] = tessellation_json(*read.tessellation, sha);
  row.meta_json = meta.dump();
  row = st.put_polyhedron(row);
  return {stored, row, std::move(prepared)};
}

std::string copy_idempotency_key(const store::Job& job) {
  return job.idempotency_key.empty() ? "job:" + std::to_string(job.id) : job.idempotency_key;
}

// The stream file, written like write_mesh writes meshes (support/atomic_file.h); the daemon
// removes temporaries a killed process left at start (remove_stale_output_temps).
void write_bytes_atomic(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  try {
    support::write_file_atomic(path, bytes);
  } catch (const std::system_error& e) {
    throw std::system_error(e.code(), path + ": " + e.what());
  }
}

}  // namespace

void check_triangles(const Mesh& mesh, const std::string& name, const Config& cfg) {
  std::int64_t triangles = 0;
  for (const auto& f : mesh.faces) triangles += f.size() >= 3 ? static_cast<std::int64_t>(f.size()) - 2 : 0;
  if (cfg.max_triangles > 0 && triangles > cfg.max_triangles)
    throw PermanentError(name + ": " + std::to_string(triangles) + " triangles, over max_triangles (" +
                         std::to_string(cfg.max_triangles) + ")");
}

Mesh read_named_mesh(const std::vector<std::uint8_t>& bytes, const std::string& name,
                     std::map<std::string, std::string>* stream_metadata, const TessellationOptions& cad,
                     const std::string& object) {
  std::map<std::string, std::string> metadata;
  return parse_input(bytes, name, stream_metadata ? stream_metadata : &metadata, cad, nullptr, object);
}

std::string object_of_prepare_key(const std::string& key) {
  const size_t at = key.find(kObjectKey);
  return at == std::string::npos ? "" : key.substr(at + std::string(kObjectKey).size());
}

std::string output_base_for(const Config& cfg, const std::string& customer, const std::string& name,
                            const std::string& copy_key) {
  // The tag names the copy (unique per idempotency key) without revealing its payload: two jobs
  // for the same part and customer (another output format, another file name) never share files.
  unsigned char h[6];
  std::string msg = "meshmark-output-v1|" + copy_key;
  crypto_generichash(h, sizeof h, reinterpret_cast<const unsigned char*>(msg.data()), msg.size(), nullptr, 0);
  std::string stem = fs::path(name).stem().string();
  return (fs::path(cfg.output_dir) / customer / (stem + "-" + support::to_hex(h, sizeof h))).string();
}

std::optional<std::string> RefusedParts::find(const std::string& key) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  const auto it = reasons_.find(key);
  if (it == reasons_.end()) return std::nullopt;
  return it->second;
}

void RefusedParts::add(const std::string& key, const std::string& reason) {
  const std::lock_guard<std::mutex> lock(mutex_);
  if (reasons_.size() >= kMaxEntries) reasons_.clear();
  reasons_.emplace(key, reason);
}

store::JobRecords run_protect(store::Store& st, const store::Job& job, const HandlerContext& ctx,
                              RefusedParts* refused) {
  const Config& cfg = ctx.config;
  json p = parse_payload(job);
  std::string customer_name = str_field(p, "customer", job);
  std::string name = fs::path(str_field(p, "name", job)).filename().string();
  if (name.empty() || name == "." || name == "..") throw PermanentError("job " + std::to_string(job.id) + ": bad name");
  std::string out_format = str_field(p, "output_format", job, false);
  const std::string object = str_field(p, "object", job, false);
  if (object.size() > 256 || std::any_of(object.begin(), object.end(), [](unsigned char c) { return c < 0x20 || c == 0x7f; }))
    throw PermanentError("job " + std::to_string(job.id) + ": payload \"object\" must be a 3MF object name of at most 256 "
                         "printable bytes");
  auto customer = st.find_customer(customer_name);
  if (!customer) throw PermanentError("unknown customer \"" + customer_name + "\" (add it with: meshmark customer add)");

  std::string sha;
  auto bytes = input_bytes(st, p, job, &sha, ctx.config);
  PartReport read;
  Mesh mesh = parse_input(bytes, name, nullptr, cfg.cad, &read, object);
  check_triangles(mesh, name, cfg);
  std::string in_format = format_of(name);
  // A CAD part's copy is a mesh: cad.copy_format unless the job or output_format names one.
  if (out_format.empty())
    out_format = cfg.output_format != "same" ? cfg.output_format : is_cad_format(in_format) ? cfg.cad_copy_format : in_format;
  if (!is_mesh_format(out_format))
    throw PermanentError("job " + std::to_string(job.id) + ": unsupported output_format \"" + out_format + "\"");

  LoadedAsset la = get_or_prepare(st, sha, bytes, name, mesh, read, cfg, refused, object);
  const store::Asset& asset = la.asset;
  store::CustomerKey ck = st.customer_key(customer->id);

  // The payload must tell this copy apart from every other copy of the asset.
  const std::string idem = copy_idempotency_key(job);
  std::set<std::string> taken;
  for (const auto& c : st.list_copies(asset.id, kAllCopies))
    if (!(c.customer_id == customer->id && c.key_version == ck.version && c.idempotency_key == idem))
      taken.insert(c.payload_hex);
  jobs::WatermarkSettings ws = cfg.watermark;
  // The mark gets what the fit left of compression.tolerance (at least watermark.share of it).
  const double fit_error = json::parse(la.row.meta_json).value("hausdorff_relative", cfg.compression.tolerance);
  const double mark_budget = cfg.compression.tolerance - fit_error;
  if (!(mark_budget > 0))
    throw PermanentError(name + ": the stored fit leaves no room for the mark within compression.tolerance (" +
                         percent(fit_error) + " of " + percent(cfg.compression.tolerance) + ")");
  ws.params.strength = jobs::strength_within(la.prepared, cfg.watermark, mark_budget);
  const jobs::CopyIdentity identity =
      jobs::issue_copy_identity(asset.sha256, customer->id, ck.version, idem, ws.message_bits, taken);
  const Nonce& nonce = identity.nonce;
  const std::uint64_t payload = identity.payload;
  const std::string phex = jobs::payload_hex(payload, ws.message_bits);

  const jobs::PreparedAsset& prep = la.prepared;
  jobs::StreamSettings ss;
  ss.quant_bits = cfg.stream_bits;
  // Not secret and not identifying the copy: levels for decoders, the asset for detection.
  ss.metadata = {{"levels", std::to_string(prep.levels)}, {"asset", asset.sha256}};
  jobs::CopyFiles files;
  jobs::MarkCost cost;
  try {
    // The part's strength keeps reference marks within the budget with a margin; a copy whose
    // own signs still move a vertex past it is made again at its own, lower strength.
    for (int attempt = 0;; ++attempt) {
      Mesh marked = jobs::make_copy(prep, ck.key.bytes(), nonce, payload, ws);
      files = jobs::make_copy_files(prep, marked, ss, stores_triangles_only(out_format));
      cost = jobs::mark_cost(prep, files.decoded);
      if (cost.max <= mark_budget) break;
      if (attempt == 2)
        throw PermanentError(name + ": the mark moves the copy " + percent(cost.max) + " of the diagonal, over its " +
                             percent(mark_budget) + " share of compression.tolerance");
      ws.params.strength *= 0.99 * mark_budget / cost.max;
    }
  } catch (const std::invalid_argument& e) {
    throw PermanentError(name + ": cannot watermark: " + e.what());
  } catch (const InputError& e) {
    throw PermanentError(name + ": cannot encode the watermarked copy: " + e.what());
  }
  // Each file: temporary name, fsync, rename. A crash between the two leaves complete files
  // only; the re-run rewrites the same bytes (everything above is deterministic).
  ctx.check_cancelled();  // the expensive part is done; nothing is written for a cancelled job
  const std::string base = output_base_for(cfg, customer->name, name, idem);
  const std::string stream_path = base + ".mmc", out = base + "." + out_format;
  std::string decoded_bytes;
  // A Draco-compressed glTF part gets a Draco-compressed copy, as fine as the stream's grid.
  const int draco_bits = read.read.draco && (out_format == "glb" || out_format == "gltf") ? cfg.stream_bits : 0;
  try {
    // A copy keeps the part's unit where both formats state one (3MF).
    decoded_bytes = mesh_file_bytes(files.decoded, out, WriteOptions{read.read.unit, draco_bits, object});
  } catch (const InputError& e) {
    throw PermanentError(name + ": cannot write the decoded copy: " + e.what());
  }
  // A full disk or an I/O error is transient: this attempt's files are removed and the job is
  // retried with backoff (never discarded for it, never leaving a stream without a copy record).
  std::vector<std::string> written;
  try {
    fs::create_directories(fs::path(base).parent_path());
    write_bytes_atomic(stream_path, files.stream);
    written.push_back(stream_path);
    write_bytes_atomic(out, std::vector<std::uint8_t>(decoded_bytes.begin(), decoded_bytes.end()));
    written.push_back(out);
  } catch (const std::exception& e) {
    for (const auto& w : written) {
      std::error_code ec;
      fs::remove(w, ec);
    }
    throw std::runtime_error(name + ": writing the copy failed, will retry: " + e.what());
  }
  const std::string stream_sha = support::sha256_file_hex(stream_path), out_sha = support::sha256_file_hex(out);

  store::NewCopy nc;
  nc.asset_id = asset.id;
  nc.customer_id = customer->id;
  nc.key_version = ck.version;
  nc.idempotency_key = idem;
  nc.nonce.assign(nonce.begin(), nonce.end());
  nc.payload_hex = phex;
  nc.params_json = jobs::copy_params_json(ws, la.row.params_key, la.row.basis_blob);
  json decoded_file{{"role", "decoded"}, {"path", out},     {"sha256", out_sha},
                    {"format", out_format}, {"levels", prep.levels}, {"vertices", files.decoded.num_vertices()}};
  if (out_format == "3mf") decoded_file["unit"] = read.read.unit.empty() ? "millimeter" : read.read.unit;
  if (draco_bits) decoded_file["draco_bits"] = draco_bits;
  nc.outputs_json =
      json{{"files", json::array({decoded_file,
                                  json{{"role", "stream"}, {"path", stream_path}, {"sha256", stream_sha}, {"format", "mmc"},
                                       {"quant_bits", ss.quant_bits}, {"bytes", files.stream.size()}}})}}
          .dump();
  nc.polyhedron_id = la.row.id;

  store::JobRecords rec;
  rec.copies.push_back(nc);
  rec.audit.push_back({ctx.worker_id, "copy.issue", "asset:" + std::to_string(asset.id),
                       json{{"customer", customer->name}, {"key_version", ck.version}, {"output", out},
                            {"stream", stream_path}}.dump()});
  const int spread = jobs::coefficients_per_bit(prep, ws.message_bits);
  const std::string warning = jobs::weak_spread_warning(name, prep, ws.message_bits);
  if (!warning.empty()) spdlog::warn("job {}: {}", job.id, warning);
  json result{{"asset_id", asset.id},
              {"asset_sha256", asset.sha256},
              {"customer", customer->name},
              {"key_version", ck.version},
              {"output", out},
              {"output_sha256", out_sha},
              {"stream", stream_path},
              {"stream_sha256", stream_sha},
              {"stream_bytes", files.stream.size()},
              {"payload", phex},
              {"vertices", mesh.num_vertices()},
              {"control_vertices", prep.control.num_vertices()},
              {"decoded_vertices", files.decoded.num_vertices()},
              {"coefficients_per_bit", spread},
              // The mark's strength and cost, and its share of the tolerance (fractions of the diagonal).
              {"strength", ws.params.strength},
              {"fit_hausdorff", fit_error},
              {"mark_budget", mark_budget},
              {"mark_max", cost.max},
              {"mark_rms", cost.rms}};
  if (!warning.empty()) result["warning"] = warning;
  if (read.tessellation) result["tessellation"] = tessellation_json(*read.tessellation, sha);
  if (!object.empty()) result["object"] = object;
  result["output_bytes"] = decoded_bytes.size();
  rec.result_json = result.dump();
  return rec;
}

DetectionRecord detect_record(store::Store& st, const jobs::Suspect& suspect, const DetectParameters& params,
                              ContextCache* contexts) {
  jobs::DetectOptions options;
  options.p_threshold = params.p_threshold;
  options.max_candidates = params.max_candidates;
  if (contexts)
    options.contexts = [contexts](const std::string& key, const std::function<ResyncContext()>& build) {
      return contexts->get(key, build);
    };
  StoreForDetection view(st);
  const auto started = std::chrono::steady_clock::now();
  const jobs::Detection det = jobs::detect_suspect(view, suspect, options);
  // Wall time of the detection itself (candidates, resynchronisation, every copy scored), for
  // the benchmark; a record of how the evidence was computed, not part of it.
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  for (const auto& w : det.warnings) spdlog::warn("detect {}: {}", suspect.name, w);
  for (const auto& t : det.tried)
    spdlog::debug("resync {} to polyhedron {}: {} level {}; context {:.1f} MB, levels {} built", suspect.name,
                  t.polyhedron_id, t.alignment.method, t.alignment.level, t.alignment.context_mb,
                  t.alignment.levels_built);

  const std::string& name = suspect.name;
  const std::string& sha = suspect.sha256;
  const jobs::PolyhedronTried* best_t = det.best ? &det.tried[static_cast<std::size_t>(det.best_tried)] : nullptr;
  store::NewDetection d;
  d.suspect_sha256 = sha;
  d.suspect_name = name;
  d.verdict = det.verdict;
  d.asset_id = det.asset_id;
  d.copy_id = det.copy_id;
  d.customer_id = det.customer_id;
  d.decoded_payload_hex = det.decoded_payload_hex;
  json details;
  details["match"] = det.match;
  details["copies_tried"] = det.copies_tried;
  details["seconds"] = seconds;
  details["p_threshold"] = params.p_threshold;
  // What `meshmark reproduce` runs the detection with again, and what ran it.
  details["parameters"] = {{"p_threshold", params.p_threshold}, {"max_candidates", params.max_candidates},
                           {"meshmark_version", meshmark_version()}, {"build_sha256", build_sha256()}};
  details["candidates"] = json::array();
  for (const auto& t : det.tried) {
    json cj{{"asset_id", t.asset_id},
            {"polyhedron_id", t.polyhedron_id},
            {"resync_method", t.alignment.method},
            {"resync_level", t.alignment.level},
            {"resync_residual", std::isfinite(t.alignment.residual) ? t.alignment.residual : -1.0},
            {"matched_fraction", t.alignment.matched_fraction},
            {"attack_model", t.alignment.attack_model},
            {"copies", json::array()}};
    if (auto a = det.region_agreement.find(t.asset_id); a != det.region_agreement.end())
      cj["region_agreement"] = a->second;
    for (const auto& s : t.scores)
      cj["copies"].push_back({{"copy_id", s.copy_id},
                              {"correlation", s.correlation},
                              {"p_value", s.corrected_p},
                              {"compared", s.compared},
                              {"binomial_neg_log10_p", s.binomial_neg_log10_p},
                              {"calibrated_neg_log10_p", s.calibrated_neg_log10_p},
                              {"sign_neg_log10_p", s.sign_neg_log10_p},
                              {"matched_statistic", s.matched_statistic},
                              {"matched_neg_log10_p", s.matched_neg_log10_p},
                              {"matched_reading", s.matched_reading},
                              {"null_mean", s.null_mean},
                              {"null_sd", s.null_sd},
                              {"payload_matches", s.payload_matches},
                              {"bit_error_rate", s.bit_error_rate},
                              {"strength", s.strength}});
    details["candidates"].push_back(cj);
  }
  if (det.best) {
    const jobs::CopyScore& best = *det.best;
    d.correlation = best.correlation;
    d.p_value = best.corrected_p;
    details["best_neg_log10_corrected_p"] = det.best_neg_log10_corrected_p;
    // Uncorrected, as computed: the verdict's p is the larger of the two, then Bonferroni.
    details["best_binomial_p"] = best.binomial_p;
    details["best_calibrated_p"] = best.calibrated_p;
    details["best_null_sd"] = best.null_sd;
    details["best_sign_neg_log10_p"] = best.sign_neg_log10_p;
    details["best_matched_neg_log10_p"] = best.matched_neg_log10_p;
    details["resync_method"] = best_t->alignment.method;
    details["resync_residual"] = best_t->alignment.residual;
    d.resync_method = best_t->alignment.method;
    if (std::isfinite(best_t->alignment.residual)) d.resync_residual = best_t->alignment.residual;
    details["best_copy_id"] = best.copy_id;
  }
  json attributed = json::array();
  for (const auto& a : det.attributed) {
    json aj{{"copy_id", a.copy_id}, {"customer_id", a.customer_id}, {"corrected_p", a.corrected_p},
            {"neg_log10_corrected_p", a.neg_log10_corrected_p}};
    if (auto c = st.get_customer(a.customer_id)) aj["customer"] = c->name;
    attributed.push_back(aj);
  }
  details["attributed"] = attributed;
  d.details_json = details.dump();

  if (!det.reason.empty()) details["reason"] = det.reason;
  d.details_json = details.dump();
  return {d, det.reason};
}

store::JobRecords run_detect(store::Store& st, const store::Job& job, const HandlerContext& ctx,
                             ContextCache* contexts) {
  const Config& cfg = ctx.config;
  if (contexts) contexts->set_budget(static_cast<std::size_t>(cfg.context_cache_mb) << 20);
  json p = parse_payload(job);
  jobs::Suspect suspect;
  suspect.name = fs::path(str_field(p, "name", job)).filename().string();
  auto bytes = input_bytes(st, p, job, &suspect.sha256, cfg);
  suspect.mesh = parse_input(bytes, suspect.name, &suspect.stream_metadata, cfg.cad);
  check_triangles(suspect.mesh, suspect.name, cfg);
  const DetectionRecord dr = detect_record(st, suspect, {cfg.p_threshold, cfg.max_candidates}, contexts);
  const store::NewDetection& d = dr.detection;
  const json details = json::parse(d.details_json);
  const json attributed = details["attributed"];
  const std::string& name = suspect.name;
  const std::string& sha = suspect.sha256;
  const int copies_tried = details.value("copies_tried", 0);
  const std::string match = details.value("match", "");
  store::JobRecords rec;
  rec.detections.push_back(d);
  if (cfg.evidence_auto && d.verdict == "attributed") {
    // Enqueued in the transaction that records the detection: a crash loses neither.
    store::JobSpec ev;
    ev.kind = "evidence";
    ev.payload_json = json{{"detect_job", job.id}}.dump();
    ev.idempotency_key = "evidence:job:" + std::to_string(job.id);
    ev.max_attempts = cfg.max_attempts;
    rec.follow_ups.push_back(ev);
  }
  rec.audit.push_back({ctx.worker_id, "detect", "job:" + std::to_string(job.id),
                       json{{"suspect_sha256", sha}, {"verdict", d.verdict}}.dump()});
  json result{{"verdict", d.verdict}, {"suspect_sha256", sha}, {"copies_tried", copies_tried}, {"match", match}};
  if (!dr.reason.empty()) result["reason"] = dr.reason;
  if (d.asset_id) result["asset_id"] = *d.asset_id;
  if (d.copy_id) result["copy_id"] = *d.copy_id;
  if (d.customer_id) {
    result["customer_id"] = *d.customer_id;
    if (auto c = st.get_customer(*d.customer_id)) result["customer"] = c->name;
  }
  if (!attributed.empty()) result["attributed"] = attributed;
  if (d.p_value) result["p_value"] = *d.p_value;
  if (details.contains("best_neg_log10_corrected_p")) result["neg_log10_p"] = details["best_neg_log10_corrected_p"];
  if (d.correlation) result["correlation"] = *d.correlation;
  for (const char* k : {"best_binomial_p", "best_calibrated_p", "best_null_sd", "best_sign_neg_log10_p",
                        "best_matched_neg_log10_p"})
    if (details.contains(k)) result[std::string(k).substr(5)] = details[k];
  if (!d.decoded_payload_hex.empty()) result["decoded_payload"] = d.decoded_payload_hex;
  const bool resynced = details.contains("resync_method");
  if (resynced) {
    result["resync_method"] = details["resync_method"];
    result["resync_residual"] = details["resync_residual"];
  }
  rec.result_json = result.dump();
  spdlog::info("detect {}: {} (match: {}; {} copies tried; best corrected p {:.3g}; resync {} residual {:.3g})", name,
               d.verdict, match.empty() ? "none" : match, copies_tried, d.p_value ? *d.p_value : 1.0,
               resynced ? d.resync_method : "none", resynced && details["resync_residual"].is_number() ? details["resync_residual"].get<double>() : 0.0);
  if (contexts) {
    const ContextCache::Stats cs = contexts->stats();
    spdlog::debug("resync contexts: {} held ({} in use), {:.1f} of {:.0f} MB; {} built, {} reused, {} evicted",
                  cs.entries, cs.in_use, static_cast<double>(cs.bytes) / (1 << 20),
                  static_cast<double>(cs.budget) / (1 << 20), cs.builds, cs.hits, cs.evictions);
  }
  return rec;
}

store::JobRecords run_evidence(store::Store& st, const store::Job& job, const HandlerContext& ctx) {
  const Config& cfg = ctx.config;
  const json p = parse_payload(job);
  if (!p.contains("detect_job") || !p["detect_job"].is_number_integer())
    throw PermanentError("job " + std::to_string(job.id) + ": payload needs \"detect_job\" (an integer job id)");
  const std::int64_t detect_job = p["detect_job"].get<std::int64_t>();
  const std::optional<store::Detection> det = st.detection_of_job(detect_job);
  if (!det) throw PermanentError("job " + std::to_string(job.id) + ": detect job " + std::to_string(detect_job) +
                                 " recorded no detection");
  EvidenceOptions o;
  o.chromium = cfg.evidence_pdf ? "" : "none";
  o.tsa_url = cfg.tsa_url;
  o.tsa_ca_file = cfg.tsa_ca_file;
  const std::string out = evidence_package_dir(cfg, *det).string();
  json result{{"detection_id", det->id}, {"package", out}};
  store::JobRecords rec;
  if (fs::exists(out / fs::path("statement.dsse.json"))) {
    // An earlier attempt wrote it whole (the rename is the last step) and died before completing.
    result["written_before"] = true;
  } else {
    fs::create_directories(fs::path(out).parent_path());
    const EvidencePackage pkg = write_evidence_package(st, store::resolve_home(cfg.home), det->id, out, o);
    result["files"] = pkg.files;
    result["key_id"] = pkg.key_id;
    if (!pkg.pdf_note.empty()) result["pdf_note"] = pkg.pdf_note;
    result["timestamp"] = pkg.timestamp_note;
  }
  result["statement_sha256"] = support::sha256_file_hex(out + "/statement.json");
  rec.audit.push_back({ctx.worker_id, "evidence.write", "detection:" + std::to_string(det->id),
                       json{{"package", out}, {"statement_sha256", result["statement_sha256"]}}.dump()});
  rec.result_json = result.dump();
  spdlog::info("evidence for detection {}: {}", det->id, out);
  return rec;
}

HandlerMap default_handlers() {
  HandlerMap m;
  auto refused = std::make_shared<RefusedParts>();
  m["protect"] = [refused](store::Store& st, const store::Job& job, const HandlerContext& ctx) {
    return run_protect(st, job, ctx, refused.get());
  };
  m["evidence"] = run_evidence;
  // One cache for every worker thread the map is handed to (copies share it).
  auto contexts = std::make_shared<ContextCache>(static_cast<std::size_t>(Config{}.context_cache_mb) << 20);
  m["detect"] = [contexts](store::Store& st, const store::Job& job, const HandlerContext& ctx) {
    return run_detect(st, job, ctx, contexts.get());
  };
  m["webhook"] = run_webhook;
  m["noop"] = [](store::Store&, const store::Job&, const HandlerContext&) { return store::JobRecords{}; };
  return m;
}

std::filesystem::path evidence_package_dir(const Config& cfg, const store::Detection& det) {
  const std::string case_id = "MM-" + std::to_string(det.id) + "-" + det.suspect_sha256.substr(0, 12);
  return fs::path(cfg.output_dir) / "evidence" / case_id;
}

store::EnqueueResult submit_protect(store::Store& st, const std::string& customer, const std::string& path,
                                    const std::string& name, int max_attempts, const std::string& actor,
                                    const std::string& output_format, const std::string& object) {
  std::string sha = st.blobs().put_file(path);
  json p{{"customer", customer}, {"input_sha256", sha}, {"name", name}};
  if (!output_format.empty()) p["output_format"] = output_format;
  if (!object.empty()) p["object"] = object;
  store::JobSpec spec;
  spec.kind = "protect";
  spec.payload_json = p.dump();
  spec.max_attempts = max_attempts;
  spec.idempotency_key = "protect:" + customer + ":" + sha + ":" + name + (output_format.empty() ? "" : ":" + output_format) +
                         (object.empty() ? "" : ":object=" + object);
  return st.enqueue(spec, actor);
}

store::EnqueueResult submit_detect(store::Store& st, const std::string& path, const std::string& name,
                                   int max_attempts, const std::string& actor) {
  std::string sha = st.blobs().put_file(path);
  store::JobSpec spec;
  spec.kind = "detect";
  spec.payload_json = json{{"input_sha256", sha}, {"name", name}}.dump();
  spec.max_attempts = max_attempts;
  spec.idempotency_key = "detect:" + sha + ":" + name;
  return st.enqueue(spec, actor);
}

}  // namespace mm::service

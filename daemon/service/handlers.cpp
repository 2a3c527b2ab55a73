#include "service/handlers.h"

#include <sodium.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <spdlog/spdlog.h>
#include <string_view>

#include "jobs/detect.h"
#include "jobs/payload.h"
#include "jobs/prepared_asset.h"
#include "jobs/protect.h"
#include "meshio/read_mesh.h"

namespace mm::service {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr int kAllCopies = 1000000;

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string format_of(const std::string& name) {
  std::string ext = lower(fs::path(name).extension().string());
  if (!ext.empty()) ext.erase(0, 1);
  if (ext != "stl" && ext != "obj" && ext != "off" && ext != "ply")
    throw PermanentError(name + ": unsupported format \"" + ext + "\" (expected .stl, .obj, .off or .ply)");
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

// The input's bytes: from the blob store, or (PDM rows) from a path, which is stored first.
std::vector<std::uint8_t> input_bytes(store::Store& st, const json& p, const store::Job& job, std::string* sha) {
  std::string h = str_field(p, "input_sha256", job, false);
  if (h.empty()) {
    std::string path = str_field(p, "input_path", job, false);
    if (path.empty()) throw PermanentError("job " + std::to_string(job.id) + ": payload needs input_sha256 or input_path");
    try {
      h = st.blobs().put_file(path);
    } catch (const store::BlobError& e) {
      throw PermanentError(e.what());
    }
  }
  if (!store::is_sha256_hex(h)) throw PermanentError("job " + std::to_string(job.id) + ": input_sha256 is not a SHA-256 hex");
  if (!st.blobs().contains(h)) throw PermanentError("job " + std::to_string(job.id) + ": input blob " + h + " is not in the store");
  *sha = h;
  return st.blobs().get(h);
}

Mesh parse_input(const std::vector<std::uint8_t>& bytes, const std::string& name) {
  std::string fmt = format_of(name);
  try {
    return parse_mesh(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), fmt, name);
  } catch (const InputError& e) {
    throw PermanentError(e.what());
  }
}

const char* method_name(Method m) { return m == Method::Additive ? "additive" : "multiplicative"; }

json settings_json(const jobs::WatermarkSettings& s) {
  return {{"method", method_name(s.params.method)},
          {"strength", s.params.strength},
          {"threshold", s.params.threshold},
          {"message_bits", s.message_bits}};
}

jobs::WatermarkSettings settings_from_json(const json& j) {
  jobs::WatermarkSettings s;
  s.params.method = j.at("method").get<std::string>() == "additive" ? Method::Additive : Method::Multiplicative;
  s.params.strength = j.at("strength").get<double>();
  s.params.threshold = j.at("threshold").get<double>();
  s.message_bits = j.at("message_bits").get<int>();
  return s;
}

struct LoadedAsset {
  store::Polyhedron row;
  jobs::PreparedAsset prepared;
};

// The asset's prepared polyhedron and basis: from the cache, or computed once and stored
// (blobs first, then the row; a concurrent worker doing the same gets the same bytes and row).
LoadedAsset get_or_prepare(store::Store& st, const store::Asset& asset, const Mesh& mesh, const Config& cfg) {
  jobs::PrepareParams pp;
  pp.max_vertices = cfg.max_vertices;
  const std::string key = pp.key();
  if (auto row = st.find_polyhedron(asset.id, key)) {
    return {*row, jobs::decode_prepared(st.blobs().get(row->polyhedron_blob), st.blobs().get(row->basis_blob),
                                        "asset " + std::to_string(asset.id) + " polyhedron")};
  }
  jobs::PreparedAsset prepared;
  try {
    prepared = jobs::prepare_asset(mesh, pp, asset.name);
  } catch (const InputError& e) {
    throw PermanentError(e.what());
  }
  store::Polyhedron row;
  row.asset_id = asset.id;
  row.params_key = key;
  row.polyhedron_blob = st.blobs().put(jobs::encode_polyhedron(prepared));
  row.basis_blob = st.blobs().put(serialize_basis(prepared.basis));
  json meta = json::parse(prepared.signature.to_json());
  row.meta_json = json{{"signature", meta}, {"control_vertices", prepared.control.num_vertices()}}.dump();
  row = st.put_polyhedron(row);
  return {row, std::move(prepared)};
}

std::optional<LoadedAsset> load_prepared(store::Store& st, std::int64_t asset_id) {
  auto row = st.find_polyhedron(asset_id, jobs::PrepareParams{}.key());
  if (!row) return std::nullopt;
  return LoadedAsset{*row, jobs::decode_prepared(st.blobs().get(row->polyhedron_blob), st.blobs().get(row->basis_blob),
                                                 "asset " + std::to_string(asset_id) + " polyhedron")};
}

// Nonce and payload of a copy, derived from what identifies the copy, so a re-run after a crash
// reproduces the same output bytes. Not secret: the key is what protects the mark.
void derive_copy_identity(const std::string& asset_sha, std::int64_t customer_id, int key_version,
                          const std::string& idem, int counter, Nonce& nonce, std::uint64_t& payload) {
  std::string msg = "meshmark-copy-v1|" + asset_sha + "|" + std::to_string(customer_id) + "|" +
                    std::to_string(key_version) + "|" + idem + "|" + std::to_string(counter);
  unsigned char h[32];
  crypto_generichash(h, sizeof h, reinterpret_cast<const unsigned char*>(msg.data()), msg.size(), nullptr, 0);
  std::copy(h, h + 24, nonce.begin());
  payload = 0;
  for (int i = 0; i < 8; ++i) payload |= std::uint64_t(h[24 + i]) << (8 * i);
}

std::string copy_idempotency_key(const store::Job& job) {
  return job.idempotency_key.empty() ? "job:" + std::to_string(job.id) : job.idempotency_key;
}

}  // namespace

std::string output_path_for(const Config& cfg, const std::string& customer, const std::string& name,
                            const std::string& asset_sha256, const std::string& format) {
  fs::path n(name);
  std::string stem = n.stem().string();
  return (fs::path(cfg.output_dir) / customer / (stem + "-" + asset_sha256.substr(0, 12) + "." + format)).string();
}

store::JobRecords run_protect(store::Store& st, const store::Job& job, const HandlerContext& ctx) {
  const Config& cfg = ctx.config;
  json p = parse_payload(job);
  std::string customer_name = str_field(p, "customer", job);
  std::string name = fs::path(str_field(p, "name", job)).filename().string();
  if (name.empty() || name == "." || name == "..") throw PermanentError("job " + std::to_string(job.id) + ": bad name");
  std::string out_format = str_field(p, "output_format", job, false);
  auto customer = st.find_customer(customer_name);
  if (!customer) throw PermanentError("unknown customer \"" + customer_name + "\" (add it with: meshmark customer add)");

  std::string sha;
  auto bytes = input_bytes(st, p, job, &sha);
  Mesh mesh = parse_input(bytes, name);
  std::string in_format = format_of(name);
  if (out_format.empty()) out_format = cfg.output_format == "same" ? in_format : cfg.output_format;
  if (out_format != "stl" && out_format != "obj" && out_format != "off" && out_format != "ply")
    throw PermanentError("job " + std::to_string(job.id) + ": unsupported output_format \"" + out_format + "\"");

  store::Asset asset = st.put_asset_bytes(bytes, name);
  LoadedAsset la = get_or_prepare(st, asset, mesh, cfg);
  store::CustomerKey ck = st.customer_key(customer->id);

  // The payload must tell this copy apart from every other copy of the asset.
  const std::string idem = copy_idempotency_key(job);
  std::set<std::string> taken;
  for (const auto& c : st.list_copies(asset.id, kAllCopies))
    if (!(c.customer_id == customer->id && c.key_version == ck.version && c.idempotency_key == idem))
      taken.insert(c.payload_hex);
  jobs::WatermarkSettings ws = cfg.watermark;
  Nonce nonce{};
  std::uint64_t payload = 0;
  std::string phex;
  for (int counter = 0;; ++counter) {
    derive_copy_identity(asset.sha256, customer->id, ck.version, idem, counter, nonce, payload);
    if (ws.message_bits < 64) payload &= (std::uint64_t(1) << ws.message_bits) - 1;
    phex = jobs::payload_hex(payload, ws.message_bits);
    if (!taken.count(phex)) break;
  }

  Mesh copy;
  try {
    copy = jobs::make_copy(la.prepared, ck.key.bytes(), nonce, payload, ws);
  } catch (const std::invalid_argument& e) {
    throw PermanentError(name + ": cannot watermark: " + e.what());
  }
  std::string out = output_path_for(cfg, customer->name, name, asset.sha256, out_format);
  fs::create_directories(fs::path(out).parent_path());
  write_mesh(copy, out);  // temporary name, fsync, rename
  std::string out_sha = store::sha256_file_hex(out);

  store::NewCopy nc;
  nc.asset_id = asset.id;
  nc.customer_id = customer->id;
  nc.key_version = ck.version;
  nc.idempotency_key = idem;
  nc.nonce.assign(nonce.begin(), nonce.end());
  nc.payload_hex = phex;
  json params = settings_json(ws);
  params["prepare"] = la.row.params_key;
  params["basis_sha256"] = la.row.basis_blob;
  nc.params_json = params.dump();
  nc.outputs_json = json{{"files", json::array({json{{"path", out}, {"sha256", out_sha}, {"format", out_format}}})}}.dump();
  nc.polyhedron_id = la.row.id;

  store::JobRecords rec;
  rec.copies.push_back(nc);
  rec.audit.push_back({ctx.worker_id, "copy.issue", "asset:" + std::to_string(asset.id),
                       json{{"customer", customer->name}, {"key_version", ck.version}, {"output", out}}.dump()});
  rec.result_json = json{{"asset_id", asset.id},
                         {"asset_sha256", asset.sha256},
                         {"customer", customer->name},
                         {"key_version", ck.version},
                         {"output", out},
                         {"output_sha256", out_sha},
                         {"payload", phex},
                         {"vertices", mesh.num_vertices()}}
                        .dump();
  return rec;
}

store::JobRecords run_detect(store::Store& st, const store::Job& job, const HandlerContext& ctx) {
  const Config& cfg = ctx.config;
  json p = parse_payload(job);
  std::string name = fs::path(str_field(p, "name", job)).filename().string();
  std::string sha;
  auto bytes = input_bytes(st, p, job, &sha);
  Mesh suspect = parse_input(bytes, name);

  // Candidate assets: exact hash of an issued copy or of an original first, then by signature.
  std::vector<std::int64_t> candidates;
  std::string match;
  auto add = [&](std::int64_t id) {
    if (std::find(candidates.begin(), candidates.end(), id) == candidates.end()) candidates.push_back(id);
  };
  std::vector<store::IssuedCopy> all_copies = st.list_copies(std::nullopt, kAllCopies);
  for (const auto& c : all_copies) {
    try {
      for (const auto& f : json::parse(c.outputs_json).value("files", json::array()))
        if (f.value("sha256", "") == sha) add(c.asset_id), match = "hash of issued copy " + std::to_string(c.id);
    } catch (const json::exception&) {
    }
  }
  if (auto a = st.find_asset(sha)) {
    add(a->id);
    if (match.empty()) match = "hash of original asset " + std::to_string(a->id);
  }
  if (candidates.empty()) {
    jobs::ShapeSignature sig = jobs::shape_signature(suspect);
    std::vector<std::pair<double, std::int64_t>> ranked;
    for (const auto& a : st.list_assets(kAllCopies)) {
      auto row = st.find_polyhedron(a.id, jobs::PrepareParams{}.key());
      if (!row) continue;
      try {
        auto meta = json::parse(row->meta_json);
        double d = jobs::signature_distance(sig, jobs::ShapeSignature::from_json(meta.at("signature").dump()));
        if (d < 0.5) ranked.push_back({d, a.id});
      } catch (const std::exception&) {
      }
    }
    std::sort(ranked.begin(), ranked.end());
    for (const auto& r : ranked) {
      if (static_cast<int>(candidates.size()) >= cfg.max_candidates) break;
      add(r.second);
    }
    if (!candidates.empty()) match = "shape signature";
  }

  struct Tried {
    std::int64_t asset_id;
    jobs::Registration reg;
    jobs::Verdict verdict;
    std::vector<store::IssuedCopy> copies;
  };
  std::vector<Tried> tried;
  int total = 0;
  for (std::int64_t asset_id : candidates) {
    auto la = load_prepared(st, asset_id);
    if (!la) continue;
    Tried t{asset_id, jobs::register_suspect(la->prepared, suspect), {}, st.list_copies(asset_id, kAllCopies)};
    std::vector<jobs::CopyCandidate> cands;
    for (const auto& c : t.copies) {
      jobs::CopyCandidate cc;
      cc.copy_id = c.id;
      cc.key = st.customer_key(c.customer_id, c.key_version).key.bytes();
      if (c.nonce.size() != cc.nonce.size()) continue;
      std::copy(c.nonce.begin(), c.nonce.end(), cc.nonce.begin());
      try {
        cc.payload = jobs::parse_payload_hex(c.payload_hex);
        cc.settings = settings_from_json(json::parse(c.params_json));
      } catch (const std::exception&) {
        continue;
      }
      cands.push_back(cc);
    }
    if (static_cast<int>(la->prepared.control.num_vertices()) == t.reg.points.rows())
      t.verdict = jobs::detect_copy(la->prepared, t.reg.points, cands, cfg.p_threshold);
    total += t.verdict.copies_tried;
    tried.push_back(std::move(t));
  }

  // Bonferroni over every copy tried for every candidate asset.
  store::NewDetection d;
  d.suspect_sha256 = sha;
  d.suspect_name = name;
  json details;
  details["match"] = match;
  details["copies_tried"] = total;
  details["p_threshold"] = cfg.p_threshold;
  details["candidates"] = json::array();
  const jobs::CopyScore* best = nullptr;
  const Tried* best_t = nullptr;
  for (auto& t : tried) {
    json cj{{"asset_id", t.asset_id},
            {"registration", t.reg.method},
            {"registration_rms", std::isfinite(t.reg.rms) ? t.reg.rms : -1.0},
            {"matched_fraction", t.reg.matched_fraction},
            {"copies", json::array()}};
    for (auto& s : t.verdict.scores) {
      s.corrected_p = std::min(1.0, s.p_value * std::max(1, total));
      cj["copies"].push_back({{"copy_id", s.copy_id},
                              {"correlation", s.correlation},
                              {"p_value", s.corrected_p},
                              {"payload_matches", s.payload_matches},
                              {"bit_error_rate", s.bit_error_rate}});
      if (!best || s.corrected_p < best->corrected_p ||
          (s.corrected_p == best->corrected_p && s.correlation > best->correlation))
        best = &s, best_t = &t;
    }
    details["candidates"].push_back(cj);
  }
  if (candidates.empty()) {
    d.verdict = "unknown asset";
  } else if (!best) {
    d.verdict = "no watermark found";
    d.asset_id = candidates.front();
  } else {
    d.asset_id = best_t->asset_id;
    d.correlation = best->correlation;
    d.p_value = best->corrected_p;
    details["best_neg_log10_corrected_p"] = std::max(0.0, best->neg_log10_p - std::log10(std::max(1, total)));
    int bits = 32;
    for (const auto& c : best_t->copies)
      if (c.id == best->copy_id) {
        bits = static_cast<int>(c.payload_hex.size()) * 4;
        if (best->corrected_p < cfg.p_threshold && best->payload_matches) {
          d.verdict = "attributed";
          d.copy_id = c.id;
          d.customer_id = c.customer_id;
        }
      }
    d.decoded_payload_hex = jobs::payload_hex(best->decoded_payload, bits);
    if (d.verdict.empty()) d.verdict = "no watermark found";
    details["best_copy_id"] = best->copy_id;
  }
  d.details_json = details.dump();

  store::JobRecords rec;
  rec.detections.push_back(d);
  rec.audit.push_back({ctx.worker_id, "detect", "job:" + std::to_string(job.id),
                       json{{"suspect_sha256", sha}, {"verdict", d.verdict}}.dump()});
  json result{{"verdict", d.verdict}, {"suspect_sha256", sha}, {"copies_tried", total}, {"match", match}};
  if (d.asset_id) result["asset_id"] = *d.asset_id;
  if (d.copy_id) result["copy_id"] = *d.copy_id;
  if (d.customer_id) {
    result["customer_id"] = *d.customer_id;
    if (auto c = st.get_customer(*d.customer_id)) result["customer"] = c->name;
  }
  if (d.p_value) result["p_value"] = *d.p_value;
  if (details.contains("best_neg_log10_corrected_p")) result["neg_log10_p"] = details["best_neg_log10_corrected_p"];
  if (d.correlation) result["correlation"] = *d.correlation;
  if (!d.decoded_payload_hex.empty()) result["decoded_payload"] = d.decoded_payload_hex;
  rec.result_json = result.dump();
  spdlog::info("detect {}: {} (match: {}; {} copies tried; best corrected p {:.3g})", name, d.verdict,
               match.empty() ? "none" : match, total, d.p_value ? *d.p_value : 1.0);
  return rec;
}

HandlerMap default_handlers() {
  HandlerMap m;
  m["protect"] = run_protect;
  m["detect"] = run_detect;
  m["noop"] = [](store::Store&, const store::Job&, const HandlerContext&) { return store::JobRecords{}; };
  return m;
}

store::EnqueueResult submit_protect(store::Store& st, const std::string& customer, const std::string& path,
                                    const std::string& name, int max_attempts, const std::string& actor,
                                    const std::string& output_format) {
  std::string sha = st.blobs().put_file(path);
  json p{{"customer", customer}, {"input_sha256", sha}, {"name", name}};
  if (!output_format.empty()) p["output_format"] = output_format;
  store::JobSpec spec;
  spec.kind = "protect";
  spec.payload_json = p.dump();
  spec.max_attempts = max_attempts;
  spec.idempotency_key = "protect:" + customer + ":" + sha + ":" + name + (output_format.empty() ? "" : ":" + output_format);
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
